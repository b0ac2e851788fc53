"""The registry of device file formats, the one list every other list is derived from.

Each format module registers a :class:`Format` here: the ``format`` name session manifests use,
its reader, whether a device of it can be the reference IMU of a rotated session, and, for a
text format with a signature line, how ``ofbe-session init`` recognises a file of it. The
manifest's format names (:func:`ofbe_data.io.manifest.format_choices`), the reference formats
of ``init`` and of the simulator (:func:`reference_formats`) and ``init``'s sniffing
(:mod:`ofbe_data.io.detection`) all ask :func:`formats`. :func:`read_device_file` reads a file
with the reader its manifest entry names. The package :mod:`ofbe_data.io.formats` imports every
format module, so importing the package fills the registry.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.device_options import DeviceSpec
from ofbe_data.io.recording import Recording

Reader = Callable[[Path, DeviceSpec], Recording]
"""A format's reader: the file and the device's manifest entry → a recording."""


@dataclass(frozen=True, kw_only=True)
class Sniffed:
    """What a text format's signature line says about a file (for ``ofbe-session init``).

    Attributes
    ----------
    evidence
        Why the file is of the format, naming the line (e.g. ``'# ofbe-logger' header at line 1``).
    model
        The device model the header states, or None.
    model_evidence
        Where the model was read (e.g. ``header chip=ADXL345``).
    rate_note
        The nominal rate as the header states it, quoted beside the measured rate; None: none.
    """

    evidence: str
    model: str | None = None
    model_evidence: str = ""
    rate_note: str | None = None


TextSniffer = Callable[[Sequence[str], int], Sniffed | None]
"""A text format's sniffer: a file's lines and the index of one of its first 300 lines (0-based)
→ what the line, if it is the format's signature line, and the lines after it say; None when the
line is not its signature."""


@dataclass(frozen=True, kw_only=True)
class Format:
    """One device file format.

    Attributes
    ----------
    name
        The ``format`` value of manifests (``ofbe-logger``, ``csv``…).
    reader
        Reads one file of a device of this format.
    reference
        Whether a device of this format can be the reference IMU of a rotated session (``init``
        takes one as the reference; the simulator writes its reference in these formats).
    signature
        What identifies a file of the format to ``init`` (e.g. ``'# ofbe-logger' header``), in the
        evidence of a file that is none of them; None: no signature line.
    sniff
        Recognises the signature line (:data:`TextSniffer`); None for a format ``init`` finds
        otherwise (a binary stream, or the generic csv every other text file is).
    order
        Where the format comes in every list of formats (the manifest's error messages, the order
        ``init`` tries the sniffers in): ascending, ties by name. The built-in formats take 10–30,
        the generic csv, which ``init`` takes any other text file for, :data:`LAST`; a new format
        left at the default comes after the built-in ones and before the generic csv.
    """

    name: str
    reader: Reader
    reference: bool = False
    signature: str | None = None
    sniff: TextSniffer | None = None
    order: int = 100


LAST = 1000
"""The :attr:`Format.order` of the generic csv, the fallback listed last."""


_FORMATS: dict[str, Format] = {}


def register_format(fmt: Format) -> Format:
    """Make ``fmt`` the format of manifests' ``format: <fmt.name>`` (called by each format module;
    registering a name again replaces its format in place)."""
    _FORMATS[fmt.name] = fmt
    return fmt


def unregister_format(name: str) -> None:
    """Remove a registered format (a plug-in's, or a test's toy format); no error when absent."""
    _FORMATS.pop(name, None)


def formats() -> tuple[Format, ...]:
    """The registered formats by :attr:`Format.order` (ties by name): the order the manifest's error
    messages list them in and ``init`` tries their sniffers in."""
    return tuple(sorted(_FORMATS.values(), key=lambda f: (f.order, f.name)))


def format_names() -> tuple[str, ...]:
    """The registered format names, sorted."""
    return tuple(sorted(_FORMATS))


def reference_formats() -> tuple[str, ...]:
    """Names of the formats a reference IMU's files come in (:attr:`Format.reference`), in the order
    of :func:`formats`."""
    return tuple(f.name for f in formats() if f.reference)


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
    fmt = _FORMATS.get(device.format)
    if fmt is None:
        raise RawFormatError(path, f"format {', '.join(format_names())}", repr(device.format))
    rec = fmt.reader(Path(path), device)
    if not rec.fs_hz > 0:  # NaN: fewer than two samples, or time that never advances
        skipped = rec.diagnostics.skipped_by_kind
        why = ", ".join(f"{n} lines skipped ({k})" for k, n in sorted(skipped.items())) or "nothing skipped"
        raise RawFormatError(path, "at least two samples with increasing time stamps",
                             f"{rec.n} usable sample(s) ({why}; are all time stamps equal?)")
    return rec
