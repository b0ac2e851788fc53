"""The registry of device file formats: each format module registers its reader here under the
``format`` name session manifests use; :func:`read_device_file` reads a file with the reader its
manifest entry names (the package :mod:`ofbe_data.io.formats` imports every format module, so
importing the package fills the registry)."""

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
