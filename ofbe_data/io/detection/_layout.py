"""Where the numbers are in a generic csv file: lines, fields, delimiter, decimal mark, comment
prefix, preamble, column line, and the numbers themselves, for :mod:`ofbe_data.io.detection`.

:func:`find_layout` looks at the lines only (no units): the delimiter that splits the last part
of the sampled lines into a constant number of fields with at least three numeric columns, the
first run of such lines (the data), the line before it when it holds names (the column line),
what comes before (``skip_rows``) and the comment prefix when comment lines appear among the data.
Every finding comes back as ``(key, value, evidence)``.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.detection._names import unit_of_text
from ofbe_data.io.formats.filebytes import SCAN_BLOCK, line_starts
from ofbe_data.io.manifest import WHITESPACE

MAX_DATA_LINES = 500_000
"""Data lines read for the statistics (the rest of a longer file is not needed to decide)."""
LAYOUT_LINES = 2000
"""Lines looked at to find the delimiter and where the data start."""
DELIMITERS = (",", ";", "\t", WHITESPACE)
"""Candidates, in order of preference."""
COMMENT_PREFIXES = ("#", "//", "%")
"""Comment prefixes looked for before the data."""
PROMPT_CHARS = "#%/>!*$@=<|~:&?^-"
"""Characters a comment or prompt line among the data starts with (``>>>``, ``> ``, ``#``, ``%``,
``//``, ``--``); a lone ``-`` starts a negative number, so it must be doubled."""

# --------------------------------------------------------------------------- lines and fields


def split_lines(text: str) -> list[str]:
    """Lines as the readers split them (``\\n``, ``\\r\\n`` and a lone ``\\r`` end a line)."""
    lines = re.split(r"\r\n|\r|\n", text)
    if lines and lines[-1] == "":
        lines.pop()
    return lines


_BOM = b"\xef\xbb\xbf"
_SOLID = np.ones(256, dtype=bool)  # bytes that make a line non-blank whatever follows: ASCII, not whitespace
_SOLID[[*range(9, 14), *range(28, 33), *range(128, 256)]] = False


class TextLines(Sequence[str]):
    """A file's lines as :func:`split_lines` gives them from its text (UTF-8, invalid bytes replaced,
    a leading byte-order mark dropped), each decoded from the bytes when it is asked for: a long
    file is held once, as bytes, with the offset of every line (issue 36: as a list of strings it
    took several times its size). Decoding line by line is decoding the whole: a line end is an
    ASCII byte, which ends any invalid sequence. Questions about every line (:meth:`starting_with`,
    :meth:`non_blank`, :meth:`first_bytes`) are answered over the bytes."""

    def __init__(self, data: bytes) -> None:
        self._data = data
        starts = line_starts(data)
        if data.startswith(_BOM):
            starts[0] = len(_BOM)
        self._starts = starts[:-1] if starts[-1] == len(data) else starts

    def __len__(self) -> int:
        return int(self._starts.shape[0])

    def _span(self, i: int) -> tuple[int, int]:
        """Bytes [start, end) of line ``i``, without its line end."""
        a = int(self._starts[i])
        e = int(self._starts[i + 1]) if i + 1 < len(self) else len(self._data)
        if e > a and self._data[e - 1] == 0x0A:
            e -= 1
        if e > a and self._data[e - 1] == 0x0D:
            e -= 1
        return a, e

    def __getitem__(self, k: int | slice) -> str | list[str]:  # type: ignore[override]
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(len(self)))]
        i = int(k) + len(self) if k < 0 else int(k)
        if not 0 <= i < len(self):
            raise IndexError(k)
        a, e = self._span(i)
        return self._data[a:e].decode("utf-8", errors="replace")

    def first_bytes(self, k: int) -> np.ndarray:
        """The ``k``-th byte of every line (0 past the end of the file; a line end counts), (L,) uint8."""
        at = self._starts + k
        np.minimum(at, len(self._data) - 1, out=at)
        out = np.frombuffer(self._data, dtype=np.uint8)[at]
        del at
        tail = self._starts[-(k + 1):]  # only the last k + 1 lines can reach the end of the file
        out[out.shape[0] - tail.shape[0]:][tail + k >= len(self._data)] = 0
        return out

    def starting_with(self, prefix: str) -> np.ndarray:
        """Which lines start with ``prefix`` (ASCII, no line end in it), (L,) bool."""
        out = np.ones(len(self), dtype=bool)
        for k, byte in enumerate(prefix.encode("ascii")):
            out &= self.first_bytes(k) == byte
        return out

    def non_blank(self) -> np.ndarray:
        """Which lines hold more than whitespace (``line.strip()`` is not empty), (L,) bool: from an
        ASCII byte that is no whitespace, else (other bytes) from the decoded line."""
        b, n = np.frombuffer(self._data, dtype=np.uint8), len(self)
        out = np.zeros(n, dtype=bool)
        i = 0
        while i < n:  # blocks of whole lines: temporaries of about SCAN_BLOCK bytes
            j = min(n, max(i + 1, int(np.searchsorted(self._starts, self._starts[i] + SCAN_BLOCK))))
            a, e = int(self._starts[i]), int(self._starts[j]) if j < n else len(self._data)
            block = b[a:e]
            cuts = self._starts[i:j] - a
            out[i:j] = np.logical_or.reduceat(_SOLID[block], cuts)
            other = np.flatnonzero(~out[i:j] & np.logical_or.reduceat(block >= 0x80, cuts)) + i
            out[other] = [bool(self[int(k)].strip()) for k in other]
            i = j
        return out


