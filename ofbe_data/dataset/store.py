"""Dataset folders of labelled windows (products.md §Dataset), format ``ofbe-windows/1``.

A dataset folder ``processed/datasets/<name>/`` holds

``windows.h5``
    ``X`` float32 (N, T, 3), m/s², sensor frame, one chunk per window (gzip 4, shuffle,
    Fletcher-32 checksums), appended recording by recording; ``y`` float64 (N, 3), m/s², the
    apparent-bias label of each window's recording; ``meta/`` with one 1-D dataset per column
    of ``windows.parquet`` in the same row order. Root attributes describe the format.
``windows.parquet``
    One row per window, columns :data:`WINDOW_COLUMNS` then one ``fold_<protocol>`` column
    per protocol; JSON provenance under the schema metadata key ``ofbe``.
``signals.parquet``
    The rows of ``windows.parquet`` plus ``X`` (:data:`SIGNAL_COLUMN`), the window as a (T, 3)
    float32 array equal to the HDF5 ``X``: what Hugging Face and Croissant read
    (:mod:`~ofbe_data.dataset.signals`); the toolkit itself reads the HDF5 file.
``datapackage.json``, ``croissant.json``, ``README.md``, ``CITATION.cff``
    Frictionless Data Package, MLCommons Croissant description, dataset card and citation file.
``SHA256SUMS``
    ``sha256sum`` lines for every other file, written last.

A dataset of more than ``shard_windows`` windows (:data:`DEFAULT_SHARD_WINDOWS` unless the
builder is told otherwise) is *sharded*: instead of ``windows.h5`` it holds
``windows-00000.h5``, ``windows-00001.h5``, … (:func:`shard_name`), each laid out like
``windows.h5`` for its ``shard_windows`` consecutive rows (the last one the remainder), with the
root attributes ``shard``, ``shard_windows`` and ``first_window_id`` added. ``windows.parquet``
is then the index of all rows: it gains the columns ``shard`` and ``shard_row`` after
``window_id`` (:data:`SHARD_COLUMNS`, also in every shard's ``meta/``) and its provenance
the key ``shards`` (``windows_per_shard`` and the ``files`` with their ``n_windows``), and
``signals.parquet`` is split the same way: ``signals-00000.parquet``, … (:func:`signals_name`),
one per HDF5 shard with its rows. A dataset of at most ``shard_windows`` windows keeps the
single-file layout byte for byte.

Folders written before ``signals.parquet`` and ``croissant.json`` existed still verify and load;
``ofbe-dataset export`` adds both to their copy.

Everything is deterministic: identical inputs give byte-identical files. HDF5 objects are
created without timestamps (``track_times=False``) in a file of the earliest format
(``libver="earliest"``): newer object headers store the modification time of groups, and
h5py offers no switch for that. No creation dates are written anywhere else either.

This module holds what every part of the store shares: the format's constants and errors, the
column schema, :class:`DatasetInfo` and reading a folder's headers. Writing is in
:mod:`~ofbe_data.dataset.writer`, the package files (datapackage, card, citation, checksums)
in :mod:`~ofbe_data.dataset.package`, verifying and loading in
:mod:`~ofbe_data.dataset.reader`, exporting in :mod:`~ofbe_data.dataset.export`.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ofbe_data.core.checksums import file_sha256 as sha256_file  # noqa: F401 (re-exported)
from ofbe_data.core.errors import ConfigError, OfbeError

SCHEMA_VERSION = "ofbe-windows/1"
#: ``format`` of the Parquet provenance.
DATASET_FORMAT = "ofbe-windows"

H5_NAME = "windows.h5"
#: Windows per shard file above which (and in which) a dataset is sharded, unless told otherwise:
#: above the paper's datasets (at most ~2,500 windows of 3,000 samples), ~150 MB of float32 X a shard.
DEFAULT_SHARD_WINDOWS = 4096
PARQUET_NAME = "windows.parquet"
DATAPACKAGE_NAME = "datapackage.json"
README_NAME = "README.md"
CITATION_NAME = "CITATION.cff"
SUMS_NAME = "SHA256SUMS"
CROISSANT_NAME = "croissant.json"
SIGNALS_NAME = "signals.parquet"
#: The column of the signal Parquet files that holds the window: (T, 3) float32, m/s².
SIGNAL_COLUMN = "X"

UNITS = "m/s^2"
FRAME = "sensor"
H5_LIBVER = "earliest"
PAPER_TITLE = ("Orientation-Free Neural Network-Based Bias Estimation for Low-Cost Stationary "
               "Accelerometers")
PAPER_AUTHORS = ("Levin", "Klein")

TF_BLOCK = 256  # windows read from the file at a time by the tf.data generator
_PROTOCOL_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")
SUMS_LINE_RE = re.compile(r"^([0-9a-f]{64}) [ *](.+)$")
SHARD_RE = re.compile(r"^windows-(\d{5})\.h5$")
"""Names of shard files: ``windows-<5 digits>.h5``."""
SIGNALS_RE = re.compile(r"^signals(-\d{5})?\.parquet$")
"""Names of signal Parquet files: ``signals.parquet`` or ``signals-<5 digits>.parquet``."""


def shard_name(index: int) -> str:
    """File name of shard ``index`` (0-based) of a sharded dataset: ``windows-00000.h5``, …."""
    return f"windows-{index:05d}.h5"


def signals_name(index: int | None = None) -> str:
    """File name of the signal Parquet file of HDF5 shard ``index`` (``signals-00000.parquet``,
    …), or of the single-file layout's ``windows.h5`` (``signals.parquet``) when ``index`` is None."""
    return SIGNALS_NAME if index is None else f"signals-{index:05d}.parquet"


