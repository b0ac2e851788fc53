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
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

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
