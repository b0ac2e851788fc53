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
``datapackage.json``, ``README.md``, ``CITATION.cff``
    Frictionless Data Package, dataset card and citation file.
``SHA256SUMS``
    ``sha256sum`` lines for every other file, written last.

Everything is deterministic: identical inputs give byte-identical files. HDF5 objects are
created without timestamps (``track_times=False``) in a file of the earliest format
(``libver="earliest"``): newer object headers store the modification time of groups, and
h5py offers no switch for that. No creation dates are written anywhere else either.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import json
import math
import os
import re
import shutil
import sys
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import yaml

from ofbe_data import __version__
from ofbe_data.atomic import atomic_directory, write_bytes_atomic
from ofbe_data.errors import ConfigError, OfbeError, OutputExistsError

SCHEMA_VERSION = "ofbe-windows/1"
#: ``format`` of the Parquet provenance.
DATASET_FORMAT = "ofbe-windows"

H5_NAME = "windows.h5"
PARQUET_NAME = "windows.parquet"
DATAPACKAGE_NAME = "datapackage.json"
README_NAME = "README.md"
CITATION_NAME = "CITATION.cff"
SUMS_NAME = "SHA256SUMS"

UNITS = "m/s^2"
FRAME = "sensor"
H5_LIBVER = "earliest"
PAPER_TITLE = ("Orientation-Free Neural Network-Based Bias Estimation for Low-Cost Stationary "
               "Accelerometers")
PAPER_AUTHORS = ("Levin", "Klein")

_HASH_BLOCK = 1 << 20
_TF_BLOCK = 256  # windows read from the file at a time by the tf.data generator
_MERGE_BLOCKS = 256  # metadata blocks merged into one array per column, to bound per-array overhead
_PROTOCOL_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")
_SUMS_LINE_RE = re.compile(r"^([0-9a-f]{64}) [ *](.+)$")


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


@dataclass(frozen=True)
class _Column:
    """One fixed column of ``windows.parquet``: kind is ``string``, ``int`` or ``float``."""

    name: str
    kind: str
    description: str
    unit: str | None = None
    nullable: bool = False


_COLUMNS: tuple[_Column, ...] = (
    _Column("window_id", "int", "row index of the window in windows.h5"),
    _Column("campaign", "string", "campaign id"),
    _Column("session", "string", "session id"),
    _Column("recording", "string", "recording id within the session"),
    _Column("device", "string", "device (DUT) id"),
    _Column("power_cycle", "int", "power cycle of the device: the bias instance"),
    _Column("window_index", "int",
            "index of the window within its recording's stationary segment; 0 is the first window "
            "(the test signal)"),
    _Column("start_sample", "int",
            "first sample of the window, counted from the start of the stationary segment", "sample"),
    *(_Column(f"bias_{a}", "float", f"apparent-bias label b_app, {a} axis, sensor frame", UNITS)
      for a in "xyz"),
    *(_Column(f"offset_{a}", "float",
              f"zero-g offset b, {a} axis, sensor frame, when the campaign fit determines it (else null)",
              UNITS, nullable=True) for a in "xyz"),
    *(_Column(f"gravity_{a}", "float", f"unit specific-force direction u, {a} component, sensor frame", "1")
      for a in "xyz"),
    _Column("roll_deg", "float", "roll of the device implied by u", "deg"),
    _Column("pitch_deg", "float", "pitch of the device implied by u", "deg"),
    _Column("g_local", "float", "local gravity magnitude", UNITS),
    _Column("fs_hz", "float", "measured sample rate of the device in this recording", "Hz"),
    _Column("label_method", "string", "how the label was made (level / reference-rodrigues / campaign-fit / "
            "multi-position)"),
    _Column("raw_sha256", "string", "SHA-256 of the raw device file labelled"),
)

#: The fixed columns of ``windows.parquet``, in order; the fold columns follow them.
WINDOW_COLUMNS: list[str] = [c.name for c in _COLUMNS]
_COLUMN_BY_NAME = {c.name: c for c in _COLUMNS}
#: Columns that identify a recording's windows (one label per recording and device).
RECORDING_KEY = ("campaign", "session", "recording", "device")
_PER_WINDOW = ("window_id", "window_index", "start_sample")
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


def _fold_doc(protocol: str) -> _Column:
    return _Column(fold_column(protocol), "int",
                   f"test fold of the window's recording under protocol {protocol!r}, -1 when it is only "
                   "ever used for training")


def _all_columns(protocols: Sequence[str]) -> list[_Column]:
    return [*_COLUMNS, *(_fold_doc(p) for p in protocols)]


def _arrow_schema(protocols: Sequence[str]) -> pa.Schema:
    return pa.schema([pa.field(c.name, _ARROW_TYPES[c.kind], nullable=c.nullable)
                      for c in _all_columns(protocols)])


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
        SPDX licence id of the data.
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


# ---------------------------------------------------------------------------------------------
# Validation of appended metadata


def _as_strings(col: pd.Series, name: str, path: Path) -> np.ndarray:
    values = col.tolist()
    for i, v in enumerate(values):
        if not isinstance(v, str):
            raise DatasetError(path, "strings (no nulls)", f"{v!r} ({type(v).__name__}) in row {i}", name)
    # interned: the few distinct ids repeat on every window, so rows share one object each
    return np.array([sys.intern(str(v)) for v in values], dtype=object)


def _as_ints(col: pd.Series, name: str, path: Path) -> np.ndarray:
    if pd.api.types.is_bool_dtype(col.dtype) or not pd.api.types.is_integer_dtype(col.dtype):
        raise DatasetError(path, "an integer column", f"dtype {col.dtype}", name)
    if col.isna().any():
        raise DatasetError(path, "integers (no nulls)", f"{int(col.isna().sum())} nulls", name)
    return col.to_numpy(dtype=np.int64)


def _as_floats(col: pd.Series, name: str, nullable: bool, path: Path) -> np.ndarray:
    if pd.api.types.is_numeric_dtype(col.dtype) and not pd.api.types.is_bool_dtype(col.dtype):
        arr = col.to_numpy(dtype=np.float64, na_value=np.nan)
    elif col.dtype == object and all(
            v is None or v is pd.NA or (isinstance(v, int | float | np.integer | np.floating)
                                        and not isinstance(v, bool | np.bool_)) for v in col):
        arr = np.array([np.nan if v is None or v is pd.NA else float(v) for v in col], dtype=np.float64)
    else:
        raise DatasetError(path, "a numeric column", f"dtype {col.dtype}", name)
    bad = ~np.isfinite(arr)
    if nullable:
        bad &= ~np.isnan(arr)
    if bad.any():
        what = "finite numbers or nulls" if nullable else "finite numbers (no nulls)"
        raise DatasetError(path, what, f"{arr[bad][0]!r} in row {int(np.flatnonzero(bad)[0])}", name)
    return arr


