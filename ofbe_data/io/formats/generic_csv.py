"""The generic ``csv`` format: any other sensor's CSV, read through the column and unit mapping of
its manifest entry (raw-formats.md §Generic csv).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.formats import register_format
from ofbe_data.io.formats.common import (
    MAX_STEP_S,
    _assemble,
    _clean_times,
    _csv_body,
    _next_line,
    _read_body,
    _read_bytes,
    find_gaps,
    fixed_point,
)
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import CsvMapping, DeviceSpec
from ofbe_data.io.recording import (
    ReadDiagnostics,
    Recording,
)

# --------------------------------------------------------------------------- generic csv

_TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6}


def _acc_scale(mapping: CsvMapping) -> float:
    if mapping.acc_unit == "m/s2":
        return 1.0
    if mapping.acc_unit == "g":
        return G0
    assert mapping.lsb_per_g is not None
    return G0 / mapping.lsb_per_g


def read_generic_csv(path: str | Path, mapping: CsvMapping, device: str | None = None) -> Recording:
    """Read a generic ``csv`` device file through its column/unit mapping.

    Parameters
    ----------
    path
        The file.
    mapping
        Columns, units, rows to skip before the header and the delimiter.
    device
        Device id to attach.

    Returns
    -------
    Recording
        ``t`` in s (as logged, converted from ``time_unit``), ``acc`` in m/s².
    """
    path = Path(path)
    data = _read_bytes(path)
    offset = 0
    for _ in range(mapping.skip_rows):
        if offset >= len(data):
            raise RawFormatError(path, f"{mapping.skip_rows} rows before the header",
                                 "end of file")
        offset = _next_line(data, offset)[1]
    col_line = mapping.skip_rows + 1
    c = mapping.columns
    wanted = {c["t"]: "float", c["ax"]: "float", c["ay"]: "float", c["az"]: "float"}
    if len(wanted) != 4:
        raise RawFormatError(path, "four distinct mapped columns", repr(c))
    body = _read_body(path, data, offset, col_line, mapping.delimiter, wanted)
    t, _ = _clean_times(body, body.values[c["t"]] * _TIME_SCALE[mapping.time_unit], MAX_STEP_S)
    v = body.values
    acc = np.stack([v[c["ax"]], v[c["ay"]], v[c["az"]]], axis=1) * _acc_scale(mapping)
    gaps = find_gaps(t, body.lines, None)
    diag = ReadDiagnostics(path, col_line, body.lines_read, int(t.shape[0]), tuple(body.skipped),
                           gaps)
    return Recording(path, "csv", t, acc, np.zeros(t.shape[0], dtype=bool), body.lines, None, None,
                     {"device": device} if device else {}, diag)


def write_generic_csv(
    path: str | Path,
    t_s: np.ndarray,
    acc_mps2: np.ndarray,
    mapping: CsvMapping,
    *,
    preamble: Sequence[str] = (),
    decimals: int = 6,
) -> None:
    """Write a generic csv file that :func:`read_generic_csv` reads with ``mapping``.

    Parameters
    ----------
    path
        Target file.
    t_s
        (N,) s; written in ``mapping.time_unit``.
    acc_mps2
        (N, 3) m/s²; written in ``mapping.acc_unit`` (counts rounded to integers).
    mapping
        Column names, units and delimiter; ``skip_rows`` must equal ``len(preamble)``.
    preamble
        Free lines written before the header.
    decimals
        Decimals for non-count values.
    """
    if len(preamble) != mapping.skip_rows:
        raise ValueError(f"preamble has {len(preamble)} lines, mapping skips {mapping.skip_rows}")
    t = np.asarray(t_s, dtype=np.float64) / _TIME_SCALE[mapping.time_unit]
    acc = np.asarray(acc_mps2, dtype=np.float64) / _acc_scale(mapping)
    cols = [fixed_point(t, decimals)]
    if mapping.acc_unit == "counts":
        cols += [pa.array(np.rint(acc[:, i]).astype(np.int64)) for i in range(3)]
    else:
        cols += [fixed_point(acc[:, i], decimals) for i in range(3)]
    c = mapping.columns
    d = mapping.delimiter
    header = d.join([c["t"], c["ax"], c["ay"], c["az"]])
    write_bytes_atomic(path, _assemble(preamble, header, _csv_body(cols, d), None))


def _read(path: Path, device: DeviceSpec) -> Recording:
    if device.csv is None:
        raise RawFormatError(path, "a csv mapping in the manifest entry", "none")
    return read_generic_csv(path, device.csv, device.id)


register_format("csv", _read)
