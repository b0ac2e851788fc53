"""Reading a device file's bytes: the one place every reader reads a file, and the SHA-256
digests a caller can collect there.

Labelling records the hash of every raw file it read. Collecting the digest from the bytes
the reader parsed (:func:`file_digests`) costs one pass over bytes already in memory, where
hashing the file afterwards would read it a second time.
"""

from __future__ import annotations

import hashlib
import mmap
import os
import re
from collections.abc import Iterable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

import numpy as np

from ofbe_data.core.atomic import file_kind
from ofbe_data.core.errors import RawFormatError

MAX_FILE_BYTES = 512 * 2**20
"""Largest device file read (512 MiB: about 8 million text lines of 60 bytes, 15 h at 150 Hz).
A larger one is refused before any of it is read: the parse holds several times the file."""
NUL_RUN = 4096
"""NUL bytes in a row that make a text file's tail preallocated or sparse, not data."""
_SCAN = 1 << 24


def _first_nul_run(path: Path, size: int) -> int | None:
    """Byte offset of the first run of :data:`NUL_RUN` NUL bytes, scanning a memory map in
    blocks (bounded memory), or None."""
    if size < NUL_RUN:
        return None
    needle = b"\0" * NUL_RUN
    with open(path, "rb") as fh, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ) as mm:
        at = mm.find(needle)
    return None if at < 0 else at


def _refuse_nul_tail(path: Path, size: int, nul: int | None) -> None:
    """Raise for a text file whose bytes from ``nul`` on are a NUL-filled tail (None: none)."""
    if nul is not None:
        raise RawFormatError(path, "text data", (
            f"{_mb(size - nul)} from byte {nul} on that start with {NUL_RUN} NUL bytes in a row "
            f"(a preallocated or sparse file: {_mb(nul)} of it is data; keep the first {nul} bytes "
            "in a copy, raw/ stays as it is)"))


def _mb(n: int) -> str:
    return f"{n / 1e6:.1f} MB"


_DIGESTS: ContextVar[dict[Path, str] | None] = ContextVar("ofbe_file_digests", default=None)


def read_file_bytes(path: Path, text: bool = True) -> bytes:
    """A device file's whole contents, in bounded memory for files that are not data.

    Before anything is read: a text file (``text``) holding a run of :data:`NUL_RUN` NUL bytes
    (a logger's preallocated or a sparse tail) is refused with where the data ends, found by
    scanning a memory map; a file over :data:`MAX_FILE_BYTES` is refused with its size. Inside
    :func:`file_digests` the file's SHA-256 is also recorded.

    Raises
    ------
    RawFormatError
        Not a regular file, no such file, unreadable, a NUL-filled tail, or too large.
    """
    kind = file_kind(path)
    if kind is not None:
        raise RawFormatError(path, "a readable data file", kind)
    try:
        size = os.stat(path).st_size
        if size > MAX_FILE_BYTES:  # not read: a NUL tail is looked for in a memory map
            if text:
                _refuse_nul_tail(path, size, _first_nul_run(Path(path), size))
            raise RawFormatError(path, f"a device file of at most {_mb(MAX_FILE_BYTES)} (about 8 million "
                                 "lines, 15 h at 150 Hz)", f"{_mb(size)}: split it into recordings")
        data = path.read_bytes()
        if text:
            at = data.find(b"\0" * NUL_RUN)
            _refuse_nul_tail(path, len(data), None if at < 0 else at)
    except FileNotFoundError:
        raise RawFormatError(path, "a readable data file", "no such file") from None
    except OSError as exc:
        raise RawFormatError(path, "a readable data file", exc.strerror or str(exc)) from None
    digests = _DIGESTS.get()
    if digests is not None:
        digests[Path(path)] = hashlib.sha256(data).hexdigest()
    return data


@contextmanager
def file_digests() -> Iterator[dict[Path, str]]:
    """Collect the hex SHA-256 of every file the readers read inside the block.

    Yields
    ------
    dict
        Path as the reader was given it → hex SHA-256 of the bytes it read, filled as files
        are read (the current thread or task only).
    """
    digests: dict[Path, str] = {}
    token = _DIGESTS.set(digests)
    try:
        yield digests
    finally:
        _DIGESTS.reset(token)


# --------------------------------------------------------------------------- whole-file passes in blocks

SCAN_BLOCK = 1 << 24
"""Bytes a whole-file pass looks at at once (16 MiB): its temporaries are a few times this, not a few
times the file (a 300 MiB file once took 4.8 GB for a per-byte running count)."""
_NOT_BLANK = re.compile(rb"[^ \t\n\r\x0b\x0c]")
_BLANK_BYTES = np.zeros(256, dtype=bool)
_BLANK_BYTES[[0x20, 0x09, 0x0A, 0x0D]] = True


def is_blank(data: bytes) -> bool:
    """``not data.strip()`` without the copy: nothing but ASCII whitespace."""
    return _NOT_BLANK.search(data) is None


