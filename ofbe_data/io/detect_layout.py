"""Where the numbers are in a generic csv file: lines, fields, delimiter, decimal mark, comment
prefix, preamble, column line, and the numbers themselves, for :mod:`ofbe_data.io.detect`.

:func:`find_layout` looks at the lines only (no units): the delimiter that splits the last part
of the sampled lines into a constant number of fields with at least three numeric columns, the
first run of such lines (the data), the line before it when it holds names (the column line),
what comes before (``skip_rows``) and the comment prefix when comment lines appear among the data.
Every finding comes back as ``(key, value, evidence)``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.manifest import WHITESPACE

MAX_DATA_LINES = 500_000
"""Data lines read for the statistics (the rest of a longer file is not needed to decide)."""
LAYOUT_LINES = 2000
"""Lines looked at to find the delimiter and where the data start."""
DELIMITERS = (",", ";", "\t", WHITESPACE)
"""Candidates, in order of preference."""
COMMENT_PREFIXES = ("#", "//", "%")
"""Comment prefixes looked for."""

# --------------------------------------------------------------------------- lines and fields


def split_lines(text: str) -> list[str]:
    """Lines as the readers split them (``\\n``, ``\\r\\n`` and a lone ``\\r`` end a line)."""
    lines = re.split(r"\r\n|\r|\n", text)
    if lines and lines[-1] == "":
        lines.pop()
    return lines


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


def _comment_prefixes(lines: list[str]) -> list[str]:
    return [p for p in COMMENT_PREFIXES if any(line.startswith(p) for line in lines)]


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


def find_layout(path: Path, lines: list[str]) -> tuple[Layout, list[tuple[str, Any, str]], list[str]]:
    """The layout of a generic csv file's lines.

    Parameters
    ----------
    path
        The file (for messages).
    lines
        Its lines (byte-order mark removed).

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
    body = [i for i, line in enumerate(lines) if line.strip() and not line.startswith(tuple(prefixes))]
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
    data_start = body[start]
    header_line = body[start - 1] if start > 0 else None
    names: list[str] = []
    trailing = (delim != WHITESPACE and width > 3 and
                all(split_fields(lines[i], delim)[-1] == "" for i in body[start:start + 200]))
    if header_line is not None:
        fields = [unquote(f) for f in split_fields(lines[header_line], delim)]
        fits = len(fields) == width or (trailing and len(fields) == width - 1)
        if fits and not all(is_number(f) for f in fields if f):
            names = fields
        else:
            warnings.append(f"line {header_line + 1} ({lines[header_line].strip()[:50]!r}) is not a "
                                f"column line of the data's {width} fields: read by position")
            header_line = None
    column_line = header_line if header_line is not None else data_start
    after = [p for p in prefixes if any(line.startswith(p) for line in lines[column_line:])]
    if len(after) > 1:
        raise RawFormatError(path, "one comment prefix among the data", " and ".join(repr(p) for p in after))
    comment = after[0] if after else None
    skip = column_line
    if comment is not None and skip and all(line.startswith(comment) for line in lines[:skip]):
        skip = 0
    if comment is not None:
        n = sum(1 for line in lines if line.startswith(comment))
        add("comment", comment, f"{n} lines start with {comment!r}, "
                                    f"{sum(1 for line in lines[column_line:] if line.startswith(comment))} "
                                    f"of them among the data")
    if skip:
        shown = ", ".join(repr(line.strip()[:30]) for line in lines[:min(skip, 3)])
        add("skip_rows", skip, f"line{'s 1–' + str(skip) if skip > 1 else ' 1'} before the "
                                   f"{'column line' if names else 'first data line'}: {shown}"
                                   f"{', …' if skip > 3 else ''}")
    if names:
        add("header", True, f"line {header_line + 1 if header_line is not None else 0} holds the column "
                                f"names: {lines[column_line].strip().lstrip(chr(0xFEFF))[:70]!r}")
    else:
        add("header", False, f"no column-name line: line {data_start + 1} is already data")
    if trailing:
        add("trailing_delimiter", True, f"every data line ends with {delim!r}: an empty last "
                                            "column, ignored")
    return Layout(delim, width, numeric, data_start, header_line, names, comment, skip, trailing,
                  column_line, decimal), found, warnings


def read_numbers(lines: list[str], lay: Layout) -> tuple[np.ndarray, int, dict[int, int]]:
    """(rows, width) float array of the data lines (NaN where not a number), their count, and the
    first value of each column of integers too long for float64 (epoch ns), which are returned
    less that first value."""
    rows: list[list[float]] = []
    base: dict[int, int] | None = None
    for line in lines[lay.data_start:]:
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
