"""Verifying the samples: every HDF5 chunk of ``X`` read, and each signal Parquet file compared with
its HDF5 file, window by window, bit for bit.

The two copies of the samples (``windows.h5``, the toolkit's, and ``signals.parquet``, the one
Hugging Face ``datasets`` and Croissant read) are each covered by ``SHA256SUMS``; but sums can be
recomputed after an edit, so :func:`~ofbe_data.dataset.reader.verify_dataset` also compares them.
Both are read together, :data:`VERIFY_BLOCK` windows at a time (the signal files' row groups), so
the memory used does not grow with the dataset. Reading every chunk also runs HDF5's Fletcher-32
check of each, so a corrupted chunk is found by ``verify`` rather than later by the loader.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ofbe_data.dataset.store import PARQUET_NAME, SIGNAL_COLUMN, DatasetError

#: Windows read at a time from an HDF5 file and its signal file (the signal files' row group).
VERIFY_BLOCK = 256

_AXES = "xyz"


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


def _read_block(x: h5py.Dataset, h5_path: Path, start: int, stop: int, first: int) -> np.ndarray:
    """Windows ``start:stop`` of X; a chunk that cannot be read (e.g. failing its Fletcher-32
    checksum) is a :class:`DatasetError` naming the file and the first window that fails."""
    try:
        return np.asarray(x[start:stop], dtype=np.float32)
    except OSError as block_error:
        bad, exc = start, block_error
        for row in range(start, stop):  # find the first window that fails
            try:
                x[row:row + 1]
            except OSError as row_error:
                bad, exc = row, row_error
                break
        raise DatasetError(h5_path, "readable X (chunks passing their Fletcher-32 checksums)",
                           f"a read error in window_id {first + bad} (row {bad}): {_one_line(exc)}",
                           "X") from block_error


def _first_difference(found: pa.Array, expected: pa.Array) -> int | None:
    """The first row where two columns of the same type differ (nulls equal nulls, NaN equals NaN)."""
    if found.equals(expected):
        return None
    for i, (a, b) in enumerate(zip(found.to_pylist(), expected.to_pylist(), strict=True)):
        if not (a == b or (a != a and b != b)):  # a != a: NaN
            return i
    return None


def _signal_x(column: pa.Array, path: Path, t: int, start: int, first: int) -> np.ndarray:
    """The windows of one batch's X column (rows ``start``…) as float32 (k, T, 3); a null is an error."""
    outer = column
    inner = outer.flatten()
    values = inner.flatten()
    for arr, per in ((outer, 1), (inner, t), (values, 3 * t)):
        if arr.null_count:
            row = start + int(np.flatnonzero(arr.is_null().to_numpy(zero_copy_only=False))[0]) // per
            raise DatasetError(path, "a (T, 3) window of float32 on every row", f"a null in window_id "
                               f"{first + row} (row {row})", SIGNAL_COLUMN)
    return values.to_numpy(zero_copy_only=False).astype(np.float32, copy=False).reshape(len(outer), t, 3)


def _compare_x(h5_x: np.ndarray, pq_x: np.ndarray, h5_path: Path, path: Path, start: int, first: int) -> None:
    """The signal file's windows bit for bit equal to the HDF5 file's (rows ``start``…)."""
    h5_bits = np.ascontiguousarray(h5_x).view(np.uint32)
    pq_bits = np.ascontiguousarray(pq_x).view(np.uint32)
    diff = h5_bits != pq_bits
    if not diff.any():
        return
    k, s, a = (int(i) for i in np.argwhere(diff)[0])
    row = start + k
    want, got = h5_x[k, s, a], pq_x[k, s, a]
    want_text, got_text = str(want), str(got)
    if want_text == got_text:  # e.g. two NaNs: show the bits
        want_text += f" (0x{int(h5_bits[k, s, a]):08x})"
        got_text += f" (0x{int(pq_bits[k, s, a]):08x})"
    n_diff, n_values = int(diff[k].sum()), diff[k].size
    raise DatasetError(path, f"the samples of {h5_path.name} bit for bit, window_id {first + row} "
                       f"(row {row}) sample {s} axis {_AXES[a]} = {want_text}",
                       f"{got_text} ({n_diff} of {n_values} values of that window differ)", SIGNAL_COLUMN)


