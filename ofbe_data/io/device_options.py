"""How a device file is read, as its manifest entry says: the device entry (:class:`DeviceSpec`),
the generic ``csv`` mapping and the ``mscip-bin`` options (raw-formats.md, "Generic csv" and
"mscip-bin").

The records live here, apart from the manifest's validation (:mod:`ofbe_data.io.manifest`),
so that the format registry and its readers (:mod:`ofbe_data.io.formats`), which the manifest
asks for the format names, and the detector of ``ofbe-session init`` share them without an
import cycle. The options records' fields are the keys a device entry of their format may hold
(:data:`FORMAT_OPTIONS`, :func:`option_keys`). The session kinds (:data:`KINDS`) are here too, so
that ``ofbe-session``'s parser offers them without importing the format registry.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ofbe_data.io.typedconfig import record_keys

KINDS = ("gravity-aligned", "rotated", "multi-position")
"""A session's ``kind`` (:mod:`ofbe_data.io.manifest`)."""
TIME_UNITS = ("s", "ms", "us", "ns", "samples")
ACC_UNITS = ("m/s2", "g", "mg", "counts")
TEMPERATURE_UNITS = ("C", "K", "F")
GYRO_UNITS = ("rad/s", "deg/s")
WHITESPACE = "whitespace"
"""``delimiter`` value for runs of spaces and/or tabs."""
COLUMN_KEYS = ("t", "ax", "ay", "az", "temperature", "gx", "gy", "gz")
GYRO_KEYS = ("gx", "gy", "gz")
"""Optional angular-rate columns: all three or none (Kalibr's gyroscope noise is read from them)."""


@dataclass(frozen=True)
class CsvMapping:
    """How to read a generic ``csv`` device file (raw-formats.md, "Generic csv").

    Attributes
    ----------
    columns
        Column for ``ax``, ``ay``, ``az`` and optionally ``t``, ``temperature`` and the
        angular rate ``gx``, ``gy``, ``gz`` (all three): names, or 0-based indices when
        ``header`` is false.
    time_unit
        ``s``, ``ms``, ``us``, ``ns`` or ``samples`` (an index; t = index / rate).
    acc_unit
        ``m/s2``, ``g``, ``mg`` or ``counts``.
    lsb_per_g
        Counts per g per axis (x, y, z); required when ``acc_unit`` is ``counts``.
    skip_rows
        Lines to skip before the column line (or the first data line without a header).
    delimiter
        Field delimiter, one character, or ``whitespace``.
    header
        Whether a column-name line follows the skipped rows.
    comment
        Lines starting with this string are skipped anywhere (None: no comments).
    sample_rate_hz
        Nominal rate, Hz: the time base for ``samples`` or a missing ``t``; otherwise
        compared with the measured rate (a warning beyond 2 %).
    zero_counts
        Counts at zero specific force per axis (counts only; 32768 for unsigned
        offset-binary ADCs).
    temperature_unit
        ``C``, ``K`` or ``F``.
    range_g
        Full-scale range, g: readings at ±range_g are saturated (None: found from the data).
    gyro_unit
        ``rad/s`` or ``deg/s``: unit of the ``gx``/``gy``/``gz`` columns.
    sort_by_time
        Read the rows in the order of their time stamps (a file sorted by another column, e.g.
        annotated by part); False: rows whose time does not increase are dropped and counted.
    """

    columns: dict[str, str | int]
    time_unit: str = "s"
    acc_unit: str = "m/s2"
    lsb_per_g: tuple[float, float, float] | float | None = None
    skip_rows: int = 0
    delimiter: str = ","
    header: bool = True
    comment: str | None = None
    sample_rate_hz: float | None = None
    zero_counts: tuple[float, float, float] | float = 0.0
    temperature_unit: str = "C"
    range_g: float | None = None
    gyro_unit: str = "rad/s"
    sort_by_time: bool = False

    def lsb_axes(self) -> np.ndarray:
        """Counts per g per axis, (3,) (ones when not counts)."""
        if self.lsb_per_g is None:
            return np.ones(3)
        return np.broadcast_to(np.asarray(self.lsb_per_g, dtype=np.float64), (3,)).copy()

    def zero_axes(self) -> np.ndarray:
        """Counts at zero specific force per axis, (3,)."""
        return np.broadcast_to(np.asarray(self.zero_counts, dtype=np.float64), (3,)).copy()

    def to_dict(self) -> dict[str, Any]:
        """The manifest keys (defaults left out)."""
        out: dict[str, Any] = {"columns": dict(self.columns)}
        if not self.header:
            out["header"] = False
        if self.skip_rows:
            out["skip_rows"] = self.skip_rows
        if self.delimiter != ",":
            out["delimiter"] = self.delimiter
        if self.comment is not None:
            out["comment"] = self.comment
        out["time_unit"] = self.time_unit
        if self.sample_rate_hz is not None:
            out["sample_rate_hz"] = self.sample_rate_hz
        out["acc_unit"] = self.acc_unit
        for key in ("lsb_per_g", "zero_counts"):
            value = getattr(self, key)
            if value is None or (key == "zero_counts" and not np.any(self.zero_axes())):
                continue
            out[key] = [float(x) for x in value] if isinstance(value, tuple) else float(value)
        if "temperature" in self.columns and self.temperature_unit != "C":
            out["temperature_unit"] = self.temperature_unit
        if self.range_g is not None:
            out["range_g"] = self.range_g
        if "gx" in self.columns and self.gyro_unit != "rad/s":
            out["gyro_unit"] = self.gyro_unit
        if self.sort_by_time:
            out["sort_by_time"] = True
        return out


