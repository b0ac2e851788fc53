"""What the device-format readers and writers share: the vectorised CSV body parser with
line-accurate diagnostics, time cleaning and gaps, UTC stamps, fixed-point writing.

Every reader returns a :class:`~ofbe_data.io.recording.Recording` in SI units with per-file
diagnostics.

Reading is vectorised: the header is located with a byte search, the body goes through
pyarrow's CSV reader (quoting off, every field read as bytes, lines with the wrong number
of fields sent to an invalid-row handler), and numeric validation is a regular expression
evaluated by pyarrow over whole columns. No Python loop runs per data line.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv

from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.formats import filebytes
from ofbe_data.io.formats.filebytes import line_starts, marked_line, next_line
from ofbe_data.io.formats.oddlines import NUMBER_CHARS, OddSplit, long_digit_run, split_odd_lines
from ofbe_data.io.recording import (
    GYRO_DEG_S,
    SKIP_EMPTY,
    SKIP_FIELD_COUNT,
    SKIP_NON_INCREASING_TIME,
    SKIP_NON_NUMERIC,
    Gap,
    SkippedLine,
    median,
)

WRAP_US = 2**32
"""``micros()`` on the ESP32 is an unsigned 32-bit counter of microseconds."""

OFBE_LOGGER_COLUMNS = ("t_us", "ax", "ay", "az")
MSCIP_TIME = "Time (s)"
MSCIP_ACCEL = ("Accel X (g)", "Accel Y (g)", "Accel Z (g)")
MSCIP_GYRO = GYRO_DEG_S
MSCIP_TEMP = "Temperature (C)"
MSCIP_COLUMNS = (MSCIP_TIME, *MSCIP_GYRO, *MSCIP_ACCEL, MSCIP_TEMP)

_INT_RE = r"^\s*[+-]?\d{1,18}\s*$"
_FLOAT_RE = r"^\s*[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d{1,3})?\s*$"
GAP_FACTOR = 1.5
"""A step between samples longer than this many nominal periods is a gap."""


# --------------------------------------------------------------------------- helpers


# the byte helpers live with the file's bytes (filebytes); the format modules' name for one
line_start = marked_line


_MASK_NON_ASCII = bytes(range(128)) + b"?" * 128


def _original_field(body: bytes, starts: np.ndarray, line_index: int, column: int,
                    delimiter: str) -> bytes:
    """Field ``column`` of line ``line_index`` (0-based, header = 0) of ``body``, as bytes."""
    line = next_line(body, int(starts[line_index]))[0]
    fields = line.split(delimiter.encode())
    return fields[column] if column < len(fields) else b""


def decode_text(raw: bytes) -> str:
    return raw.decode("utf-8", errors="backslashreplace")


def _show(raw: bytes, limit: int = 40) -> str:
    text = repr(raw)[1:]
    return text if len(text) <= limit else text[: limit - 3] + "..."


@dataclass
class Body:
    """Parsed data lines of one file: validated numeric columns and their file lines."""

    values: dict[str, np.ndarray]
    lines: np.ndarray
    lines_read: int
    skipped: list[SkippedLine]
    path: Path
    header_line: int


_NUMBER_BYTES = b"0123456789+-.eE\r\n"
_INT_LIMIT = 10**18  # the validating path accepts at most 18 digits
_LINE_ENDS = b"\r\n"


def _row_lines(invalid: Sequence[SkippedLine], header_line: int, lines_read: int) -> np.ndarray:
    """File line of every parsed row: the data lines less those pyarrow handed to the
    invalid-row handler, (rows,) int64."""
    every = np.arange(header_line + 1, header_line + 1 + lines_read, dtype=np.int64)
    if not invalid:
        return every
    bad = np.array(sorted(s.line for s in invalid), dtype=np.int64)
    return np.setdiff1d(every, bad, assume_unique=True)


@dataclass(frozen=True)
class _Scan:
    """One pass over the data lines: how many there are, and whether they hold nothing but
    number bytes, the delimiter and line ends (the typed fast path's condition)."""

    lines_read: int
    numeric: bool


def _scan_data_lines(data: bytes, data_start: int, delimiter: str) -> _Scan:
    """Count the data lines after the column line (which ends at ``data_start``) as
    :func:`count_lines` would on the body less its column line, and test their bytes.

    One ``bytes.translate`` pass over the file deletes the number bytes and the delimiter;
    what is left of the data lines is their line ends plus anything else (a few percent of
    the file), and both answers are read off that remainder. Lone carriage returns take the
    exact count over the original bytes (deleting a field could join a ``\r`` with the next
    ``\n``).
    """
    delete = NUMBER_CHARS + delimiter.encode()
    rest = data.translate(None, delete)[len(data[:data_start].translate(None, delete)):]
    numeric = not rest.translate(None, _LINE_ENDS)
    if b"\r" in rest:
        tail = data[data_start:]
        ends = tail.count(b"\n") + tail.count(b"\r") - tail.count(b"\r\n")
    else:
        ends = rest.count(b"\n")
    unterminated = data_start < len(data) and data[-1:] not in (b"\n", b"\r")
    return _Scan(ends + int(unterminated), numeric)


def _int_too_long(v: np.ndarray) -> bool:
    """``np.abs(v).max() >= _INT_LIMIT`` without the temporary (int64: ``abs`` of the most
    negative value stays negative, as it does there)."""
    if not v.size:
        return False
    if int(v.max()) >= _INT_LIMIT:
        return True
    lo = int(v.min())
    if lo > -_INT_LIMIT:
        return False
    if lo != np.iinfo(np.int64).min:
        return True
    return bool(np.any((v <= -_INT_LIMIT) & (v != lo)))


def _read_typed(wanted: Mapping[str, str],
                parse: Callable[[dict[str, pa.DataType]], pacsv.CSVStreamingReader], capacity: int
                ) -> tuple[int, dict[str, np.ndarray]] | None:
    """Fast path for clean files: parse straight into int64/float64 columns.

    Taken only when every byte after the column line is a digit, sign, point, exponent,
    delimiter or line end (the caller's :func:`_scan_data_lines`), and then only when every
    value parses, none is empty, integers have at most 18 digits and floats are finite:
    exactly the values the validating path would accept. Anything else (garbling, junk,
    NaN/inf text) returns None, and the validating path finds and reports it line by line.
    The batches are copied into arrays of ``capacity`` rows as they come (bounded memory: the
    parsed file is never held twice); returns the number of rows and the columns.
    """
    types = {n: pa.int64() if k == "int" else pa.float64() for n, k in wanted.items()}
    out = {n: np.empty(capacity, dtype=np.int64 if k == "int" else np.float64) for n, k in wanted.items()}
    rows = 0
    try:
        for batch in parse(types):
            if rows + batch.num_rows > capacity or any(batch.column(n).null_count for n in wanted):
                return None
            for name in wanted:
                out[name][rows:rows + batch.num_rows] = batch.column(name).to_numpy()
            rows += batch.num_rows
    except pa.ArrowInvalid:
        return None
    pa.default_memory_pool().release_unused()  # the parser's blocks: back to the system
    values = {name: out[name][:rows] for name in wanted}
    for n, v in values.items():  # floats: min and max are NaN with any NaN, ±inf with any infinity
        if _int_too_long(v) if wanted[n] == "int" else v.size and not np.isfinite((v.min(), v.max())).all():
            return None
    return rows, values


def read_body(
    path: Path,
    data: bytes,
    header_offset: int,
    header_line: int,
    delimiter: str,
    wanted: Mapping[str, str],
) -> Body:
    """Parse the CSV body that starts with its column-name line at ``header_offset``.

    Parameters
    ----------
    path
        File, for messages.
    data
        Whole file contents.
    header_offset, header_line
        Byte offset and 1-based line number of the column-name line.
    delimiter
        Field delimiter.
    wanted
        Column name → ``"int"`` or ``"float"`` for the columns to return.

    Returns
    -------
    Body
        Columns as int64 / float64 arrays over the valid lines only.
    """
    header_raw, data_start = next_line(data, header_offset)
    try:
        names = [n.strip() for n in header_raw.decode("utf-8").lstrip("\ufeff").split(delimiter)]
    except UnicodeDecodeError:
        raise RawFormatError(path, "a column-name line", _show(header_raw), header_line) from None
    missing = [w for w in wanted if w not in names]
    if missing:
        raise RawFormatError(path, "columns " + ", ".join(wanted),
                             f"{delimiter.join(names)!r} (missing {', '.join(missing)})",
                             header_line)
    if len(set(names)) != len(names):
        raise RawFormatError(path, "unique column names", repr(delimiter.join(names)), header_line)
    terminated = not data or data[-1:] in (b"\n", b"\r")
    scan = _scan_data_lines(data, data_start, delimiter)
    lines_read = scan.lines_read
    rows = _Rows(path, names, delimiter, wanted)
    if scan.numeric:
        # the body as a view of the file's bytes (no copy), unless its last line needs an end:
        # pyarrow cannot skip a column line that has no line end
        source = pa.py_buffer(data).slice(header_offset) if terminated else data[header_offset:] + b"\n"
        fast = rows.typed(source, header_line, lines_read)
        if fast is not None:
            return fast
    body = data[header_offset:] if terminated else data[header_offset:] + b"\n"
    if not scan.numeric:
        split = split_odd_lines(body, data_start - header_offset, delimiter)
        around = None if split is None else rows.around(split, header_line, lines_read)
        if around is not None:
            return around
    return _validated_in_pieces(rows, body, data_start - header_offset, header_line, lines_read)


def _validated_in_pieces(rows: _Rows, body: bytes, head: int, header_line: int, lines_read: int) -> Body:
    """:meth:`_Rows.validated` of pieces of whole lines (about SCAN_BLOCK / 4 bytes each), each headed by
    the column line ``body[:head]``: lines are parsed one by one, so the rows, values and skipped
    lines are the whole body's, in memory bounded by a piece (every field as bytes is several times
    its text, issue 36)."""
    starts, size = line_starts(body, head), max(1, filebytes.SCAN_BLOCK // 4)
    starts = starts[:-1] if starts[-1] == len(body) else starts
    if len(body) - head <= size or starts.shape[0] != lines_read:
        return rows.validated(body, header_line, lines_read)
    kinds = {n: np.int64 if k == "int" else np.float64 for n, k in rows.wanted.items()}
    out = Body({n: np.empty(lines_read, dtype=t) for n, t in kinds.items()},  # filled piece by piece
                np.empty(lines_read, dtype=np.int64), lines_read, [], rows.path, header_line)
    i = kept = 0
    while i < lines_read:
        j = min(lines_read, max(i + 1, int(np.searchsorted(starts, starts[i] + size))))
        piece = body[:head] + body[int(starts[i]):int(starts[j]) if j < lines_read else len(body)]
        try:
            part = rows.validated(piece, header_line + i, j - i)
        except RawFormatError as exc:  # the line the whole body's message names
            raise RawFormatError(rows.path, exc.expected, exc.found, header_line) from None
        m = part.lines.shape[0]
        out.lines[kept:kept + m] = part.lines
        for n, v in part.values.items():
            out.values[n][kept:kept + m] = v
        kept, i = kept + m, j
        out.skipped += part.skipped
    out.values, out.lines = {n: v[:kept] for n, v in out.values.items()}, out.lines[:kept]
    return out


@dataclass(frozen=True)
class _Rows:
    """How to parse the data lines of one file: the typed fast path, the validating path,
    and the two together around a few garbled lines (:mod:`~ofbe_data.io.formats.oddlines`)."""

    path: Path
    names: list[str]
    delimiter: str
    wanted: Mapping[str, str]

    def parse(self, source: bytes | pa.Buffer, types: dict[str, pa.DataType], header_line: int,
              invalid: list[SkippedLine], stream: bool = False) -> pa.Table | pacsv.CSVStreamingReader:
        """``source`` (column line, data lines) through pyarrow, as a table (``stream``: batch by
        batch); lines with the wrong number of fields go to ``invalid`` (emptied first) with their
        file line."""
        invalid.clear()

        def on_invalid(row: pacsv.InvalidRow) -> str:
            line = header_line - 1 + (row.number or 0)
            invalid.append(SkippedLine(line, SKIP_FIELD_COUNT,
                                       f"expected {row.expected_columns} fields, found {row.actual_columns}"))
            return "skip"

        return (pacsv.open_csv if stream else pacsv.read_csv)(
            pa.BufferReader(source),
            read_options=pacsv.ReadOptions(use_threads=False, column_names=self.names, skip_rows=1),
            parse_options=pacsv.ParseOptions(delimiter=self.delimiter, quote_char=False,
                                             ignore_empty_lines=False, invalid_row_handler=on_invalid),
            convert_options=pacsv.ConvertOptions(column_types=types, include_columns=list(self.wanted)),
        )

    def typed(self, source: bytes | pa.Buffer, header_line: int, lines_read: int) -> Body | None:
        """The fast path (:func:`_read_typed`): None when it does not apply."""
        invalid: list[SkippedLine] = []
        fast = _read_typed(self.wanted, lambda types: self.parse(source, types, header_line, invalid, True),
                           lines_read)
        if fast is None:
            return None
        rows, values = fast
        row_lines = _row_lines(invalid, header_line, lines_read)
        if row_lines.shape[0] != rows:
            return None
        return Body(values, row_lines, lines_read, sorted(invalid, key=lambda s: s.line), self.path,
                     header_line)

    def around(self, split: OddSplit, header_line: int, lines_read: int) -> Body | None:
        """The fast path over the clean lines and the validating path over the odd ones, lines
        mapped back; None unless every odd line is skipped (a valid one would need merging).

        The typed parse accepts two kinds of field the patterns refuse, both made of number
        bytes only: exponents of four digits (``1e-1234`` reads as 0) and integers of more
        than 18 digits with a small value; a clean part that could hold one is left to the
        validating path."""
        kinds = set(self.wanted.values())
        if ("float" in kinds and (b"e" in split.clean or b"E" in split.clean)
                or "int" in kinds and long_digit_run(split.clean)):
            return None
        clean = self.typed(split.clean, 0, split.clean_lines.size)  # body line k = data line k - 1
        if clean is None:
            return None
        odd = self.validated(split.odd, 0, split.odd_lines.size)
        if odd.lines.size:
            return None
        first = header_line + 1  # file line of data line 0
        skipped = ([SkippedLine(first + int(split.clean_lines[s.line - 1]), s.kind, s.detail)
                    for s in clean.skipped]
                   + [SkippedLine(first + int(split.odd_lines[s.line - 1]), s.kind, s.detail)
                      for s in odd.skipped])
        skipped.sort(key=lambda s: s.line)
        return Body(clean.values, first + split.clean_lines[clean.lines - 1], lines_read, skipped,
                     self.path, header_line)

    def validated(self, body: bytes, header_line: int, lines_read: int) -> Body:
        """The validating path: every field as bytes, tested by a regular expression."""
        path, names, delimiter, wanted = self.path, self.names, self.delimiter, self.wanted
        invalid: list[SkippedLine] = []
        try:
            # pyarrow decodes an invalid row's text as UTF-8 before calling the handler, so
            # bytes >= 0x80 (never valid in a number) are masked for parsing; messages
            # quote the original bytes
            table = self.parse(body if body.isascii() else body.translate(_MASK_NON_ASCII),
                               {n: pa.binary() for n in names}, header_line, invalid)
        except pa.ArrowInvalid as exc:
            raise RawFormatError(path, "CSV data lines", f"unreadable data ({exc})", header_line) from None
        row_lines = _row_lines(invalid, header_line, lines_read)
        if row_lines.shape[0] != table.num_rows:  # pragma: no cover - pyarrow contract
            raise RawFormatError(path, f"{row_lines.shape[0]} parsed rows", str(table.num_rows))
        ok = np.ones(table.num_rows, dtype=bool)
        empty = np.ones(table.num_rows, dtype=bool)
        first_bad: dict[int, str] = {}
        starts: np.ndarray | None = None
        for name, kind in wanted.items():
            col = table.column(name)
            good = pc.match_substring_regex(col, _INT_RE if kind == "int" else _FLOAT_RE)
            good_np = good.to_numpy(zero_copy_only=False)
            empty &= (pc.binary_length(col).to_numpy(zero_copy_only=False) == 0)
            for i in np.flatnonzero(~good_np & ok):
                raw = col[int(i)].as_py()
                if b"?" in raw:  # masked bytes: quote the original field
                    if starts is None:
                        starts = line_starts(body)
                    raw = _original_field(body, starts, int(row_lines[i]) - header_line,
                                          names.index(name), delimiter)
                first_bad[int(i)] = f"field {name!r} is not a number: {_show(raw)}"
            ok &= good_np
        skipped = list(invalid)
        for i, detail in first_bad.items():
            if empty[i]:
                skipped.append(SkippedLine(int(row_lines[i]), SKIP_EMPTY, "empty line"))
            else:
                skipped.append(SkippedLine(int(row_lines[i]), SKIP_NON_NUMERIC, detail))
        keep = pa.array(ok)
        values: dict[str, np.ndarray] = {}
        for name, kind in wanted.items():
            col = pc.utf8_trim_whitespace(pc.cast(table.column(name).filter(keep), pa.string()))
            col = pc.utf8_ltrim(col, "+")  # the patterns allow a plus sign, pyarrow's casts do not
            values[name] = pc.cast(col, pa.int64() if kind == "int" else pa.float64()).to_numpy()
        skipped.sort(key=lambda s: s.line)
        out = Body(values, row_lines[ok], lines_read, skipped, path, header_line)
        for name, kind in wanted.items():
            if kind == "float":  # an exponent beyond float64's range parses as ±inf
                overflow = ~np.isfinite(out.values[name])
                drop(out, overflow, SKIP_NON_NUMERIC,
                      [f"field {name!r} is out of float64 range: {out.values[name][i]}"
                       for i in np.flatnonzero(overflow)])
        return out


def drop(body: Body, bad: np.ndarray, kind: str, details: Sequence[str] | str) -> None:
    """Remove rows flagged in ``bad`` from ``body``, recording them as skipped."""
    idx = np.flatnonzero(bad)
    if idx.size == 0:
        return
    if isinstance(details, str):
        details = [details] * idx.size
    for i, detail in zip(idx, details, strict=True):
        body.skipped.append(SkippedLine(int(body.lines[i]), kind, detail))
    body.skipped.sort(key=lambda s: s.line)
    keep = ~bad
    body.values = {k: v[keep] for k, v in body.values.items()}
    body.lines = body.lines[keep]


MAX_STEP_S = 1.0
"""A time step longer than this (or not positive) is abnormal; a sample with abnormal
steps on both sides whose neighbours are consistent with each other is a corrupted
timestamp, not a gap."""


def clean_times(body: Body, t: np.ndarray, max_step: float, modulus: int | None = None
                 ) -> tuple[np.ndarray, int]:
    """Drop corrupted or backward time stamps; undo counter wraps.

    Works on whole arrays. A sample whose steps from and to its neighbours are both
    abnormal (not positive, or longer than ``max_step``) while the step between the
    neighbours is normal is dropped as inconsistent; then every sample not after all the
    samples kept before it is dropped (a block of any length that jumps back). With
    ``modulus`` (an unsigned counter), steps are taken modulo it, so a
    wrap is a normal step and is undone.

    Parameters
    ----------
    body
        Parsed body; dropped rows are removed from it and recorded as skipped.
    t
        (N,) raw time stamps in counter units (int64) or seconds (float64).
    max_step
        Longest normal step, same units as ``t``.
    modulus
        Counter modulus (2³² for ``micros()``), or None for plain times.

    Returns
    -------
    t, wraps
        Kept, unwrapped, strictly increasing times (float64, same units) and the number
        of wraps undone.

    Raises
    ------
    RawFormatError
        When no sample is left: every reader ends its line checks here.
    """

    clean = _clean_times_fast(t, max_step, modulus)
    if clean is not None:
        return clean

    def steps(x: np.ndarray) -> np.ndarray:
        d = np.diff(x)
        return d % modulus if modulus is not None else d

    def abnormal(d: np.ndarray) -> np.ndarray:
        return (d <= 0) | (d > max_step)

    def backward(d: np.ndarray) -> np.ndarray:
        return (d == 0) | (d >= modulus // 2) if modulus is not None else d <= 0

    if t.size >= 3:
        d = steps(t)
        bridge = t[2:] - t[:-2]
        bridge = bridge % modulus if modulus is not None else bridge
        spike = np.zeros(t.shape, dtype=bool)
        spike[1:-1] = abnormal(d[:-1]) & abnormal(d[1:]) & ~abnormal(bridge)
        spike[0] = backward(d[:1])[0] and not abnormal(d[1:2])[0]
        spike[-1] = backward(d[-1:])[0] and not abnormal(d[-2:-1])[0]
        details = [f"time stamp {t[i]} inconsistent with its neighbours" for i in np.flatnonzero(spike)]
        drop(body, spike, SKIP_NON_INCREASING_TIME, details)
        t = t[~spike]
    if t.size >= 2:
        # a sample must come after every sample kept before it: compare with the running
        # maximum of the (signed, unwrapped) times, so a whole block that jumps back is dropped
        signed = steps(t).astype(np.float64)
        if modulus is not None:
            signed[signed >= modulus // 2] -= modulus
        u = np.concatenate(([0.0], np.cumsum(signed)))
        before = np.maximum.accumulate(u)
        bad = np.zeros(t.shape, dtype=bool)
        bad[1:] = u[1:] <= before[:-1]
        details = [f"time stamp {t[i]} not after an earlier sample" for i in np.flatnonzero(bad)]
        drop(body, bad, SKIP_NON_INCREASING_TIME, details)
        t = t[~bad]
    if t.size == 0:
        raise RawFormatError(body.path, "at least one valid data line", "none", body.header_line)
    d = steps(t)
    wraps = int(np.count_nonzero(np.diff(t) < 0)) if modulus is not None else 0
    out = np.empty(t.shape, dtype=np.float64)
    out[0] = t[0]
    out[1:] = float(t[0]) + np.cumsum(d, dtype=np.float64 if modulus is None else np.int64)
    return out, wraps


def _clean_times_fast(t: np.ndarray, max_step: float, modulus: int | None
                      ) -> tuple[np.ndarray, int] | None:
    """:func:`clean_times` of a series whose every step (modulo ``modulus``) is normal, in
    a few passes; None when some step is not, and the caller takes the general path.

    Every step in (0, max_step] means no spike and nothing backward: nothing is dropped, and
    the result is the one the general path computes from the same steps (for plain times,
    also when the running sum of the steps keeps increasing, as it then checks).
    """
    if t.size < 2:
        return None
    d = np.diff(t)
    wraps = 0
    if modulus is not None:
        if not max_step < modulus // 2:  # a backward step must be abnormal for the shortcut
            return None
        back = d < 0
        wraps = int(np.count_nonzero(back))
        if wraps:
            if not (int(t.min()) >= 0 and int(t.max()) < modulus):
                return None
            d = d + back * modulus  # d % modulus for steps between two counter values
    if not (d.min() > 0 and d.max() <= max_step):
        return None
    out = np.empty(t.shape, dtype=np.float64)
    out[0] = t[0]
    if modulus is None:
        u = np.cumsum(d, dtype=np.float64)
        if not bool(np.all(u[1:] > u[:-1])):  # the running sum stalled (tiny steps): general path
            return None
        out[1:] = float(t[0]) + u
    elif wraps or t.dtype != np.int64:
        out[1:] = float(t[0]) + np.cumsum(d, dtype=np.int64)
    else:  # the running sum of the (exact, positive, bounded) integer steps is t − t[0] itself
        out[1:] = float(t[0]) + (t[1:] - t[0])
    return out, wraps


def find_gaps(t: np.ndarray, lines: np.ndarray, period_s: float | None,
              factor: float | None = None) -> tuple[Gap, ...]:
    """Gaps in a time series.

    Parameters
    ----------
    t
        (N,) increasing times, s.
    lines
        (N,) file line of each sample.
    period_s
        Nominal sample period, s; the median step is used when None.
    factor
        A step longer than this many periods is a gap (default :data:`GAP_FACTOR`).

    Returns
    -------
    tuple of Gap
        One per step longer than ``GAP_FACTOR`` periods.
    """
    if t.size < 2:
        return ()
    dt = np.diff(t)
    period = median(dt) if period_s is None else period_s
    idx = np.flatnonzero(dt > (GAP_FACTOR if factor is None else factor) * period)
    return tuple(
        Gap(int(lines[i + 1]), float(t[i + 1]), float(dt[i]), int(round(dt[i] / period)) - 1)
        for i in idx
    )


def parse_utc(text: str | None) -> datetime | None:
    if not text:
        return None
    try:
        stamp = datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except ValueError:
        return None
    return stamp if stamp.tzinfo else stamp.replace(tzinfo=UTC)


def format_utc(stamp: datetime) -> str:
    """ISO 8601 UTC with milliseconds and a ``Z``, as both device headers write it."""
    stamp = stamp.astimezone(UTC)
    return stamp.strftime("%Y-%m-%dT%H:%M:%S.") + f"{stamp.microsecond // 1000:03d}Z"