def signal_names(layout: Sequence[tuple[str, int]] | None) -> list[str]:
    """The signal Parquet files that go with a folder's HDF5 layout (:func:`shard_layout`'s value):
    ``["signals.parquet"]`` for one ``windows.h5``, one ``signals-<shard>.parquet`` per shard."""
    return [SIGNALS_NAME] if layout is None else [signals_name(i) for i in range(len(layout))]


class DatasetError(OfbeError):
    """A dataset folder, or what is written to one, does not follow ``ofbe-windows/1``.

    Parameters
    ----------
    path
        The file (or folder) at fault.
    expected, found
        What the format asks for and what is there.
    field
        Dataset, column or key inside the file, when there is one.
    """

    def __init__(self, path: str | Path, expected: str, found: str, field: str | None = None) -> None:
        self.path = Path(path)
        self.expected = expected
        self.found = found
        self.field = field
        where = f"{path}: {field}: " if field else f"{path}: "
        super().__init__(f"{where}expected {expected}, found {found}")


class ChecksumError(DatasetError):
    """A file's SHA-256 differs from the one recorded in ``SHA256SUMS`` or ``datapackage.json``."""


# ---------------------------------------------------------------------------------------------
# Columns


def spdx_licence(value: str, source: str = "licence") -> str:
    """``value`` as a normalised SPDX licence expression (``CC-BY-4.0``, ``MIT OR Apache-2.0``).

    Raises
    ------
    ConfigError
        Not a known SPDX licence id or expression (the message says where the list is).
    """
    from license_expression import get_spdx_licensing

    info = get_spdx_licensing().validate(value)
    if info.errors or not info.normalized_expression:
        raise ConfigError(source, "licence", "an SPDX licence id such as CC-BY-4.0, CC0-1.0 or ODbL-1.0 "
                          "(https://spdx.org/licenses/)", repr(value))
    return str(info.normalized_expression)


@dataclass(frozen=True)
class ColumnSpec:
    """One fixed column of ``windows.parquet``: kind is ``string``, ``int`` or ``float``."""

    name: str
    kind: str
    description: str
    unit: str | None = None
    nullable: bool = False


