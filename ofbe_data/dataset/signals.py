"""The signal Parquet files: every window with its samples, for readers other than the toolkit.

``windows.h5`` is the toolkit's own store of the samples (one compressed, checksummed chunk per
window); ``windows.parquet`` holds labels and metadata only. Tools that read Parquet (Hugging
Face ``datasets``, MLCommons Croissant, pandas, DuckDB, Spark …) need both in one table, so a
dataset folder also holds ``signals.parquet``: the rows of ``windows.parquet``, in the same order
and with the same columns, plus :data:`~ofbe_data.dataset.store.SIGNAL_COLUMN` (``X``), the
window as a fixed-size list of T fixed-size lists of 3 float32 (axes (sample, x/y/z), m/s²,
sensor frame), copied from the HDF5 file bit for bit. A sharded dataset has one signal file per
HDF5 shard, ``signals-00000.parquet``, …, with that shard's rows (the index columns ``shard``
and ``shard_row`` included).

The files are written from the finished HDF5 file(s) and ``windows.parquet``, one row group of
:data:`SIGNAL_ROW_GROUP` windows at a time, with every Parquet writer option that shapes the
bytes spelled out (:data:`SIGNAL_PARQUET_OPTIONS`): the same inputs give the same bytes.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ofbe_data.core.atomic import is_write_failure
from ofbe_data.dataset.store import (
    DATASET_FORMAT,
    FRAME,
    H5_NAME,
    PARQUET_NAME,
    SCHEMA_VERSION,
    SIGNAL_COLUMN,
    UNITS,
    DatasetError,
    read_parquet_provenance,
    shard_layout,
    signal_names,
    signal_schema,
    signal_type,
)

#: Windows per Parquet row group of a signal file (about 9 MB of float32 at T = 3000): the unit
#: that Hugging Face ``datasets`` and pyarrow's dataset scanner read at a time.
SIGNAL_ROW_GROUP = 256

#: ``pyarrow.parquet.ParquetWriter`` options of the signal files, all fixed rather than left to
#: the installed pyarrow's defaults. Dictionary encoding pays: the samples are quantised
#: (ADC counts times a scale), so few distinct float32 values repeat; zstd level 3 then makes
#: the file smaller than the gzip+shuffle HDF5 file (docs/datasets.md, "Sizes").
SIGNAL_PARQUET_OPTIONS: dict[str, Any] = {
    "version": "2.6",
    "data_page_version": "1.0",
    "compression": "zstd",
    "compression_level": 3,
    "use_dictionary": True,
    "dictionary_pagesize_limit": 1 << 20,
    "data_page_size": 1 << 20,
    "write_batch_size": 1024,
    "use_byte_stream_split": False,
    "write_page_index": False,
    "write_page_checksum": False,
    "store_schema": True,
}


def _signal_provenance(prov: dict[str, Any], shard: int | None, first: int, n: int) -> dict[str, Any]:
    """The ``ofbe`` schema metadata of a signal file."""
    out = {"format": DATASET_FORMAT, "schema_version": SCHEMA_VERSION, "content": "signals",
           "name": prov.get("name"), "campaign": prov.get("campaign"),
           "window_length": prov.get("window_length"), "units": UNITS, "frame": FRAME,
           "signal_column": SIGNAL_COLUMN, "first_window_id": first, "n_windows": n}
    if shard is not None:
        out["shard"] = shard
    return out


def _signal_array(x: np.ndarray, window_length: int) -> pa.FixedSizeListArray:
    """(n, T, 3) float32 as Arrow fixed-size lists of :func:`signal_type` (one row per window)."""
    outer = signal_type(window_length)
    flat = pa.array(np.ascontiguousarray(x, dtype=np.float32).reshape(-1), type=pa.float32())
    inner = pa.FixedSizeListArray.from_arrays(flat, type=outer.value_type)
    return pa.FixedSizeListArray.from_arrays(inner, type=outer)


def _write_one(h5_path: Path, out: Path, rows: pa.Table, schema: pa.Schema, window_length: int,
               metadata: dict[str, Any]) -> None:
    """Write one signal file from one HDF5 file and its rows of ``windows.parquet``."""
    n = rows.num_rows
    tmp = out.parent / f".{out.name}.partial"
    try:
        with h5py.File(h5_path, "r") as f:
            x = f.get("X")
            if not isinstance(x, h5py.Dataset) or x.dtype != np.float32 or x.shape != (n, window_length, 3):
                found = f"{x.dtype} {x.shape}" if isinstance(x, h5py.Dataset) else "none"
                raise DatasetError(h5_path, f"float32 of shape ({n}, {window_length}, 3) (its rows of "
                                   f"{PARQUET_NAME})", found, "X")
            schema = schema.with_metadata({b"ofbe": json.dumps(metadata, allow_nan=False).encode()})
            with pq.ParquetWriter(tmp, schema,
                                  write_statistics=[c for c in schema.names if c != SIGNAL_COLUMN],
                                  **SIGNAL_PARQUET_OPTIONS) as writer:
                for start in range(0, n, SIGNAL_ROW_GROUP):
                    stop = min(start + SIGNAL_ROW_GROUP, n)
                    block = rows.slice(start, stop - start)
                    arrays = [*block.columns, _signal_array(x[start:stop], window_length)]
                    writer.write_table(pa.Table.from_arrays(arrays, schema=schema),
                                       row_group_size=SIGNAL_ROW_GROUP)
        os.replace(tmp, out)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        if is_write_failure(exc):  # a full disk: the commands report it as such
            raise
        raise DatasetError(out, f"{out.name} written from the X of {h5_path}",
                           f"an unreadable file ({exc})") from exc
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def write_signal_files(folder: str | Path) -> list[str]:
    """Write ``signals.parquet`` (or one ``signals-<shard>.parquet`` per HDF5 shard) into a folder.

    Parameters
    ----------
    folder
        A dataset folder that already holds its HDF5 file(s) and ``windows.parquet``; an existing
        signal file of the same name is replaced.

    Returns
    -------
    list of str
        The names of the files written, in window order.

    Raises
    ------
    DatasetError
        When ``windows.parquet`` or an HDF5 file is missing or unreadable, or their shapes disagree
        (naming the file, what was expected and what was found).
    """
    folder = Path(folder)
    pq_path = folder / PARQUET_NAME
    prov = read_parquet_provenance(pq_path)
    t = prov.get("window_length")
    protocols = prov.get("protocols")
    if isinstance(t, bool) or not isinstance(t, int) or t < 1 or not isinstance(protocols, dict):
        raise DatasetError(pq_path, "provenance with window_length (an integer >= 1) and protocols",
                           f"window_length {t!r}, protocols {type(protocols).__name__}", "ofbe")
    layout = shard_layout(folder)
    sharded = layout is not None
    h5_files = [(H5_NAME, None)] if layout is None else [(name, n) for name, n in layout]
    schema = signal_schema(list(protocols), t, sharded)
    try:
        table = pq.read_table(pq_path).replace_schema_metadata(None)
    except (OSError, pa.ArrowException) as exc:
        raise DatasetError(pq_path, "a readable Parquet file", f"an unreadable one ({exc})") from exc
    expected = schema.remove(schema.get_field_index(SIGNAL_COLUMN))
    if table.schema.names != expected.names or table.schema.types != expected.types:
        raise DatasetError(pq_path, f"the columns {expected.names} with their types",
                           f"{[f'{f.name}:{f.type}' for f in table.schema]}")
    names = signal_names(layout)
    first = 0
    for i, ((h5_name, n), out_name) in enumerate(zip(h5_files, names, strict=True)):
        h5_path = folder / h5_name
        if n is None:  # one windows.h5: all the rows
            n = table.num_rows
        if first + n > table.num_rows:
            raise DatasetError(pq_path, f"at least {first + n} rows (the windows of {h5_name})",
                               f"{table.num_rows}")
        rows = table.slice(first, n)
        meta = _signal_provenance(prov, i if sharded else None, first, n)
        _write_one(h5_path, folder / out_name, rows, schema, t, meta)
        first += n
    if first != table.num_rows:
        raise DatasetError(pq_path, f"{first} rows (one per window of the HDF5 files)", f"{table.num_rows}")
    return names
