"""``ofbe-autocal``'s outputs: ``summary.csv``, ``summary.parquet`` and ``<file>.epochs.parquet``.

One row per recording in ``summary.csv`` and ``summary.parquet`` (the same values; the Parquet
file typed: strings, integers, a boolean, a UTC timestamp and nullable floats), for either
mode. The columns (:data:`COLUMNS`, docs/free-living.md) are the contract's
(products.md, "Free-living calibration"), then ofbe's own convention and the standard errors:

- ``offset_*``, ``scale_*``, ``temp_offset_*``, ``temp_mean_c``: GGIR's convention,
  calibrated = (raw + offset)·scale + (T − temp_mean_c)·temp_offset;
- ``ofbe_offset_*`` (g), ``a_xx`` … ``a_zz``, ``ofbe_temp_slope_*`` (g/°C): ofbe's,
  raw = A·u + ofbe_offset + ofbe_temp_slope·(T − temp_mean_c);
- ``<column>_se`` for every one of them: the standard error of a fitted value, empty for a
  value the model fixes or GGIR's mode (which gives none).

Floats are rounded when written (:data:`DECIMALS`; standard errors to 6 significant digits),
far below anything physical, so that the bytes do not depend on the machine's BLAS
(:mod:`ofbe_data.core.precision`); the same inputs give the same bytes, the Parquet files
included (no time stamps in them).
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Sequence
from datetime import datetime, timedelta

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ofbe_data.core.precision import SE_SIGNIFICANT_DIGITS, UNIT_DECIMALS, round_decimals, round_significant
from ofbe_data.freeliving.epochs import EpochTable
from ofbe_data.freeliving.ggir import GgirResult
from ofbe_data.freeliving.ofbe import GGIR_COLUMNS, OFBE_COLUMNS, OfbeResult

AXES = "xyz"
HEAD = ("file", "sha256", "device", "start_utc", "hours", "n_epochs", "n_still", "mode", "model",
        "calibrated", "qc", "cal_error_start_mg", "cal_error_end_mg")
VALUES = (*GGIR_COLUMNS, "temp_mean_c", *OFBE_COLUMNS)
ERRORS = tuple(f"{n}_se" for n in (*GGIR_COLUMNS, *OFBE_COLUMNS))
COLUMNS = (*HEAD, *VALUES, *ERRORS)
"""The columns of ``summary.csv`` and ``summary.parquet``, in order."""

DECIMALS: dict[str, int] = {
    "hours": 9, "cal_error_start_mg": 9, "cal_error_end_mg": 9, "temp_mean_c": 6,
    **{f"{q}_{a}": 12 for q in ("offset", "temp_offset", "ofbe_offset", "ofbe_temp_slope") for a in AXES},
    **{f"scale_{a}": UNIT_DECIMALS for a in AXES}, **{f"a_{r}{c}": UNIT_DECIMALS for r in AXES for c in AXES},
}
"""Decimal places of each float column (g and g/°C to 1e-12, errors in mg to 1e-9)."""

_INTEGERS = ("n_epochs", "n_still")
_STRINGS = ("file", "sha256", "device", "mode", "model", "qc")
SUMMARY_SCHEMA = pa.schema(
    [pa.field(n, pa.string() if n in _STRINGS else pa.int64() if n in _INTEGERS else pa.bool_()
              if n == "calibrated" else pa.timestamp("us", tz="UTC") if n == "start_utc" else pa.float64())
     for n in COLUMNS])
"""``summary.parquet``'s typed columns."""

EPOCH_SCHEMA = pa.schema([
    pa.field("epoch", pa.int64()), *(pa.field(f"mean_{a}", pa.float64()) for a in AXES),
    *(pa.field(f"sd_{a}", pa.float64()) for a in AXES), pa.field("temperature_c", pa.float64()),
    pa.field("idle", pa.bool_()), pa.field("used", pa.bool_()), pa.field("weight", pa.float64()),
])
"""``<file>.epochs.parquet``: per epoch kept, its 0-based row in the file (header not counted),
means and standard deviations (g, as read), temperature (°C), whether it was idle, whether it
entered the fit, and its robust weight (0 to 1; empty in GGIR's mode)."""


def _rounded(name: str, value: float | None) -> float | None:
    if value is None or (isinstance(value, float) and value != value):
        return None
    if name.endswith("_se"):
        return round_significant(value, SE_SIGNIFICANT_DIGITS)
    return round_decimals(value, DECIMALS[name])


def _check_start(start_utc: datetime | None) -> datetime | None:
    if start_utc is not None and start_utc.utcoffset() != timedelta(0):
        raise ValueError(f"start_utc: expected a time in UTC, found {start_utc.isoformat()}")
    return start_utc