_COLUMNS: tuple[ColumnSpec, ...] = (
    ColumnSpec("window_id", "int", "row index of the window in windows.h5"),
    ColumnSpec("campaign", "string", "campaign id"),
    ColumnSpec("session", "string", "session id"),
    ColumnSpec("recording", "string", "recording id within the session"),
    ColumnSpec("device", "string", "device (DUT) id"),
    ColumnSpec("power_cycle", "int", "power cycle of the device: the bias instance"),
    ColumnSpec("window_index", "int",
            "index of the window within its recording's stationary segment; 0 is the first window "
            "(the test signal)"),
    ColumnSpec("start_sample", "int",
            "first sample of the window, counted from the start of the stationary segment", "sample"),
    *(ColumnSpec(f"bias_{a}", "float", f"apparent-bias label b_app, {a} axis, sensor frame", UNITS)
      for a in "xyz"),
    *(ColumnSpec(f"offset_{a}", "float",
              f"zero-g offset b, {a} axis, sensor frame, when the campaign fit determines it (else null)",
              UNITS, nullable=True) for a in "xyz"),
    *(ColumnSpec(f"gravity_{a}", "float", f"unit specific-force direction u, {a} component, sensor frame",
                 "1") for a in "xyz"),
    ColumnSpec("roll_deg", "float", "roll of the device implied by u", "deg"),
    ColumnSpec("pitch_deg", "float", "pitch of the device implied by u", "deg"),
    ColumnSpec("g_local", "float", "local gravity magnitude", UNITS),
    ColumnSpec("fs_hz", "float", "measured sample rate of the device in this recording", "Hz"),
    ColumnSpec("label_method", "string",
               "how the label was made (level / reference-rodrigues / campaign-fit / multi-position)"),
    ColumnSpec("raw_sha256", "string", "SHA-256 of the raw device file labelled"),
)

#: The fixed columns of ``windows.parquet``, in order; the fold columns follow them.
WINDOW_COLUMNS: list[str] = [c.name for c in _COLUMNS]
COLUMN_BY_NAME = {c.name: c for c in _COLUMNS}
#: Columns that identify a recording's windows (one label per recording and device).
RECORDING_KEY = ("campaign", "session", "recording", "device")
#: Columns of a sharded dataset's index (``windows.parquet``), right after ``window_id``.
SHARD_COLUMNS = ("shard", "shard_row")
PER_WINDOW = ("window_id", "window_index", "start_sample", *SHARD_COLUMNS)
_ARROW_TYPES = {"string": pa.string(), "int": pa.int64(), "float": pa.float64()}


def fold_column(protocol: str) -> str:
    """Name of the fold column of a protocol: ``fold_<protocol>``.

    Raises
    ------
    ConfigError
        When the protocol name is empty or holds characters other than letters, digits,
        ``.``, ``_`` and ``-`` (or starts with one of the last three).
    """
    if not isinstance(protocol, str) or not _PROTOCOL_RE.match(protocol):
        raise ConfigError("protocols", "protocol name",
                          "letters, digits, '.', '_' or '-', starting with a letter or digit",
                          repr(protocol))
    return f"fold_{protocol}"


def _fold_doc(protocol: str) -> ColumnSpec:
    return ColumnSpec(fold_column(protocol), "int",
                   f"test fold of the window's recording under protocol {protocol!r}, -1 when it is only "
                   "ever used for training")


_SHARD_DOCS = (ColumnSpec("shard", "int", "shard file holding the window: windows-<shard, 5 digits>.h5"),
               ColumnSpec("shard_row", "int", "row of the window within its shard file"))


def all_columns(protocols: Sequence[str], sharded: bool = False) -> list[ColumnSpec]:
    shard = list(_SHARD_DOCS) if sharded else []
    return [_COLUMNS[0], *shard, *_COLUMNS[1:], *(_fold_doc(p) for p in protocols)]


def arrow_schema(protocols: Sequence[str], sharded: bool = False) -> pa.Schema:
    return pa.schema([pa.field(c.name, _ARROW_TYPES[c.kind], nullable=c.nullable)
                      for c in all_columns(protocols, sharded)])


def signal_type(window_length: int) -> pa.DataType:
    """Arrow type of :data:`SIGNAL_COLUMN`: a fixed-size list of T fixed-size lists of 3 float32
    (one window, axes (sample, x/y/z), m/s²); list items named ``element`` as in Parquet's LIST."""
    inner = pa.list_(pa.field("element", pa.float32()), 3)
    return pa.list_(pa.field("element", inner), window_length)


def signal_schema(protocols: Sequence[str], window_length: int, sharded: bool = False) -> pa.Schema:
    """Columns of a signal Parquet file: those of ``windows.parquet``, then :data:`SIGNAL_COLUMN`."""
    base = arrow_schema(protocols, sharded)
    return base.append(pa.field(SIGNAL_COLUMN, signal_type(window_length), nullable=False))


def _is_signal_type(t: pa.DataType, window_length: int) -> bool:
    """Whether ``t`` is a (T, 3) float32 window, whatever its list items are called."""
    return (pa.types.is_fixed_size_list(t) and t.list_size == window_length
            and pa.types.is_fixed_size_list(t.value_type) and t.value_type.list_size == 3
            and t.value_type.value_type == pa.float32())