def count_lines(data: bytes) -> int:
    """Number of lines as pyarrow splits them (\\n, \\r\\n and lone \\r all end a line)."""
    n = data.count(b"\n") + data.count(b"\r") - data.count(b"\r\n")
    if data and data[-1:] not in (b"\n", b"\r"):
        n += 1
    return n


def marked_line(data: bytes, marker: bytes) -> int:
    """Offset of the first line that starts with ``marker``, or −1."""
    pos = 0
    while True:
        idx = data.find(marker, pos)
        if idx <= 0:
            return idx
        if data[idx - 1 : idx] in (b"\n", b"\r"):
            return idx
        pos = idx + 1


def next_line(data: bytes, offset: int) -> tuple[bytes, int]:
    """The line starting at ``offset`` (without its end) and the offset after it."""
    end = len(data)
    for sep in (b"\n", b"\r"):
        i = data.find(sep, offset)
        if i != -1:
            end = min(end, i)
    nxt = end
    if data[end : end + 2] == b"\r\n":
        nxt = end + 2
    elif end < len(data):
        nxt = end + 1
    return data[offset:end], nxt


def line_starts(data: bytes, start: int = 0) -> np.ndarray:
    """``start`` and the offset after every line end of ``data`` from ``start`` on (``\\n``, ``\\r\\n`` and a
    lone ``\\r``, as pyarrow splits lines): where each line starts, and ``len(data)`` last when ``data``
    ends with a line end; (E + 1,) int64, scanned in blocks of :data:`SCAN_BLOCK` bytes."""
    b = np.frombuffer(data, dtype=np.uint8)
    n, crs = b.shape[0], data.find(b"\r", start) >= 0
    parts = [np.full(1, start, dtype=np.int64)]
    for a in range(start, n, SCAN_BLOCK):
        e = min(n, a + SCAN_BLOCK)
        lf = b[a:min(n, e + 1)] == 0x0A  # one byte more: a \r before a \n ends no line
        ends = lf[:e - a]
        if crs:
            after = lf[1:] if e < n else np.append(lf[1:], False)
            ends = ends | ((b[a:e] == 0x0D) & ~after)
        parts.append(np.flatnonzero(ends) + (a + 1))
    return np.concatenate(parts)


def first_solid_line(data: bytes, starts: np.ndarray, keep: np.ndarray) -> int:
    """The first line that ``keep`` marks and that holds a byte other than a space, tab or line end.

    Parameters
    ----------
    data
        The bytes.
    starts
        (L,) int64, where each line starts (:func:`line_starts` less a final entry at ``len(data)``).
    keep
        (L,) bool, the lines that count.

    Returns
    -------
    int
        Its index, or L when there is none (blocks of bytes from the first marked line on are
        looked at until one holds it).
    """
    n = starts.shape[0]
    if not keep.any():
        return n
    b = np.frombuffer(data, dtype=np.uint8)
    pos, size = int(starts[int(np.argmax(keep))]), 4096
    while pos < b.shape[0]:  # growing blocks: the line is usually among the first bytes looked at
        solid = np.flatnonzero(~_BLANK_BYTES[b[pos:pos + size]]) + pos
        lines = np.searchsorted(starts, solid, side="right") - 1
        hit = np.flatnonzero(keep[lines])
        if hit.size:
            return int(lines[hit[0]])
        pos, size = pos + size, max(1, min(2 * size, SCAN_BLOCK // 16))
    return n


def kept_lines(data: bytes, starts: np.ndarray, keep: np.ndarray, first: int) -> Iterator[bytes | memoryview]:
    """The bytes of the lines that ``keep`` marks, from line ``first`` on, in order: pieces of whole
    lines of about :data:`SCAN_BLOCK` bytes, views of ``data`` where every line is kept.

    Parameters
    ----------
    data
        The bytes.
    starts
        (L,) int64, where each line starts (as :func:`first_solid_line` takes them).
    keep
        (L,) bool, the lines to keep.
    first
        The first line to look at.
    """
    n, view = starts.shape[0], memoryview(data)
    i = first
    while i < n:
        j = min(n, max(i + 1, int(np.searchsorted(starts, starts[i] + SCAN_BLOCK))))
        a, e = int(starts[i]), int(starts[j]) if j < n else len(data)
        marked = keep[i:j]
        if marked.all():
            yield view[a:e]
        elif marked.any():
            lengths = np.diff(np.append(starts[i:j], e))
            block = np.frombuffer(data, dtype=np.uint8, count=e - a, offset=a)
            yield block[np.repeat(marked, lengths)].tobytes()
        i = j


def split_first_line(pieces: Iterable[bytes | memoryview]) -> tuple[bytes, list[bytes | memoryview]]:
    """The bytes of ``pieces`` up to and with their first ``\\n`` (all of them when there is none), and
    the pieces after it."""
    head: list[bytes] = []
    rest: list[bytes | memoryview] = []
    for piece in pieces:
        if rest:
            rest.append(piece)
            continue
        at = bytes(piece).find(b"\n")
        if at < 0:
            head.append(bytes(piece))
        else:
            head.append(bytes(piece[:at + 1]))
            rest.append(piece[at + 1:])
    return b"".join(head), rest
