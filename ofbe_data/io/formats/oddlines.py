"""The few garbled lines of a file, set apart so that the rest can take the typed fast path.

A serial link garbles a handful of lines of a long file (a stray byte, a lost field). The
validating path reads every field as bytes and tests it with a regular expression, several
times the cost of the typed parse. When only a few lines hold bytes that no number has,
:func:`split_odd_lines` cuts them out: the other lines go through the typed parse, the odd
ones alone through the validating path, with every line number mapped back (the caller in
:mod:`~ofbe_data.io.formats.common` keeps that path's results exactly, or falls back to it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ofbe_data.io.formats.filebytes import line_starts

NUMBER_CHARS = b"0123456789+-.eE"
"""Bytes a number may hold (digits, signs, point, exponent)."""


@dataclass(frozen=True)
class OddSplit:
    """A CSV body (column line, then data lines) split into two bodies with the same column
    line.

    Attributes
    ----------
    clean
        The column line and every data line without an odd byte.
    odd
        The column line and the data lines with one.
    clean_lines, odd_lines
        0-based index among the original data lines of each data line of ``clean`` and ``odd``.
    """

    clean: bytes
    odd: bytes
    clean_lines: np.ndarray
    odd_lines: np.ndarray


def split_odd_lines(body: bytes, data_start: int, delimiter: str, max_odd: int = 64) -> OddSplit | None:
    """Split ``body`` into its data lines with and without bytes other than number bytes, the
    delimiter and ``\\n``.

    Parameters
    ----------
    body
        Column line, then data lines; every line ends with ``\\n``.
    data_start
        Offset of the first data line (after the column line's ``\\n``).
    delimiter
        Field delimiter.
    max_odd
        More odd lines than this: None (the validating path is then as cheap).

    Returns
    -------
    OddSplit or None
        None when a ``\\r`` is among the data lines (line ends other than ``\\n``), when no
        line or too many lines are odd, or when the body does not end with ``\\n``.
    """
    if not body.endswith(b"\n"):
        return None
    delete = NUMBER_CHARS + delimiter.encode()
    rest = body.translate(None, delete)[len(body[:data_start].translate(None, delete)):]
    if b"\r" in rest:
        return None
    odd = _odd_lines(np.frombuffer(rest, dtype=np.uint8), max_odd)
    if odd is None or odd.size == 0:
        return None
    bounds = line_starts(body, data_start)  # no \r among the data lines: every line ends with \n
    starts, ends = bounds[:-1], bounds[1:]
    head, view = body[:data_start], memoryview(body)
    clean, odd_parts, prev = [head], [head], data_start
    for k in odd.tolist():
        a, b = int(starts[k]), int(ends[k])
        clean.append(view[prev:a])
        odd_parts.append(view[a:b])
        prev = b
    clean.append(view[prev:])
    kept = np.ones(starts.shape[0], dtype=bool)
    kept[odd] = False
    return OddSplit(b"".join(clean), b"".join(odd_parts), np.flatnonzero(kept), odd)


def _odd_lines(rest: np.ndarray, max_odd: int, block: int = 1 << 20) -> np.ndarray | None:
    """The data lines (0-based, increasing, int64) holding a byte of ``rest`` (the data lines' bytes
    less number bytes and delimiters: line ends and odd bytes) other than ``\\n``; None as soon as
    there are more than ``max_odd`` (blocks of ``block`` bytes: a text column stops at the first)."""
    found: list[np.ndarray] = []
    count = lines_before = 0
    for a in range(0, rest.shape[0], block):
        newline = rest[a:a + block] == 0x0A
        at = np.flatnonzero(~newline)
        if at.size:
            lines = np.unique(np.cumsum(newline)[at] + lines_before)  # newlines before each odd byte
            lines = lines[1:] if found and lines[0] == found[-1][-1] else lines  # a line across blocks
            found += [lines] if lines.size else []
            count += lines.size
            if count > max_odd:
                return None
        lines_before += int(np.count_nonzero(newline))
    return np.concatenate(found) if found else np.zeros(0, dtype=np.int64)


_DIGITS_AS_ZERO = bytes(0x30 if 0x30 <= i <= 0x39 else 0x20 for i in range(256))


def long_digit_run(data: bytes, digits: int = 19) -> bool:
    """Whether ``data`` holds ``digits`` or more consecutive ASCII digits (an integer field the
    validating path refuses, at most 18 digits, however small the typed parse finds it)."""
    return b"0" * digits in data.translate(_DIGITS_AS_ZERO)
