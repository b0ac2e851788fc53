"""One reader per wearable format, each a stream of samples in g with what the file says of its device.

- Axivity ``.cwa``: ofbe's own block reader, resampled as GGIRread does
  (:mod:`ofbe_data.freeliving.axivity`); bad blocks are named and imputed as GGIR imputes them.
- GENEActiv ``.bin`` and ActiGraph ``.gt3x``: the ``actfast`` package (MIT; an optional extra,
  ``pip install 'ofbe[wearables]'``), which reads the whole file at once. GENEActiv samples are
  the calibrated values GGIRread's reader gives (``(raw·100 − offset) / gain``, float32), each
  with the temperature of its page; ActiGraph samples are rounded to 1 mg half away from zero, as
  GGIR's ``read.gt3x`` gives them, and have no temperature. Time-stamp gaps (ActiGraph's
  idle-sleep mode writes no samples while asleep) are counted and, as in GGIR, closed up.
- csv: any file ofbe's generic reader reads, through the ``session.yaml`` that names it (in its
  folder or up to three folders above) or, without one, ``ofbe-session init``'s detection; the
  samples as read (m/s² back to g with g0 = 9.80665 m/s², raw-formats.md), at the manifest's or
  the measured rate.
"""

from __future__ import annotations

import math
import re
from abc import ABC, abstractmethod
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ofbe_data.core.errors import OfbeError
from ofbe_data.freeliving.axivity import AxivityStream
from ofbe_data.freeliving.blocks import BadBlock, RawFileError
from ofbe_data.freeliving.epochs import is_epoch_csv
from ofbe_data.io.detect import sniff_text
from ofbe_data.io.detect_result import Hints
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import MANIFEST_NAME, DeviceSpec, load_manifest
from ofbe_data.io.recording import TEMPERATURE

CWA_FORMAT, BIN_FORMAT, GT3X_FORMAT, CSV_FORMAT = "Axivity CWA", "GENEActiv BIN", "ActiGraph GT3X", "csv"
ACTFAST_FORMATS = {".bin": BIN_FORMAT, ".gt3x": GT3X_FORMAT}
"""The formats read through actfast, by file suffix."""
RAW_SUFFIXES = (".cwa", ".bin", ".gt3x", ".csv")
"""Suffixes :func:`open_wearable` takes (case ignored)."""
CHUNK_SAMPLES = 1 << 18
"""Samples handed on at a time from a file read whole."""
GT3X_DECIMALS = 3
"""GGIR's ``read.gt3x`` gives ActiGraph samples rounded to 1 mg."""
MANIFEST_LEVELS = 3
"""Folders above a csv searched for the ``session.yaml`` that names it."""
INSTALL_HINT = "pip install 'ofbe[wearables]'"


class MissingReaderError(OfbeError):
    """A raw file needs an optional package that is not installed.

    Parameters
    ----------
    path
        The file.
    fmt
        Its format.
    """

    def __init__(self, path: str | Path, fmt: str) -> None:
        self.path = Path(path)
        super().__init__(f"{path}: reading a {fmt} file needs the actfast package, which is not installed; "
                         f"install it with: {INSTALL_HINT}")


@dataclass(frozen=True)
class DeviceInfo:
    """What a file says of its device.

    Attributes
    ----------
    format
        ``Axivity CWA``, ``GENEActiv BIN``, ``ActiGraph GT3X`` or ``csv``.
    device
        Maker and model, e.g. ``Axivity AX3``.
    serial
        Serial number, when the file has one.
    sample_rate_hz
        Rate of the samples handed on, Hz (the resampled rate for ``.cwa``).
    range_g
        Accelerometer range, ±g, when known.
    utc_offset_s
        Device clock minus UTC, s, when the file says.
    has_temperature
        Whether the samples come with a temperature.
    """

    format: str
    device: str
    serial: str | None
    sample_rate_hz: float
    range_g: float | None
    utc_offset_s: float | None
    has_temperature: bool


