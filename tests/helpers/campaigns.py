"""Simulated campaigns shared by the test session: built once, read by every module that asks.

Several modules need the same small campaign (the tiny multi-position and gravity-aligned sets,
labelled, for the exports; a free-living one for ``ofbe-autocal``). :func:`shared_campaign`
builds each once per test session, for every pytest-xdist worker together: the first worker to ask
builds it in a folder of the session's base temporary directory that all workers share, under a
file lock, and the others wait for it and read it. The campaign is checked before each use against
the digest taken when it was built, so a test that writes into a shared campaign fails the next
module that reads it, instead of changing what that module tests.

Tests read a shared campaign; what they write goes to their own ``tmp_path``.
"""

from __future__ import annotations

import fcntl
import hashlib
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

__all__ = ["SharedCampaignChanged", "shared_campaign", "tree_digest"]

_DIGEST = ".digest"


class SharedCampaignChanged(AssertionError):
    """A shared campaign's files are not those it was built with: a test wrote into it."""


def tree_digest(folder: Path) -> str:
    """SHA-256 over every file's relative path and bytes under ``folder`` (the digest file left out),
    in sorted order."""
    h = hashlib.sha256()
    for path in sorted(p for p in folder.rglob("*") if p.is_file() and p.name != _DIGEST):
        h.update(str(path.relative_to(folder)).encode() + b"\0")
        h.update(hashlib.sha256(path.read_bytes()).digest())
    return h.hexdigest()


def _shared_root(factory: pytest.TempPathFactory) -> Path:
    """The folder every worker of this session sees: the base temporary directory's parent under
    pytest-xdist (each worker has its own base below it), the base itself otherwise."""
    base = factory.getbasetemp()
    return base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base


def shared_campaign(factory: pytest.TempPathFactory, name: str, build: Callable[[Path], None]) -> Path:
    """The folder ``build`` fills, built once for the whole test session.

    Parameters
    ----------
    factory
        pytest's ``tmp_path_factory`` (session-scoped).
    name
        The campaign's folder name, unique per ``build``.
    build
        Fills the empty folder it is given (simulates, labels…), deterministically.

    Returns
    -------
    Path
        The built folder. Treat it as read-only.

    Raises
    ------
    SharedCampaignChanged
        The folder's files differ from those ``build`` wrote.
    """
    root = _shared_root(factory) / "shared-campaigns"
    root.mkdir(exist_ok=True)
    folder = root / name
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes, also if this process dies
        if not (folder / _DIGEST).is_file():
            partial = root / f"{name}.partial"
            shutil.rmtree(partial, ignore_errors=True)
            shutil.rmtree(folder, ignore_errors=True)
            partial.mkdir()
            build(partial)
            (partial / _DIGEST).write_text(tree_digest(partial))
            partial.rename(folder)
        if tree_digest(folder) != (folder / _DIGEST).read_text():
            raise SharedCampaignChanged(f"{folder}: expected the files it was built with, found them "
                                        "changed: a test wrote into a shared campaign (write to tmp_path "
                                        "instead)")
    return folder
