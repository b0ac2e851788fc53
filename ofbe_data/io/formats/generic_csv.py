"""The generic ``csv`` format: any other sensor's text file, read through the column and unit
mapping of its manifest entry (raw-formats.md §Generic csv).

A file is first normalised, whole-buffer and without a per-line Python loop: byte-order mark,
``skip_rows`` preamble, ``comment`` lines and blank lines before the data are cut out
(keeping a map from every remaining line to its line in the file), runs of whitespace
become one comma for ``delimiter: whitespace``, quotes and an empty trailing column are
taken off the column names, and a header is synthesised for ``header: false``. The result
goes through the same pyarrow parser as the device formats, so garbled lines are counted
and skipped with their true line numbers.

Time comes from the ``t`` column in ``time_unit`` (``samples``: an index over
``sample_rate_hz``), or, without a ``t`` column, from the data line's position over
``sample_rate_hz`` (a skipped line leaves a one-sample gap). Spacing is reported, never
resampled. Accelerations become m/s² (``counts``: (value − zero_counts) / lsb_per_g · g0
per axis). An optional temperature column goes to ``extra[TEMPERATURE]`` in °C.

Saturation is judged against the range: with ``range_g``, a reading at or beyond
:data:`SATURATION_FRACTION` of it is saturated, and the recording's
:class:`~ofbe_data.io.recording.FullScale` (what a pile-up of identical extreme readings is
compared with) is that limit; without, the full scale is inferred from the file's own extremes
(:func:`~ofbe_data.io.recording.full_scale`). A pile-up of quantised readings well inside the
range is never saturation.
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pyarrow as pa

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.device_options import GYRO_KEYS
from ofbe_data.io.formats import register_format
from ofbe_data.io.formats.common import (
    MAX_STEP_S,
    _Body,
    _clean_times,
    _line_starts,
    _read_body,
    find_gaps,
)
from ofbe_data.io.formats.filebytes import read_file_bytes
from ofbe_data.io.formats.writing import _assemble, _csv_body, fixed_point
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import WHITESPACE, CsvMapping, DeviceSpec
from ofbe_data.io.recording import (
    GYRO,
    TEMPERATURE,
    ReadDiagnostics,
    Recording,
    SkippedLine,
    full_scale,
    median,
)

_TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
_ACC_SCALE = {"m/s2": 1.0, "g": G0, "mg": G0 / 1000.0}
_BOM = b"\xef\xbb\xbf"
EPOCH_RANGE_S = (1.0e9, 4.0e9)
"""Time stamps in this range (2001–2096 as Unix seconds) are taken as epoch time: they give
the recording's UTC start for the coarse synchronisation."""
SATURATION_FRACTION = 0.99
"""With ``range_g``, readings at or beyond this fraction of the range are saturated."""
JITTER_GAP_MADS = 6.0
"""With uneven spacing, a step is a gap only beyond the median step plus this many median
absolute deviations (and always beyond 1.5 median steps)."""


# --------------------------------------------------------------------------- normalisation


def _split_lines(data: bytes) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive, without the line end) of every line, (L,) int64 each."""
    starts = _line_starts(data)
    if starts[-1] == len(data):
        starts = starts[:-1]
    nxt = np.append(starts[1:], len(data))
    b = np.frombuffer(data, dtype=np.uint8)
    ends = nxt.copy()
    for _ in range(2):  # strip \n, then \r (a CRLF ends in both)
        last = np.clip(ends - 1, 0, None)
        strip = (ends > starts) & ((b[last] == 0x0A) | (b[last] == 0x0D)) if b.size else ends < 0
        ends = np.where(strip, ends - 1, ends)
    return starts, ends


def _starts_with(data: bytes, starts: np.ndarray, ends: np.ndarray, prefix: bytes) -> np.ndarray:
    """Which lines start with ``prefix``, (L,) bool (vectorised over lines)."""
    if not prefix or starts.size == 0:
        return np.zeros(starts.shape, dtype=bool)
    b = np.frombuffer(data, dtype=np.uint8)
    k = len(prefix)
    idx = np.clip(starts[:, None] + np.arange(k), 0, len(data) - 1)
    return ((ends - starts) >= k) & np.all(b[idx] == np.frombuffer(prefix, dtype=np.uint8), axis=1)


def _blank(data: bytes, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Lines holding nothing but spaces and tabs, (L,) bool."""
    b = np.frombuffer(data, dtype=np.uint8)
    solid = ~((b == 0x20) | (b == 0x09) | (b == 0x0A) | (b == 0x0D))
    before = np.concatenate(([0], np.cumsum(solid, dtype=np.int64)))
    return before[ends] - before[starts] == 0


