"""Reading a dataset: headers, verification against the checksums, loading as numpy, pandas or tf.data.

Both layouts are read: one ``windows.h5``, or shard files ``windows-00000.h5``, … indexed by
``windows.parquet`` (:mod:`~ofbe_data.dataset.store`). A sharded dataset is loaded lazily: its X
is read shard by shard (:meth:`LoadedDataset.iter_shards`, :meth:`LoadedDataset.tf_dataset`) or
all at once on first use of :attr:`LoadedDataset.X`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ofbe_data.dataset.store import (
    CROISSANT_NAME,
    DATAPACKAGE_NAME,
    H5_NAME,
    PARQUET_NAME,
    RECORDING_KEY,
    SCHEMA_VERSION,
    SHARD_COLUMNS,
    SHARD_RE,
    SIGNAL_COLUMN,
    SIGNALS_RE,
    SUMS_LINE_RE,
    SUMS_NAME,
    TF_BLOCK,
    ChecksumError,
    DatasetError,
    arrow_schema,
    check_version,
    read_dataset_info,
    read_h5_header,
    read_json,
    read_parquet_provenance,
    same_signal_schema,
    sha256_file,
    shard_layout,
    shard_name,
    signal_names,
    signal_schema,
)
from ofbe_data.dataset.verify_signals import compare_signals

# ---------------------------------------------------------------------------------------------
# Verification and loading


def _read_sums(path: Path) -> dict[str, str]:
    if not path.is_file():
        raise DatasetError(path, "a SHA256SUMS file", "no such file")
    sums: dict[str, str] = {}
    for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
        if not line.strip():
            continue
        m = SUMS_LINE_RE.match(line)
        if m is None:
            raise DatasetError(path, "'<64 hex digits>  <file name>'", repr(line), f"line {i}")
        name = m.group(2)
        if "/" in name or "\\" in name or name in (".", ".."):
            raise DatasetError(path, "a plain file name of the dataset folder", repr(name), f"line {i}")
        sums[name] = m.group(1)
    h5_names = _h5_names_of(sums)
    if h5_names != [H5_NAME] and h5_names != [shard_name(k) for k in range(len(h5_names))]:
        raise DatasetError(path, "lines for the shards windows-00000.h5, windows-00001.h5, … without a gap",
                           ", ".join(h5_names))
    for required in (*h5_names, PARQUET_NAME, DATAPACKAGE_NAME):
        if required not in sums:
            raise DatasetError(path, f"a line for {required}", "none")
    listed = sorted(n for n in sums if SIGNALS_RE.match(n))
    expected = signal_names(None if h5_names == [H5_NAME] else [(n, 0) for n in h5_names])
    if listed and listed != expected:
        raise DatasetError(path, f"lines for the signal files {', '.join(expected)} (one per HDF5 file) "
                           "or none", ", ".join(listed))
    return sums


def _signals_of(sums: dict[str, str]) -> list[str]:
    """The signal Parquet files a checked SHA256SUMS lists, in window order (none for older folders)."""
    return sorted(n for n in sums if SIGNALS_RE.match(n))


def _h5_names_of(sums: dict[str, str]) -> list[str]:
    """The HDF5 data files a checked SHA256SUMS lists: ``windows.h5``, or every shard in order."""
    shards = sorted(n for n in sums if SHARD_RE.match(n))
    return shards if shards and H5_NAME not in sums else [H5_NAME]


def _compare_meta(h5_path: Path, pq_path: Path, table: pa.Table, protocols: Sequence[str],
                  sharded: bool = False) -> None:
    """An HDF5 file's y and meta/ agree with its rows of windows.parquet, column by column, row by row."""
    schema = arrow_schema(protocols, sharded)
    found = [f"{f.name}:{f.type}" for f in table.schema]
    if found != [f"{f.name}:{f.type}" for f in schema]:
        raise DatasetError(pq_path, f"the columns {[f'{f.name}:{f.type}' for f in schema]}", f"{found}")
    n = table.num_rows
    try:
        with h5py.File(h5_path, "r") as f:
            if "meta" not in f or "y" not in f:
                raise DatasetError(h5_path, "datasets X, y and group meta", f"{sorted(f)}")
            group = f["meta"]
            if sorted(group) != sorted(schema.names):
                raise DatasetError(h5_path, f"one dataset per column {sorted(schema.names)}",
                                   f"{sorted(group)}", "meta")
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
                raise DatasetError(h5_path, f"y equal to bias_x/y/z of {PARQUET_NAME}", "different values",
                                   "y")
    except OSError as exc:  # e.g. a chunk of y failing its Fletcher-32 checksum
        raise DatasetError(h5_path, "readable y and meta/ (chunks passing their Fletcher-32 checksums)",
                           f"a read error ({' '.join(str(exc).split())})") from exc


