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

# the format modules register themselves on import
from ofbe_data.io.formats import generic_csv, mscip_bin, mscip_csv, ofbe_logger  # noqa: E402, F401
from ofbe_data.io.formats.registry import Reader, format_names, read_device_file, register_format

__all__ = ["Reader", "format_names", "read_device_file", "register_format"]
