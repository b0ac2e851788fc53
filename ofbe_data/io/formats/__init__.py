"""The device file formats behind one registry: a format is one module here.

Each module reads (and writes) one family of files and registers its reader under the
``format`` name that session manifests use: ``ofbe-logger``
(:mod:`~ofbe_data.io.formats.ofbe_logger`), ``mscip-csv``
(:mod:`~ofbe_data.io.formats.mscip_csv`) and the generic ``csv``
(:mod:`~ofbe_data.io.formats.generic_csv`); the parsing machinery they share is in
:mod:`~ofbe_data.io.formats.common`. :func:`read_device_file` reads any file its manifest
entry describes. docs/architecture.md has the checklist for adding a format. Like the rest of
:mod:`ofbe_data.io`, it may import :mod:`ofbe_data.core` only.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.manifest import DeviceSpec
from ofbe_data.io.recording import Recording

Reader = Callable[[Path, DeviceSpec], Recording]
"""A format's reader: the file and the device's manifest entry → a recording."""

_READERS: dict[str, Reader] = {}


def register_format(name: str, reader: Reader) -> None:
    """Make ``reader`` the reader of manifests' ``format: <name>`` (called by each format module)."""
    _READERS[name] = reader


def format_names() -> tuple[str, ...]:
    """The registered format names, sorted."""
    return tuple(sorted(_READERS))


def read_device_file(path: str | Path, device: DeviceSpec) -> Recording:
    """Read one device file with the reader its manifest entry names.

    Parameters
    ----------
    path
        The file.
    device
        The device's manifest entry (format and, for ``csv``, the mapping).

    Returns
    -------
    Recording

    Raises
    ------
    RawFormatError
        An unknown format, or whatever the format's reader raises.
    """
    reader = _READERS.get(device.format)
    if reader is None:
        raise RawFormatError(path, f"format {', '.join(format_names())}", repr(device.format))
    rec = reader(Path(path), device)
    if not rec.fs_hz > 0:  # NaN: fewer than two samples, or time that never advances
        skipped = rec.diagnostics.skipped_by_kind
        why = ", ".join(f"{n} lines skipped ({k})" for k, n in sorted(skipped.items())) or "nothing skipped"
        raise RawFormatError(path, "at least two samples with increasing time stamps",
                             f"{rec.n} usable sample(s) ({why}; are all time stamps equal?)")
    return rec


# the format modules register themselves on import
from ofbe_data.io.formats import generic_csv, mscip_bin, mscip_csv, ofbe_logger  # noqa: E402, F401