_SHARD_ATTRS = ("shard", "shard_windows", "first_window_id")


def _check_samples(folder: Path, h5_names: Sequence[str], names: Sequence[str], counts: Sequence[int],
                   table: pa.Table, protocols: Sequence[str], t: int, sharded: bool) -> None:
    """Every HDF5 file's X read whole (its chunks' Fletcher-32 sums) and, when the folder has signal
    files, each one's schema (``windows.parquet``'s columns plus X, (T, 3) float32) and row count
    (its HDF5 file's windows), then its rows against the HDF5 file's X bit for bit and against its
    rows of the index (:func:`~ofbe_data.dataset.verify_signals.compare_signals`)."""
    schema = signal_schema(protocols, t, sharded)
    columns = [c for c in schema.names if c != SIGNAL_COLUMN]
    first = 0
    for i, (h5_name, n) in enumerate(zip(h5_names, counts, strict=True)):
        path = folder / names[i] if names else None
        if path is not None:
            try:
                with pq.ParquetFile(path) as pf:
                    found, rows = pf.schema_arrow, pf.metadata.num_rows
            except (OSError, pa.ArrowException) as exc:
                raise DatasetError(path, "a readable Parquet file", f"an unreadable one ({exc})") from exc
            if not same_signal_schema(found, schema, t):
                raise DatasetError(path, f"the columns {[f'{f.name}:{f.type}' for f in schema]}",
                                   f"{[f'{f.name}:{f.type}' for f in found]}")
            if rows != n:
                raise DatasetError(path, f"{n} rows (the windows of its HDF5 file)", f"{rows}")
        compare_signals(folder / h5_name, path, table.slice(first, n).select(columns), first)
        first += n


def _check_croissant(folder: Path, actual: dict[str, str]) -> None:
    """Every file croissant.json names with a sha256 has that hash."""
    path = folder / CROISSANT_NAME
    doc = read_json(path)
    for entry in doc.get("distribution", []):
        if not isinstance(entry, dict) or "sha256" not in entry:
            continue
        name = entry.get("contentUrl")
        if name not in actual:
            raise DatasetError(path, f"contentUrl one of the files of {SUMS_NAME}", repr(name),
                               "distribution")
        if entry["sha256"] != actual[name]:
            raise ChecksumError(folder / name, f"sha256 {entry['sha256']} (from {CROISSANT_NAME})",
                                f"sha256 {actual[name]}")


