"""When the device files a recording names are one file.

Two devices of one recording may read one file only when each reads its own acceleration
columns (two triads of a generic csv, raw-formats.md); one file may serve one recording only.
Both rules compare *files*, not names: ``link.csv`` (a symbolic or hard link to ``both.csv``)
is ``both.csv``, so a link cannot make two devices read the same columns (:func:`file_identity`).
"""

from __future__ import annotations

import os
from pathlib import Path

from ofbe_data.io.device_options import CsvMapping

AXES = ("ax", "ay", "az")


def file_identity(path: str | Path, name: str) -> str:
    """What makes two file names one file: the device and inode of ``path`` where it exists
    (links resolved by the system), else ``name`` normalised.

    Parameters
    ----------
    path
        The file as the process opens it.
    name
        Its name as written (relative to the session folder).
    """
    try:
        st = os.stat(path)
    except OSError:
        return os.path.normpath(name)
    return f"inode {st.st_dev}:{st.st_ino}"


def same_file_note(name: str, other: str) -> str:
    """`` (the same file as 'b.csv', through a link)`` when two names of one file differ, else ``""``."""
    if os.path.normpath(name) == os.path.normpath(other):
        return ""
    return f" (the same file as {other!r}, through a link)"


def distinct_columns(a: CsvMapping | None, b: CsvMapping | None) -> bool:
    """Whether two devices read different acceleration columns of one file (both generic csv)."""
    if a is None or b is None:
        return False
    return not {a.columns[k] for k in AXES} & {b.columns[k] for k in AXES}
