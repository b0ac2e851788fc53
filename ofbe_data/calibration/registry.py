"""The formats of ``ofbe-export``: what a format is (:class:`Format`) and how formats that live
outside this package register themselves (the entry-point group :data:`ENTRY_POINT_GROUP`).

The calibration formats are this package's own, one module each in :mod:`ofbe_data.calibration.exports`
(:data:`~ofbe_data.calibration.exports.CALIBRATION_FORMATS`).
Other packages add theirs without this package importing them: an entry point in their
``pyproject.toml``::

    [project.entry-points."ofbe.export_formats"]
    tflite = "ofbe_model.cli.export_formats:TFLITE"

whose object is a :class:`Format`. :func:`plugin_formats` loads them when the parser is built
(``importlib.metadata``); one whose module cannot be imported (the model package or its
requirements not installed) is absent from the command, and asking for it by name says which
package provides it (:class:`Unavailable`). This is how the model package registers ``tflite``
and ``c-header``. This module imports nothing heavy: ``ofbe-export --help`` builds its parser from
the formats' names, help, options and examples alone, so a format imports what it needs (NumPy,
pandas, TensorFlow) in its handler, when it runs.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from dataclasses import KW_ONLY, dataclass
from importlib import import_module
from importlib.metadata import entry_points
from typing import TYPE_CHECKING

from ofbe_data.core.errors import OfbeError

if TYPE_CHECKING:
    from ofbe_data.calibration.output import ExportFile

PROG = "ofbe-export"
"""The command's name, which its messages begin with."""
ENTRY_POINT_GROUP = "ofbe.export_formats"
"""The entry-point group other packages register their export formats in."""


class ExportRegistryError(OfbeError):
    """An entry point of :data:`ENTRY_POINT_GROUP` is not a format (a packaging mistake)."""


@dataclass(frozen=True)
class Format:
    """An export format: what it makes (``help``), how (``handler``), its own options
    (``options``, added to its ``ofbe-export FORMAT`` parser) and command lines that use it
    (``examples``, shown by ``ofbe-export FORMAT --help``).

    Attributes
    ----------
    handler
        Turns the parsed arguments into the files to write (writing, ``--out``, ``--force``
        and ``--store`` are shared: :func:`ofbe_data.calibration.output.write_outputs`): the
        function, or where it is, ``"module:function"``, imported when the format runs
        (:meth:`files`), so that listing the formats imports none of their work.
    help
        One line: what the format is.
    options
        Adds the format's own options to its parser, or None.
    examples
        Command lines that use the format.
    reads_raw
        Whether the format takes ``--raw`` (the campaign's raw folder).
    name
        ``FORMAT`` on the command line, for a format of this package
        (:mod:`ofbe_data.calibration.exports`); an entry point's format is named by its entry
        point, and a name given here must be the same.
    order
        Where a format of this package comes in ``ofbe-export --help`` and every list of formats:
        ascending, ties by name (the built-in ones take 10–50). The formats of entry points follow
        them, by name.
    """

    handler: Callable[[argparse.Namespace], list[ExportFile]] | str
    help: str
    options: Callable[[argparse.ArgumentParser], None] | None = None
    examples: tuple[str, ...] = ()
    reads_raw: bool = True
    _: KW_ONLY
    name: str = ""
    order: int = 100

    def files(self, args: argparse.Namespace) -> list[ExportFile]:
        """The files this format makes of the parsed arguments (its handler, imported now when
        it is given as ``"module:function"``)."""
        handler = self.handler
        if isinstance(handler, str):
            module, _, function = handler.partition(":")
            handler = getattr(import_module(module), function)
        return handler(args)


@dataclass(frozen=True)
class Unavailable:
    """A format registered by another package whose module cannot be imported here.

    Attributes
    ----------
    name
        The format's name (the entry point's).
    target
        The entry point's object reference, ``module:attribute``.
    reason
        Why the import failed (the ``ImportError``'s message).
    """

    name: str
    target: str
    reason: str

    @property
    def package(self) -> str:
        """The top-level package that provides the format (``ofbe_model``)."""
        return self.target.split(":", 1)[0].split(".", 1)[0]

    @property
    def message(self) -> str:
        """The one line ``ofbe-export NAME`` answers with."""
        what = " (the model package)" if self.package == "ofbe_model" else ""
        return (f"{self.name}: expected the package that provides this format, {self.package}{what}, to be "
                f"importable, found it is not ({self.reason}); install it with its requirements "
                f"(pip install ofbe), or use a calibration format")


def plugin_formats(group: str = ENTRY_POINT_GROUP) -> tuple[dict[str, Format], dict[str, Unavailable]]:
    """The formats other packages register in ``group``, loaded now, sorted by name.

    Returns
    -------
    formats, unavailable
        Name → format, for every entry point whose module imports; name → why not, for the
        others.

    Raises
    ------
    ExportRegistryError
        An entry point's object is not a :class:`Format`.
    """
    formats: dict[str, Format] = {}
    unavailable: dict[str, Unavailable] = {}
    for ep in sorted(entry_points(group=group), key=lambda e: e.name):
        try:
            found = ep.load()
        except ImportError as exc:
            unavailable[ep.name] = Unavailable(ep.name, ep.value, str(exc))
            continue
        if not isinstance(found, Format):
            raise ExportRegistryError(f"entry point {ep.name} = {ep.value!r} of {group}: expected a Format "
                                      f"(ofbe_data.calibration.registry), found {type(found).__name__}")
        if found.name not in ("", ep.name):
            raise ExportRegistryError(f"entry point {ep.name} = {ep.value!r} of {group}: expected a Format "
                                      f"named {ep.name!r} or unnamed, found one named {found.name!r}")
        formats[ep.name] = found
    return formats, unavailable