def _check_shards(folder: Path, h5_names: Sequence[str], prov: dict[str, Any], table: pa.Table,
                  attrs0: dict[str, Any], protocols: Sequence[str], t: int) -> list[int]:
    """Every shard: its header, X, and its rows of the index. Returns the windows per shard."""
    pq_path = folder / PARQUET_NAME
    layout = shard_layout(folder)
    if layout is None or [name for name, _ in layout] != list(h5_names):
        found = "none" if layout is None else ", ".join(name for name, _ in layout)
        raise DatasetError(pq_path, f"the shards {', '.join(h5_names)} (as in {SUMS_NAME})", found,
                           "ofbe.shards.files")
    per = prov["shards"].get("windows_per_shard")
    common = {k: v for k, v in attrs0.items() if k not in (*_SHARD_ATTRS, "n_windows")}
    counts, first = [], 0
    for i, (name, n) in enumerate(layout):
        path = folder / name
        attrs = read_h5_header(path)
        check_version(path, attrs.get("schema_version"))
        expected_attrs = {**common, "shard": i, "shard_windows": per, "first_window_id": first}
        for key, value in expected_attrs.items():
            if attrs.get(key) != value:
                raise DatasetError(path, f"{value!r} (as in {h5_names[0]} and {PARQUET_NAME})",
                                   repr(attrs.get(key)), key)
        if n > per or (i < len(layout) - 1 and n != per):
            raise DatasetError(pq_path, f"{per} windows in every shard but the last (at most {per} there)",
                               f"{n} in {name}", "ofbe.shards.files")
        with h5py.File(path, "r") as f:
            x = f.get("X")
            if not isinstance(x, h5py.Dataset) or x.dtype != np.float32 or x.shape != (n, t, 3):
                found = f"{x.dtype} {x.shape}" if isinstance(x, h5py.Dataset) else "none"
                raise DatasetError(path, f"float32 of shape ({n}, {t}, 3) (n_windows from {PARQUET_NAME})",
                                   found, "X")
        if first + n > table.num_rows:
            raise DatasetError(pq_path, f"at least {first + n} rows (the shards' windows)",
                               f"{table.num_rows}")
        rows = table.slice(first, n)
        for col, want, text in (("shard", np.full(n, i), str(i)), ("shard_row", np.arange(n), "0..n-1")):
            if col not in rows.column_names or not np.array_equal(rows.column(col).to_numpy(), want):
                raise DatasetError(pq_path, f"{col} = {text} on the rows of {name}", "other values", col)
        _compare_meta(path, pq_path, rows, protocols, sharded=True)
        counts.append(n)
        first += n
    return counts