def _normalise_meta(meta: pd.DataFrame, protocols: Mapping[str, Mapping[str, Any]],
                    path: Path) -> dict[str, np.ndarray]:
    """Check one block of window metadata and return its columns as numpy arrays.

    Parameters
    ----------
    meta
        n rows, the columns :data:`WINDOW_COLUMNS` less ``window_id`` plus ``fold_<protocol>``
        for every protocol (any order, nothing else).
    protocols
        The dataset's protocols.
    path
        File named in errors.

    Returns
    -------
    dict
        Column name → array of n values (object arrays of ``str``, int64, float64 with NaN
        for nulls), in file order.
    """
    if not isinstance(meta, pd.DataFrame):
        raise DatasetError(path, "window metadata as a pandas DataFrame", type(meta).__name__, "meta")
    expected = [*WINDOW_COLUMNS[1:], *(fold_column(p) for p in protocols)]
    columns = [str(c) for c in meta.columns]
    dup = sorted({c for c in columns if columns.count(c) > 1})
    missing = [c for c in expected if c not in columns]
    extra = [c for c in columns if c not in expected]
    if dup or missing or extra:
        found = "; ".join(f"{k} {v}" for k, v in (("missing", missing), ("unexpected", extra),
                                                   ("duplicated", dup)) if v)
        raise DatasetError(path, f"exactly the columns {expected}", found, "meta")
    out: dict[str, np.ndarray] = {}
    for name in expected:
        col = meta[name]
        doc = _COLUMN_BY_NAME.get(name)
        if doc is None:  # fold column
            arr = _as_ints(col, name, path)
            n_folds = protocols[name[len("fold_"):]].get("n_folds")
            upper = n_folds - 1 if n_folds is not None else None
            bad = (arr < -1) | ((arr > upper) if upper is not None else False)
            if bad.any():
                rng_txt = f"-1..{upper}" if upper is not None else ">= -1"
                raise DatasetError(path, f"fold indices in {rng_txt}", f"{arr[bad][0]}", name)
        elif doc.kind == "string":
            arr = _as_strings(col, name, path)
        elif doc.kind == "int":
            arr = _as_ints(col, name, path)
            if name in ("window_index", "start_sample") and (arr < 0).any():
                raise DatasetError(path, "values >= 0", f"{arr[arr < 0][0]}", name)
        else:
            arr = _as_floats(col, name, doc.nullable, path)
        out[name] = arr
    return out


def _check_recordings(cols: Mapping[str, np.ndarray], path: Path) -> None:
    """Every recording-level column is constant within a recording; window indices are unique."""
    frame = pd.DataFrame({k: v for k, v in cols.items()})
    keys = list(RECORDING_KEY)
    dup = frame.duplicated([*keys, "window_index"])
    if dup.any():
        row = frame.loc[dup].iloc[0]
        raise DatasetError(path, "one window per (recording, device, window_index)",
                           f"window_index {row['window_index']} twice for "
                           f"{'/'.join(str(row[k]) for k in keys)}", "window_index")
    level = [c for c in frame.columns if c not in (*keys, *_PER_WINDOW)]
    counts = frame.groupby(keys, sort=False, dropna=False)[level].nunique(dropna=False)
    bad = counts > 1
    if bad.to_numpy().any():
        column = next(c for c in level if bad[c].any())
        group = counts.index[bad[column].to_numpy()][0]
        raise DatasetError(path, "one value per recording (it labels the whole recording)",
                           f"{int(counts.loc[group, column])} different values for "
                           f"{'/'.join(map(str, group))}", column)


# ---------------------------------------------------------------------------------------------
# Writing