def _compare_batch(batch: pa.RecordBatch, rows: pa.Table, x: h5py.Dataset, h5_path: Path, path: Path,
                   start: int, first: int) -> None:
    """One batch of a signal file (rows ``start``…) against its rows of the index and the HDF5 X."""
    k = batch.num_rows
    h5_x = _read_block(x, h5_path, start, start + k, first)
    expected = rows.slice(start, k)
    span = f"{first}..{first + rows.num_rows - 1}"
    for name in rows.column_names:
        row = _first_difference(batch.column(name), expected.column(name).combine_chunks())
        if row is not None:
            at = start + row
            raise DatasetError(path, f"the columns of {PARQUET_NAME} equal to its rows {span}",
                               f"{name} = {batch.column(name)[row].as_py()!r} in window_id {first + at} "
                               f"(row {at}), where {PARQUET_NAME} has {expected.column(name)[row].as_py()!r}")
    pq_x = _signal_x(batch.column(SIGNAL_COLUMN), path, int(x.shape[1]), start, first)
    _compare_x(h5_x, pq_x, h5_path, path, start, first)


def compare_signals(h5_path: Path, signal_path: Path | None, rows: pa.Table, first: int) -> None:
    """Read every window of an HDF5 file's ``X`` and compare it with its signal file, if any.

    Parameters
    ----------
    h5_path
        ``windows.h5`` or a shard, whose ``X`` is float32 (n, T, 3) (already checked).
    signal_path
        Its signal Parquet file (schema and row count already checked), or ``None`` for a folder
        without signal files: then ``X`` is only read, for its chunks' Fletcher-32 checksums.
    rows
        The n rows of ``windows.parquet`` for this file, with the columns of the signal file but ``X``.
    first
        ``window_id`` of the file's first window (named in errors with the row in the file).

    Raises
    ------
    DatasetError
        A chunk of ``X`` that cannot be read (naming the HDF5 file and the first window that
        fails), or the first window where the signal file differs from the HDF5 file (``X``, bit
        for bit) or from ``windows.parquet`` (any other column), naming the signal file, the
        window (``window_id`` and row), what was expected and what was found.
    """
    n = rows.num_rows
    try:
        with h5py.File(h5_path, "r") as f:
            x = f["X"]
            if signal_path is None:
                for start in range(0, n, VERIFY_BLOCK):
                    _read_block(x, h5_path, start, min(start + VERIFY_BLOCK, n), first)
                return
            start = 0
            try:
                with pq.ParquetFile(signal_path, pre_buffer=False) as pf:  # one row group at a time
                    for batch in pf.iter_batches(batch_size=VERIFY_BLOCK, use_threads=False,
                                                 columns=[*rows.column_names, SIGNAL_COLUMN]):
                        if start + batch.num_rows > n:
                            raise DatasetError(signal_path, f"{n} rows (the windows of its HDF5 file)",
                                               f"more than {n}")
                        _compare_batch(batch, rows, x, h5_path, signal_path, start, first)
                        start += batch.num_rows
            except (OSError, pa.ArrowException) as exc:
                raise DatasetError(signal_path, "a readable Parquet file",
                                   f"an unreadable one ({_one_line(exc)})") from exc
            if start != n:
                raise DatasetError(signal_path, f"{n} rows (the windows of its HDF5 file)", f"{start}")
    except OSError as exc:  # the HDF5 file itself cannot be opened
        raise DatasetError(h5_path, "a readable HDF5 file", f"an unreadable one ({_one_line(exc)})") from exc