@dataclass(frozen=True, eq=False)
class Samples:
    """Consecutive samples of one file.

    Attributes
    ----------
    time_s
        Shape (n,): device clock, s since 1970 read as UTC (csv: the file's own time axis).
    acc_g
        Shape (3, n): acceleration, g, one row per axis of the device, uncalibrated.
    temperature_c
        Shape (n,): temperature, °C, or None.
    """

    time_s: np.ndarray
    acc_g: np.ndarray
    temperature_c: np.ndarray | None


class Wearable(ABC):
    """A wearable file open for reading: :attr:`info`, then :meth:`chunks` once.

    After the chunks are read, :attr:`bad_blocks`, :attr:`imputed_samples`, :attr:`gap_stretches`
    and :attr:`gap_samples` say what was skipped, filled in or missing.
    """

    exact_rate = True
    """Whether ``rate · epoch`` must be a whole number of samples (device formats: GGIR's rule)."""

    def __init__(self, path: Path, info: DeviceInfo, absolute_clock: bool = True) -> None:
        self.path = path
        self.info = info
        self.absolute_clock = absolute_clock
        self.bad_blocks: tuple[BadBlock, ...] = ()
        self.imputed_samples = 0
        self.gap_stretches = 0
        self.gap_samples = 0

    @abstractmethod
    def chunks(self) -> Iterator[Samples]:
        """The file's samples, in order, a bounded block at a time."""

    def _count_gaps(self, time_s: np.ndarray, before: float | None) -> None:
        """Count time-stamp gaps longer than 1.5 sample periods and the samples missing in them."""
        t = time_s if before is None else np.concatenate([[before], time_s])
        dt = np.diff(t)
        gaps = dt[dt > 1.5 / self.info.sample_rate_hz]
        self.gap_stretches += len(gaps)
        self.gap_samples += int(np.sum(np.round(gaps * self.info.sample_rate_hz) - 1))


class CwaWearable(Wearable):
    """An Axivity ``.cwa`` file, resampled as GGIRread does."""

    def __init__(self, path: Path) -> None:
        self.stream = AxivityStream(path)
        h = self.stream.header
        super().__init__(path, DeviceInfo(CWA_FORMAT, f"Axivity {h.hardware}", str(h.device_id),
                                          h.sample_rate_hz, h.range_g,
                                          None if h.time_zone_min is None else 60.0 * h.time_zone_min, True))

    def chunks(self) -> Iterator[Samples]:
        for c in self.stream:
            acc = c.values[3:6] if len(c.values) >= 6 else c.values[:3]
            yield Samples(c.time_s, acc, c.temperature_c)
        self.bad_blocks = self.stream.bad_blocks
        self.imputed_samples = self.stream.imputed_rows


def _actfast() -> Any:
    try:
        import actfast
    except ImportError:
        return None
    return actfast


def _number(text: str | None) -> float | None:
    """The first number in ``text`` (``"85.7 Hz"`` → 85.7, ``"-8 to 8"`` → −8), or None."""
    m = re.search(r"[-+]?\d+(?:[.,]\d+)?", text or "")
    return float(m.group().replace(",", ".")) if m else None


def _offset_s(text: str | None) -> float | None:
    """``GMT +01:00`` or ``-05:00:00`` → seconds east of UTC; None when not given."""
    m = re.search(r"([-+]?)(\d{1,2}):(\d{2})(?::(\d{2}))?", text or "")
    if not m:
        return None
    sign = -1.0 if m.group(1) == "-" else 1.0
    return sign * (int(m.group(2)) * 3600 + int(m.group(3)) * 60 + int(m.group(4) or 0))


def round_half_away(x: np.ndarray, decimals: int) -> np.ndarray:
    """Round to ``decimals`` places, halves away from zero (C's ``round``, as ``read.gt3x``)."""
    scale = 10.0**decimals
    return np.sign(x) * np.floor(np.abs(x) * scale + 0.5) / scale