def same_signal_schema(found: pa.Schema, expected: pa.Schema, window_length: int) -> bool:
    """Same column names and types, X a (T, 3) float32 window whatever its list items are called
    (Parquet's LIST says ``element``, Arrow ``item``: readers of other versions may differ)."""
    return found.names == expected.names and all(
        _is_signal_type(f.type, window_length) if f.name == SIGNAL_COLUMN else f.type == e.type
        for f, e in zip(found, expected, strict=True))


# ---------------------------------------------------------------------------------------------
# Dataset description


def _is_json(value: Any) -> bool:
    try:
        json.dumps(value, allow_nan=False)
    except (TypeError, ValueError):
        return False
    return True


@dataclass(frozen=True)
class DatasetInfo:
    """What a dataset is: identity, provenance texts, windowing and protocols.

    Attributes
    ----------
    name
        Dataset name (the folder name under ``processed/datasets``).
    campaign
        Campaign the windows come from.
    kind
        Session kind (``gravity-aligned``, ``rotated``, ``multi-position``, ``simulated`` ...).
    title
        One-line title.
    description
        How the data were recorded or simulated (Markdown, for the card).
    labelling
        How the labels were made (Markdown, for the card).
    window_length
        Samples per window, T.
    stride
        Samples between the starts of consecutive windows of a recording.
    fs_hz
        Nominal sample rate, Hz.
    protocols
        Protocol name → JSON-ready description, e.g. ``{"description": ..., "n_folds": 5,
        "seed": 0}``. Each gets the column ``fold_<protocol>``; order is kept.
    licence
        SPDX licence id (or expression) of the data, checked and normalised
        (``cc-by-4.0`` → ``CC-BY-4.0``) by :func:`spdx_licence`.
    authors
        Authors (names of persons or of a group).
    version
        Dataset version.
    label_fidelity
        Known label errors (JSON-ready; a flat mapping or a mapping of mappings), rendered as a
        table on the card; ``None`` when not quantified.
    extra
        Further JSON-ready properties, kept in ``datapackage.json`` and listed on the card.
    """

    name: str
    campaign: str
    kind: str
    title: str
    description: str
    labelling: str
    window_length: int
    stride: int
    fs_hz: float
    protocols: dict[str, dict[str, Any]]
    licence: str = "CC-BY-4.0"
    authors: tuple[str, ...] = ("ofbe contributors",)
    version: str = "1.0.0"
    label_fidelity: dict[str, Any] | None = None
    extra: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        src = "DatasetInfo"
        for key in ("name", "campaign", "kind", "title", "licence", "version"):
            value = getattr(self, key)
            if not isinstance(value, str) or not value.strip():
                raise ConfigError(src, key, "a non-empty string", repr(value))
        object.__setattr__(self, "licence", spdx_licence(self.licence, src))
        if "/" in self.name or self.name.startswith("."):
            raise ConfigError(src, "name", "a folder name (no '/', not starting with '.')", repr(self.name))
        for key in ("description", "labelling"):
            if not isinstance(getattr(self, key), str):
                raise ConfigError(src, key, "a string", repr(getattr(self, key)))
        for key in ("window_length", "stride"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
                raise ConfigError(src, key, "an integer >= 1", repr(value))
            object.__setattr__(self, key, int(value))
        if (isinstance(self.fs_hz, bool) or not isinstance(self.fs_hz, int | float | np.number)
                or not math.isfinite(self.fs_hz) or self.fs_hz <= 0):
            raise ConfigError(src, "fs_hz", "a finite sample rate > 0 Hz", repr(self.fs_hz))
        object.__setattr__(self, "fs_hz", float(self.fs_hz))
        if isinstance(self.authors, str) or not all(isinstance(a, str) and a.strip() for a in self.authors):
            raise ConfigError(src, "authors", "a sequence of non-empty names", repr(self.authors))
        object.__setattr__(self, "authors", tuple(self.authors))
        if not self.authors:
            raise ConfigError(src, "authors", "at least one author", "none")
        if not isinstance(self.protocols, Mapping):
            raise ConfigError(src, "protocols", "a mapping of protocol name to description",
                              repr(self.protocols))
        for name, proto in self.protocols.items():
            fold_column(name)
            if not isinstance(proto, Mapping):
                raise ConfigError(src, f"protocols.{name}", "a mapping", repr(proto))
            n_folds = proto.get("n_folds")
            if n_folds is not None and (isinstance(n_folds, bool) or not isinstance(n_folds, int)
                                        or n_folds < 1):
                raise ConfigError(src, f"protocols.{name}.n_folds", "an integer >= 1", repr(n_folds))
        for key in ("protocols", "label_fidelity", "extra"):
            if not _is_json(getattr(self, key)):
                raise ConfigError(src, key, "JSON values (str, int, float, bool, None, lists, string-keyed "
                                  "mappings; no NaN, no numpy scalars)", repr(getattr(self, key)))
            # as they will read back from the files: tuples become lists, keys strings
            object.__setattr__(self, key, json.loads(json.dumps(getattr(self, key))))
        if self.label_fidelity is not None and not isinstance(self.label_fidelity, Mapping):
            raise ConfigError(src, "label_fidelity", "a mapping or None", repr(self.label_fidelity))
        if not isinstance(self.extra, Mapping):
            raise ConfigError(src, "extra", "a mapping", repr(self.extra))

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready copy of every field (``authors`` as a list)."""
        out = dataclasses.asdict(self)
        out["authors"] = list(self.authors)
        return json.loads(json.dumps(out))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], source: str | Path = "DatasetInfo") -> DatasetInfo:
        """Rebuild from :meth:`to_dict`'s output.

        Raises
        ------
        DatasetError
            When keys are missing or unknown, or a value is invalid (naming ``source``).
        """
        names = [f.name for f in dataclasses.fields(cls)]
        if not isinstance(data, Mapping):
            raise DatasetError(source, "a mapping of DatasetInfo fields", type(data).__name__, "dataset_info")
        unknown = sorted(set(data) - set(names))
        required = [f.name for f in dataclasses.fields(cls)
                    if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING]
        missing = [n for n in required if n not in data]
        if unknown or missing:
            raise DatasetError(source, f"the DatasetInfo fields {names}",
                               f"missing {missing}, unknown {unknown}", "dataset_info")
        kwargs = dict(data)
        if "authors" in kwargs and isinstance(kwargs["authors"], list):
            kwargs["authors"] = tuple(kwargs["authors"])
        try:
            return cls(**kwargs)
        except ConfigError as exc:
            raise DatasetError(source, exc.expected, exc.found, f"dataset_info.{exc.key}") from exc


def json_bytes(obj: Any) -> bytes:
    return (json.dumps(obj, indent=2, ensure_ascii=False, allow_nan=False) + "\n").encode()


def _plain(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    return value


def read_h5_header(path: Path) -> dict[str, Any]:
    """Root attributes (``protocols`` parsed) plus ``n_windows`` from the shape of X."""
    if not path.is_file():
        raise DatasetError(path, "an HDF5 file", "no such file")
    try:
        with h5py.File(path, "r") as f:
            attrs = {k: _plain(v) for k, v in f.attrs.items()}
            attrs["n_windows"] = int(f["X"].shape[0]) if "X" in f else None
    except OSError as exc:
        raise DatasetError(path, "an HDF5 file", f"unreadable ({exc})") from exc
    if "protocols" in attrs:
        try:
            attrs["protocols"] = json.loads(attrs["protocols"])
        except (TypeError, ValueError) as exc:
            raise DatasetError(path, "a JSON object", repr(attrs["protocols"]), "protocols") from exc
    return attrs


def read_parquet_provenance(path: Path) -> dict[str, Any]:
    if not path.is_file():
        raise DatasetError(path, "a Parquet file", "no such file")
    try:
        meta = pq.read_schema(path).metadata or {}
    except (OSError, pa.ArrowException) as exc:
        raise DatasetError(path, "a Parquet file", f"unreadable ({exc})") from exc
    if b"ofbe" not in meta:
        raise DatasetError(path, "schema metadata key 'ofbe'", "none")
    try:
        return json.loads(meta[b"ofbe"])
    except ValueError as exc:
        raise DatasetError(path, "JSON under schema metadata key 'ofbe'", "invalid JSON") from exc


def read_json(path: Path) -> dict[str, Any]:
    if not path.is_file():
        raise DatasetError(path, "a JSON file", "no such file")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise DatasetError(path, "valid JSON", f"a parse error ({exc})") from exc
    if not isinstance(doc, dict):
        raise DatasetError(path, "a JSON object", type(doc).__name__)
    return doc


def check_version(path: Path, found: Any, field: str = "schema_version") -> None:
    if found != SCHEMA_VERSION:
        raise DatasetError(path, f"{SCHEMA_VERSION!r}", repr(found), field)


def check_info_matches(info: DatasetInfo, attrs: Mapping[str, Any], path: Path) -> None:
    """The structural fields of ``info`` agree with windows.h5's root attributes."""
    check_version(path, attrs.get("schema_version"))
    for key in ("name", "campaign", "kind", "window_length", "stride", "fs_hz", "protocols"):
        if attrs.get(key) != getattr(info, key):
            raise DatasetError(path, f"{getattr(info, key)!r} (as in the dataset description)",
                               repr(attrs.get(key)), key)


def shard_layout(folder: str | Path) -> list[tuple[str, int]] | None:
    """The shard files of a dataset folder and their windows, or ``None`` for the single-file layout.

    A folder with ``windows.h5`` is single-file; otherwise the ``shards`` key of
    ``windows.parquet``'s provenance lists the shards.

    Returns
    -------
    list of (str, int) or None
        ``[(file name, n_windows), ...]`` in shard order.

    Raises
    ------
    DatasetError
        A malformed ``shards`` entry, or an unreadable ``windows.parquet`` (when there is no
        ``windows.h5``).
    """
    folder = Path(folder)
    if (folder / H5_NAME).exists() or not (folder / PARQUET_NAME).is_file():
        return None
    pq_path = folder / PARQUET_NAME
    shards = read_parquet_provenance(pq_path).get("shards")
    if shards is None:
        return None  # a single-file dataset whose windows.h5 is missing: reported where it is opened
    files = shards.get("files") if isinstance(shards, dict) else None
    expected = "a list of {path: windows-<5 digits>.h5, n_windows: int >= 1} in shard order"
    if not isinstance(files, list) or not files:
        raise DatasetError(pq_path, expected, repr(files), "ofbe.shards.files")
    out: list[tuple[str, int]] = []
    for i, entry in enumerate(files):
        ok = (isinstance(entry, dict) and entry.get("path") == shard_name(i)
              and isinstance(entry.get("n_windows"), int) and not isinstance(entry.get("n_windows"), bool)
              and entry["n_windows"] >= 1)
        if not ok:
            raise DatasetError(pq_path, expected, repr(entry), f"ofbe.shards.files[{i}]")
        out.append((entry["path"], int(entry["n_windows"])))
    return out


def header_h5(folder: str | Path) -> Path:
    """The HDF5 file whose root attributes describe the dataset: ``windows.h5``, or shard 0."""
    folder = Path(folder)
    layout = shard_layout(folder)
    return folder / (H5_NAME if layout is None else layout[0][0])


def read_dataset_info(path: str | Path) -> DatasetInfo:
    """The :class:`DatasetInfo` of a dataset folder, from ``datapackage.json`` (``ofbe.dataset_info``).

    Raises
    ------
    DatasetError
        When the description is missing or disagrees with ``windows.h5``'s attributes.
    """
    folder = Path(path)
    dp_path = folder / DATAPACKAGE_NAME
    doc = read_json(dp_path)
    ofbe = doc.get("ofbe")
    if not isinstance(ofbe, dict) or "dataset_info" not in ofbe:
        raise DatasetError(dp_path, "an 'ofbe' object with 'dataset_info'", "none", "ofbe")
    info = DatasetInfo.from_dict(ofbe["dataset_info"], dp_path)
    h5_path = header_h5(folder)
    check_info_matches(info, read_h5_header(h5_path), h5_path)
    return info


#: Names that moved out of this module when it was split (0.2.0): still importable from here for
#: one release; import them from their module (``ofbe_data.dataset.<module>``) instead.
_MOVED = {
    "LoadedDataset": "reader",
    "WindowWriter": "writer",
    "export_dataset": "export",
    "fold_sizes": "package",
    "load_dataset": "reader",
    "verify_dataset": "reader",
    "write_package_files": "package",
}


def __getattr__(name: str) -> Any:
    if name in _MOVED:
        import importlib

        return getattr(importlib.import_module(f"ofbe_data.dataset.{_MOVED[name]}"), name)
    raise AttributeError(f"module 'ofbe_data.dataset.store' has no attribute {name!r}")