@dataclass(frozen=True)
class BinOptions:
    """Options of an ``mscip-bin`` device entry (raw-formats.md, "mscip-bin").

    Attributes
    ----------
    sample_rate_hz
        Time base when the stream has no time sub-packets, Hz (None: from the stream).
    acc_unit
        Unit of the accelerometer sub-packet: ``g`` (default), ``mg`` or ``m/s2``.
    """

    sample_rate_hz: float | None = None
    acc_unit: str = "g"

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {}
        if self.sample_rate_hz is not None:
            out["sample_rate_hz"] = self.sample_rate_hz
        if self.acc_unit != "g":
            out["acc_unit"] = self.acc_unit
        return out


@dataclass(frozen=True)
class DeviceSpec:
    """One device of a session (an entry under ``devices`` of ``session.yaml``).

    Attributes
    ----------
    id
        Device id (key under ``devices``).
    model
        Model name, e.g. ``ADXL345``.
    role
        ``dut`` (gets labels) or ``reference``.
    format
        File format of its recordings (a name of :func:`ofbe_data.io.formats.format_names`).
    reference_to_sensor
        (3, 3) nominal rotation taking reference-frame vectors to this sensor's frame, or
        None when not given (identity assumed where needed).
    csv
        Column/unit mapping for ``format: csv``.
    bin
        Options for ``format: mscip-bin``.
    """

    id: str
    model: str
    role: str
    format: str
    reference_to_sensor: np.ndarray | None = None
    csv: CsvMapping | None = None
    bin: BinOptions | None = None

    def to_dict(self) -> dict[str, Any]:
        """The manifest keys of the entry (its id is the key it stands under)."""
        out: dict[str, Any] = {"model": self.model, "role": self.role, "format": self.format}
        if self.reference_to_sensor is not None:
            out["reference_to_sensor"] = matrix_to_list(self.reference_to_sensor)
        if self.csv is not None:
            out.update(self.csv.to_dict())
        if self.bin is not None:
            out.update(self.bin.to_dict())
        return out


def matrix_to_list(m: np.ndarray) -> list[list[float | int]]:
    """A matrix as nested lists for YAML, whole numbers as ints: (R, C) → R lists of C numbers."""
    rows: list[list[float | int]] = []
    for row in np.asarray(m, dtype=float):
        rows.append([int(v) if float(v).is_integer() else float(v) for v in row])
    return rows


FORMAT_OPTIONS: dict[str, Any] = {"csv": CsvMapping, "mscip-bin": BinOptions}
"""The options record of each device format that has one: its fields are keys of that format's
manifest entries, beside ``model``, ``role``, ``format`` and ``reference_to_sensor``."""


def option_keys(fmt: str | None) -> frozenset[str]:
    """Keys of the options of a device entry of format ``fmt``; of every format when None."""
    if fmt is None:
        return frozenset().union(*(record_keys(r) for r in FORMAT_OPTIONS.values()))
    return record_keys(FORMAT_OPTIONS[fmt]) if fmt in FORMAT_OPTIONS else frozenset()


def option_key_paths(prefix: str) -> dict[str, tuple[str, ...]]:
    """Each options key, and each key of ``columns``, with its path and the formats that have it.

    Parameters
    ----------
    prefix
        Path of a device entry, e.g. ``devices.<id>.``.

    Returns
    -------
    dict
        E.g. ``sample_rate_hz`` → ``("devices.<id>.sample_rate_hz with format: csv or mscip-bin",)``.
    """
    formats: dict[str, list[str]] = {}
    for fmt, record in FORMAT_OPTIONS.items():
        for key in sorted(record_keys(record)):
            formats.setdefault(key, []).append(fmt)
    out = {k: (f"{prefix}{k} with format: {' or '.join(f)}",) for k, f in formats.items()}
    columns = " or ".join(formats["columns"])
    out.update({k: (f"{prefix}columns.{k} with format: {columns}",) for k in COLUMN_KEYS})
    return out
