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
per axis). An optional temperature column goes to ``extra[TEMPERATURE]`` in °C: a cell without a
value (empty, ``NaN``, ``NA``…) is a sample without temperature (NaN), never a skipped line, and a
value no sensor reads (beyond −40…125 °C once converted) stops the file, naming the unit the
values look like (:func:`~ofbe_data.io.recording.checked_temperature`).

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
import pyarrow.compute as pc
import pyarrow.csv as pacsv

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.device_options import GYRO_KEYS, WHITESPACE, CsvMapping, DeviceSpec
from ofbe_data.io.formats.common import (
    MAX_STEP_S,
    Body,
    clean_times,
    find_gaps,
    read_body,
)
from ofbe_data.io.formats.filebytes import (
    first_solid_line,
    is_blank,
    kept_lines,
    line_starts,
    read_file_bytes,
    split_first_line,
)
from ofbe_data.io.formats.registry import LAST, Format, register_format
from ofbe_data.io.formats.writing import assemble, csv_body, fixed_point
from ofbe_data.io.gravity import G0
from ofbe_data.io.recording import (
    GYRO,
    MISSING_CELLS,
    SKIP_NON_NUMERIC,
    TEMPERATURE,
    TEMPERATURE_NOTE,
    ReadDiagnostics,
    Recording,
    SkippedLine,
    checked_temperature,
    full_scale,
    median,
    missing_temperature_note,
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
    starts = line_starts(data)
    if starts[-1] == len(data):
        starts = starts[:-1]
    b = np.frombuffer(data, dtype=np.uint8)
    ends = np.append(starts[1:], len(data))
    for _ in range(2 if b.size else 0):  # strip \n, then \r (a CRLF ends in both); in place
        last = ends - 1
        np.clip(last, 0, None, out=last)
        end = b[last]
        del last
        ends -= (ends > starts) & ((end == 0x0A) | (end == 0x0D))
    return starts, ends


def _starts_with(data: bytes, starts: np.ndarray, ends: np.ndarray, prefix: bytes) -> np.ndarray:
    """Which lines start with ``prefix``, (L,) bool (vectorised over lines)."""
    if not prefix or starts.size == 0:
        return np.zeros(starts.shape, dtype=bool)
    b = np.frombuffer(data, dtype=np.uint8)
    out = (ends - starts) >= len(prefix)
    for j, byte in enumerate(prefix):  # one byte of the prefix at a time: (L,) temporaries
        out &= b[np.minimum(starts + j, len(data) - 1)] == byte
    return out


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


def _commas(pieces: list[bytes | memoryview], delimiter: str) -> list[bytes | memoryview]:
    """:func:`_to_commas` of each piece (views pass through unchanged with commas)."""
    return pieces if delimiter == "," else [_to_commas(bytes(p), delimiter) for p in pieces]


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
    if data.startswith(_BOM):  # same offsets, so the same line numbers
        data = b"".join((b" " * len(_BOM), memoryview(data)[len(_BOM):]))
    starts, ends = _split_lines(data)
    n = starts.shape[0]
    if is_blank(data):
        raise RawFormatError(path, "a column line and data lines" if mapping.header else "data lines",
                             "an empty file" if not data else "only blank lines")
    if mapping.skip_rows >= n:
        raise RawFormatError(path, f"{mapping.skip_rows} preamble rows (skip_rows) and then data",
                             f"{n} lines in all")
    keep = np.arange(n) >= mapping.skip_rows
    if mapping.comment is not None:
        keep &= ~_starts_with(data, starts, ends, mapping.comment.encode())
    first = first_solid_line(data, starts, keep)  # the first kept line that is not blank
    if first == n:
        raise RawFormatError(path, "a column line and data lines" if mapping.header else "data lines",
                             "only preamble, comment or blank lines")
    keep[:first] = False
    line_of = np.flatnonzero(keep)
    line_of += 1
    # the kept lines as pieces (views of data where nothing is cut out), each converted on its own:
    # a piece starts at a line start, which is all _to_commas' rules look across
    head_raw, pieces = split_first_line(kept_lines(data, starts, keep, first))
    del starts, ends, keep
    head_line = head_raw.rstrip(b"\r\n")
    if mapping.header:
        rest = _commas(pieces, mapping.delimiter)
    else:
        buf = _commas([head_raw, *pieces], mapping.delimiter)
        head_line = _to_commas(head_line, mapping.delimiter)
    del pieces, data  # converted pieces hold no view of the file: a caller that let it go frees it here
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
    pieces = [(header + "\n").encode(), *body]
    if bytes(next(p for p in reversed(pieces) if len(p))[-1:]) not in (b"\n", b"\r"):
        pieces.append(b"\n")  # the parser copies an unterminated body to end it: end it here
    return b"".join(pieces), line_of, wanted, int(line_of[1] - 1) if line_of.size > 1 else n


def _relabel(body: Body, line_of: np.ndarray) -> np.ndarray:
    """Replace the buffer line numbers of ``body`` by file lines; returns the buffer rows
    (0-based data-line index) of the kept samples."""
    rows = body.lines - 1
    body.lines = line_of[body.lines]
    body.skipped = [SkippedLine(int(line_of[s.line]), s.kind, s.detail) for s in body.skipped]
    return rows


# --------------------------------------------------------------------------- reading


def _acc(values: dict[str, np.ndarray], mapping: CsvMapping, keys: dict[str, str]) -> np.ndarray:
    raw = np.stack([values[keys["ax"]], values[keys["ay"]], values[keys["az"]]], axis=1)
    if mapping.acc_unit == "counts":  # (raw - zero) / lsb * g0, in place
        raw -= mapping.zero_axes()
        raw /= mapping.lsb_axes()
        raw *= G0
    else:
        raw *= _ACC_SCALE[mapping.acc_unit]
    return raw


def _parse(path: Path, buf: bytes, line_of: np.ndarray, wanted: dict[str, str]) -> Body:
    """The normalised buffer's data lines through the shared parser (buffer line numbers kept;
    an error names the file line)."""
    try:
        return read_body(path, buf, 0, 0, ",", wanted)
    except RawFormatError as exc:
        raise RawFormatError(path, exc.expected, exc.found,
                             None if exc.line is None else int(line_of[min(exc.line, len(line_of) - 1)])
                             ) from None


_NON_ASCII = bytes.maketrans(bytes(range(128, 256)), b"?" * 128)


def _missing_cells(buf: bytes, name: str) -> np.ndarray:
    """Buffer data lines (1-based after the column line) whose cell ``name`` holds no value
    (:data:`~ofbe_data.io.recording.MISSING_CELLS`), (M,) int64."""
    invalid: list[int] = []

    def skip(row: pacsv.InvalidRow) -> str:
        invalid.append(int(row.number or 0) - 1)
        return "skip"

    table = pacsv.read_csv(
        pa.BufferReader(buf.translate(_NON_ASCII)),  # markers are ASCII; other bytes never match
        read_options=pacsv.ReadOptions(use_threads=False),
        parse_options=pacsv.ParseOptions(quote_char=False, ignore_empty_lines=False,
                                         invalid_row_handler=skip),
        convert_options=pacsv.ConvertOptions(column_types={name: pa.string()}, include_columns=[name]),
    )
    cells = pc.utf8_lower(pc.utf8_trim_whitespace(table.column(name)))
    missing = pc.is_in(cells, value_set=pa.array(sorted(MISSING_CELLS))).to_numpy(zero_copy_only=False)
    rows = np.setdiff1d(np.arange(1, table.num_rows + len(invalid) + 1), np.array(invalid, dtype=np.int64))
    return rows[missing]


def _keep_missing_temperatures(path: Path, buf: bytes, line_of: np.ndarray, body: Body,
                               wanted: dict[str, str], name: str) -> Body:
    """``body`` with the lines back that were skipped only for a temperature cell holding no value
    (empty, ``NaN``, ``NA``…): a sample without temperature (NaN), never a garbled line. Other text
    in the temperature column still skips its line. Parses again only when such a line exists."""
    if not any(s.kind == SKIP_NON_NUMERIC and s.detail.startswith(f"field {name!r} ") for s in body.skipped):
        return body
    rest = _parse(path, buf, line_of, {k: v for k, v in wanted.items() if k != name})
    back = np.setdiff1d(np.intersect1d(rest.lines, _missing_cells(buf, name)), body.lines)
    if back.size == 0:
        return body
    keep = np.isin(rest.lines, np.union1d(body.lines, back))
    lines = rest.lines[keep]
    values = {k: v[keep] for k, v in rest.values.items()}
    values[name] = np.full(lines.shape[0], np.nan)
    values[name][np.searchsorted(lines, body.lines)] = body.values[name]
    back_set = set(back.tolist())
    return Body(values, lines, body.lines_read, [s for s in body.skipped if s.line not in back_set], path,
                 body.header_line)


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
        valid data line), naming the file and line (a temperature beyond the range a sensor reads:
        :class:`~ofbe_data.io.recording.ImplausibleTemperatureError`).
    """
    path = Path(path)
    # the file's bytes are _normalise's alone: let go once converted (bounded memory, issue 36)
    buf, line_of, keys, preamble = _normalise(path, read_file_bytes(path), mapping)
    wanted = {name: "float" for name in keys.values()}
    body = _parse(path, buf, line_of, wanted)
    if "temperature" in keys:
        body = _keep_missing_temperatures(path, buf, line_of, body, wanted, keys["temperature"])
    del buf
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
        t, _ = clean_times(body, t_raw, max_step)
    except RawFormatError as exc:  # no data line left: name the column line (or the first line)
        raise RawFormatError(path, exc.expected, exc.found, int(line_of[0]) if mapping.header else None
                             ) from None
    v = body.values
    acc = _acc(v, mapping, keys)
    needed = {keys[k] for k in keys if k not in ("t", "ax", "ay", "az")}
    body.values = v = {k: c for k, c in v.items() if k in needed}  # the rest is read: freed here
    del t_raw, d
    pa.default_memory_pool().release_unused()  # their pyarrow buffers, back to the system
    saturated = np.zeros(t.shape[0], dtype=bool)
    declared = None if mapping.range_g is None else mapping.range_g * G0
    if mapping.range_g is not None:
        saturated = np.any(np.abs(acc) >= SATURATION_FRACTION * mapping.range_g * G0, axis=1)
    # what a pile-up of extreme readings is judged against: the declared range, else the file's own
    judged_against = full_scale(acc, declared, SATURATION_FRACTION)
    extra: dict[str, np.ndarray] = {}
    header = {"device": device} if device else {}
    if "temperature" in keys:  # refused when no sensor reads it; NaN: a sample without temperature
        column = mapping.columns["temperature"]
        temp = checked_temperature(path, v[keys["temperature"]], body.lines, mapping.temperature_unit, column)
        note = missing_temperature_note(column, np.isnan(temp), body.lines)
        if note:
            header[TEMPERATURE_NOTE] = note
        if not np.all(np.isnan(temp)):
            extra[TEMPERATURE] = temp
    if "gx" in keys:
        scale = np.pi / 180.0 if mapping.gyro_unit == "deg/s" else 1.0
        extra.update({name: v[keys[k]] * scale for name, k in zip(GYRO, GYRO_KEYS, strict=True)})
    period, gap_step = _gap_period(t)
    gaps = find_gaps(t, body.lines, period, gap_step / period if period > 0 else None)
    diag = ReadDiagnostics(path, preamble, body.lines_read, int(t.shape[0]), tuple(body.skipped), gaps,
                           saturated_samples=int(saturated.sum()))
    header["acc_unit"] = mapping.acc_unit
    if mapping.sort_by_time:  # read in time order: a garbled rejection says so (skipped_lines_problem)
        header["sort_by_time"] = "true"
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
    write_bytes_atomic(path, assemble(preamble, header, csv_body(cols, d), None))


def _read(path: Path, device: DeviceSpec) -> Recording:
    if device.csv is None:
        raise RawFormatError(path, "a csv mapping in the manifest entry", "none")
    return read_generic_csv(path, device.csv, device.id)


# init: any text file no other format recognises, so it comes last
register_format(Format(name="csv", reader=_read, order=LAST))