def _clean_name(raw: str) -> str:
    name = raw.strip()
    if len(name) >= 2 and name[0] == name[-1] and name[0] in "\"'":
        name = name[1:-1].strip()
    return name


def _to_commas(buf: bytes, delimiter: str) -> bytes:
    """Data lines with ``delimiter`` turned into commas; a comma that is not the delimiter is
    a decimal comma and becomes a point."""
    if delimiter == WHITESPACE:
        # every run of spaces/tabs becomes one comma (vectorised), then leading and trailing
        # commas of a line go
        b = np.frombuffer(buf, dtype=np.uint8)
        ws = (b == 0x20) | (b == 0x09)
        first = ws.copy()
        first[1:] &= ~ws[:-1]
        keep = ~ws | first
        out = b[keep].copy()
        out[first[keep]] = 0x2C
        buf = out.tobytes()
        for end in (b"\n", b"\r"):
            buf = buf.replace(end + b",", end).replace(b"," + end, end)
        buf = buf[1:] if buf.startswith(b",") else buf
        return buf[:-1] if buf.endswith(b",") else buf
    if delimiter == ",":
        return buf
    if b"," in buf:
        buf = buf.replace(b",", b".")
    return buf.replace(delimiter.encode(), b",")


def _normalise(path: Path, data: bytes, mapping: CsvMapping) -> tuple[bytes, np.ndarray, dict[str, str], int]:
    """The file as one comma-separated buffer headed by a column line, and where its lines were.

    Returns
    -------
    buffer, line_of, names, preamble
        The buffer (column line first); for each of its lines the 1-based line in the file
        (the column line's entry is the file line of the header, or of the first data line
        when ``header`` is false); the mapped column key → name in the buffer; the number of
        file lines before the first data line.
    """
    if data.startswith(_BOM):
        data = b" " * len(_BOM) + data[len(_BOM):]  # same offsets, so the same line numbers
    starts, ends = _split_lines(data)
    n = starts.shape[0]
    if not data.strip():
        raise RawFormatError(path, "a column line and data lines" if mapping.header else "data lines",
                             "an empty file" if not data else "only blank lines")
    if mapping.skip_rows >= n:
        raise RawFormatError(path, f"{mapping.skip_rows} preamble rows (skip_rows) and then data",
                             f"{n} lines in all")
    keep = np.arange(n) >= mapping.skip_rows
    if mapping.comment is not None:
        keep &= ~_starts_with(data, starts, ends, mapping.comment.encode())
    blank = _blank(data, starts, ends)
    first = int(np.argmax(keep & ~blank)) if np.any(keep & ~blank) else n
    if first == n:
        raise RawFormatError(path, "a column line and data lines" if mapping.header else "data lines",
                             "only preamble, comment or blank lines")
    keep[:first] = False
    line_of = np.flatnonzero(keep) + 1
    lengths = np.append(starts[1:], len(data)) - starts
    buf = np.frombuffer(data, dtype=np.uint8)[np.repeat(keep, lengths)].tobytes()
    cut = buf.find(b"\n")
    cut = len(buf) if cut < 0 else cut + 1
    head_line = buf[:cut].rstrip(b"\r\n")
    if mapping.header:
        rest = _to_commas(buf[cut:], mapping.delimiter)
    else:
        buf = _to_commas(buf, mapping.delimiter)
        head_line = _to_commas(head_line, mapping.delimiter)
    try:
        head_text = head_line.decode("utf-8")
    except UnicodeDecodeError:
        raise RawFormatError(path, "a text line", repr(head_line[:40]), int(line_of[0])) from None
    c = mapping.columns
    if mapping.header:
        if mapping.delimiter == WHITESPACE:
            parts = head_text.split()
        else:
            parts = head_text.split(mapping.delimiter)
        names = [_clean_name(x) for x in parts]
        if len(names) > 1 and names[-1] == "":
            names[-1] = "\x00trailing"  # an empty last column name: a trailing comma on every line
        missing = [str(c[k]) for k in c if c[k] not in names]
        if missing:
            raise RawFormatError(path, "columns " + ", ".join(map(str, c.values())),
                                 f"{head_text.strip()!r} (missing {', '.join(missing)})", int(line_of[0]))
        if len(set(names)) != len(names):
            raise RawFormatError(path, "unique column names", repr(head_text.strip()), int(line_of[0]))
        body = rest
        header = ",".join(f"c{i}" for i in range(len(names)))
        wanted = {k: f"c{names.index(str(v))}" for k, v in c.items()}
    else:
        fields = head_text.count(",") + 1
        too_far = {k: v for k, v in c.items() if int(v) >= fields}
        if too_far:
            k, v = next(iter(too_far.items()))
            raise RawFormatError(path, f"a column {v} ({k}, 0-based) in the first data line",
                                 f"{fields} fields", int(line_of[0]))
        body = buf
        header = ",".join(f"c{i}" for i in range(fields))
        line_of = np.concatenate(([line_of[0] - 1], line_of))
        wanted = {k: f"c{int(v)}" for k, v in c.items()}
    return (header + "\n").encode() + body, line_of, wanted, int(line_of[1] - 1) if line_of.size > 1 else n


