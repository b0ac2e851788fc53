"""One reader per wearable format, each a stream of samples in g with what the file says of its device.

Every reader below reads its file in blocks (memory bounded whatever the file's length) and once:
the file's SHA-256 (:attr:`Wearable.sha256`) comes from the bytes the reader reads
(:mod:`ofbe_data.freeliving.hashing`), not from a second pass.

- Axivity ``.cwa``: ofbe's own block reader, resampled as GGIRread does
  (:mod:`ofbe_data.freeliving.axivity`); bad blocks are named and imputed as GGIR imputes them.
- GENEActiv ``.bin``: ofbe's own page reader (:mod:`ofbe_data.freeliving.geneactiv`): the
  calibrated values GGIRread's and actfast's readers give (``(raw·100 − offset) / gain``,
  float32), each with the temperature of its page; a damaged page is named.
- ActiGraph ``.gt3x``: ofbe's own record reader (:mod:`ofbe_data.freeliving.actigraph`), through
  the zip member: samples rounded to 1 mg half away from zero, as GGIR's ``read.gt3x`` gives them,
  without temperature; a record failing its checksum is named and skipped. Time-stamp gaps
  (ActiGraph's idle-sleep mode writes no samples while asleep) are counted and, as in GGIR,
  closed up.
- csv: any file ofbe's generic reader reads, through the ``session.yaml`` that names it (in its
  folder or up to three folders above) or, without one, ``ofbe-session init``'s detection; the
  samples as read (m/s² back to g with g0 = 9.80665 m/s², raw-formats.md), at the manifest's or
  the measured rate. (The generic reader reads the whole file; its hash is a second pass.)
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

from ofbe_data.core.checksums import file_sha256
from ofbe_data.freeliving.actigraph import Gt3xChunk, Gt3xStream, round_half_away
from ofbe_data.freeliving.axivity import AxivityStream
from ofbe_data.freeliving.blocks import BadBlock, RawFileError
from ofbe_data.freeliving.epochs import is_epoch_csv
from ofbe_data.freeliving.geneactiv import BinChunk, BinStream
from ofbe_data.freeliving.hashing import HashingReader
from ofbe_data.io.detection import Hints, sniff_text
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import MANIFEST_NAME, DeviceSpec, load_manifest
from ofbe_data.io.recording import TEMPERATURE

CWA_FORMAT, BIN_FORMAT, GT3X_FORMAT, CSV_FORMAT = "Axivity CWA", "GENEActiv BIN", "ActiGraph GT3X", "csv"
RAW_SUFFIXES = (".cwa", ".bin", ".gt3x", ".csv")
"""Suffixes :func:`open_wearable` takes (case ignored)."""
CHUNK_SAMPLES = 1 << 18
"""Samples handed on at a time from a file read whole (csv)."""
MANIFEST_LEVELS = 3
"""Folders above a csv searched for the ``session.yaml`` that names it."""

__all__ = ["BIN_FORMAT", "CSV_FORMAT", "CWA_FORMAT", "GT3X_FORMAT", "RAW_SUFFIXES", "BinWearable",
           "CsvWearable", "CwaWearable", "DeviceInfo", "Gt3xWearable", "Samples",
           "Wearable", "local_iso", "open_wearable", "round_half_away", "utc_iso"]


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
    and :attr:`gap_samples` say what was skipped, filled in or missing, and :attr:`sha256` is the
    file's SHA-256 (hex), from the same reading where the format allows.
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
        self.sha256: str | None = None

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
        self.sha256 = self.stream.sha256 or file_sha256(self.path)


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


class _HashedFile:
    """A file open through a :class:`HashingReader` until its samples are read (or its reader fails)."""

    def __init__(self, path: Path) -> None:
        self._raw = open(path, "rb")  # noqa: SIM115 - closed by close(), after the last chunk
        self.reader = HashingReader(self._raw)

    def finish(self) -> str:
        """The file's SHA-256 (what the reader did not take is read now), and close it."""
        try:
            return self.reader.hexdigest()
        finally:
            self.close()

    def close(self) -> None:
        self._raw.close()


