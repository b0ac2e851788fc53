"""Session-file detection: what the files of a session folder are, from the files alone, for
``ofbe-session init`` (and the wearable readers of ``ofbe-autocal``).

For one file, :func:`sniff_text` finds its format (a registered format's signature line,
:func:`ofbe_data.io.formats.formats`; an MSCIP binary stream; else a generic csv) and, for a
generic csv, every key of its manifest entry, each :class:`Decision` with its evidence, in a
:class:`Detection`; :class:`Hints` is what the command line says. For a folder,
:func:`data_files`, :func:`assign_devices`, :func:`group_recordings`, :func:`init_devices` and
:func:`power_cycle_of` find its data files, devices, recordings and power cycle. Nothing is
guessed: a case the files do not settle raises :class:`DetectionError` (one file; the message
names the flag to give) or :class:`SessionFilesError` (the folder).

The public names are these; the modules behind them are private (a module outside this package
imports from here only):

- ``_sniff``: one file, end to end, read back through the reader ``ofbe-session check`` uses;
- ``_layout``: delimiter, preamble, comment prefix, column line and unit row; the numbers;
- ``_names``, ``_columns``: the columns from their names, or from their positions and values;
- ``_time``, ``_units``: the time unit and rate; the acceleration, angular-rate and
  temperature units;
- ``_banner``: a model and range stated in the preamble;
- ``_result``: the records (hints, decisions, parts, the detection);
- ``_session``: a folder's files together (devices, recordings, power cycle).

Part of :mod:`ofbe_data.io`: it may import :mod:`ofbe_data.core` and :mod:`ofbe_data.io` only.
"""

from __future__ import annotations

from ofbe_data.io.detection._result import Decision, Detection, Hints, Part, show_value
from ofbe_data.io.detection._session import (
    DATA_SUFFIXES,
    DeviceEntry,
    SessionFilesError,
    assign_devices,
    data_files,
    group_recordings,
    init_devices,
    power_cycle_of,
    sanitise,
)
from ofbe_data.io.detection._sniff import sniff_text
from ofbe_data.io.detection._units import DetectionError, fmt_num, quiet_mean

__all__ = [
    "DATA_SUFFIXES",
    "Decision",
    "Detection",
    "DetectionError",
    "DeviceEntry",
    "Hints",
    "Part",
    "SessionFilesError",
    "assign_devices",
    "data_files",
    "fmt_num",
    "group_recordings",
    "init_devices",
    "power_cycle_of",
    "quiet_mean",
    "sanitise",
    "show_value",
    "sniff_text",
]
