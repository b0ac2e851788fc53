"""Writing an export's files: to ``--out`` (a file, or a folder built whole under a temporary
name) and to a calibration store (``--store``, :mod:`ofbe_data.calibration.store`), every
target checked before any is written, and whatever this call made removed again when a later
write fails (``ofbe-export``, :mod:`ofbe_data.cli.export`)."""

from __future__ import annotations

import os
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from ofbe_data.calibration.store import CalibrationStoreError, store_path
from ofbe_data.core.atomic import atomic_directory, write_bytes_atomic
from ofbe_data.core.errors import OfbeError, OutputExistsError

FILE_SUFFIXES = frozenset({".json", ".yaml", ".yml", ".csv", ".h", ".tflite"})
"""Suffixes that make ``--out`` a file name (an error when there are several results)."""


class ExportUsageError(OfbeError):
    """The command line asks for something the format cannot do (exit status 2)."""


@dataclass(frozen=True)
class ExportFile:
    """One file an export writes.

    Attributes
    ----------
    name
        Its name inside ``--out`` when that is a folder.
    data
        Its bytes.
    device, when, store_format
        Where ``--store`` files it (``store_format`` a key of
        :data:`ofbe_data.calibration.formats.FORMAT_EXTENSIONS`); None: not filed.
    out
        Whether it goes to ``--out`` (False: a file for ``--store`` only).
    """

    name: str
    data: bytes
    device: str | None = None
    when: datetime | None = None
    store_format: str | None = None
    out: bool = True


def written_time() -> datetime:
    """Now, UTC, whole seconds (``SOURCE_DATE_EPOCH`` when set, for reproducible files)."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH")
    if epoch and epoch.strip().isdigit():
        return datetime.fromtimestamp(int(epoch), tz=UTC)
    return datetime.now(UTC).replace(microsecond=0)



# ----------------------------------------------------------------------------- writing


def _out_targets(files: Sequence[ExportFile], out: Path, force: bool, folder: bool = False
                 ) -> tuple[list[tuple[Path, bytes]], bool]:
    """(path, bytes) to write for ``--out`` and whether ``out`` is a new folder to build whole
    (``folder``: the user wrote ``--out`` with a trailing slash, a folder even for one file)."""
    names = [f.name for f in files]
    if len(set(names)) != len(names):
        raise CalibrationStoreError(f"{out}: two files of this export share a name: "
                                    f"{sorted({n for n in names if names.count(n) > 1})}")
    if out.is_dir():
        targets = [(out / f.name, f.data) for f in files]
    elif folder and not out.exists():
        return [(out / f.name, f.data) for f in files], True
    elif len(files) == 1:
        targets = [(out, files[0].data)]
    else:
        if out.exists() or out.suffix in FILE_SUFFIXES:
            raise ExportUsageError(f"{out}: expected a folder for {len(files)} files "
                                   f"({', '.join(names[:3])}{', …' if len(names) > 3 else ''}), found "
                                   f"{'an existing file' if out.exists() else 'a file name'}; give a folder")
        return [(out / f.name, f.data) for f in files], True
    if not force:
        for path, _ in targets:
            if path.exists():
                raise OutputExistsError(path)
    return targets, False


def _store_targets(files: Sequence[ExportFile], store: Path, force: bool) -> list[tuple[Path, bytes]]:
    targets: dict[Path, ExportFile] = {}
    for f in files:
        if f.device is None or f.store_format is None:
            continue
        if f.when is None:
            raise CalibrationStoreError(f"{f.name}: expected a recording time to file it in {store}, "
                                        "found none")
        path = store_path(store, f.device, f.when, f.store_format)
        if path in targets:
            when = ("minute (imucal's own store names keep minutes only)" if f.store_format == "imucal"
                    else "time")
            raise CalibrationStoreError(
                f"{path}: {targets[path].name} and {f.name} would be filed under the same device and {when}; "
                "pass --raw so that each is filed at its own recording's start time")
        if path.exists() and not force:
            raise OutputExistsError(path)
        targets[path] = f
    return [(p, f.data) for p, f in targets.items()]


def write_outputs(files: Sequence[ExportFile], out: Path | None, store: Path | None, force: bool,
                  out_is_folder: bool = False) -> list[Path]:
    """Write every file to ``--out`` and ``--store``; check every target before writing any.

    ``out_is_folder``: ``--out`` names a folder even for one file (written with a trailing slash).
    """
    if not files:
        raise CalibrationStoreError("nothing to export")
    to_out = [f for f in files if f.out]
    out_targets, new_folder = (([], False) if out is None or not to_out
                               else _out_targets(to_out, out, force, out_is_folder))
    store_targets = _store_targets(files, store, force) if store is not None else []
    for path, _ in ([] if new_folder else out_targets) + store_targets:
        _check_folder_for(path)
    written: list[Path] = []
    made: list[Path] = []  # files and folders this call created, removed again if a later write fails
    try:
        if new_folder and out is not None:
            with atomic_directory(out) as tmp:
                for path, data in out_targets:
                    target = tmp / path.relative_to(out)
                    target.parent.mkdir(parents=True, exist_ok=True)
                    target.write_bytes(data)
            written.append(out)
            made.append(out)
        else:
            for path, data in out_targets:
                made += _new_folders(path.parent) + ([] if path.exists() else [path])
                path.parent.mkdir(parents=True, exist_ok=True)
                write_bytes_atomic(path, data)
                written.append(path)
        for path, data in store_targets:
            made += _new_folders(path.parent) + ([] if path.exists() else [path])
            path.parent.mkdir(parents=True, exist_ok=True)
            write_bytes_atomic(path, data)
            written.append(path)
    except BaseException:
        for path in reversed(made):  # newest first: files before the folders that hold them
            if path.is_dir() and not path.is_symlink():
                shutil.rmtree(path, ignore_errors=True)
            else:
                path.unlink(missing_ok=True)
        raise
    return written


def _new_folders(folder: Path) -> list[Path]:
    """The folders ``folder.mkdir(parents=True)`` would create, outermost first."""
    missing = []
    while not folder.exists() and folder != folder.parent:
        missing.append(folder)
        folder = folder.parent
    return missing[::-1]


def _check_folder_for(path: Path) -> None:
    """Refuse, before anything is written, a target whose folder cannot be made: the nearest
    existing ancestor of its folder must be a folder (not a file)."""
    missing = _new_folders(path.parent)
    folder = missing[0].parent if missing else path.parent  # the nearest that exists
    if not folder.is_dir():
        raise CalibrationStoreError(f"{path}: expected {folder} to be a folder to write into, found a file")