class ActfastWearable(Wearable):
    """A GENEActiv ``.bin`` or ActiGraph ``.gt3x`` file, read whole through actfast.

    Raises
    ------
    MissingReaderError
        actfast is not installed.
    RawFileError
        actfast cannot read the file, or it holds no acceleration.
    """

    def __init__(self, path: Path, fmt: str) -> None:
        reader = _actfast()
        if reader is None:
            raise MissingReaderError(path, fmt)
        try:
            data = reader.read(str(path))
        except (ValueError, RuntimeError) as exc:
            raise RawFileError(path, f"a readable {fmt} file", f"{exc}") from None
        meta: dict[str, dict[str, str]] = data.get("metadata", {})
        series = data.get("timeseries", {})
        if fmt == BIN_FORMAT:
            high, low = series.get("high_frequency", {}), series.get("low_frequency", {})
            ident, caps = meta.get("Device Identity", {}), meta.get("Device Capabilities", {})
            conf = meta.get("Configuration Info", {})
            rate = _number(conf.get("Measurement Frequency"))
            device = f"GENEActiv {ident.get('Device Model', '')}".strip()
            serial, rng = ident.get("Device Unique Serial Code"), _number(caps.get("Accelerometer Range"))
            offset = _offset_s(conf.get("Time Zone"))
            self._temp = (low.get("datetime"), low.get("temperature"))
        else:
            high = series.get("acceleration", {})
            info = meta.get("info", {})
            rate = _number(info.get("Sample Rate"))
            device = f"ActiGraph {info.get('Device Type', '')}".strip()
            serial, rng, offset = info.get("Serial Number"), _number(info.get("Acceleration Max")), \
                _offset_s(info.get("TimeZone"))
            self._temp = (None, None)
        acc, when = high.get("acceleration"), high.get("datetime")
        if acc is None or when is None or len(acc) == 0:
            raise RawFileError(path, f"acceleration samples in a {fmt} file", "none")
        if rate is None or not rate > 0:
            raise RawFileError(path, "the sample rate in the file's header", "none")
        self._acc, self._when = acc, when
        has_temp = self._temp[1] is not None and len(self._temp[1]) > 0
        super().__init__(path, DeviceInfo(fmt, device, serial, float(rate), None if rng is None else abs(rng),
                                          offset, has_temp))

    def chunks(self) -> Iterator[Samples]:
        before: float | None = None
        page_t, page_temp = self._temp
        for a in range(0, len(self._acc), CHUNK_SAMPLES):
            b = min(a + CHUNK_SAMPLES, len(self._acc))
            t = self._when[a:b].astype(np.float64) / 1e9
            acc = np.ascontiguousarray(self._acc[a:b].T, dtype=np.float64)
            if self.info.format == GT3X_FORMAT:
                acc = round_half_away(acc, GT3X_DECIMALS)
            temp = None
            if self.info.has_temperature and page_t is not None and page_temp is not None:
                page = np.clip(np.searchsorted(page_t, self._when[a:b], side="right") - 1, 0, len(page_t) - 1)
                temp = page_temp[page].astype(np.float64)
            self._count_gaps(t, before)
            before = float(t[-1])
            yield Samples(t, acc, temp)
        self._acc = self._when = np.zeros(0)  # let the whole-file arrays go