def _merge(blocks: Sequence[Mapping[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """Concatenate metadata blocks column by column (columns of the first block, in order)."""
    return {name: np.concatenate([b[name] for b in blocks]) for name in blocks[0]}


def _set_attrs(obj: h5py.HLObject, attrs: Mapping[str, Any]) -> None:
    for key, value in attrs.items():
        obj.attrs[key] = value


def _root_attrs(info: DatasetInfo) -> dict[str, Any]:
    return {
        "schema_version": SCHEMA_VERSION, "units": UNITS, "frame": FRAME,
        "window_length": np.int64(info.window_length), "stride": np.int64(info.stride),
        "fs_hz": np.float64(info.fs_hz), "name": info.name, "campaign": info.campaign, "kind": info.kind,
        "protocols": json.dumps(info.protocols, allow_nan=False), "toolkit_version": __version__,
    }


def _parquet_provenance(info: DatasetInfo) -> dict[str, Any]:
    return {"format": DATASET_FORMAT, "schema_version": SCHEMA_VERSION, "name": info.name,
            "campaign": info.campaign, "window_length": info.window_length, "stride": info.stride,
            "units": UNITS, "protocols": info.protocols}


def _parquet_bytes(table: pa.Table) -> bytes:
    buf = io.BytesIO()
    pq.write_table(table, buf, compression="zstd")
    return buf.getvalue()


def _json_bytes(obj: Any) -> bytes:
    return (json.dumps(obj, indent=2, ensure_ascii=False, allow_nan=False) + "\n").encode()


class WindowWriter:
    """Write ``windows.h5`` and ``windows.parquet`` window block by window block, then the rest.

    Use as a context manager inside :func:`ofbe_data.atomic.atomic_directory`::

        with atomic_directory(out) as tmp, WindowWriter(tmp, info) as writer:
            for X, meta in blocks:          # e.g. one recording at a time
                writer.append(X, meta)

    ``X`` goes to the HDF5 file at once and is not kept; only the (small) metadata is held
    until the end. On a clean exit the writer completes ``windows.h5`` (``y`` and ``meta/``),
    writes ``windows.parquet`` and then :func:`write_package_files`. On an exception it closes
    the HDF5 file, removes its temporary name and re-raises; the caller discards the folder.

    Parameters
    ----------
    folder
        Existing folder to write into; it must not hold ``windows.h5`` or ``windows.parquet``.
    info
        What the dataset is.
    """

    def __init__(self, folder: str | Path, info: DatasetInfo) -> None:
        self.folder = Path(folder)
        self.info = info
        self._h5_path = self.folder / H5_NAME
        self._parquet_path = self.folder / PARQUET_NAME
        self._tmp_h5 = self.folder / f".{H5_NAME}.partial"
        self._file: h5py.File | None = None
        self._x: h5py.Dataset | None = None
        self._blocks: list[dict[str, np.ndarray]] = []  # metadata only (1-D arrays), merged in batches
        self._pending: list[dict[str, np.ndarray]] = []
        self._n = 0

    @property
    def n_windows(self) -> int:
        """Windows appended so far."""
        return self._n

    def __enter__(self) -> WindowWriter:
        if not self.folder.is_dir():
            raise DatasetError(self.folder, "an existing folder to write the dataset into", "none")
        for p in (self._h5_path, self._parquet_path):
            if p.exists():
                raise DatasetError(p, "a folder without this file (a fresh dataset)", "an existing file")
        if self._file is not None:
            raise DatasetError(self._h5_path, "a writer entered once", "a second `with`")
        t = self.info.window_length
        self._file = h5py.File(self._tmp_h5, "w", libver=H5_LIBVER)
        try:
            _set_attrs(self._file, _root_attrs(self.info))
            self._x = self._file.create_dataset(
                "X", shape=(0, t, 3), maxshape=(None, t, 3), dtype=np.float32, chunks=(1, t, 3),
                compression="gzip", compression_opts=4, shuffle=True, fletcher32=True, track_times=False)
            _set_attrs(self._x, {"units": UNITS, "frame": FRAME, "description":
                                 "specific force measured by the accelerometer, sensor frame; axes are "
                                 "(window, sample, x/y/z)"})
        except BaseException:
            self._abort()
            raise
        return self

    def append(self, X: np.ndarray, meta: pd.DataFrame) -> None:
        """Append n windows.

        Parameters
        ----------
        X
            (n, T, 3) specific force, m/s², sensor frame; stored as float32.
        meta
            n rows: :data:`WINDOW_COLUMNS` less ``window_id`` plus one ``fold_<protocol>``
            column per protocol. ``y`` is taken from ``bias_x/y/z``; ``window_id`` is assigned
            here (the running row index).

        Raises
        ------
        DatasetError
            On a wrong shape, a non-finite sample, missing/unexpected columns or a wrong dtype.
        """
        if self._x is None:
            raise DatasetError(self._h5_path, "append() inside `with WindowWriter(...)`", "a closed writer")
        t = self.info.window_length
        arr = np.asarray(X)
        if arr.ndim != 3 or arr.shape[1:] != (t, 3):
            raise DatasetError(self._h5_path, f"X of shape (n, {t}, 3)", f"shape {arr.shape}", "X")
        if arr.dtype.kind not in "fiu":
            raise DatasetError(self._h5_path, "a real numeric X", f"dtype {arr.dtype}", "X")
        if len(meta) != arr.shape[0]:
            raise DatasetError(self._parquet_path, f"{arr.shape[0]} metadata rows (one per window of X)",
                               f"{len(meta)}", "meta")
        x32 = arr.astype(np.float32, copy=False)
        finite = np.isfinite(x32)
        if not finite.all():
            raise DatasetError(self._h5_path, "finite samples (after conversion to float32)",
                               f"{int((~finite).sum())} non-finite", "X")
        cols = _normalise_meta(meta, self.info.protocols, self._parquet_path)
        n = arr.shape[0]
        if n == 0:
            return
        start = self._n
        self._x.resize(start + n, axis=0)
        self._x[start:start + n] = x32
        self._pending.append(cols)
        if len(self._pending) >= _MERGE_BLOCKS:
            self._blocks.append(_merge(self._pending))
            self._pending = []
        self._n = start + n

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: object) -> None:
        if exc_type is not None:
            self._abort()
            return
        try:
            self._finish()
        except BaseException:
            self._abort()
            raise

    def _abort(self) -> None:
        if self._file is not None:
            self._file.close()
        self._file = None
        self._x = None
        self._tmp_h5.unlink(missing_ok=True)

    def _finish(self) -> None:
        if self._file is None:
            raise DatasetError(self._h5_path, "a writer inside `with`", "a closed writer")
        if self._n == 0:
            raise DatasetError(self._h5_path, "at least one window", "0 windows appended")
        names = [c.name for c in _all_columns(list(self.info.protocols))]
        cols = {"window_id": np.arange(self._n, dtype=np.int64), **_merge([*self._blocks, *self._pending])}
        self._blocks, self._pending = [], []
        _check_recordings(cols, self._parquet_path)
        y = np.column_stack([cols["bias_x"], cols["bias_y"], cols["bias_z"]]).astype(np.float64)
        f = self._file
        ds_y = f.create_dataset("y", data=y, chunks=(min(self._n, 4096), 3), compression="gzip",
                                compression_opts=4, shuffle=True, fletcher32=True, track_times=False)
        _set_attrs(ds_y, {"units": UNITS, "frame": FRAME, "description":
                          "apparent-bias label b_app of the window's recording (bias_x/y/z), sensor frame"})
        group = f.create_group("meta")
        group.attrs["columns"] = json.dumps(names)
        group.attrs["description"] = "one dataset per column of windows.parquet, same row order; NaN = null"
        for col in _all_columns(list(self.info.protocols)):
            values = cols[col.name]
            if col.kind == "string":
                ds = group.create_dataset(col.name, data=values, dtype=h5py.string_dtype("utf-8"),
                                          track_times=False)
            else:
                ds = group.create_dataset(col.name, data=values, track_times=False)
            ds.attrs["description"] = col.description
            if col.unit is not None:
                ds.attrs["units"] = col.unit
        f.close()
        self._file = None
        self._x = None
        os.replace(self._tmp_h5, self._h5_path)
        schema = _arrow_schema(list(self.info.protocols))
        arrays = [pa.array(cols[fld.name].tolist() if fld.type == pa.string() else cols[fld.name],
                           type=fld.type, from_pandas=True) for fld in schema]
        table = pa.Table.from_arrays(arrays, schema=schema).replace_schema_metadata(
            {b"ofbe": json.dumps(_parquet_provenance(self.info), allow_nan=False).encode()})
        write_bytes_atomic(self._parquet_path, _parquet_bytes(table))
        write_package_files(self.folder, self.info)


# ---------------------------------------------------------------------------------------------
# Reading headers


def sha256_file(path: str | Path) -> str:
    """Hex SHA-256 of a file, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(_HASH_BLOCK), b""):
            h.update(block)
    return h.hexdigest()


def _plain(value: Any) -> Any:
    if isinstance(value, bytes):
        return value.decode()
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    return value


def _read_h5_header(path: Path) -> dict[str, Any]:
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


def _read_parquet_provenance(path: Path) -> dict[str, Any]:
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


def _read_json(path: Path) -> dict[str, Any]:
    if not path.is_file():
        raise DatasetError(path, "a JSON file", "no such file")
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise DatasetError(path, "valid JSON", f"a parse error ({exc})") from exc
    if not isinstance(doc, dict):
        raise DatasetError(path, "a JSON object", type(doc).__name__)
    return doc


def _check_version(path: Path, found: Any, field: str = "schema_version") -> None:
    if found != SCHEMA_VERSION:
        raise DatasetError(path, f"{SCHEMA_VERSION!r}", repr(found), field)


def _check_info_matches(info: DatasetInfo, attrs: Mapping[str, Any], path: Path) -> None:
    """The structural fields of ``info`` agree with windows.h5's root attributes."""
    _check_version(path, attrs.get("schema_version"))
    for key in ("name", "campaign", "kind", "window_length", "stride", "fs_hz", "protocols"):
        if attrs.get(key) != getattr(info, key):
            raise DatasetError(path, f"{getattr(info, key)!r} (as in the dataset description)",
                               repr(attrs.get(key)), key)


def read_dataset_info(path: str | Path) -> DatasetInfo:
    """The :class:`DatasetInfo` of a dataset folder, from ``datapackage.json`` (``ofbe.dataset_info``).

    Raises
    ------
    DatasetError
        When the description is missing or disagrees with ``windows.h5``'s attributes.
    """
    folder = Path(path)
    dp_path = folder / DATAPACKAGE_NAME
    doc = _read_json(dp_path)
    ofbe = doc.get("ofbe")
    if not isinstance(ofbe, dict) or "dataset_info" not in ofbe:
        raise DatasetError(dp_path, "an 'ofbe' object with 'dataset_info'", "none", "ofbe")
    info = DatasetInfo.from_dict(ofbe["dataset_info"], dp_path)
    _check_info_matches(info, _read_h5_header(folder / H5_NAME), folder / H5_NAME)
    return info


# ---------------------------------------------------------------------------------------------
# Package files: datapackage.json, README.md, CITATION.cff, SHA256SUMS


def fold_sizes(meta: pd.DataFrame) -> dict[str, dict[str, Any]]:
    """Test-set sizes of every protocol's folds.

    A recording here is one labelled series: a distinct (campaign, session, recording,
    device) (those of the key columns that ``meta`` has).

    Parameters
    ----------
    meta
        Window metadata with ``fold_<protocol>`` columns.

    Returns
    -------
    dict
        ``{protocol: {"folds": {fold: {"test_recordings": r, "test_windows": w}},
        "train_only": {"recordings": r, "windows": w}}}``, folds ascending, protocols in column
        order; ``train_only`` counts the rows with fold −1.
    """
    keys = [k for k in RECORDING_KEY if k in meta.columns]
    out: dict[str, dict[str, Any]] = {}
    for col in meta.columns:
        if not str(col).startswith("fold_"):
            continue
        folds = meta[col].to_numpy(dtype=np.int64)

        def count(mask: np.ndarray) -> tuple[int, int]:
            sub = meta.loc[mask, keys]
            return (int(len(sub.drop_duplicates())) if keys else int(mask.sum())), int(mask.sum())

        per_fold = {}
        for k in sorted(int(v) for v in np.unique(folds) if v >= 0):
            r, w = count(folds == k)
            per_fold[k] = {"test_recordings": r, "test_windows": w}
        r, w = count(folds < 0)
        out[str(col)[len("fold_"):]] = {"folds": per_fold, "train_only": {"recordings": r, "windows": w}}
    return out


def _device_counts(meta: pd.DataFrame) -> dict[str, dict[str, int]]:
    out = {}
    for device in sorted(meta["device"].unique()):
        sub = meta[meta["device"] == device]
        out[str(device)] = {"recordings": int(len(sub[list(RECORDING_KEY)].drop_duplicates())),
                            "windows": int(len(sub)), "power_cycles": int(sub["power_cycle"].nunique())}
    return out


_LICENCES = {
    "CC-BY-4.0": ("Creative Commons Attribution 4.0 International",
                  "https://creativecommons.org/licenses/by/4.0/"),
    "CC0-1.0": ("Creative Commons Zero v1.0 Universal", "https://creativecommons.org/publicdomain/zero/1.0/"),
    "CC-BY-SA-4.0": ("Creative Commons Attribution Share Alike 4.0 International",
                     "https://creativecommons.org/licenses/by-sa/4.0/"),
    "ODbL-1.0": ("Open Data Commons Open Database License v1.0", "https://opendatacommons.org/licenses/odbl/1-0/"),
    "MIT": ("MIT License", "https://opensource.org/licenses/MIT"),
}


def _licence_entry(licence: str) -> dict[str, str]:
    title, url = _LICENCES.get(licence, (licence, None))
    entry = {"name": licence, "title": title}
    if url is not None:
        entry["path"] = url
    return entry


def _package_name(name: str) -> str:
    return re.sub(r"[^a-z0-9._-]+", "-", name.lower()).strip("-") or "dataset"


def _field_entry(col: _Column) -> dict[str, Any]:
    entry: dict[str, Any] = {"name": col.name, "type": {"string": "string", "int": "integer",
                                                        "float": "number"}[col.kind],
                             "description": col.description,
                             "constraints": {"required": not col.nullable}}
    if col.unit is not None:
        entry["unit"] = col.unit
    return entry


def _datapackage(info: DatasetInfo, attrs: Mapping[str, Any], meta: pd.DataFrame,
                 files: Mapping[str, tuple[int, str]], sizes: Mapping[str, Any]) -> dict[str, Any]:
    h5_bytes, h5_hash = files[H5_NAME]
    pq_bytes, pq_hash = files[PARQUET_NAME]
    t = info.window_length
    protocols = {p: {**spec, "fold_column": fold_column(p), "fold_sizes": sizes.get(p)}
                 for p, spec in info.protocols.items()}
    return {
        "profile": "data-package",
        "name": _package_name(info.name),
        "title": info.title,
        "description": info.description,
        "version": info.version,
        "licenses": [_licence_entry(info.licence)],
        "contributors": [{"title": a, "role": "author"} for a in info.authors],
        "keywords": ["accelerometer", "bias estimation", "IMU", "stationary", "deep learning"],
        "sources": [{"title": f"Campaign {info.campaign} ({info.kind})"}],
        "resources": [
            {"name": "windows-h5", "path": H5_NAME, "profile": "data-resource", "format": "hdf5",
             "mediatype": "application/x-hdf5", "bytes": h5_bytes, "hash": f"sha256:{h5_hash}",
             "description": f"X float32 (N, {t}, 3) {UNITS}, sensor frame, one gzip+shuffle+fletcher32 chunk "
                            f"per window; y float64 (N, 3) {UNITS}; meta/ one dataset per column of "
                            f"{PARQUET_NAME}, same row order"},
            {"name": "windows", "path": PARQUET_NAME, "profile": "tabular-data-resource", "format": "parquet",
             "mediatype": "application/vnd.apache.parquet", "bytes": pq_bytes, "hash": f"sha256:{pq_hash}",
             "description": "one row per window, same order as windows.h5",
             "schema": {"fields": [_field_entry(c) for c in _all_columns(list(info.protocols))],
                        "primaryKey": "window_id"}},
        ],
        "ofbe": {
            "schema_version": SCHEMA_VERSION, "name": info.name, "campaign": info.campaign, "kind": info.kind,
            "units": UNITS, "frame": FRAME, "fs_hz": info.fs_hz, "window_length": t, "stride": info.stride,
            "n_windows": int(len(meta)),
            "n_recordings": int(len(meta[list(RECORDING_KEY)].drop_duplicates())),
            "devices": _device_counts(meta), "protocols": protocols,
            "toolkit_version": attrs.get("toolkit_version"), "dataset_info": info.to_dict(),
        },
    }


def _md_cell(value: Any) -> str:
    if isinstance(value, float):
        text = f"{value:.6g}"
    elif value is None:
        text = "–"
    elif isinstance(value, dict | list):
        text = json.dumps(value, ensure_ascii=False)
    else:
        text = str(value)
    return text.replace("|", "\\|").replace("\n", " ")


def _md_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> list[str]:
    lines = ["| " + " | ".join(_md_cell(h) for h in header) + " |",
             "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(_md_cell(v) for v in row) + " |" for row in rows]
    return lines


def _fidelity_table(fidelity: Mapping[str, Any]) -> list[str]:
    if fidelity and all(isinstance(v, Mapping) for v in fidelity.values()):
        cols: list[str] = []
        for v in fidelity.values():
            cols += [str(k) for k in v if str(k) not in cols]
        return _md_table(["", *cols], [[k, *(v.get(c) for c in cols)] for k, v in fidelity.items()])
    return _md_table(["quantity", "value"], [[k, v] for k, v in fidelity.items()])


def _readme(info: DatasetInfo, attrs: Mapping[str, Any], meta: pd.DataFrame,
            files: Mapping[str, tuple[int, str]], sizes: Mapping[str, Any]) -> str:
    t, s, fs = info.window_length, info.stride, info.fs_hz
    n = len(meta)
    n_rec = len(meta[list(RECORDING_KEY)].drop_duplicates())
    devices = _device_counts(meta)
    protos = list(info.protocols)
    out = [f"# {info.title}", "",
           f"`{info.name}`: {n} windows of {t} samples (three-axis accelerometer, {UNITS}) from {n_rec} "
           f"recordings of {len(devices)} devices, campaign `{info.campaign}` ({info.kind}). Each window is "
           "labelled with the apparent bias of its recording.", "",
           f"Version {info.version} · licence {info.licence} · format `{SCHEMA_VERSION}` · built with ofbe "
           f"{attrs.get('toolkit_version')}.", "",
           "## What it is", "",
           "Stationary accelerometer data cut into fixed-length windows, for training and evaluating "
           "orientation-free bias estimators (Levin & Klein, *" + PAPER_TITLE + "*). The input is a window "
           "of raw specific force; the target is the apparent bias b_app = b + (A − I)·u·g_local of the "
           "recording it comes from, in the sensor frame (raw-formats.md).", "",
           "## How it was recorded", "", info.description.strip() or "Not described.", "",
           "## How the labels were made", "", info.labelling.strip() or "Not described.", "",
           "## Label fidelity", ""]
    out += (_fidelity_table(info.label_fidelity) if info.label_fidelity
            else ["Not quantified for this dataset."])
    out += ["", "## Units and frames", "",
            "The sensor frame is the chip's own logged axes. A resting ideal accelerometer reads the "
            "specific force, pointing up with magnitude g_local (chip flat, z up: [0, 0, +g]).", "",
            f"- `X`: specific force, {UNITS}, float32, axes (window, sample, x/y/z) of the device's sensor "
            "frame, as recorded (no calibration applied).",
            f"- `y` = `bias_x/y/z`: apparent-bias label, {UNITS}, float64, sensor frame.",
            f"- `offset_x/y/z`: zero-g offset, {UNITS}, sensor frame, null where the campaign fit does not "
            "determine it.",
            "- `gravity_x/y/z`: unit specific-force direction u in the sensor frame; `roll_deg`, "
            "`pitch_deg`: tilt implied by u, degrees; `g_local`: local gravity, " + UNITS + ".", "",
            "## Sampling and windowing", "",
            f"- Nominal sample rate {fs:g} Hz (the measured rate of each recording is in `fs_hz`).",
            f"- Window length T = {t} samples ({t / fs:.6g} s at the nominal rate), stride {s} samples.",
            "- Windows are cut from each recording's stationary segment only. `window_index` 0 is the "
            "first window of the segment (the test signal); `start_sample` counts from the segment's "
            "first sample.", "",
            "## Devices", ""]
    out += _md_table(["device", "recordings", "windows", "power cycles"],
                     [[d, c["recordings"], c["windows"], c["power_cycles"]] for d, c in devices.items()])
    out += ["", "## Protocols and folds", "",
            "A recording below is one labelled series (campaign, session, recording, device). All windows of "
            "a recording share its fold; −1 marks recordings used only for training.", ""]
    if not protos:
        out += ["No protocols.", ""]
    for p in protos:
        spec = dict(info.protocols[p])
        desc = spec.pop("description", "")
        out += [f"### {p}", ""]
        if desc:
            out += [str(desc), ""]
        props = ", ".join(f"{k} = {_md_cell(v)}" for k, v in spec.items())
        out += [f"Column `{fold_column(p)}`" + (f"; {props}." if props else "."), ""]
        fs_ = sizes.get(p, {"folds": {}, "train_only": {"recordings": 0, "windows": 0}})
        rows = [[k, v["test_recordings"], v["test_windows"]] for k, v in fs_["folds"].items()]
        rows.append(["−1 (training only)", fs_["train_only"]["recordings"], fs_["train_only"]["windows"]])
        out += _md_table(["fold", "test recordings", "test windows"], rows) + [""]
    out += ["## Files", ""]
    out += _md_table(["file", "bytes", "sha256", "content"],
                     [[H5_NAME, files[H5_NAME][0], f"`{files[H5_NAME][1]}`",
                       f"`X` (N, {t}, 3) float32, `y` (N, 3) float64, `meta/` columns"],
                      [PARQUET_NAME, files[PARQUET_NAME][0], f"`{files[PARQUET_NAME][1]}`",
                       "one row per window (same order)"],
                      [DATAPACKAGE_NAME, "", "", "Frictionless Data Package description"],
                      [README_NAME, "", "", "this card"],
                      [CITATION_NAME, "", "", "how to cite"],
                      [SUMS_NAME, "", "", "SHA-256 of every other file (`sha256sum -c SHA256SUMS`)"]])
    out += ["", "Columns of `windows.parquet` (and of `windows.h5:/meta`):", ""]
    out += _md_table(["column", "type", "unit", "meaning"],
                     [[c.name, {"string": "string", "int": "int64", "float": "float64"}[c.kind]
                       + (" (nullable)" if c.nullable else ""), c.unit or "", c.description]
                      for c in _all_columns(protos)])
    where = f"processed/datasets/{info.name}"
    out += ["", "## Loading", "", "```python", "from ofbe_data import load_dataset",
            "", f'ds = load_dataset("{where}")   # checks SHA256SUMS and the schema version',
            f"ds.X     # float32 (N, {t}, 3), {UNITS}", f"ds.y     # float64 (N, 3), {UNITS}",
            "ds.meta  # pandas DataFrame, one row per window",
            f'frame = load_dataset("{where}", as_="pandas")  # metadata and labels (bias_x/y/z), no X',
            f'tfds = load_dataset("{where}", as_="tf")       # tf.data.Dataset of (X, y), streamed',
            "```", "", "Without the toolkit: `h5py.File(\"windows.h5\")[\"X\"]` and "
            "`pyarrow.parquet.read_table(\"windows.parquet\")`.", ""]
    if info.extra:
        out += ["## Other properties", ""]
        out += _md_table(["property", "value"], [[k, v] for k, v in info.extra.items()]) + [""]
    out += ["## Licence", "", f"{_licence_entry(info.licence)['title']} (`{info.licence}`).", "",
            "## Citation", "", f"Cite the dataset ({CITATION_NAME}: {', '.join(info.authors)}, "
            f"*{info.title}*, version {info.version}) and the paper: {' & '.join(PAPER_AUTHORS)}, "
            f"*{PAPER_TITLE}*.", "",
            "## Schema version", "", f"`{SCHEMA_VERSION}`: in the root attributes of `{H5_NAME}`, the "
            f"`ofbe` metadata of `{PARQUET_NAME}` and `ofbe.schema_version` of `{DATAPACKAGE_NAME}`.", ""]
    return "\n".join(out)


def _citation(info: DatasetInfo) -> dict[str, Any]:
    return {
        "cff-version": "1.2.0",
        "message": "If you use this dataset, please cite it as below and cite the paper it serves.",
        "type": "dataset",
        "title": info.title,
        "version": info.version,
        "license": info.licence,
        "authors": [{"name": a} for a in info.authors],
        "abstract": info.description.strip() or info.title,
        "keywords": ["accelerometer", "bias estimation", "IMU"],
        "references": [{"type": "article", "title": PAPER_TITLE,
                        "authors": [{"family-names": a} for a in PAPER_AUTHORS]}],
    }


def _sums_text(folder: Path) -> str:
    names = sorted(p.name for p in folder.iterdir()
                   if p.is_file() and p.name != SUMS_NAME and not p.name.startswith("."))
    return "".join(f"{sha256_file(folder / n)}  {n}\n" for n in names)


def write_package_files(folder: str | Path, info: DatasetInfo) -> None:
    """Write ``datapackage.json``, ``README.md``, ``CITATION.cff`` and, last, ``SHA256SUMS``.

    Parameters
    ----------
    folder
        Folder that already holds ``windows.h5`` and ``windows.parquet``.
    info
        Dataset description; its structural fields (name, campaign, kind, windowing, protocols)
        must agree with ``windows.h5``'s attributes.

    Raises
    ------
    DatasetError
        When a data file is missing or unreadable, or disagrees with ``info``.
    """
    folder = Path(folder)
    h5_path, pq_path = folder / H5_NAME, folder / PARQUET_NAME
    attrs = _read_h5_header(h5_path)
    _check_info_matches(info, attrs, h5_path)
    _check_version(pq_path, _read_parquet_provenance(pq_path).get("schema_version"))
    meta = pq.read_table(pq_path).replace_schema_metadata(None).to_pandas()
    files = {n: ((folder / n).stat().st_size, sha256_file(folder / n)) for n in (H5_NAME, PARQUET_NAME)}
    sizes = fold_sizes(meta)
    write_bytes_atomic(folder / DATAPACKAGE_NAME, _json_bytes(_datapackage(info, attrs, meta, files, sizes)))
    write_bytes_atomic(folder / README_NAME, _readme(info, attrs, meta, files, sizes).encode())
    write_bytes_atomic(folder / CITATION_NAME,
                       yaml.safe_dump(_citation(info), sort_keys=False, allow_unicode=True).encode())
    write_bytes_atomic(folder / SUMS_NAME, _sums_text(folder).encode())


# ---------------------------------------------------------------------------------------------
# Verification and loading


def _read_sums(path: Path) -> dict[str, str]:
    if not path.is_file():
        raise DatasetError(path, "a SHA256SUMS file", "no such file")
    sums: dict[str, str] = {}
    for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if not line.strip():
            continue
        m = _SUMS_LINE_RE.match(line)
        if m is None:
            raise DatasetError(path, "'<64 hex digits>  <file name>'", repr(line), f"line {i}")
        name = m.group(2)
        if "/" in name or "\\" in name or name in (".", ".."):
            raise DatasetError(path, "a plain file name of the dataset folder", repr(name), f"line {i}")
        sums[name] = m.group(1)
    for required in (H5_NAME, PARQUET_NAME, DATAPACKAGE_NAME):
        if required not in sums:
            raise DatasetError(path, f"a line for {required}", "none")
    return sums


def _compare_meta(h5_path: Path, pq_path: Path, table: pa.Table, protocols: Sequence[str]) -> None:
    """windows.h5 (y, meta/) and windows.parquet agree column by column and row by row."""
    schema = _arrow_schema(protocols)
    found = [f"{f.name}:{f.type}" for f in table.schema]
    if found != [f"{f.name}:{f.type}" for f in schema]:
        raise DatasetError(pq_path, f"the columns {[f'{f.name}:{f.type}' for f in schema]}", f"{found}")
    n = table.num_rows
    with h5py.File(h5_path, "r") as f:
        if "meta" not in f or "y" not in f:
            raise DatasetError(h5_path, "datasets X, y and group meta", f"{sorted(f)}")
        group = f["meta"]
        if sorted(group) != sorted(schema.names):
            raise DatasetError(h5_path, f"one dataset per column {sorted(schema.names)}", f"{sorted(group)}",
                               "meta")
        for fld in schema:
            ds = group[fld.name]
            if ds.shape != (n,):
                raise DatasetError(h5_path, f"shape ({n},) like {PARQUET_NAME}", f"{ds.shape}",
                                   f"meta/{fld.name}")
            col = table.column(fld.name)
            is_string = h5py.check_string_dtype(ds.dtype) is not None
            want = {pa.string(): "UTF-8 strings", pa.int64(): "int64", pa.float64(): "float64"}[fld.type]
            if (is_string != (fld.type == pa.string())
                    or (not is_string and ds.dtype != np.dtype(want))):
                raise DatasetError(h5_path, want, f"{ds.dtype}", f"meta/{fld.name}")
            if fld.type == pa.string():
                same = ds.asstr()[...].tolist() == col.to_pylist()
            else:
                same = np.array_equal(ds[...], col.to_numpy(), equal_nan=fld.type == pa.float64())
            if not same:
                raise DatasetError(h5_path, f"meta/{fld.name} equal to the column of {PARQUET_NAME}",
                                   "different values", f"meta/{fld.name}")
        y = f["y"]
        if y.shape != (n, 3) or y.dtype != np.float64:
            raise DatasetError(h5_path, f"float64 of shape ({n}, 3)", f"{y.dtype} {y.shape}", "y")
        bias = np.column_stack([table.column(f"bias_{a}").to_numpy() for a in "xyz"])
        if not np.array_equal(y[...], bias):
            raise DatasetError(h5_path, f"y equal to bias_x/y/z of {PARQUET_NAME}", "different values", "y")
    if not np.array_equal(table.column("window_id").to_numpy(), np.arange(n)):
        raise DatasetError(pq_path, "window_id = 0..N-1 in order", "other values", "window_id")


def verify_dataset(path: str | Path) -> dict[str, Any]:
    """Check a dataset folder: checksums, schema version, and that its files agree.

    Checks, in order: every file of ``SHA256SUMS`` exists and has its hash; the hashes and
    sizes of ``datapackage.json``'s resources; the schema version in ``windows.h5``,
    ``windows.parquet`` and ``datapackage.json``; the dataset description against the HDF5
    attributes; shapes and dtypes of ``X`` and ``y``; the Parquet schema; and ``meta/`` and ``y``
    against the Parquet columns, row by row. ``X`` itself is covered by the checksum (and by
    its chunks' Fletcher-32 sums when read).

    Returns
    -------
    dict
        ``path``, ``schema_version``, ``name``, ``campaign``, ``n_windows``, ``n_recordings``,
        ``n_devices``, ``window_length``, ``stride``, ``protocols`` and ``files`` (name → sha256).

    Raises
    ------
    ChecksumError
        A file's hash differs from the recorded one (naming the file and both hashes).
    DatasetError
        Anything else (naming the file, what was expected and what was found).
    """
    folder = Path(path)
    if not folder.is_dir():
        raise DatasetError(folder, "a dataset folder", "no such folder")
    sums_path = folder / SUMS_NAME
    sums = _read_sums(sums_path)
    actual: dict[str, str] = {}
    for name, expected in sums.items():
        file = folder / name
        if not file.is_file():
            raise DatasetError(file, f"a file listed in {SUMS_NAME}", "no such file")
        actual[name] = sha256_file(file)
        if actual[name] != expected:
            raise ChecksumError(file, f"sha256 {expected} (from {SUMS_NAME})", f"sha256 {actual[name]}")
    dp_path, h5_path, pq_path = folder / DATAPACKAGE_NAME, folder / H5_NAME, folder / PARQUET_NAME
    doc = _read_json(dp_path)
    resources = {r.get("path"): r for r in doc.get("resources", []) if isinstance(r, dict)}
    for name in (H5_NAME, PARQUET_NAME):
        res = resources.get(name)
        if res is None:
            raise DatasetError(dp_path, f"a resource with path {name!r}", "none", "resources")
        if res.get("hash") != f"sha256:{actual[name]}":
            raise ChecksumError(folder / name, f"{res.get('hash')} (from {DATAPACKAGE_NAME})",
                                f"sha256:{actual[name]}")
        size = (folder / name).stat().st_size
        if res.get("bytes") != size:
            raise DatasetError(dp_path, f"bytes = {size} (the size of {name})", repr(res.get("bytes")),
                               f"resources[{name}].bytes")
    attrs = _read_h5_header(h5_path)
    _check_version(h5_path, attrs.get("schema_version"))
    prov = _read_parquet_provenance(pq_path)
    _check_version(pq_path, prov.get("schema_version"))
    ofbe = doc.get("ofbe") if isinstance(doc.get("ofbe"), dict) else {}
    _check_version(dp_path, ofbe.get("schema_version"), "ofbe.schema_version")
    info = read_dataset_info(folder)
    for key in ("name", "campaign", "window_length", "stride", "protocols"):
        if prov.get(key) != attrs.get(key):
            raise DatasetError(pq_path, f"{attrs.get(key)!r} (as in {H5_NAME})", repr(prov.get(key)), key)
    t = info.window_length
    with h5py.File(h5_path, "r") as f:
        x = f.get("X")
        if not isinstance(x, h5py.Dataset) or x.dtype != np.float32 or x.shape[1:] != (t, 3):
            found = f"{x.dtype} {x.shape}" if isinstance(x, h5py.Dataset) else "none"
            raise DatasetError(h5_path, f"float32 of shape (N, {t}, 3)", found, "X")
        n = int(x.shape[0])
    table = pq.read_table(pq_path)
    if table.num_rows != n:
        raise DatasetError(pq_path, f"{n} rows (one per window of {H5_NAME})", f"{table.num_rows}")
    _compare_meta(h5_path, pq_path, table, list(info.protocols))
    keys = table.select(list(RECORDING_KEY)).to_pandas().drop_duplicates()
    return {"path": str(folder), "schema_version": SCHEMA_VERSION, "name": info.name,
            "campaign": info.campaign, "n_windows": n, "n_recordings": int(len(keys)),
            "n_devices": int(keys["device"].nunique()), "window_length": t, "stride": info.stride,
            "protocols": list(info.protocols), "files": dict(sorted(actual.items()))}


@dataclass(frozen=True, eq=False)
class LoadedDataset:
    """A dataset in memory.

    Attributes
    ----------
    X
        float32 (N, T, 3), m/s², sensor frame.
    y
        float64 (N, 3), m/s²: the apparent-bias labels.
    meta
        One row per window (the columns of ``windows.parquet``).
    info
        Root attributes of ``windows.h5`` (``protocols`` parsed) and ``dataset_info`` (the
        description from ``datapackage.json``).
    """

    X: np.ndarray
    y: np.ndarray
    meta: pd.DataFrame
    info: dict[str, Any]


_LOADERS = ("numpy", "pandas", "tf")


def _info_dict(folder: Path) -> dict[str, Any]:
    attrs = _read_h5_header(folder / H5_NAME)
    attrs.pop("n_windows", None)
    _check_version(folder / H5_NAME, attrs.get("schema_version"))
    pq_path = folder / PARQUET_NAME
    _check_version(pq_path, _read_parquet_provenance(pq_path).get("schema_version"))
    return {**attrs, "dataset_info": read_dataset_info(folder).to_dict()}


def _read_meta(folder: Path) -> pd.DataFrame:
    path = folder / PARQUET_NAME
    try:
        return pq.read_table(path).replace_schema_metadata(None).to_pandas()
    except (OSError, pa.ArrowException) as exc:
        raise DatasetError(path, "a readable Parquet file", f"an unreadable one ({exc})") from exc


def load_dataset(path: str | Path, as_: str = "numpy", verify: bool = True) -> Any:
    """Load a dataset folder.

    Parameters
    ----------
    path
        The dataset folder (``processed/datasets/<name>``).
    as_
        ``"numpy"``: a :class:`LoadedDataset` (X float32 (N, T, 3), y float64 (N, 3), meta, info).
        ``"pandas"``: the metadata frame alone (no X); its ``bias_x/y/z`` columns are ``y``
        (verified equal to ``windows.h5:/y``), and ``frame.attrs["ofbe"]`` holds ``info``.
        ``"tf"``: a ``tf.data.Dataset`` of ``(X_i, y_i)`` pairs, float32 (T, 3) and float64 (3,),
        in file order. X is *streamed*: a generator (with ``output_signature``) reads 256
        windows at a time from ``windows.h5`` on each pass, so the dataset need not fit in
        memory; ``y`` is held in memory. Cardinality is set to N. TensorFlow is imported here.
    verify
        Run :func:`verify_dataset` first (checksums, schema version, agreement of the files).
        Without it the schema version is still checked.

    Raises
    ------
    DatasetError
        On an unknown ``as_`` or a bad dataset (:class:`ChecksumError` for a hash mismatch).
    """
    folder = Path(path)
    if as_ not in _LOADERS:
        raise DatasetError(folder, f"as_ one of {list(_LOADERS)}", repr(as_), "as_")
    if verify:
        verify_dataset(folder)
    info = _info_dict(folder)
    if as_ == "pandas":
        meta = _read_meta(folder)
        meta.attrs["ofbe"] = info
        return meta
    h5_path = folder / H5_NAME
    if as_ == "numpy":
        try:
            with h5py.File(h5_path, "r") as f:
                x = np.asarray(f["X"][...], dtype=np.float32)
                y = np.asarray(f["y"][...], dtype=np.float64)
        except OSError as exc:  # e.g. a chunk failing its Fletcher-32 checksum
            raise DatasetError(h5_path, "readable X and y (chunks passing their Fletcher-32 checksums)",
                               f"a read error ({exc})") from exc
        return LoadedDataset(X=x, y=y, meta=_read_meta(folder), info=info)
    return _tf_dataset(h5_path, int(info["window_length"]))


def _window_generator(h5_path: Path, y: np.ndarray) -> Callable[[], Iterator[tuple[np.ndarray, np.ndarray]]]:
    def gen() -> Iterator[tuple[np.ndarray, np.ndarray]]:
        with h5py.File(h5_path, "r") as f:
            x = f["X"]
            for start in range(0, x.shape[0], _TF_BLOCK):
                block = x[start:start + _TF_BLOCK]
                for i in range(block.shape[0]):
                    yield block[i], y[start + i]

    return gen


def _tf_dataset(h5_path: Path, window_length: int) -> Any:
    import tensorflow as tf

    with h5py.File(h5_path, "r") as f:
        y = np.asarray(f["y"][...], dtype=np.float64)
    signature = (tf.TensorSpec(shape=(window_length, 3), dtype=tf.float32),
                 tf.TensorSpec(shape=(3,), dtype=tf.float64))
    ds = tf.data.Dataset.from_generator(_window_generator(h5_path, y), output_signature=signature)
    return ds.apply(tf.data.experimental.assert_cardinality(len(y)))


# ---------------------------------------------------------------------------------------------
# Export


def export_dataset(src: str | Path, dest: str | Path, *, title: str | None = None, licence: str | None = None,
                   authors: Sequence[str] | None = None, version: str | None = None,
                   force: bool = False) -> Path:
    """Copy a verified dataset to ``dest`` with its package files rewritten.

    The data files are copied byte for byte; ``datapackage.json``, ``README.md``,
    ``CITATION.cff`` and ``SHA256SUMS`` are rewritten from the description stored in the
    dataset (so the export is self-contained) with the overrides given. Without overrides the
    export is byte-identical to ``src``. The copy is verified before it is moved into place.

    Parameters
    ----------
    src
        A dataset folder.
    dest
        The new folder.
    title, licence, authors, version
        Overrides of the description (``None`` keeps the stored value).
    force
        Replace an existing ``dest`` (only once the new one is complete).

    Returns
    -------
    Path
        ``dest``.

    Raises
    ------
    OutputExistsError
        ``dest`` exists and ``force`` is not set.
    DatasetError
        ``src`` fails :func:`verify_dataset`, or an override is invalid.
    """
    src, dest = Path(src), Path(dest)
    verify_dataset(src)
    if dest.exists() and not force:
        raise OutputExistsError(dest)
    info = read_dataset_info(src)
    overrides = {k: v for k, v in (("title", title), ("licence", licence), ("version", version),
                                   ("authors", tuple(authors) if authors is not None else None))
                 if v is not None}
    try:
        info = dataclasses.replace(info, **overrides)
    except ConfigError as exc:
        raise DatasetError(dest, exc.expected, exc.found, exc.key) from exc
    with atomic_directory(dest, replace=force) as tmp:
        for name in (H5_NAME, PARQUET_NAME):
            shutil.copyfile(src / name, tmp / name)
        write_package_files(tmp, info)
        verify_dataset(tmp)
    return dest
