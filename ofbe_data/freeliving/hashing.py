"""A file read once: its SHA-256 computed from the bytes a reader reads anyway.

``ofbe-autocal`` writes each raw file's SHA-256 in its summary; hashing a week-long file first and
reading it afterwards would go over it twice. :class:`HashingReader` wraps the open file: the
bytes a reader takes in file order are hashed as they go by; a small jump forward (up to
``catch_up`` bytes, e.g. over a file header the reader skips) is read and hashed on the spot; a
larger jump (a ``.cwa`` reader's look at the file's last blocks, ``zipfile`` reading a ``.gt3x``'s
central directory at the end) is left for :meth:`HashingReader.hexdigest`, which reads and hashes
whatever the reader did not take in order. Bytes read out of order are never hashed twice or
left out: the digest is that of the whole file, the same as
:func:`ofbe_data.core.checksums.file_sha256`.

For a ``.gt3x`` (a zip) a strict single pass is impossible: ``zipfile`` reads the central
directory at the end of the file first. It is a few hundred bytes, read again at the end; the
members are read, and hashed, in file order (:attr:`HashingReader.reread_bytes` counts what was
read twice).
"""

from __future__ import annotations

import errno
import hashlib
import io
from typing import BinaryIO

CATCH_UP_BYTES = 1 << 22
"""A forward jump up to this long is read and hashed at once (bytes)."""
TAIL_CHUNK = 1 << 20
"""Bytes read at a time by :meth:`HashingReader.hexdigest`."""


class HashingReader(io.RawIOBase):
    """A seekable binary file whose SHA-256 is computed from what is read through it.

    Parameters
    ----------
    fh
        The file, open for binary reading, at position 0.
    catch_up
        A forward jump up to this many bytes past what is hashed is read and hashed at once.

    Attributes
    ----------
    reread_bytes
        Bytes that :meth:`hexdigest` read itself: those the reader did not take in file order
        (read twice), or never read.
    """

    def __init__(self, fh: BinaryIO, catch_up: int = CATCH_UP_BYTES) -> None:
        super().__init__()
        self._fh = fh
        self._catch_up = catch_up
        self._sha = hashlib.sha256()
        self._hashed = 0  # bytes [0, _hashed) are in the hash
        self._pos = 0  # the reader's position
        self._at = 0  # the underlying file's position
        self._digest: str | None = None
        self.reread_bytes = 0

    # ------------------------------------------------------------------ io.RawIOBase

    def readable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def tell(self) -> int:
        return self._pos

    def seek(self, offset: int, whence: int = io.SEEK_SET) -> int:
        if whence == io.SEEK_SET:
            pos = offset
        elif whence == io.SEEK_CUR:
            pos = self._pos + offset
        elif whence == io.SEEK_END:
            pos = self._fh.seek(0, io.SEEK_END) + offset
            self._at = pos - offset
        else:
            raise ValueError(f"whence: expected 0, 1 or 2, found {whence!r}")
        if pos < 0:  # as a file does (zipfile relies on it for files shorter than a zip's end record)
            raise OSError(errno.EINVAL, f"negative seek position {pos}")
        self._pos = pos
        return pos

    def _raw_read(self, pos: int, n: int) -> bytes:
        if self._at != pos:
            self._fh.seek(pos)
        data = self._fh.read(n) if n >= 0 else self._fh.read()
        self._at = pos + len(data)
        return data

    def read(self, size: int | None = -1) -> bytes:
        n = -1 if size is None else size
        p = self._pos
        gap = p - self._hashed
        if 0 < gap <= self._catch_up:
            self._sha.update(self._raw_read(self._hashed, gap))
            self._hashed = p
        data = self._raw_read(p, n)
        end = p + len(data)
        if p <= self._hashed < end:
            self._sha.update(memoryview(data)[self._hashed - p:])
            self._hashed = end
        self._pos = end
        return data

    def readinto(self, buffer: bytearray | memoryview) -> int:  # type: ignore[override]
        data = self.read(len(buffer))
        memoryview(buffer).cast("B")[: len(data)] = data
        return len(data)

    # ------------------------------------------------------------------ the digest

    def hexdigest(self) -> str:
        """The file's SHA-256 (hex): what was not hashed yet is read now, to the end of the file."""
        if self._digest is None:
            self._fh.seek(self._hashed)
            self._at = self._hashed
            while block := self._fh.read(TAIL_CHUNK):
                self._sha.update(block)
                self.reread_bytes += len(block)
                self._hashed += len(block)
            self._at = self._hashed
            self._digest = self._sha.hexdigest()
        return self._digest