def starting_with(lines: Sequence[str], prefix: str) -> np.ndarray:
    """Which of ``lines`` start with ``prefix`` (ASCII), (L,) bool; over the bytes for :class:`TextLines`."""
    if isinstance(lines, TextLines):
        return lines.starting_with(prefix)
    return np.array([line.startswith(prefix) for line in lines], dtype=bool).reshape(-1)


def non_blank(lines: Sequence[str]) -> np.ndarray:
    """Which of ``lines`` hold more than whitespace, (L,) bool; over the bytes for :class:`TextLines`."""
    if isinstance(lines, TextLines):
        return lines.non_blank()
    return np.array([bool(line.strip()) for line in lines], dtype=bool).reshape(-1)


class _Indices:
    """Line indices held as an int64 array, read back as ints (``body[k]``) and lists of ints."""

    def __init__(self, values: np.ndarray) -> None:
        self._values = values

    def __len__(self) -> int:
        return int(self._values.shape[0])

    def __getitem__(self, k: int | slice) -> Any:
        return self._values[k].tolist()


def split_fields(line: str, delimiter: str) -> list[str]:
    """Fields of a line, stripped (whitespace: runs of blanks, leading ones ignored)."""
    if delimiter == WHITESPACE:
        return line.split()
    return [f.strip() for f in line.split(delimiter)]


def is_number(text: str, decimal_comma: bool = False) -> bool:
    """Whether a field is a plain decimal number (no quotes; a decimal comma only when allowed)."""
    if not text or text[0] in "\"'" or "_" in text:
        return False
    if decimal_comma and "," in text and "." not in text:
        text = text.replace(",", ".", 1)
    try:
        float(text)
    except ValueError:
        return False
    return text.lower() not in ("nan", "inf", "-inf", "+inf", "infinity", "-infinity")


def unquote(name: str) -> str:
    """A column name without surrounding blanks, quotes and byte-order mark."""
    name = name.strip().lstrip("\ufeff").strip()
    if len(name) >= 2 and name[0] == name[-1] and name[0] in "\"'":
        name = name[1:-1].strip()
    return name


# --------------------------------------------------------------------------- layout