def verify_dataset(path: str | Path) -> dict[str, Any]:
    """Check a dataset folder: checksums, schema version, and that its files agree.

    Checks, in order: every file of ``SHA256SUMS`` exists and has its hash; the hashes and
    sizes of ``datapackage.json``'s resources; the schema version in ``windows.h5`` (every
    shard of a sharded dataset), ``windows.parquet`` and ``datapackage.json``; the dataset
    description against the HDF5 attributes; shapes and dtypes of ``X`` and ``y``; the Parquet
    schema; and ``meta/`` and ``y`` against the Parquet columns, row by row (each shard against
    its rows of the index); the sha256 of every file ``croissant.json`` names. Then every chunk of
    ``X`` is read (so its Fletcher-32 sum is checked), 256 windows at a time, and each signal
    Parquet file, when ``SHA256SUMS`` lists them (it must list all or none), is checked for its
    schema and row count and compared with its HDF5 file window by window: ``X`` bit for bit and
    every other column against its rows of ``windows.parquet``. Sums can be recomputed after an
    edit; this finds the two copies disagreeing, naming the first window that differs. Folders
    written before the signal files and ``croissant.json`` existed verify without them.

    Returns
    -------
    dict
        ``path``, ``schema_version``, ``name``, ``campaign``, ``n_windows``, ``n_recordings``,
        ``n_devices``, ``window_length``, ``stride``, ``protocols``, ``n_shards`` (1 for
        ``windows.h5``), ``signals`` (the signal files compared with the HDF5 files, in window
        order; none for older folders) and ``files`` (name → sha256).

    Raises
    ------
    ChecksumError
        A file's hash differs from the recorded one (naming the file and both hashes).
    DatasetError
        Anything else (naming the file, what was expected and what was found; for a signal file
        that differs from its HDF5 file, the first ``window_id`` and row that does; for a chunk
        that cannot be read, the HDF5 file and window).
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
    h5_names = _h5_names_of(sums)
    signals = _signals_of(sums)
    sharded = h5_names != [H5_NAME]
    dp_path, h5_path, pq_path = folder / DATAPACKAGE_NAME, folder / h5_names[0], folder / PARQUET_NAME
    doc = read_json(dp_path)
    resources = {r.get("path"): r for r in doc.get("resources", []) if isinstance(r, dict)}
    for name in (*h5_names, PARQUET_NAME, *signals):
        res = resources.get(name)
        if res is None:
            raise DatasetError(dp_path, f"a resource with path {name!r}", "none", "resources")
        if res.get("hash") != f"sha256:{actual[name]}":
            raise ChecksumError(folder / name, f"{res.get('hash')} (from {DATAPACKAGE_NAME})",
                                f"sha256:{actual[name]}")
        size = (folder / name).stat().st_size
        # the tabular windows.parquet has no bytes since frictionless cannot count them (package.py)
        if name == PARQUET_NAME and "bytes" not in res:
            continue
        if res.get("bytes") != size:
            raise DatasetError(dp_path, f"bytes = {size} (the size of {name})", repr(res.get("bytes")),
                               f"resources[{name}].bytes")
    attrs = read_h5_header(h5_path)
    check_version(h5_path, attrs.get("schema_version"))
    prov = read_parquet_provenance(pq_path)
    check_version(pq_path, prov.get("schema_version"))
    ofbe = doc.get("ofbe") if isinstance(doc.get("ofbe"), dict) else {}
    check_version(dp_path, ofbe.get("schema_version"), "ofbe.schema_version")
    info = read_dataset_info(folder)
    for key in ("name", "campaign", "window_length", "stride", "protocols"):
        if prov.get(key) != attrs.get(key):
            raise DatasetError(pq_path, f"{attrs.get(key)!r} (as in {h5_names[0]})", repr(prov.get(key)), key)
    t = info.window_length
    table = pq.read_table(pq_path)
    if sharded:
        counts = _check_shards(folder, h5_names, prov, table, attrs, list(info.protocols), t)
        n = sum(counts)
        if table.num_rows != n:
            raise DatasetError(pq_path, f"{n} rows (one per window of the shards)", f"{table.num_rows}")
    else:
        with h5py.File(h5_path, "r") as f:
            x = f.get("X")
            if not isinstance(x, h5py.Dataset) or x.dtype != np.float32 or x.shape[1:] != (t, 3):
                found = f"{x.dtype} {x.shape}" if isinstance(x, h5py.Dataset) else "none"
                raise DatasetError(h5_path, f"float32 of shape (N, {t}, 3)", found, "X")
            n = int(x.shape[0])
        if table.num_rows != n:
            raise DatasetError(pq_path, f"{n} rows (one per window of {H5_NAME})", f"{table.num_rows}")
        _compare_meta(h5_path, pq_path, table, list(info.protocols))
        counts = [n]
    if CROISSANT_NAME in sums:
        _check_croissant(folder, actual)
    _check_samples(folder, h5_names, signals, counts, table.replace_schema_metadata(None),
                   list(info.protocols), t, sharded)
    if not np.array_equal(table.column("window_id").to_numpy(), np.arange(n)):
        raise DatasetError(pq_path, "window_id = 0..N-1 in order", "other values", "window_id")
    keys = table.select(list(RECORDING_KEY)).to_pandas().drop_duplicates()
    return {"path": str(folder), "schema_version": SCHEMA_VERSION, "name": info.name,
            "campaign": info.campaign, "n_windows": n, "n_recordings": int(len(keys)),
            "n_devices": int(keys["device"].nunique()), "window_length": t, "stride": info.stride,
            "protocols": list(info.protocols), "n_shards": len(h5_names), "signals": list(signals),
            "files": dict(sorted(actual.items()))}


# ---------------------------------------------------------------------------------------------
# Loading


@dataclass(frozen=True)
class Shard:
    """One HDF5 file of a dataset and the windows (``window_id`` start:stop) it holds."""

    path: Path
    start: int
    stop: int

    @property
    def n_windows(self) -> int:
        """Windows in the file."""
        return self.stop - self.start


def _read_x(shard: Shard, out: np.ndarray | None = None) -> np.ndarray:
    """X of one file (into ``out`` when given), with its Fletcher-32 failures as DatasetError."""
    try:
        with h5py.File(shard.path, "r") as f:
            x = f["X"]
            if out is None:
                return np.asarray(x[...], dtype=np.float32)
            x.read_direct(out)
            return out
    except OSError as exc:  # e.g. a chunk failing its Fletcher-32 checksum
        raise DatasetError(shard.path, "readable X and y (chunks passing their Fletcher-32 checksums)",
                           f"a read error ({exc})") from exc


class LoadedDataset:
    """A loaded dataset: labels and metadata in memory, X in memory or read shard by shard.

    Attributes
    ----------
    y
        float64 (N, 3), m/s²: the apparent-bias labels.
    meta
        One row per window (the columns of ``windows.parquet``; for a sharded dataset less
        ``shard`` and ``shard_row``, so both layouts give the same frame).
    info
        Root attributes of ``windows.h5`` (``protocols`` parsed) and ``dataset_info`` (the
        description from ``datapackage.json``); for a sharded dataset also ``shards`` (the
        index's ``windows_per_shard`` and ``files``).
    shards
        The HDF5 files and their window ranges (one for ``windows.h5``; empty when built
        from arrays).

    ``X`` (float32 (N, T, 3), m/s², sensor frame) is a property: for ``windows.h5`` it is read
    when the dataset is loaded, for a sharded dataset on first use (then kept).
    """

    def __init__(self, X: np.ndarray | None, y: np.ndarray, meta: pd.DataFrame, info: dict[str, Any],
                 shards: Sequence[Shard] = ()) -> None:
        if X is None and not shards:
            raise DatasetError("LoadedDataset", "X or the shard files to read it from", "neither")
        self._X = X
        self.y = y
        self.meta = meta
        self.info = info
        self.shards = tuple(shards)

    @property
    def X(self) -> np.ndarray:
        """float32 (N, T, 3), m/s²: every window (read from the shards on first use)."""
        if self._X is None:
            t = int(self.info["window_length"])
            x = np.empty((self.shards[-1].stop, t, 3), dtype=np.float32)
            for shard in self.shards:
                _read_x(shard, x[shard.start:shard.stop])
            self._X = x
        return self._X

    @property
    def sharded(self) -> bool:
        """Whether the windows are in several shard files."""
        return len(self.shards) > 1 or any(s.path.name != H5_NAME for s in self.shards)

    def iter_shards(self) -> Iterator[tuple[np.ndarray, np.ndarray, pd.DataFrame]]:
        """``(X, y, meta)`` of each HDF5 file in turn, reading one shard at a time.

        Yields
        ------
        X : numpy.ndarray
            float32 (n, T, 3) of the shard (a view of :attr:`X` when it is already in memory).
        y : numpy.ndarray
            float64 (n, 3).
        meta : pandas.DataFrame
            The shard's rows of :attr:`meta` (index = ``window_id``).
        """
        if not self.shards:
            yield self.X, self.y, self.meta
            return
        for shard in self.shards:
            x = self._X[shard.start:shard.stop] if self._X is not None else _read_x(shard)
            yield x, self.y[shard.start:shard.stop], self.meta.iloc[shard.start:shard.stop]

    def tf_dataset(self) -> Any:
        """A ``tf.data.Dataset`` of ``(X_i, y_i)``, float32 (T, 3) and float64 (3,), in file order.

        X is streamed from the HDF5 files, shard after shard, 256 windows at a time, on every
        pass (from memory when the dataset was built from arrays). Cardinality is N.
        TensorFlow is imported here.
        """
        return _tf_dataset(self.shards, self.y, int(self.info["window_length"]),
                           None if self.shards else self.X)


_LOADERS = ("numpy", "pandas", "tf")
_NOT_INFO = ("n_windows", *_SHARD_ATTRS)


def _layout(folder: Path) -> tuple[list[Shard], dict[str, Any] | None]:
    """The HDF5 files of a folder with their window ranges, and the index's ``shards`` entry."""
    layout = shard_layout(folder)
    if layout is None:
        return [], None
    shards, first = [], 0
    for name, n in layout:
        shards.append(Shard(folder / name, first, first + n))
        first += n
    return shards, read_parquet_provenance(folder / PARQUET_NAME)["shards"]


def _info_dict(folder: Path, h5_path: Path, shards: dict[str, Any] | None) -> dict[str, Any]:
    attrs = read_h5_header(h5_path)
    for key in _NOT_INFO:
        attrs.pop(key, None)
    check_version(h5_path, attrs.get("schema_version"))
    pq_path = folder / PARQUET_NAME
    check_version(pq_path, read_parquet_provenance(pq_path).get("schema_version"))
    return {**attrs, "dataset_info": read_dataset_info(folder).to_dict(),
            **({"shards": shards} if shards is not None else {})}


def _read_meta(folder: Path) -> pd.DataFrame:
    path = folder / PARQUET_NAME
    try:
        table = pq.read_table(path).replace_schema_metadata(None)
    except (OSError, pa.ArrowException) as exc:
        raise DatasetError(path, "a readable Parquet file", f"an unreadable one ({exc})") from exc
    drop = [c for c in SHARD_COLUMNS if c in table.column_names]
    return (table.drop_columns(drop) if drop else table).to_pandas()


def load_dataset(path: str | Path, as_: str = "numpy", verify: bool = True) -> Any:
    """Load a dataset folder (one ``windows.h5`` or shard files).

    Parameters
    ----------
    path
        The dataset folder (``processed/datasets/<name>``).
    as_
        ``"numpy"``: a :class:`LoadedDataset` (X float32 (N, T, 3), y float64 (N, 3), meta, info);
        for a sharded dataset X is not read until used (:meth:`LoadedDataset.iter_shards` reads
        one shard at a time).
        ``"pandas"``: the metadata frame alone (no X); its ``bias_x/y/z`` columns are ``y``
        (verified equal to the HDF5 ``y``), and ``frame.attrs["ofbe"]`` holds ``info``. The
        index columns ``shard``/``shard_row`` of a sharded dataset are left out.
        ``"tf"``: a ``tf.data.Dataset`` of ``(X_i, y_i)`` pairs, float32 (T, 3) and float64 (3,),
        in file order. X is *streamed*: a generator (with ``output_signature``) reads 256
        windows at a time from the HDF5 file(s) on each pass, so the dataset need not fit in
        memory; ``y`` is held in memory. Cardinality is set to N. TensorFlow is imported here.
    verify
        Run :func:`verify_dataset` first (checksums of every file, schema version, agreement
        of the files). Without it the schema version is still checked.

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
    shards, index = _layout(folder)
    h5_path = shards[0].path if shards else folder / H5_NAME
    info = _info_dict(folder, h5_path, index)
    if as_ == "pandas":
        meta = _read_meta(folder)
        meta.attrs["ofbe"] = info
        return meta
    t = int(info["window_length"])
    if shards:
        meta = _read_meta(folder)
        y = meta[["bias_x", "bias_y", "bias_z"]].to_numpy(dtype=np.float64)
        if len(y) != shards[-1].stop:
            raise DatasetError(folder / PARQUET_NAME, f"{shards[-1].stop} rows (the shards' windows)",
                               f"{len(y)}")
        if as_ == "tf":
            return _tf_dataset(shards, y, t)
        return LoadedDataset(None, y, meta, info, shards)
    if as_ == "numpy":
        try:
            with h5py.File(h5_path, "r") as f:
                x = np.asarray(f["X"][...], dtype=np.float32)
                y = np.asarray(f["y"][...], dtype=np.float64)
        except OSError as exc:  # e.g. a chunk failing its Fletcher-32 checksum
            raise DatasetError(h5_path, "readable X and y (chunks passing their Fletcher-32 checksums)",
                               f"a read error ({exc})") from exc
        return LoadedDataset(x, y, _read_meta(folder), info, (Shard(h5_path, 0, len(y)),))
    with h5py.File(h5_path, "r") as f:
        y = np.asarray(f["y"][...], dtype=np.float64)
    return _tf_dataset([Shard(h5_path, 0, len(y))], y, t)


def _window_generator(shards: Sequence[Shard], y: np.ndarray, x: np.ndarray | None,
                      ) -> Callable[[], Iterator[tuple[np.ndarray, np.ndarray]]]:
    def gen() -> Iterator[tuple[np.ndarray, np.ndarray]]:
        if x is not None:
            for i in range(len(y)):
                yield x[i], y[i]
            return
        for shard in shards:
            with h5py.File(shard.path, "r") as f:
                xs = f["X"]
                for start in range(0, xs.shape[0], TF_BLOCK):
                    block = xs[start:start + TF_BLOCK]
                    for i in range(block.shape[0]):
                        yield block[i], y[shard.start + start + i]

    return gen


def _tf_dataset(shards: Sequence[Shard], y: np.ndarray, window_length: int,
                x: np.ndarray | None = None) -> Any:
    from ofbe_data.core.cli import import_tensorflow

    tf = import_tensorflow()

    signature = (tf.TensorSpec(shape=(window_length, 3), dtype=tf.float32),
                 tf.TensorSpec(shape=(3,), dtype=tf.float64))
    ds = tf.data.Dataset.from_generator(_window_generator(shards, y, x), output_signature=signature)
    return ds.apply(tf.data.experimental.assert_cardinality(len(y)))