def summary_row(file: str, sha256: str, result: GgirResult | OfbeResult, device: str | None = None,
                start_utc: datetime | None = None) -> dict[str, object]:
    """One row of the summary, floats rounded as written.

    Parameters
    ----------
    file, sha256
        The file as named and the SHA-256 of its bytes.
    result
        Either mode's result.
    device, start_utc
        The device's id and the recording's start (an aware UTC time), where the input tells
        them (raw files); None for epoch csv files.

    Raises
    ------
    ValueError
        ``start_utc`` is not a UTC time.
    """
    row: dict[str, object] = {"file": file, "sha256": sha256, "device": device,
                              "start_utc": _check_start(start_utc), "hours": float(result.hours),
                              "n_epochs": result.n_epochs, "n_still": result.n_still,
                              "calibrated": result.calibrated, "qc": result.qc,
                              "cal_error_start_mg": None if result.cal_error_start is None
                              else result.cal_error_start * 1000.0,
                              "cal_error_end_mg": None if result.cal_error_end is None
                              else result.cal_error_end * 1000.0, "temp_mean_c": result.temp_mean_c}
    values: dict[str, float | None] = {n: None for n in (*GGIR_COLUMNS, *OFBE_COLUMNS, *ERRORS)}
    if isinstance(result, GgirResult):
        row.update(mode="ggir", model=result.model)
        for k, a in enumerate(AXES):
            values[f"offset_{a}"], values[f"scale_{a}"] = float(result.offset[k]), float(result.scale[k])
            values[f"temp_offset_{a}"] = float(result.temp_offset[k])
    else:
        row.update(mode="ofbe", model=None if result.model is None else f"ofbe {result.model}")
        values.update(result.columns)
    row.update(values)
    for name in ("hours", "cal_error_start_mg", "cal_error_end_mg", "temp_mean_c", *values):
        row[name] = _rounded(name, row[name])  # type: ignore[arg-type]
    return row


def _cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, datetime):
        return value.isoformat()
    if isinstance(value, float):
        return repr(value)
    return str(value)


def summary_csv(rows: Sequence[dict[str, object]]) -> bytes:
    """``summary.csv``'s bytes: a header and one line per row, ``\\n`` line ends."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(COLUMNS)
    for row in rows:
        writer.writerow([_cell(row[c]) for c in COLUMNS])
    return buf.getvalue().encode("utf-8")


def parquet_bytes(table: pa.Table) -> bytes:
    """The Parquet file (zstd) of ``table``, written into an Arrow buffer."""
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression="zstd")
    return bytes(sink.getvalue().to_pybytes())


def summary_parquet(rows: Sequence[dict[str, object]]) -> bytes:
    """``summary.parquet``'s bytes: the rows of :func:`summary_csv`, typed (:data:`SUMMARY_SCHEMA`)."""
    data = {n: [row[n] for row in rows] for n in COLUMNS}
    return parquet_bytes(pa.Table.from_pydict(data, schema=SUMMARY_SCHEMA))


def epochs_table(epochs: EpochTable, result: GgirResult | OfbeResult) -> pa.Table:
    """The still epochs of one recording (and, in ofbe's mode, its idle ones) as
    :data:`EPOCH_SCHEMA`'s table; the file, mode and model in its metadata."""
    if isinstance(result, GgirResult):
        keep = result.still if result.still.shape == (epochs.n,) else np.zeros(epochs.n, dtype=bool)
        idle = np.zeros(epochs.n, dtype=bool)
        used = keep & (result.cal_error_end is not None)
        weight = np.full(epochs.n, np.nan)
        mode, model = "ggir", result.model
    else:
        keep = result.still | result.idle
        idle, weight = result.idle, result.weights
        used = result.still & np.isfinite(weight)
        mode, model = "ofbe", result.model
    rows = np.flatnonzero(keep)
    temps = (epochs.temperature_c[rows].tolist() if epochs.temperature_c is not None else [None] * rows.size)
    data: dict[str, object] = {"epoch": rows.tolist()}
    for k, a in enumerate(AXES):
        data[f"mean_{a}"] = epochs.mean_g[rows, k].tolist()
    for k, a in enumerate(AXES):
        data[f"sd_{a}"] = epochs.sd_g[rows, k].tolist()
    data.update(temperature_c=temps, idle=idle[rows].tolist(), used=used[rows].tolist(),
                weight=[None if not np.isfinite(w) else round_decimals(float(w), UNIT_DECIMALS)
                        for w in weight[rows]])
    table = pa.Table.from_pydict(data, schema=EPOCH_SCHEMA)
    meta = {"file": epochs.path, "mode": mode, "model": model}
    return table.replace_schema_metadata({b"ofbe_autocal": json.dumps(meta, sort_keys=True).encode()})