@dataclass
class Layout:
    """Where the numbers of a generic csv file are.

    Attributes
    ----------
    delimiter
        One character, or ``whitespace``.
    width
        Fields per data line.
    numeric
        0-based columns that hold numbers.
    data_start
        0-based index (in the file's lines) of the first data line.
    header_line
        0-based index of the column line, or None without one.
    names
        Column names (unquoted), empty without a column line.
    comment
        Comment prefix to write in the manifest (comment lines among the data), or None.
    skip_rows
        Lines before the column line (or the first data line) to write as ``skip_rows``.
    trailing
        Every data line ends with the delimiter (an empty last column).
    column_line
        0-based index of the column line, or of the first data line without one.
    decimal_comma
        Numbers are written with a decimal comma (delimiter ``;`` or tab).
    units
        Per column, the unit a unit row under the column line states (``s,g,g,g``), else empty.
    unit_row
        0-based index of that unit row, or None.
    """

    delimiter: str
    width: int
    numeric: list[int]
    data_start: int
    header_line: int | None
    names: list[str]
    comment: str | None
    skip_rows: int
    trailing: bool
    column_line: int
    decimal_comma: bool
    units: list[str | None] = field(default_factory=list)
    unit_row: int | None = None


def _comment_prefixes(lines: Sequence[str]) -> list[str]:
    return [p for p in COMMENT_PREFIXES if starting_with(lines, p).any()]


