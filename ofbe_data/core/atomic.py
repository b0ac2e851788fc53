"""Write files and folders atomically: to a temporary name beside the target, then rename.

A Ctrl-C may come at any instant: the few steps that must not be cut in two (making a temporary
file or folder and keeping its name for the clean-up, renaming outputs into place, removing what
an interrupted run made) run with Ctrl-C held off (:func:`interrupts_deferred`), so that an
interrupted run leaves whole files and folders or none, and no temporary name behind.
"""

from __future__ import annotations

import errno
import os
import shutil
import signal
import stat
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _default_mode(path: Path, directory: bool) -> None:
    """Give a temporary file or folder the permissions a plain create would (mkstemp and
    mkdtemp make them private to the owner)."""
    os.chmod(path, (0o777 if directory else 0o666) & ~_umask())


WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EIO, errno.EFBIG})
"""The ``errno`` values of a failed write (a full disk, a quota, an I/O error)."""


def is_write_failure(exc: BaseException) -> bool:
    """Whether ``exc`` is a failed write: an ``OSError`` whose errno is in :data:`WRITE_ERRNOS`."""
    return isinstance(exc, OSError) and exc.errno in WRITE_ERRNOS


def _against(exc: OSError, path: Path) -> OSError:
    """``exc`` naming ``path``: a write on a descriptor names no file, and the kernel's copy
    names its source; a user wants the file that could not be written."""
    return OSError(exc.errno, exc.strerror, str(path))


def copy_file(src: str | Path, dst: str | Path) -> None:
    """``shutil.copyfile``, with a failed write (:func:`is_write_failure`) naming ``dst``."""
    try:
        shutil.copyfile(src, dst)
    except OSError as exc:
        if is_write_failure(exc):
            raise _against(exc, Path(dst)) from exc
        raise


_HELD = (signal.SIGINT, signal.SIGTERM)
"""The signals :func:`interrupts_deferred` holds off where a Python handler takes them: Ctrl-C, and
the SIGTERM with which a pool stops its workers (:mod:`ofbe_data.core.parallel`)."""


@contextmanager
def interrupts_deferred() -> Iterator[None]:
    """Hold Ctrl-C (SIGINT) off while the block runs, then deliver it: a Ctrl-C meanwhile raises
    ``KeyboardInterrupt`` (or whatever the handler in force does) as the block ends, never inside.
    SIGTERM is held the same way where a Python handler takes it (in a pool's workers).

    SIGINT is also blocked in this thread while the block runs, and a blocked signal stays
    blocked in a process started from it (the mask survives ``fork`` and ``exec``): a worker
    process started here cannot be interrupted before it ignores Ctrl-C itself
    (:func:`ofbe_data.core.worker_setup.init_worker`). Outside the main thread, or where no Python
    handler takes the signals (Ctrl-C ignored in a worker), nothing changes.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = {s: h for s in _HELD if callable(h := signal.getsignal(s))}
    if not held:
        yield
        return
    caught: list[int] = []

    def hold(signum: int, _frame: Any) -> None:
        caught.append(signum)

    for s in held:
        signal.signal(s, hold)
    try:
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT}) if signal.SIGINT in held else None
        try:
            yield
        finally:
            if mask is not None:
                signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # one pending is held now
    finally:
        for s, handler in held.items():
            signal.signal(s, handler)
        for s in dict.fromkeys(caught):
            signal.raise_signal(s)  # to the handler in force: KeyboardInterrupt here


def write_bytes_atomic(path: str | Path, data: bytes) -> None:
    """Write ``data`` to ``path`` so that readers see either the old file or the new one.

    Parameters
    ----------
    path
        Target file; its folder must exist.
    data
        File contents.
    """
    path = Path(path)
    tmp, fh = None, None
    try:
        with interrupts_deferred():  # the temporary file and its name here, or neither
            fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
            fh = os.fdopen(fd, "wb")
        with fh:
            fh.write(data)
        _default_mode(Path(tmp), directory=False)
        os.replace(tmp, path)
    except BaseException as exc:
        if fh is not None:
            fh.close()
        if tmp is not None:
            with interrupts_deferred():
                Path(tmp).unlink(missing_ok=True)
        if isinstance(exc, OSError) and exc.filename is None:  # a write on the descriptor names no file
            raise _against(exc, path) from exc
        raise


@contextmanager
def atomic_directory(target: str | Path, *, replace: bool = False) -> Iterator[Path]:
    """Build a folder under a temporary name and move it to ``target`` on success.

    Parameters
    ----------
    target
        Final folder. Its parent is created if needed.
    replace
        Whether an existing ``target`` may be replaced (it is removed only after the new
        folder is complete).

    Yields
    ------
    Path
        The temporary folder to fill. On an exception (Ctrl-C included) it is removed and
        ``target`` is left untouched; a Ctrl-C while the folder is moved into place (and an
        old one removed) waits for the move to end, so ``target`` is then whole.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp: Path | None = None
    try:
        with interrupts_deferred():  # the temporary folder and its name here, or neither
            tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent))
            _default_mode(tmp, directory=True)
        yield tmp
        with interrupts_deferred():
            if target.exists():
                if not replace:
                    raise FileExistsError(target)
                old = target.with_name(f".{target.name}.old-{os.getpid()}")
                os.replace(target, old)
                os.replace(tmp, target)
                shutil.rmtree(old)
            else:
                os.replace(tmp, target)
    except BaseException:
        if tmp is not None:
            with interrupts_deferred():
                shutil.rmtree(tmp, ignore_errors=True)
        raise


def file_kind(path: str | Path) -> str | None:
    """None for a regular file (or a link to one), else what ``path`` is: "a directory",
    "a FIFO (named pipe)", "a socket", "a device", or "no such file".

    Readers check this before they open a file: opening a FIFO blocks until someone writes to
    it, and reading a device may never end.
    """
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return "no such file"
    if stat.S_ISREG(mode):
        return None
    if stat.S_ISDIR(mode):
        return "a directory"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "a device or other special file"


def folders_under(root: str | Path) -> set[Path]:
    """``root`` and every folder under it that exists now (empty when ``root`` does not)."""
    root = Path(root)
    if not root.is_dir():
        return set()
    return {root, *(p for p in root.rglob("*") if p.is_dir())}


def remove_new_empty_folders(root: str | Path, before: set[Path]) -> None:
    """Remove the folders under ``root`` (and ``root``) that were not in ``before`` and are
    empty, deepest first: what a failed run made and left with nothing in it."""
    for folder in sorted(folders_under(root) - before, key=lambda p: len(p.parts), reverse=True):
        try:
            folder.rmdir()
        except OSError:  # not empty (or gone): kept
            pass