def _relabel(body: _Body, line_of: np.ndarray) -> np.ndarray:
    """Replace the buffer line numbers of ``body`` by file lines; returns the buffer rows
    (0-based data-line index) of the kept samples."""
    rows = body.lines - 1
    body.lines = line_of[body.lines]
    body.skipped = [SkippedLine(int(line_of[s.line]), s.kind, s.detail) for s in body.skipped]
    return rows


# --------------------------------------------------------------------------- reading


def _acc(values: dict[str, np.ndarray], mapping: CsvMapping, keys: dict[str, str]) -> np.ndarray:
    raw = np.stack([values[keys["ax"]], values[keys["ay"]], values[keys["az"]]], axis=1)
    if mapping.acc_unit == "counts":
        return (raw - mapping.zero_axes()) / mapping.lsb_axes() * G0
    return raw * _ACC_SCALE[mapping.acc_unit]


def _celsius(x: np.ndarray, unit: str) -> np.ndarray:
    if unit == "K":
        return x - 273.15
    if unit == "F":
        return (x - 32.0) * (5.0 / 9.0)
    return x


def _gap_period(t: np.ndarray) -> tuple[float, float]:
    """Median step and the step beyond which a step is a gap, s."""
    d = np.diff(t)
    if d.size == 0:
        return float("nan"), float("inf")
    med = median(d)
    mad = median(np.abs(d - med))
    return med, max(1.5 * med, med + JITTER_GAP_MADS * mad)


def spacing_stats(t: np.ndarray) -> dict[str, str]:
    """Median, relative spread and largest of the sample steps, as header entries."""
    d = np.diff(t)
    if d.size == 0:
        return {}
    med = median(d)
    cv = float(np.std(d) / med) if med > 0 else float("nan")
    return {"step_median_s": f"{med:.6g}", "step_cv": f"{cv:.4g}", "step_max_s": f"{float(d.max()):.6g}"}