def _choose_delimiter(path: Path, sample: list[str]) -> tuple[str, int, list[int], bool, str]:
    """Delimiter, fields per line, numeric columns, decimal commas, evidence."""
    tail = sample[len(sample) // 2:] if len(sample) >= 20 else sample[1:] or sample
    for delim in DELIMITERS:
        # the reader takes a comma that is not the delimiter for a decimal mark
        comma = delim not in (",", WHITESPACE)
        split = [split_fields(line, delim) for line in tail]
        counts = np.array([len(f) for f in split])
        width = int(np.bincount(counts).argmax())
        rows = [f for f in split if len(f) == width]
        numeric = [c for c in range(width) if np.mean([is_number(r[c], comma) for r in rows]) >= 0.9]
        share = len(rows) / len(split)
        if width >= 3 and len(numeric) >= 3 and share >= 0.8:
            name = {WHITESPACE: "runs of blanks"}.get(delim, repr(delim))
            decimal = comma and any("," in r[c] for r in rows[:50] for c in numeric)
            return delim, width, numeric, decimal, (f"{width} fields split on {name} in {100 * share:.3g} % "
                                                    f"of {len(split)} sampled data lines, {len(numeric)} of "
                                                    "them numeric")
    if any(re.fullmatch(r"\s*[+-]?\d+,\d+(\s+[+-]?\d+,\d+){2,}\s*", line) for line in tail[:50]):
        raise RawFormatError(path, "decimal commas only with a ';' or tab delimiter (the reader cannot tell "
                                   "them from blanks between the fields)",
                             f"decimal commas, e.g. {tail[0][:40]!r}")
    raise RawFormatError(path, "data lines of at least 3 numeric fields split on ',', ';', tab or blanks",
                         f"none (e.g. {tail[0][:40]!r})" if tail else "no data lines")


def find_layout(path: Path, lines: Sequence[str]) -> tuple[Layout, list[tuple[str, Any, str]], list[str]]:
    """The layout of a generic csv file's lines.

    Parameters
    ----------
    path
        The file (for messages).
    lines
        Its lines (byte-order mark removed): a list, or :class:`TextLines` (whole-file passes over
        the bytes).

    Returns
    -------
    layout, findings, warnings
        The layout; ``(key, value, evidence)`` for ``delimiter``, ``decimal_comma``,
        ``comment``, ``skip_rows``, ``header`` and ``trailing_delimiter``; things to look at.

    Raises
    ------
    RawFormatError
        No run of data lines (at least three numeric fields on a constant number of fields), or
        decimal commas between comma- or blank-separated fields.
    """
    prefixes = _comment_prefixes(lines)
    solid = non_blank(lines)
    for p in prefixes:
        solid &= ~starting_with(lines, p)
    body = _Indices(np.flatnonzero(solid))  # lines neither blank nor comments
    del solid
    if not body:
        raise RawFormatError(path, "data lines", "none (only blank or comment lines)")
    found: list[tuple[str, Any, str]] = []
    warnings: list[str] = []

    def add(key: str, value: Any, why: str) -> None:
        found.append((key, value, why))

    sample = [lines[i].lstrip("\ufeff") for i in body[:LAYOUT_LINES]]
    delim, width, numeric, decimal, why = _choose_delimiter(path, sample)
    add("delimiter", delim, why)
    if decimal:
        example = next((f for line in sample[::-1] for f in split_fields(line, delim) if "," in f), "")
        add("decimal_comma", True, f"numbers such as {example!r}: the reader takes a comma that is not "
                                   "the delimiter for the decimal mark")

    def is_data(i: int) -> bool:
        f = split_fields(lines[i].lstrip("\ufeff"), delim)
        return len(f) == width and all(is_number(f[c], decimal) for c in numeric)

    start = next((k for k in range(len(body))
                  if all(is_data(body[j]) for j in range(k, min(k + 5, len(body))))), None)
    if start is None:
        raise RawFormatError(path, "a run of data lines", "none")
    numbering = None
    if start + 1 < len(body) and _numbers_columns(split_fields(lines[body[start]], delim), width):
        numbering, start = body[start], start + 1
    data_start = body[start]
    header_line = body[start - 1] if start > 0 and numbering is None else None
    names: list[str] = []
    units: list[str | None] = []
    unit_row = None
    trailing = (delim != WHITESPACE and width > 3 and
                all(split_fields(lines[i], delim)[-1] == "" for i in body[start:start + 200]))

    def fits(fields: list[str]) -> bool:
        return len(fields) == width or (trailing and len(fields) == width - 1)

    # '#timestamp [ns],w_RS_S_x [rad s^-1],…' (EuRoC, Kalibr): a commented column line, names as written
    commented = None if numbering is not None else _commented_column_line(lines, data_start, delim, prefixes,
                                                                           fits)
    if commented is not None:
        header_line = commented
    if header_line is not None:
        fields = [unquote(f) for f in split_fields(lines[header_line], delim)]
        stated = unit_row_units(fields) if commented is None else None
        if stated is not None and start > 1 and fits(fields):
            above = [unquote(f) for f in split_fields(lines[body[start - 2]].lstrip("\ufeff"), delim)]
            if fits(above) and len(above) == len(fields) and not any(is_number(f) for f in above if f):
                unit_row, header_line, fields, units = header_line, body[start - 2], above, stated
        if fits(fields) and not all(is_number(f) for f in fields if f):
            names = fields
        else:
            warnings.append(f"line {header_line + 1} ({lines[header_line].strip()[:50]!r}) is not a "
                                f"column line of the data's {width} fields: read by position")
            header_line = None
    column_line = header_line if header_line is not None else data_start
    comment, why, others = _prompt_prefix(lines, max(column_line, unit_row or 0, numbering or 0) + 1, delim,
                                          is_data)
    warnings.extend(others)
    if comment is not None and header_line is not None and lines[header_line].startswith(comment):
        warnings.append(f"lines among the data start with {comment!r} as the column line (line "
                        f"{header_line + 1}) does: no comment key, the reader skips them as unreadable lines")
        comment = None
    if unit_row is not None:
        shown = ", ".join(f"{n}: {u}" for n, u in zip(names, units, strict=False) if u)
        if comment is None:
            comment = lines[unit_row]
            why = (f"line {unit_row + 1} under the column line states the units ({shown}); no manifest key "
                   "skips one line after the column line, so that line itself is the comment string (lines "
                   "starting with it are skipped)")
        else:
            add("unit_row", unit_row + 1, f"line {unit_row + 1} under the column line states the units "
                                          f"({shown}); with the comment key taken by {comment!r} the reader "
                                          "skips it as one unreadable line")
    skip = column_line
    if comment is not None and skip and all(line.startswith(comment) for line in lines[:skip]):
        skip = 0
    if comment is not None:
        add("comment", comment, why)
    if skip:
        shown = ", ".join(repr(line.strip()[:30]) for line in lines[:min(skip, 3)])
        what = (f"line{'s 1–' + str(skip) if skip > 1 else ' 1'} before the "
                f"{'column line' if names else 'first data line'}: {shown}{', …' if skip > 3 else ''}")
        if numbering is not None:
            what += (f"; line {numbering + 1} ({lines[numbering].strip()[:40]!r}) numbers the columns, it is "
                     "not data")
        add("skip_rows", skip, what)
    if names:
        add("header", True, f"line {header_line + 1 if header_line is not None else 0} holds the column "
                                f"names: {lines[column_line].strip().lstrip(chr(0xFEFF))[:70]!r}")
    else:
        add("header", False, f"no column-name line: line {data_start + 1} is "
                             + ("the first data line" if numbering is not None else "already data"))
    if trailing:
        add("trailing_delimiter", True, f"every data line ends with {delim!r}: an empty last "
                                            "column, ignored")
    return Layout(delim, width, numeric, data_start, header_line, names, comment, skip, trailing,
                  column_line, decimal, units, unit_row), found, warnings


def _commented_column_line(lines: list[str], data_start: int, delim: str, prefixes: list[str],
                           fits: Callable[[list[str]], bool]) -> int | None:
    """The line right before the data (blank lines aside) when it starts with a comment prefix
    and holds the data's number of distinct, non-numeric names (``#timestamp [ns],w_RS_S_x …``),
    else None. Its first name keeps the prefix: the reader matches names as written."""
    i = data_start - 1
    while i >= 0 and not lines[i].strip():
        i -= 1
    if i < 0 or not prefixes or not lines[i].startswith(tuple(prefixes)):
        return None
    fields = [unquote(f) for f in split_fields(lines[i], delim)]
    if not fits(fields) or any(is_number(f) for f in fields if f) or len(set(fields)) != len(fields):
        return None
    return i


def _numbers_columns(fields: list[str], width: int) -> bool:
    """Whether a line's fields are the column numbers 0, 1, 2… or 1, 2, 3… (a spreadsheet's or a
    plotting tool's first line), not a sample."""
    if len(fields) != width or width < 3 or not all(re.fullmatch(r"\d{1,3}", f) for f in fields):
        return False
    values = [int(f) for f in fields]
    return values[0] in (0, 1) and values == list(range(values[0], values[0] + width))


UNIT_PLACEHOLDERS = ("-", "--", "—", "/", "1", "n/a", "na", "#", "")
"""Fields of a unit row that state no unit (an index column's, say)."""


def unit_row_units(fields: list[str]) -> list[str | None] | None:
    """The units a row of units states per column (``s,g,g,g``; ``[s];[m/s²];…``), or None when the
    row is no unit row (a field that is neither a unit nor a placeholder, or fewer than two units)."""
    out: list[str | None] = []
    for f in fields:
        text = f.strip().strip("[]()").strip()
        unit = unit_of_text(text) if text else None
        if unit is None and text.lower() not in UNIT_PLACEHOLDERS:
            return None
        out.append(unit)
    return out if sum(u is not None for u in out) >= 2 else None


_PROMPT_BYTES = np.zeros(256, dtype=bool)
_PROMPT_BYTES[list(PROMPT_CHARS.encode())] = True


def _prompt_lines(lines: Sequence[str], first: int, delim: str) -> list[int]:
    """Lines from ``first`` on that start with a character of :data:`PROMPT_CHARS` other than the
    delimiter (``-`` only doubled): the lines that may be comment or prompt lines."""
    if isinstance(lines, TextLines):
        c0, c1 = lines.first_bytes(0), lines.first_bytes(1)
        maybe = _PROMPT_BYTES[c0] & ((c0 != ord("-")) | (c1 == ord("-")))
        if len(delim) == 1:
            maybe &= c0 != ord(delim)
        maybe[:first] = False
        return np.flatnonzero(maybe).tolist()
    return [i for i in range(first, len(lines)) if (c := lines[i][:1]) and c in PROMPT_CHARS and c != delim
            and (c != "-" or lines[i].startswith("--"))]


def _prompt_prefix(lines: Sequence[str], first: int, delim: str, is_data: Callable[[int], bool]
                   ) -> tuple[str | None, str, list[str]]:
    """The comment prefix of the comment or prompt lines among the data (from line ``first``,
    0-based): the prefix the most of them share (``>>>``, ``>``, ``#``, ``%``, ``//``), its evidence,
    and warnings for lines that start with another prefix (the reader skips them as unreadable).
    A data line is never one of them, whatever its first character."""
    groups: dict[str, list[int]] = {}
    for i in _prompt_lines(lines, first, delim):
        if not is_data(i):
            groups.setdefault(lines[i][:1], []).append(i)
    if not groups:
        return None, "", []
    order = sorted(groups, key=lambda c: -len(groups[c]))
    best = groups[order[0]]
    runs = [lines[i][:len(lines[i]) - len(lines[i].lstrip(PROMPT_CHARS))] for i in best]
    prefix = os.path.commonprefix(runs)
    n_all = int(starting_with(lines, prefix).sum())
    why = (f"{n_all} line{'s' if n_all != 1 else ''} start{'' if n_all != 1 else 's'} with {prefix!r}, "
           f"{len(best)} of them among the data (e.g. line "
           f"{best[0] + 1}: {lines[best[0]].strip()[:30]!r}): comment or prompt lines, not garbled data")
    warnings = [f"{len(groups[c])} line{'s' if len(groups[c]) != 1 else ''} among the data start"
                f"{'' if len(groups[c]) != 1 else 's'} with {c!r} (e.g. line {groups[c][0] + 1}: "
                f"{lines[groups[c][0]].strip()[:30]!r}); only one comment prefix can be given, so the reader "
                "skips them as unreadable lines" for c in order[1:]]
    return prefix, why, warnings


def read_numbers(lines: Sequence[str], lay: Layout) -> tuple[np.ndarray, int, dict[int, int]]:
    """(rows, width) float array of the data lines (NaN where not a number), their count, and the
    first value of each column of integers too long for float64 (epoch ns), which are returned
    less that first value."""
    rows: list[list[float]] = []
    base: dict[int, int] | None = None
    for i in range(lay.data_start, len(lines)):  # line by line: never the whole file as text
        line = lines[i]
        if not line.strip() or (lay.comment and line.startswith(lay.comment)):
            continue
        if lay.decimal_comma:
            line = line.replace(",", ".")
        f = split_fields(line, lay.delimiter)
        if len(f) != lay.width:
            continue
        if base is None:
            base = {c: int(f[c]) for c in lay.numeric if re.fullmatch(r"[+-]?\d{16,}", f[c])}
        try:
            rows.append([float(int(f[c]) - base[c]) if c in base else float(f[c]) if c in lay.numeric
                         else np.nan for c in range(lay.width)])
        except ValueError:
            continue
        if len(rows) >= MAX_DATA_LINES:
            break
    arr = np.array(rows, dtype=np.float64).reshape(-1, lay.width)
    return arr[np.all(np.isfinite(arr[:, lay.numeric]), axis=1)], len(rows), base or {}
