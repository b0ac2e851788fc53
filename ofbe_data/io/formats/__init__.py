"""The device file formats behind one registry: a format is one module here.

Each module reads (and writes) one family of files and registers a
:class:`~ofbe_data.io.formats.registry.Format` (its reader, whether it can be a reference IMU's,
how ``ofbe-session init`` recognises it) under the ``format`` name that session manifests use:
``ofbe-logger`` (:mod:`~ofbe_data.io.formats.ofbe_logger`), ``mscip-csv``
(:mod:`~ofbe_data.io.formats.mscip_csv`), ``mscip-bin`` (:mod:`~ofbe_data.io.formats.mscip_bin`)
and the generic ``csv`` (:mod:`~ofbe_data.io.formats.generic_csv`); the parsing machinery they
share is in :mod:`~ofbe_data.io.formats.common`. :func:`read_device_file` reads any file its
manifest entry describes; :func:`formats` lists the formats, and every other list of formats
(the manifest's, ``init``'s, the simulator's reference formats) is derived from it.
docs/architecture.md has the checklist for adding a format. Like the rest of
:mod:`ofbe_data.io`, it may import :mod:`ofbe_data.core` only.
"""

from __future__ import annotations

# The format modules register themselves on import, in this order (the order manifests' error
# messages list the formats in): the native logger, the reference IMU's two formats, and last the
# generic csv, which init takes any text file for that no other format recognises.
# isort: off
from ofbe_data.io.formats import ofbe_logger  # noqa: F401
from ofbe_data.io.formats import mscip_csv  # noqa: F401
from ofbe_data.io.formats import mscip_bin  # noqa: F401
from ofbe_data.io.formats import generic_csv  # noqa: F401
# isort: on
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

__all__ = ["Format", "Reader", "Sniffed", "TextSniffer", "format_names", "formats", "read_device_file",
           "reference_formats", "register_format", "unregister_format"]
