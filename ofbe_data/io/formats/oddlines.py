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
    rest = body[data_start:].translate(None, NUMBER_CHARS + delimiter.encode())
    if b"\r" in rest:
        return None
    r = np.frombuffer(rest, dtype=np.uint8)
    newline = r == 0x0A
    line_of = np.cumsum(newline) - newline  # data line of every remaining byte
    odd = np.unique(line_of[~newline])
    if odd.size == 0 or odd.size > max_odd:
        return None
    n_lines = int(np.count_nonzero(newline))
    ends = np.flatnonzero(np.frombuffer(body, dtype=np.uint8)[data_start:] == 0x0A) + data_start + 1
    starts = np.concatenate(([data_start], ends[:-1]))
    head = body[:data_start]
    clean, odd_parts, prev = [head], [head], data_start
    for k in odd.tolist():
        a, b = int(starts[k]), int(ends[k])
        clean.append(body[prev:a])
        odd_parts.append(body[a:b])
        prev = b
    clean.append(body[prev:])
    kept = np.setdiff1d(np.arange(n_lines, dtype=np.int64), odd, assume_unique=True)
    return OddSplit(b"".join(clean), b"".join(odd_parts), kept, odd.astype(np.int64))


_DIGITS_AS_ZERO = bytes(0x30 if 0x30 <= i <= 0x39 else 0x20 for i in range(256))


def long_digit_run(data: bytes, digits: int = 19) -> bool:
    """Whether ``data`` holds ``digits`` or more consecutive ASCII digits (an integer field the
    validating path refuses, at most 18 digits, however small the typed parse finds it)."""
    return b"0" * digits in data.translate(_DIGITS_AS_ZERO)
