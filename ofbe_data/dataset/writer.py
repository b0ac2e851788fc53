"""Writing a dataset: window metadata normalised and checked, windows streamed into HDF5 + Parquet
(one ``windows.h5``, or shard files ``windows-00000.h5``, … above ``shard_windows`` windows), then
the signal Parquet file(s) copied from the finished HDF5 file(s) and the package files."""

from __future__ import annotations

import errno
import io
import json
import shutil
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ofbe_data import __version__
from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.dataset.chunks import Chunk, ChunkSink, x_dataset
from ofbe_data.dataset.package import write_package_files
from ofbe_data.dataset.signals import write_signal_files
from ofbe_data.dataset.store import (
    COLUMN_BY_NAME,
    DATASET_FORMAT,
    FRAME,
    H5_LIBVER,
    H5_NAME,
    PARQUET_NAME,
    PER_WINDOW,
    RECORDING_KEY,
    SCHEMA_VERSION,
    UNITS,
    WINDOW_COLUMNS,
    DatasetError,
    DatasetInfo,
    all_columns,
    arrow_schema,
    fold_column,
    shard_name,
)

_MERGE_BLOCKS = 256  # metadata blocks merged into one array per column, to bound per-array overhead

# ---------------------------------------------------------------------------------------------
# Validation of appended metadata


FREE_SPACE_RESERVE = 2**20
"""Bytes kept free beyond the next HDF5 or signal file (for the index Parquet and the card)."""

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
        doc = COLUMN_BY_NAME.get(name)
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
    level = [c for c in frame.columns if c not in (*keys, *PER_WINDOW)]
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


def _parquet_provenance(info: DatasetInfo, shards: dict[str, Any] | None = None) -> dict[str, Any]:
    prov = {"format": DATASET_FORMAT, "schema_version": SCHEMA_VERSION, "name": info.name,
            "campaign": info.campaign, "window_length": info.window_length, "stride": info.stride,
            "units": UNITS, "protocols": info.protocols}
    if shards is not None:  # only for sharded datasets: single-file ones keep their bytes
        prov["shards"] = shards
    return prov


def _parquet_bytes(table: pa.Table) -> bytes:
    buf = io.BytesIO()
    pq.write_table(table, buf, compression="zstd")
    return buf.getvalue()


