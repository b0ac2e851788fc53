"""The device file formats behind one registry: a format is one module here.

Each module reads (and writes) one family of files and registers a
:class:`~ofbe_data.io.formats.registry.Format` (its reader, whether it can be a reference IMU's,
how ``ofbe-session init`` recognises it) under the ``format`` name that session manifests use:
``ofbe-logger`` (:mod:`~ofbe_data.io.formats.ofbe_logger`), ``mscip-csv``
(:mod:`~ofbe_data.io.formats.mscip_csv`), ``mscip-bin`` (:mod:`~ofbe_data.io.formats.mscip_bin`)
and the generic ``csv`` (:mod:`~ofbe_data.io.formats.generic_csv`); the parsing machinery they
share is in :mod:`~ofbe_data.io.formats.common`. :func:`read_device_file` reads any file its
manifest entry describes; :func:`formats` lists the formats, and every other list of formats
(the manifest's, ``init``'s, the simulator's reference formats) is derived from it, in each
format's own order (:attr:`Format.order`).

Importing this package imports every public module in it
(:func:`ofbe_data.core.plugins.import_submodules`), so a new format is one new module that calls
:func:`register_format`: no list to edit (docs/architecture.md has the checklist). Like the rest
of :mod:`ofbe_data.io`, it may import :mod:`ofbe_data.core` only.
"""

from __future__ import annotations

from ofbe_data.core.plugins import import_submodules
from ofbe_data.io.formats.registry import (
    Format,
    Reader,
    Sniffed,
    TextSniffer,
    format_names,
    formats,
    read_device_file,
    reference_formats,
    register_format,
    unregister_format,
)

# each format module registers its format when imported: adding a format is adding its module
import_submodules(__name__)

__all__ = ["Format", "Reader", "Sniffed", "TextSniffer", "format_names", "formats", "read_device_file",
           "reference_formats", "register_format", "unregister_format"]
