"""The ``ofbe-logger`` format: the SparkFun ESP32 + ADXL345 logger's serial capture (header
comments, boot lines, t_us and raw counts).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pyarrow as pa

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.formats.common import (
    MAX_STEP_S,
    OFBE_LOGGER_COLUMNS,
    WRAP_US,
    clean_times,
    decode_text,
    drop,
    find_gaps,
    line_start,
    parse_utc,
    read_body,
)
from ofbe_data.io.formats.filebytes import count_lines, next_line, read_file_bytes
from ofbe_data.io.formats.registry import Format, Sniffed, register_format
from ofbe_data.io.formats.writing import LineHook, assemble, csv_body
from ofbe_data.io.gravity import G0
from ofbe_data.io.recording import (
    SKIP_OUT_OF_RANGE,
    ReadDiagnostics,
    Recording,
)

# --------------------------------------------------------------------------- ofbe-logger


def _parse_logger_header(path: Path, data: bytes) -> tuple[dict[str, str], int, int, int]:
    """Locate the ``# ofbe-logger`` header; return (keys, boot lines, column-line offset,
    column-line number)."""
    start = line_start(data, b"# ofbe-logger")
    if start < 0:
        raise RawFormatError(path, "a '# ofbe-logger' header line", "none in the file")
    boot_lines = count_lines(data[:start])
    header: dict[str, str] = {}
    offset, line_no = start, boot_lines + 1
    while True:
        if offset >= len(data):
            raise RawFormatError(path, "the column line t_us,ax,ay,az after the header",
                                 "end of file", line_no)
        raw, nxt = next_line(data, offset)
        if not raw.startswith(b"#"):
            break
        for token in decode_text(raw[1:]).split():
            if "=" in token:
                key, _, value = token.partition("=")
                header[key] = value
        offset, line_no = nxt, line_no + 1
    return header, boot_lines, offset, line_no


def _header_number(path: Path, header: dict[str, str], key: str, line: int) -> float:
    try:
        value = float(header[key])
    except KeyError:
        raise RawFormatError(path, f"header key {key}=<number>", "no such key", line) from None
    except ValueError:
        raise RawFormatError(path, f"header key {key}=<number>", repr(header[key]), line) from None
    if not np.isfinite(value) or value <= 0:
        raise RawFormatError(path, f"header key {key} > 0", repr(header[key]), line)
    return value


def read_ofbe_logger(path: str | Path, device: str | None = None) -> Recording:
    """Read an ``ofbe-logger`` CSV (SparkFun Thing Plus ESP32 + ADXL345).

    Parameters
    ----------
    path
        The file.
    device
        Device id to attach (defaults to the header's ``device=``).

    Returns
    -------
    Recording
        ``t`` in s since the logger booted (wraps of ``micros()`` undone), ``acc`` in
        m/s² (counts / lsb_per_g · g0), saturation flagged where an axis sits at
        −range_g·lsb_per_g or +range_g·lsb_per_g − 1.

    Raises
    ------
    RawFormatError
        Missing header, header keys or columns, or no valid data line.
    """
    path = Path(path)
    data = read_file_bytes(path)
    header, boot_lines, col_offset, col_line = _parse_logger_header(path, data)
    lsb = _header_number(path, header, "lsb_per_g", boot_lines + 1)
    range_g = _header_number(path, header, "range_g", boot_lines + 1)
    odr = _header_number(path, header, "odr_hz", boot_lines + 1) if "odr_hz" in header else None
    wanted = {c: "int" for c in OFBE_LOGGER_COLUMNS}
    body = read_body(path, data, col_offset, col_line, ",", wanted)
    limit = int(round(range_g * lsb))
    v = body.values
    axes = ("ax", "ay", "az")
    in_range = v["t_us"].size == 0 or (int(v["t_us"].min()) >= 0 and int(v["t_us"].max()) < WRAP_US
                and all(int(v[a].min()) >= -limit and int(v[a].max()) <= limit - 1 for a in axes))
    if not in_range:  # the common case needs neither the masks nor the messages
        t_bad = (v["t_us"] < 0) | (v["t_us"] >= WRAP_US)
        counts = np.stack([v[a] for a in axes], axis=1)
        c_bad = ((counts < -limit) | (counts > limit - 1)).any(axis=1)
        details = [
            f"t_us {v['t_us'][i]} outside 0..2^32-1" if t_bad[i]
            else f"counts {counts[i].tolist()} outside {-limit}..{limit - 1}"
            for i in np.flatnonzero(t_bad | c_bad)
        ]
        drop(body, t_bad | c_bad, SKIP_OUT_OF_RANGE, details)
    t_us, wraps = clean_times(body, body.values["t_us"], MAX_STEP_S * 1e6, WRAP_US)
    t = t_us / 1e6
    v = body.values
    n = int(t.shape[0])
    saturated = np.zeros(n, dtype=bool)
    acc = np.empty((n, 3), dtype=np.float64)
    for k, a in enumerate(axes):
        saturated |= (v[a] == -limit) | (v[a] == limit - 1)
        acc[:, k] = v[a]  # counts as float64, then / lsb · g0 as one expression would
    acc /= lsb
    acc *= G0
    gaps = find_gaps(t, body.lines, 1.0 / odr if odr else None)
    diag = ReadDiagnostics(path, col_line, body.lines_read, int(t.shape[0]), tuple(body.skipped),
                           gaps, wraps, int(saturated.sum()), boot_lines)
    return Recording(path, "ofbe-logger", t, acc, saturated,
                     body.lines, parse_utc(header.get("host_start_utc")), odr,
                     dict(header) | ({"device": device} if device else {}),
                     diag)


def write_ofbe_logger(
    path: str | Path,
    t_us: np.ndarray,
    counts: np.ndarray,
    header: Mapping[str, str],
    boot_lines: Sequence[str] = (),
    corrupt: LineHook | None = None,
) -> None:
    """Write an ``ofbe-logger`` CSV (atomically).

    Parameters
    ----------
    path
        Target file.
    t_us
        (N,) int64 microseconds since boot, not yet wrapped (written modulo 2³²).
    counts
        (N, 3) integer counts.
    header
        Header keys: ``fw``, ``board``, ``chip``, ``device``, ``odr_hz``, ``range_g``,
        ``full_res``, ``lsb_per_g``, ``host_start_utc``.
    boot_lines
        Boot-noise lines written before the header.
    corrupt
        Optional hook that receives the data lines (bytes, no line ends) and returns
        them modified — the simulator uses it to garble the serial link.
    """
    first = " ".join(f"{k}={header[k]}" for k in ("fw", "board", "chip", "device"))
    second = " ".join(f"{k}={header[k]}" for k in ("odr_hz", "range_g", "full_res", "lsb_per_g"))
    preamble = [*boot_lines, f"# ofbe-logger {first}", f"# {second}",
                f"# host_start_utc={header['host_start_utc']}"]
    counts = np.asarray(counts, dtype=np.int64)
    cols = [pa.array(np.asarray(t_us, dtype=np.int64) % WRAP_US)]
    cols += [pa.array(counts[:, i]) for i in range(3)]
    data = assemble(preamble, ",".join(OFBE_LOGGER_COLUMNS), csv_body(cols), corrupt)
    write_bytes_atomic(path, data)


def sniff_ofbe_logger(lines: Sequence[str], i: int) -> Sniffed | None:
    """Whether line ``i`` of a file (0-based) is an ofbe-logger header, with the chip and nominal
    rate its ``key=value`` comment lines state (``ofbe-session init``)."""
    if not lines[i].startswith("# ofbe-logger"):
        return None
    keys = dict(tok.split("=", 1) for j in range(i, min(i + 10, len(lines)))
                if lines[j].startswith("#") for tok in lines[j][1:].split() if "=" in tok)
    chip = keys.get("chip") or None
    return Sniffed(evidence=f"'# ofbe-logger' header at line {i + 1}", model=chip,
                   model_evidence=f"header chip={chip}" if chip else "",
                   rate_note=f"header odr_hz={keys['odr_hz']} (nominal)" if keys.get("odr_hz") else None)


register_format(Format(name="ofbe-logger", reader=lambda path, device: read_ofbe_logger(path, device.id),
                       signature="'# ofbe-logger' header", sniff=sniff_ofbe_logger, order=10))
