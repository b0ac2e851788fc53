"""The ``mscip-csv`` format: the Memsense MS-IMU3025 vendor CSV export (reference IMU)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.formats.common import (
    MAX_STEP_S,
    MSCIP_ACCEL,
    MSCIP_COLUMNS,
    MSCIP_GYRO,
    MSCIP_TEMP,
    MSCIP_TIME,
    clean_times,
    decode_text,
    find_gaps,
    line_start,
    parse_utc,
    read_body,
)
from ofbe_data.io.formats.filebytes import count_lines, next_line, read_file_bytes
from ofbe_data.io.formats.registry import Format, Sniffed, register_format
from ofbe_data.io.formats.writing import assemble, csv_body, fixed_point
from ofbe_data.io.gravity import G0
from ofbe_data.io.recording import (
    TEMPERATURE,
    ReadDiagnostics,
    Recording,
    checked_temperature,
)

# --------------------------------------------------------------------------- mscip-csv


def read_mscip_csv(path: str | Path, device: str | None = None) -> Recording:
    """Read a Memsense MS-IMU3025 CSV export (``mscip-csv``).

    Parameters
    ----------
    path
        The file.
    device
        Device id to attach.

    Returns
    -------
    Recording
        ``t`` in s relative to ``Start (UTC)``, ``acc`` in m/s² (g · g0); gyro (deg/s)
        and temperature (°C) in ``extra`` when present.
    """
    path = Path(path)
    data = read_file_bytes(path)
    col_offset = line_start(data, MSCIP_TIME.encode())
    if col_offset < 0:
        raise RawFormatError(path, f"a column line starting with {MSCIP_TIME!r}", "none in the file")
    preamble = data[:col_offset]
    col_line = count_lines(preamble) + 1
    header: dict[str, str] = {}
    for raw in preamble.splitlines():
        key, sep, value = decode_text(raw).partition(",")
        if sep:
            header[key.strip()] = value.strip()
    header_names = decode_text(next_line(data, col_offset)[0]).split(",")
    wanted = {MSCIP_TIME: "float", **{c: "float" for c in MSCIP_ACCEL}}
    wanted.update({c: "float" for c in (*MSCIP_GYRO, MSCIP_TEMP) if c in header_names})
    body = read_body(path, data, col_offset, col_line, ",", wanted)
    t, _ = clean_times(body, body.values[MSCIP_TIME], MAX_STEP_S)
    v = body.values
    acc = np.stack([v[c] for c in MSCIP_ACCEL], axis=1) * G0
    rate = None
    if "Sample Rate (Hz)" in header:
        try:
            rate = float(header["Sample Rate (Hz)"])
        except ValueError:
            raise RawFormatError(path, "Sample Rate (Hz),<number>",
                                 repr(header["Sample Rate (Hz)"])) from None
    gaps = find_gaps(t, body.lines, 1.0 / rate if rate else None)
    extra = {c: v[c] for c in MSCIP_GYRO if c in v}
    if MSCIP_TEMP in v:  # the MS-IMU3025 writes °C: a value no device reads is refused, as in csv
        extra[TEMPERATURE] = checked_temperature(path, v[MSCIP_TEMP], body.lines, "C", MSCIP_TEMP,
                                                  settable=False)
    diag = ReadDiagnostics(path, col_line, body.lines_read, int(t.shape[0]), tuple(body.skipped),
                           gaps)
    hdr = header | ({"device": device} if device else {})
    return Recording(path, "mscip-csv", t, acc, np.zeros(t.shape[0], dtype=bool), body.lines,
                     parse_utc(header.get("Start (UTC)")), rate, hdr, diag, extra)


def write_mscip_csv(
    path: str | Path,
    t_s: np.ndarray,
    acc_g: np.ndarray,
    gyro_dps: np.ndarray,
    temperature_c: np.ndarray,
    *,
    serial: str,
    rate_hz: float,
    start_utc: str,
) -> None:
    """Write a Memsense vendor-style CSV export (atomically).

    Parameters
    ----------
    path
        Target file.
    t_s
        (N,) s relative to ``start_utc`` (6 decimals written).
    acc_g
        (N, 3) specific force in g (5 decimals).
    gyro_dps
        (N, 3) angular rate, deg/s (4 decimals).
    temperature_c
        (N,) °C (1 decimal).
    serial, rate_hz, start_utc
        Header values.
    """
    preamble = ["MSCIP Data Export", "Device,MS-IMU3025", f"Serial,{serial}",
                f"Sample Rate (Hz),{rate_hz:g}", f"Start (UTC),{start_utc}"]
    cols = [fixed_point(t_s, 6)]
    cols += [fixed_point(gyro_dps[:, i], 4) for i in range(3)]
    cols += [fixed_point(acc_g[:, i], 5) for i in range(3)]
    cols += [fixed_point(temperature_c, 1)]
    write_bytes_atomic(path, assemble(preamble, ",".join(MSCIP_COLUMNS), csv_body(cols), None))


def sniff_mscip_csv(lines: Sequence[str], i: int) -> Sniffed | None:
    """Whether line ``i`` of a file (0-based) starts an MSCIP export (its title or its column line),
    with the device and nominal rate of the header lines that follow it (``ofbe-session init``)."""
    line = lines[i]
    if line.strip() != "MSCIP Data Export" and not line.startswith("Time (s),Gyro X (deg/s)"):
        return None
    model, model_why, rate_note = None, "", None
    for other in lines[i:i + 10]:
        key, _, value = other.partition(",")
        if key == "Device" and value.strip() and model is None:
            model, model_why = value.strip(), f"header line {other.strip()!r}"
        elif key == "Sample Rate (Hz)" and value.strip():
            rate_note = f"header line {other.strip()!r} (nominal)"
    return Sniffed(evidence=f"MSCIP export line {i + 1}: {line.strip()[:40]!r}", model=model,
                   model_evidence=model_why, rate_note=rate_note)


register_format(Format(name="mscip-csv", reader=lambda path, device: read_mscip_csv(path, device.id),
                       reference=True, signature="MSCIP export lines", sniff=sniff_mscip_csv, order=20))