class WindowWriter:
    """Write ``windows.h5`` (or its shards) and ``windows.parquet`` block by block, then the rest.

    Use as a context manager inside :func:`ofbe_data.core.atomic.atomic_directory`::

        with atomic_directory(out) as tmp, WindowWriter(tmp, info) as writer:
            for X, meta in blocks:          # e.g. one recording at a time
                writer.append(X, meta)

    The open HDF5 file is built in memory (HDF5's ``core`` driver, no backing store): ``X``
    is compressed into it at once and the raw block is not kept, so the writer holds one
    file's compressed image and the (small) metadata. A completed file's image is written to
    disk in one atomic write (temporary name, then rename), after checking that its disk has
    room for it: a full disk is then a Python ``OSError`` on a plain write, never HDF5 failing
    to close a half-written file (which can crash the process), and nothing partial is left.
    On a clean exit the writer completes the HDF5 file (``y`` and ``meta/``),
    writes ``windows.parquet``, the signal Parquet file(s) (:func:`write_signal_files`, reading
    the HDF5 file(s) back one row group at a time) and then :func:`write_package_files`. On an
    exception it drops the in-memory file and re-raises; the caller discards the folder.

    With ``shard_windows`` = S, the (S+1)-th window starts a new file: the full one is completed
    (``y``, ``meta/`` of its rows, the shard attributes), written as ``windows-00000.h5``,
    and so on; blocks that straddle a boundary are split. At most one shard is in memory. A
    dataset of at most S windows is written exactly as without sharding. The bytes are those
    HDF5 writes to a disk file (``libver="earliest"``: the image is the file).

    Parameters
    ----------
    folder
        Existing folder to write into; it must not hold ``windows.h5``, a shard or
        ``windows.parquet``.
    info
        What the dataset is.
    shard_windows
        Windows per shard file; ``None`` (the default): one file whatever the size.
    """

    def __init__(self, folder: str | Path, info: DatasetInfo, shard_windows: int | None = None) -> None:
        self.folder = Path(folder)
        self.info = info
        if shard_windows is not None and (isinstance(shard_windows, bool)
                                          or not isinstance(shard_windows, int | np.integer)
                                          or shard_windows < 1):
            raise DatasetError(self.folder, "shard_windows an integer >= 1 (or None: one file)",
                               repr(shard_windows), "shard_windows")
        self.shard_windows = None if shard_windows is None else int(shard_windows)
        self._h5_path = self.folder / H5_NAME
        self._parquet_path = self.folder / PARQUET_NAME
        self._mem_name = f"{self.folder / H5_NAME}.in-memory"  # never created on disk
        self._file: h5py.File | None = None
        self._x: h5py.Dataset | None = None
        self._closed: list[dict[str, np.ndarray]] = []  # metadata of the completed shards
        self._blocks: list[dict[str, np.ndarray]] = []  # metadata only (1-D arrays), merged in batches
        self._pending: list[dict[str, np.ndarray]] = []
        self._n = 0
        self._shard = 0  # index of the open file
        self._shard_n = 0  # windows in the open file
        self._entered = False
        self._mode: str | None = None  # "samples" (append) or "chunks" (append_chunks)
        self._sink: ChunkSink | None = None  # the open file's, with append_chunks

    @property
    def n_windows(self) -> int:
        """Windows appended so far."""
        return self._n

    @property
    def n_shards(self) -> int:
        """HDF5 files begun so far (1 until the first shard is full and another window comes)."""
        return self._shard + 1

    def __enter__(self) -> WindowWriter:
        if not self.folder.is_dir():
            raise DatasetError(self.folder, "an existing folder to write the dataset into", "none")
        for p in (self._h5_path, self.folder / shard_name(0), self._parquet_path):
            if p.exists():
                raise DatasetError(p, "a folder without this file (a fresh dataset)", "an existing file")
        if self._entered:
            raise DatasetError(self._h5_path, "a writer entered once", "a second `with`")
        self._entered = True
        self._open()
        return self

    def _open(self) -> None:
        """Create the next HDF5 file under its temporary name, with the root attributes and X."""
        t = self.info.window_length
        self._file = h5py.File(self._mem_name, "w", libver=H5_LIBVER, driver="core", backing_store=False)
        try:
            _set_attrs(self._file, _root_attrs(self.info))
            self._x = x_dataset(self._file, t)
            _set_attrs(self._x, {"units": UNITS, "frame": FRAME, "description":
                                 "specific force measured by the accelerometer, sensor frame; axes are "
                                 "(window, sample, x/y/z)"})
        except BaseException:
            self._abort()
            raise

    def _need_space(self, path: Path, nbytes: int, what: str) -> None:
        """Refuse to begin a write of ``nbytes`` when the folder's disk has less than that plus
        :data:`FREE_SPACE_RESERVE` free.

        Raises
        ------
        OSError
            ``ENOSPC``, naming ``path`` and both sizes (the commands report it as a failed write).
        """
        free = shutil.disk_usage(self.folder).free
        if free < nbytes + FREE_SPACE_RESERVE:
            raise OSError(errno.ENOSPC, f"expected {(nbytes + FREE_SPACE_RESERVE) / 1e6:.1f} MB free for "
                                        f"{what}, found {free / 1e6:.1f} MB free on its disk", str(path))

    def append(self, X: np.ndarray, meta: pd.DataFrame) -> None:
        """Append n windows.

        Parameters
        ----------
        X
            (n, T, 3) specific force, m/s², sensor frame; stored as float32.
        meta
            n rows: :data:`WINDOW_COLUMNS` less ``window_id`` plus one ``fold_<protocol>``
            column per protocol. ``y`` is taken from ``bias_x/y/z``; ``window_id`` is assigned
            here (the running row index), and so are ``shard``/``shard_row`` when sharded.

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
        self._use("samples")
        self._place(arr.shape[0], cols, lambda a, b: self._write_x(x32[a:b]))

    def append_chunks(self, chunks: Sequence[Chunk], cols: Mapping[str, np.ndarray]) -> None:
        """Append n windows already compressed (:func:`ofbe_data.dataset.chunks.compress_windows`,
        in a worker) with their metadata already checked (:meth:`normalise_meta`).

        Parameters
        ----------
        chunks
            n stored chunks of ``X``, in window order.
        cols
            The n windows' rows of :meth:`normalise_meta`'s columns.

        Raises
        ------
        DatasetError
            Not as many metadata rows as chunks.
        """
        if self._x is None:
            raise DatasetError(self._h5_path, "append_chunks() inside `with WindowWriter(...)`",
                               "a closed writer")
        n = len(chunks)
        rows = {len(v) for v in cols.values()}
        if rows != {n}:
            raise DatasetError(self._parquet_path, f"{n} metadata rows (one per chunk)", f"{sorted(rows)}",
                               "meta")
        self._use("chunks")
        self._place(n, cols, lambda a, b: self._chunk_sink().write(self._shard_n, chunks[a:b]))

    def _use(self, mode: str) -> None:
        """Take windows one way for the writer's life: ``samples`` (append) or ``chunks``."""
        if self._mode not in (None, mode):
            raise DatasetError(self._h5_path, "windows appended one way (append or append_chunks)", "both",
                               "X")
        self._mode = mode

    def _chunk_sink(self) -> ChunkSink:
        assert self._x is not None
        if self._sink is None:
            self._sink = ChunkSink(self._x)
        return self._sink

    def normalise_meta(self, meta: pd.DataFrame) -> dict[str, np.ndarray]:
        """Check window metadata (the columns :meth:`append` takes) once for many blocks: column
        name → numpy array, to be sliced for :meth:`append_chunks`."""
        return _normalise_meta(meta, self.info.protocols, self._parquet_path)

    def _place(self, n: int, cols: Mapping[str, np.ndarray], write: Callable[[int, int], None]) -> None:
        """Put n windows into the open file(s): ``write(a, b)`` stores windows a..b of the block
        at the open file's next row; a block that straddles a shard boundary is split."""
        done = 0
        while done < n:
            if self.shard_windows is not None and self._shard_n == self.shard_windows:
                self._next_shard()
            room = n - done
            if self.shard_windows is not None:
                room = min(room, self.shard_windows - self._shard_n)
            write(done, done + room)
            part = dict(cols) if room == n else {k: v[done:done + room] for k, v in cols.items()}
            self._pending.append(part)
            if len(self._pending) >= _MERGE_BLOCKS:
                self._blocks.append(_merge(self._pending))
                self._pending = []
            done += room
            self._shard_n += room
            self._n += room

    def _write_x(self, x32: np.ndarray) -> None:
        assert self._x is not None
        start, n = self._shard_n, x32.shape[0]
        self._x.resize(start + n, axis=0)
        self._x[start:start + n] = x32

    def _shard_cols(self, sharded: bool) -> dict[str, np.ndarray]:
        """The open file's metadata, merged, with ``window_id`` (and the shard columns) in front."""
        n, first = self._shard_n, self._n - self._shard_n
        cols = {"window_id": np.arange(first, first + n, dtype=np.int64)}
        if sharded:
            cols["shard"] = np.full(n, self._shard, dtype=np.int64)
            cols["shard_row"] = np.arange(n, dtype=np.int64)
        cols.update(_merge([*self._blocks, *self._pending]))
        self._blocks, self._pending = [], []
        return cols

    def _next_shard(self) -> None:
        """Complete the full open file as a shard and open the next one."""
        cols = self._shard_cols(sharded=True)
        self._complete(cols, sharded=True)
        self._closed.append(cols)
        self._shard += 1
        self._shard_n = 0
        self._open()

    def _complete(self, cols: Mapping[str, np.ndarray], sharded: bool) -> None:
        """Write ``y`` and ``meta/`` of the open file's rows, close it and give it its name."""
        assert self._file is not None
        f = self._file
        n = self._shard_n
        columns = all_columns(list(self.info.protocols), sharded)
        y = np.column_stack([cols["bias_x"], cols["bias_y"], cols["bias_z"]]).astype(np.float64)
        ds_y = f.create_dataset("y", data=y, chunks=(min(n, 4096), 3), compression="gzip",
                                compression_opts=4, shuffle=True, fletcher32=True, track_times=False)
        _set_attrs(ds_y, {"units": UNITS, "frame": FRAME, "description":
                          "apparent-bias label b_app of the window's recording (bias_x/y/z), sensor frame"})
        group = f.create_group("meta")
        group.attrs["columns"] = json.dumps([c.name for c in columns])
        group.attrs["description"] = (
            "one dataset per column of windows.parquet, same row order; NaN = null" if not sharded else
            "one dataset per column of windows.parquet for this shard's rows, same order; NaN = null")
        for col in columns:
            values = cols[col.name]
            if col.kind == "string":
                ds = group.create_dataset(col.name, data=values, dtype=h5py.string_dtype("utf-8"),
                                          track_times=False)
            else:
                ds = group.create_dataset(col.name, data=values, track_times=False)
            ds.attrs["description"] = col.description
            if col.unit is not None:
                ds.attrs["units"] = col.unit
        if sharded:
            _set_attrs(f, {"shard": np.int64(self._shard), "shard_windows": np.int64(self.shard_windows),
                           "first_window_id": np.int64(cols["window_id"][0])})
        if self._sink is not None:
            self._sink.finish()  # after y and meta/, as HDF5's cache would flush the last windows
            self._sink = None
        f.flush()
        image = f.id.get_file_image()
        f.close()
        self._file = None
        self._x = None
        target = self.folder / (shard_name(self._shard) if sharded else H5_NAME)
        self._need_space(target, len(image), f"{target.name} ({n} windows)")
        write_bytes_atomic(target, image)

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
            try:
                self._file.close()
            except Exception:  # noqa: BLE001 - the file is discarded; the original error is re-raised
                pass
        self._sink = None
        self._file = None
        self._x = None

    def _finish(self) -> None:
        if self._file is None:
            raise DatasetError(self._h5_path, "a writer inside `with`", "a closed writer")
        if self._n == 0:
            raise DatasetError(self._h5_path, "at least one window", "0 windows appended")
        sharded = self._shard > 0
        last = self._shard_cols(sharded)
        cols = _merge([*self._closed, last]) if sharded else last
        _check_recordings(cols, self._parquet_path)
        self._complete(last, sharded)
        shards = None
        if sharded:
            self._closed.append(last)
            shards = {"windows_per_shard": self.shard_windows,
                      "files": [{"path": shard_name(i), "n_windows": int(len(c["window_id"]))}
                                for i, c in enumerate(self._closed)]}
        self._closed = []
        schema = arrow_schema(list(self.info.protocols), sharded)
        arrays = [pa.array(cols[fld.name].tolist() if fld.type == pa.string() else cols[fld.name],
                           type=fld.type, from_pandas=True) for fld in schema]
        table = pa.Table.from_arrays(arrays, schema=schema).replace_schema_metadata(
            {b"ofbe": json.dumps(_parquet_provenance(self.info, shards), allow_nan=False).encode()})
        write_bytes_atomic(self._parquet_path, _parquet_bytes(table))
        h5_bytes = sum(p.stat().st_size for p in self.folder.glob("windows*.h5"))
        self._need_space(self.folder / "signals.parquet", h5_bytes,
                         "the signal Parquet files (about the size of the HDF5 files)")
        write_signal_files(self.folder)
        write_package_files(self.folder, self.info)