def read_generic_csv(path: str | Path, mapping: CsvMapping, device: str | None = None) -> Recording:
    """Read a generic ``csv`` device file through its column/unit mapping.

    Parameters
    ----------
    path
        The file.
    mapping
        Columns, units, preamble, delimiter, comments and rates (every key of the spec).
    device
        Device id to attach.

    Returns
    -------
    Recording
        ``t`` in s (as logged, converted from ``time_unit``; from the line position without a
        ``t`` column), ``acc`` in m/s², ``extra[TEMPERATURE]`` in °C when mapped; header
        entries ``step_median_s``, ``step_cv`` and ``step_max_s`` describe the spacing.

    Raises
    ------
    RawFormatError
        Structure that does not match the mapping (missing columns, nothing but preamble, no
        valid data line), naming the file and line.
    """
    path = Path(path)
    data = read_file_bytes(path)
    buf, line_of, keys, preamble = _normalise(path, data, mapping)
    wanted = {name: "float" for name in keys.values()}
    try:
        body = _read_body(path, buf, 0, 0, ",", wanted)
    except RawFormatError as exc:
        raise RawFormatError(path, exc.expected, exc.found,
                             None if exc.line is None else int(line_of[min(exc.line, len(line_of) - 1)])
                             ) from None
    rows = _relabel(body, line_of)
    rate = mapping.sample_rate_hz
    if "t" not in keys:
        assert rate is not None
        t_raw = rows.astype(np.float64) / rate
    elif mapping.time_unit == "samples":
        assert rate is not None
        t_raw = body.values[keys["t"]] / rate
    else:
        t_raw = body.values[keys["t"]] * _TIME_SCALE[mapping.time_unit]
    if mapping.sort_by_time:  # stable: rows of equal time keep their order (then the first is kept)
        order = np.argsort(t_raw, kind="stable")
        t_raw = t_raw[order]
        body.values = {name: col[order] for name, col in body.values.items()}
        body.lines = body.lines[order]
    body.values["__t"] = t_raw
    d = np.diff(t_raw)
    typical = median(d[d > 0]) if np.any(d > 0) else 0.0
    max_step = max(MAX_STEP_S, 10.0 / rate if rate else 0.0, 10.0 * typical)
    try:
        t, _ = _clean_times(body, t_raw, max_step)
    except RawFormatError as exc:  # no data line left: name the column line (or the first line)
        raise RawFormatError(path, exc.expected, exc.found, int(line_of[0]) if mapping.header else None
                             ) from None
    v = body.values
    acc = _acc(v, mapping, keys)
    saturated = np.zeros(t.shape[0], dtype=bool)
    declared = None if mapping.range_g is None else mapping.range_g * G0
    if mapping.range_g is not None:
        saturated = np.any(np.abs(acc) >= SATURATION_FRACTION * mapping.range_g * G0, axis=1)
    # what a pile-up of extreme readings is judged against: the declared range, else the file's own
    judged_against = full_scale(acc, declared, SATURATION_FRACTION)
    extra: dict[str, np.ndarray] = {}
    if "temperature" in keys:
        extra[TEMPERATURE] = _celsius(v[keys["temperature"]], mapping.temperature_unit)
    if "gx" in keys:
        scale = np.pi / 180.0 if mapping.gyro_unit == "deg/s" else 1.0
        extra.update({name: v[keys[k]] * scale for name, k in zip(GYRO, GYRO_KEYS, strict=True)})
    period, gap_step = _gap_period(t)
    gaps = find_gaps(t, body.lines, period, gap_step / period if period > 0 else None)
    diag = ReadDiagnostics(path, preamble, body.lines_read, int(t.shape[0]), tuple(body.skipped), gaps,
                           saturated_samples=int(saturated.sum()))
    header = {"device": device} if device else {}
    header["acc_unit"] = mapping.acc_unit
    header.update(spacing_stats(t))
    start = None
    if "t" in keys and mapping.time_unit != "samples" and EPOCH_RANGE_S[0] <= t[0] <= EPOCH_RANGE_S[1]:
        start = datetime.fromtimestamp(float(t[0]), UTC)
    return Recording(path, "csv", t, acc, saturated, body.lines, start, rate, header, diag, extra,
                     judged_against)


# --------------------------------------------------------------------------- writing


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

    Supports named columns in the order t, ax, ay, az (``header: true``, one-character
    delimiter); the simulator and the examples use it. Files in the other layouts the reader
    takes are built by the tests as text.

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
    if not mapping.header or mapping.delimiter == WHITESPACE or mapping.time_unit == "samples":
        raise ValueError("write_generic_csv writes named columns, one-character delimiters and times")
    t = np.asarray(t_s, dtype=np.float64) / _TIME_SCALE[mapping.time_unit]
    acc = np.asarray(acc_mps2, dtype=np.float64)
    if mapping.acc_unit == "counts":
        counts = acc / G0 * mapping.lsb_axes() + mapping.zero_axes()
        cols = [fixed_point(t, decimals)]
        cols += [pa.array(np.rint(counts[:, i]).astype(np.int64)) for i in range(3)]
    else:
        acc = acc / _ACC_SCALE[mapping.acc_unit]
        cols = [fixed_point(t, decimals)] + [fixed_point(acc[:, i], decimals) for i in range(3)]
    c = mapping.columns
    d = mapping.delimiter
    header = d.join(str(c[k]) for k in ("t", "ax", "ay", "az"))
    write_bytes_atomic(path, _assemble(preamble, header, _csv_body(cols, d), None))


def _read(path: Path, device: DeviceSpec) -> Recording:
    if device.csv is None:
        raise RawFormatError(path, "a csv mapping in the manifest entry", "none")
    return read_generic_csv(path, device.csv, device.id)


register_format("csv", _read)
