"""Reading a device file's bytes: the one place every reader reads a file, and the SHA-256
digests a caller can collect there.

Labelling records the hash of every raw file it read. Collecting the digest from the bytes
the reader parsed (:func:`file_digests`) costs one pass over bytes already in memory, where
hashing the file afterwards would read it a second time.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path

from ofbe_data.core.atomic import file_kind
from ofbe_data.core.errors import RawFormatError

_DIGESTS: ContextVar[dict[Path, str] | None] = ContextVar("ofbe_file_digests", default=None)


def read_file_bytes(path: Path) -> bytes:
    """A device file's whole contents.

    Inside :func:`file_digests` the file's SHA-256 is also recorded.

    Raises
    ------
    RawFormatError
        Not a regular file, no such file, or unreadable.
    """
    kind = file_kind(path)
    if kind is not None:
        raise RawFormatError(path, "a readable data file", kind)
    try:
        data = path.read_bytes()
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
