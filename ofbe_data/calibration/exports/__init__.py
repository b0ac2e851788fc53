"""The calibration formats of ``ofbe-export`` (:data:`CALIBRATION_FORMATS`), one module each: a
:class:`~ofbe_data.calibration.registry.Format` (named, ordered) whose handler turns the parsed
command line into the files to write, with its own options and examples.

SOURCE is a labels folder (``processed/labels/<campaign>``), one ``<session>.parquet``, the JSON
``ofbe-predict`` prints (:mod:`ofbe_data.calibration.results`), or, for ``ggir``, ``json`` and
``imucal``, an ``ofbe-autocal`` output folder (:mod:`ofbe_data.calibration.autocal`, recognised
by its ``summary.parquet``): one file per device and power cycle, per estimate, or per calibrated
recording (``ggir``: one file per run). The conversions are in
:mod:`ofbe_data.calibration.formats`; writing, ``--force`` and ``--store`` are shared
(:mod:`ofbe_data.calibration.output`).

Importing this package imports every public module in it
(:func:`ofbe_data.core.plugins.import_submodules`); each defines its format as ``FORMAT``. A new
calibration format is one new module: no list to edit. :func:`export_formats` is the one registry
of the command: these formats by their ``order``, then those other packages register through the
entry-point group (the model package's ``tflite`` and ``c-header``,
:mod:`ofbe_data.calibration.registry`).

Building the parser imports nothing heavy: each format's handler imports its work (here, from
:mod:`~ofbe_data.calibration.handlers`) when the format runs; its options' defaults and choices
are in :mod:`~ofbe_data.calibration.defaults`.
"""

from __future__ import annotations

from ofbe_data.calibration.defaults import GGIR_DATA, GGIR_DATA_README
from ofbe_data.calibration.registry import ExportRegistryError, Format, Unavailable, plugin_formats
from ofbe_data.core.plugins import import_submodules

__all__ = ["CALIBRATION_FORMATS", "GGIR_DATA", "GGIR_DATA_README", "export_formats", "export_names"]


def _calibration_formats() -> dict[str, Format]:
    """Every ``FORMAT`` of this package's modules, by name, in their order (ties by name).

    Raises
    ------
    ExportRegistryError
        A ``FORMAT`` that is not a named Format, or two of the same name.
    """
    found: dict[str, Format] = {}
    for module in import_submodules(__name__):
        fmt = getattr(module, "FORMAT", None)
        if fmt is None:
            continue
        if not isinstance(fmt, Format) or not fmt.name:
            raise ExportRegistryError(f"{module.__name__}.FORMAT: expected a named Format "
                                      f"(ofbe_data.calibration.registry), found {fmt!r}")
        if fmt.name in found:
            raise ExportRegistryError(f"{module.__name__}.FORMAT: expected a new format name, found "
                                      f"{fmt.name!r}, which another module defines")
        found[fmt.name] = fmt
    return dict(sorted(found.items(), key=lambda item: (item[1].order, item[0])))


CALIBRATION_FORMATS: dict[str, Format] = _calibration_formats()
"""FORMAT → how to export it: this package's calibration formats, in their order."""


def export_formats() -> tuple[dict[str, Format], dict[str, Unavailable]]:
    """Every format of ``ofbe-export``: :data:`CALIBRATION_FORMATS`, then those registered by
    other packages (:func:`ofbe_data.calibration.registry.plugin_formats`), and the registered
    ones that cannot be imported here.

    Raises
    ------
    ExportRegistryError
        A registered format is not a Format, or takes the name of a calibration format.
    """
    plugins, unavailable = plugin_formats()
    clash = sorted(set(plugins) & set(CALIBRATION_FORMATS))
    if clash:
        raise ExportRegistryError(f"entry points {', '.join(clash)}: expected new format names, found "
                                  "names of ofbe's calibration formats")
    return {**CALIBRATION_FORMATS, **plugins}, unavailable


def export_names() -> tuple[str, ...]:
    """The name of every format registered with ``ofbe-export``, those that cannot be imported
    here included (:func:`export_formats`)."""
    formats, unavailable = export_formats()
    return (*formats, *unavailable)