class CsvWearable(Wearable):
    """A csv file of samples, read with ofbe's generic reader (see the module docstring).

    Its epochs hold ``round(rate · epoch)`` samples (a measured rate is seldom a whole number
    of samples per epoch). ``hints`` are detection's command-line hints (``--rate``, ``--unit``…,
    for a file the detection does not settle alone); a manifest's entry wins.

    Raises
    ------
    RawFormatError, ManifestError, DetectionError
        As the generic reader, the manifest or the detection raise them.
    """

    exact_rate = False

    def __init__(self, path: Path, hints: Hints | None = None) -> None:
        if is_epoch_csv(path):
            raise RawFileError(path, "a csv of samples", "an epoch csv (columns meanx … sdz): read it with "
                                                         "ofbe_data.freeliving.read_epoch_csv")
        spec, model = _csv_spec(path, hints)
        rec = read_device_file(path, spec)
        rate = rec.nominal_rate_hz if rec.nominal_rate_hz else rec.fs_hz
        self._t = np.asarray(rec.t, dtype=np.float64)
        self._acc = np.ascontiguousarray(np.asarray(rec.acc, dtype=np.float64).T) / G0
        temp = rec.extra.get(TEMPERATURE)
        usable = temp is not None and bool(np.all(np.isfinite(temp)))
        self._temp = np.asarray(temp, dtype=np.float64) if usable else None
        absolute = bool(self._t.size and self._t[0] > 1e8)  # Unix seconds, not a clock from 0
        offset = 0.0 if rec.start_utc is not None and absolute else None
        super().__init__(path, DeviceInfo(CSV_FORMAT, f"csv ({model})", None, float(rate), None, offset,
                                          self._temp is not None), absolute)
        self.gap_stretches = len(rec.diagnostics.gaps)
        self.gap_samples = int(rec.diagnostics.missing_samples)

    def chunks(self) -> Iterator[Samples]:
        for a in range(0, len(self._t), CHUNK_SAMPLES):
            b = a + CHUNK_SAMPLES
            yield Samples(self._t[a:b], self._acc[:, a:b], None if self._temp is None else self._temp[a:b])


def _csv_spec(path: Path, hints: Hints | None) -> tuple[DeviceSpec, str]:
    """The device entry that reads ``path``: from a ``session.yaml`` naming it, else detected."""
    target = path.resolve()
    folder = target.parent
    for _ in range(MANIFEST_LEVELS + 1):
        if (folder / MANIFEST_NAME).is_file():
            manifest = load_manifest(folder)
            for recording in manifest.recordings:
                for device, rel in recording.files.items():
                    if (manifest.folder / rel).resolve() == target:
                        spec = manifest.devices[device]
                        return spec, spec.model
        folder = folder.parent
    det = sniff_text(path, hints or Hints())
    model = det.model or "unknown"
    return DeviceSpec("autocal", model, "dut", det.format, csv=det.mapping), model


def open_wearable(path: str | Path, hints: Hints | None = None) -> Wearable:
    """Open a raw wearable file by its suffix (``.cwa``, ``.bin``, ``.gt3x``, ``.csv``); ``hints``
    (what ``ofbe-session init`` takes on its command line) go to a csv's detection.

    Raises
    ------
    RawFileError
        An unknown suffix, or a file its reader cannot read.
    MissingReaderError
        A ``.bin`` or ``.gt3x`` file without actfast installed.
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".cwa":
        return CwaWearable(p)
    if suffix in ACTFAST_FORMATS:
        return ActfastWearable(p, ACTFAST_FORMATS[suffix])
    if suffix == ".csv":
        return CsvWearable(p, hints)
    raise RawFileError(p, f"a raw wearable file ({', '.join(RAW_SUFFIXES)})",
                       f"a {suffix or 'suffix-less'} file")


def utc_iso(device_s: float, utc_offset_s: float | None) -> str | None:
    """ISO 8601 UTC time (``…Z``, to the millisecond) of a device-clock time, or None."""
    if utc_offset_s is None or not math.isfinite(device_s):
        return None
    return _iso(device_s - utc_offset_s) + "Z"


def local_iso(device_s: float) -> str:
    """ISO 8601 device-clock time without an offset, to the millisecond."""
    return _iso(device_s)


def _iso(seconds: float) -> str:
    ms = int(round(seconds * 1000.0))
    stamp = np.datetime64(ms, "ms")
    return str(stamp)
