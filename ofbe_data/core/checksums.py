"""Per-file SHA-256 lists of a pipeline stage's outputs (``checksums/<stage>.sha256``).

DVC's lock file holds one hash per output folder; when a fresh clone on another machine
reproduces a folder with another hash, it does not say which file differs. Each data stage
(``simulate``, ``label``, ``datasets``) therefore also writes the SHA-256 of every file it
made, one ``<sha256>  <path>`` line per file (the format of ``sha256sum``; paths relative to
the repository root, ``/``-separated, sorted), a small text file committed beside
``dvc.lock``. ``sha256sum -c checksums/label.sha256`` (or ``diff`` of two lists) names the
files that differ.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path

from ofbe_data.core.atomic import write_bytes_atomic

CHUNK = 1 << 20
"""Bytes read at a time."""


def file_sha256(path: str | Path) -> str:
    """Hex SHA-256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(CHUNK), b""):
            h.update(block)
    return h.hexdigest()


def sha256_list(roots: Sequence[str | Path], base: str | Path = ".") -> bytes:
    """``<sha256>  <path>`` lines for every file under ``roots`` (a root may be a file).

    Parameters
    ----------
    roots
        Folders (searched recursively) or files.
    base
        Paths are written relative to it (the repository root).

    Returns
    -------
    bytes
        The list, sorted by path, ``\\n``-terminated lines, UTF-8.
    """
    base = Path(base).resolve()
    files: set[Path] = set()
    for root in map(Path, roots):
        if root.is_file():
            files.add(root.resolve())
        elif root.is_dir():
            files.update(p.resolve() for p in root.rglob("*") if p.is_file())
    named = sorted((p.relative_to(base).as_posix(), p) for p in files)
    return "".join(sha256sum_line(file_sha256(p), rel) for rel, p in named).encode("utf-8")


def sha256sum_line(digest: str, name: str) -> str:
    r"""One line of a list ``sha256sum -c`` reads: ``<digest>  <name>\n``.

    A name holding a backslash or a newline is written as GNU coreutils writes it (md5sum.c:
    the line starts with ``\``, the name has ``\`` as ``\\`` and a newline as ``\n``), so a
    raw file named with a newline cannot break the list or name another file.
    """
    if "\\" in name or "\n" in name:
        return "\\" + f"{digest}  " + name.replace("\\", "\\\\").replace("\n", "\\n") + "\n"
    return f"{digest}  {name}\n"


def write_sha256_list(path: str | Path, roots: Sequence[str | Path], base: str | Path = ".") -> Path:
    """Write :func:`sha256_list` of ``roots`` to ``path`` atomically; returns ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(path, sha256_list(roots, base))
    return path