class _StreamWearable(Wearable):
    """A wearable read by one of ofbe's block streams (``.bin``, ``.gt3x``) through a
    :class:`_HashedFile`: the stream is opened by :meth:`_open`, each of its chunks becomes
    :class:`Samples` by :meth:`_samples`, and :meth:`_bad` says what it skipped."""

    _file: _HashedFile
    _stream: Any

    def _open(self, path: Path, stream_type: Any) -> None:
        self._file = _HashedFile(path)
        try:
            self._stream = stream_type(path, self._file.reader)
        except BaseException:
            self._file.close()
            raise

    @abstractmethod
    def _samples(self, chunk: Any, time_s: np.ndarray) -> Samples:
        """One chunk of the stream as samples, its times ``time_s`` (s) already converted."""

    @abstractmethod
    def _bad(self) -> tuple[BadBlock, ...]:
        """The pages or records the stream skipped or cut."""

    def chunks(self) -> Iterator[Samples]:
        before: float | None = None
        try:
            for c in self._stream:
                t = c.time_ns.astype(np.float64) / 1e9
                self._count_gaps(t, before)
                before = float(t[-1])
                yield self._samples(c, t)
            self.sha256 = self._file.finish()
        finally:
            self._file.close()
            self.bad_blocks = self._bad()


class BinWearable(_StreamWearable):
    """A GENEActiv ``.bin`` file, page by page (:mod:`ofbe_data.freeliving.geneactiv`).

    Raises
    ------
    RawFileError
        Not a GENEActiv file, a header without calibration or sample rate, or (while reading) a
        page out of the page layout.
    """

    def __init__(self, path: Path) -> None:
        self._open(path, BinStream)
        meta = self._stream.header.metadata
        ident, caps = meta.get("Device Identity", {}), meta.get("Device Capabilities", {})
        conf = meta.get("Configuration Info", {})
        rate = _number(conf.get("Measurement Frequency"))
        if rate is None or not rate > 0:
            self._file.close()
            raise RawFileError(path, "a 'Measurement Frequency' under 'Configuration Info' in the header",
                               "none")
        rng = _number(caps.get("Accelerometer Range"))
        device = f"GENEActiv {ident.get('Device Model', '').strip()}".strip()
        super().__init__(path, DeviceInfo(BIN_FORMAT, device, ident.get("Device Unique Serial Code"),
                                          float(rate), None if rng is None else abs(rng),
                                          _offset_s(conf.get("Time Zone")), True))

    def _samples(self, chunk: BinChunk, time_s: np.ndarray) -> Samples:
        return Samples(time_s, chunk.acc_g.astype(np.float64), chunk.temperature_c.astype(np.float64))

    def _bad(self) -> tuple[BadBlock, ...]:
        return tuple(self._stream.bad_pages)


class Gt3xWearable(_StreamWearable):
    """An ActiGraph ``.gt3x`` file, record by record (:mod:`ofbe_data.freeliving.actigraph`).

    Raises
    ------
    RawFileError
        Not a zip archive with ``info.txt`` and ``log.bin`` (an older NHANES-style file is refused
        with that reason), no whole sample rate, or (while reading) a damaged ``log.bin``.
    """

    def __init__(self, path: Path) -> None:
        self._open(path, Gt3xStream)
        info = self._stream.info
        device = f"ActiGraph {info.get('Device Type', '')}".strip()
        rng = _number(info.get("Acceleration Max"))
        rate = float(self._stream.sample_rate_hz)
        super().__init__(path, DeviceInfo(GT3X_FORMAT, device, info.get("Serial Number"), rate,
                                          None if rng is None else abs(rng), _offset_s(info.get("TimeZone")),
                                          False))

    def _samples(self, chunk: Gt3xChunk, time_s: np.ndarray) -> Samples:
        return Samples(time_s, chunk.acc_g, None)

    def _bad(self) -> tuple[BadBlock, ...]:
        return tuple(self._stream.bad_records)


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
        self.sha256 = file_sha256(path)

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
    """
    p = Path(path)
    suffix = p.suffix.lower()
    if suffix == ".cwa":
        return CwaWearable(p)
    if suffix == ".bin":
        return BinWearable(p)
    if suffix == ".gt3x":
        return Gt3xWearable(p)
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
