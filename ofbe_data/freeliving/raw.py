"""Raw wearable files (``.cwa``, ``.bin``, ``.gt3x``, csv of samples) made into epochs as GGIR makes them.

:func:`read_raw_epochs` reads a file chunk by chunk (:mod:`ofbe_data.freeliving.wearables`) and
summarises it into 10-s epochs following GGIR's ``g.calibrate`` (wadpac/GGIR, R/g.calibrate.R,
GGIR 3.x as stored at commit ad173355402e; Apache-2.0; written anew here):

1. **Idle samples out.** Samples whose three axes are exactly 0 are removed before anything else
   (g.calibrate: ``zeros = which(x == 0 & y == 0 & z == 0)``, then ``g.imputeTimegaps(...,
   impute = FALSE)``, which drops them); the samples either side become neighbours.
2. **Whole hours.** g.calibrate reads blocks of about 12 h and keeps, of what it has, only whole
   hours (``use = floor(LD / (3600·sf)) · 3600·sf``); the rest waits for the next block, and
   what is left after the file's last block is never used. So the epochs come from the first
   ``⌊N / (3600·sf)⌋`` hours of the N samples kept. And a file whose first block holds fewer than
   ``2 · 3600 · sf + 1`` samples is "too short" (g.readaccfile, with g.calibrate's ``ws`` of
   3600 s): no epochs at all, so any file under 2 hours (:attr:`RawEpochs.ggir_too_short`).
   (``ggir_whole_hours=False`` keeps every whole epoch instead: only a partial last epoch goes.)
3. **Epochs of ``sf · 10`` samples**, in order (``rollMean``/``rollSD`` with ``calibEpochSize``
   = 10): per axis the mean (GGIR: differences of a cumulative sum; here sums per epoch, equal to
   rounding) and the standard deviation with ``n − 1`` (R's ``sd``), and the mean temperature.
4. **Temperature checks on samples**: GGIR stops using the temperature when the first 10 samples
   of a block average above 120 °C or a block's samples vary by less than 0.01 °C (standard
   deviation); :attr:`RawEpochs.ggir_temperature_ok` applies them to all samples kept.

What ``g.calibrate`` does next (duplicate epochs, the 72-hour rule, still epochs, the fit) is
:func:`ofbe_data.freeliving.ggir.ggir_calibrate`, given ``RawEpochs.epochs``.

Where this cannot be GGIR: GGIR reads a file in pieces of about 12 h, and for ``.cwa`` each piece
is one ``readAxivity`` call whose grid starts afresh at its first block; ofbe reads the file as
one call, so the grid's phase and a few samples at each piece's edge differ (about 14 edges in a
week). GGIR removes zeros piece by piece, and where a piece ends in zeros it also overwrites the
last sample kept with the one before (``g.imputeTimegaps``' ``imputelast``); ofbe removes zeros
only. Csv files are not GGIR's formats: their epochs hold ``round(rate · epoch)`` samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ofbe_data.freeliving.blocks import BadBlock, RawFileError
from ofbe_data.freeliving.epochs import EpochTable
from ofbe_data.freeliving.wearables import Samples, local_iso, open_wearable, utc_iso
from ofbe_data.io.detection import Hints

GGIR_EPOCH_S = 10.0
"""GGIR's ``calibEpochSize``, s."""
GGIR_BLOCK_S = 3600.0
"""GGIR's ``blockResolution``: data are used in whole hours, s."""
TEMPERATURE_MAX_C = 120.0
"""GGIR ignores the temperature when its first 10 samples average above this, °C."""
TEMPERATURE_MIN_SD_C = 0.01
"""… or when its samples vary by less than this (standard deviation), °C."""


@dataclass(frozen=True)
class IdleSleep:
    """Stretches where a device wrote no real samples.

    ActiGraph's idle-sleep mode repeats the last sample while the device sleeps (in its csv
    exports; its ``.gt3x`` files write nothing then: a time-stamp gap); other devices write zeros.

    Attributes
    ----------
    stretches
        Runs of at least one epoch of bit-identical consecutive samples (zeros included).
    samples
        Samples in those runs.
    epochs
        Epochs made whose standard deviation is exactly 0 on every axis (all samples identical).
    gap_stretches
        Time-stamp gaps longer than 1.5 sample periods (samples never written).
    gap_samples
        Samples missing in those gaps (not filled in: the samples either side become neighbours,
        as GGIR reads ``.gt3x`` files).
    """

    stretches: int
    samples: int
    epochs: int
    gap_stretches: int
    gap_samples: int


@dataclass(frozen=True, eq=False)
class RawEpochs:
    """A raw file made into GGIR's epochs, with what the file says of its device.

    Attributes
    ----------
    epochs
        The epochs (GGIR's ``spheredata`` layout, with each epoch's start time).
    path
        The file.
    format
        ``Axivity CWA``, ``GENEActiv BIN``, ``ActiGraph GT3X`` or ``csv``.
    device
        Maker and model, e.g. ``Axivity AX3``.
    serial
        Serial number, when the file has one.
    start_utc
        First sample, ISO 8601 UTC (``2019-02-26T10:55:06.000Z``); None when the file does not
        say how its clock relates to UTC.
    start_local
        First sample on the device clock, ISO 8601 without an offset.
    sample_rate_hz
        Rate of the samples epoched, Hz (for ``.cwa``: the header's rate, resampled to).
    range_g
        Accelerometer range, ±g, when known.
    hours
        Hours of samples read: ``n_samples / sample_rate_hz / 3600``.
    n_samples
        Samples read (after resampling, imputed ones included).
    n_zero_samples
        All-zero samples removed (step 1).
    n_tail_samples
        Samples kept but after the last whole hour (or epoch), not epoched (step 2).
    imputed_samples
        Samples GGIRread's rules filled in (``.cwa``: bad blocks, time jumps).
    bad_blocks
        Blocks skipped, with their number and byte offset (``.cwa``).
    idle_sleep
        Idle-sleep stretches and time-stamp gaps.
    epoch_s
        Epoch length, s.
    ggir_whole_hours
        Whether only whole hours were epoched (GGIR's rule, the default).
    ggir_temperature_ok
        Whether GGIR's sample-level temperature checks pass (None without temperature).
    ggir_too_short
        Fewer than ``2 · 3600 · sf + 1`` samples: GGIR's "file too short" (with
        ``ggir_whole_hours`` the epochs are then none, and ``ggir_calibrate`` says "not enough
        data").
    sha256
        SHA-256 of the file's bytes (hex), computed while the file was read (no second pass for
        ``.cwa``, ``.bin`` and ``.gt3x``; see :mod:`ofbe_data.freeliving.hashing`).
    """

    epochs: EpochTable
    path: str
    format: str
    device: str
    serial: str | None
    start_utc: str | None
    start_local: str | None
    sample_rate_hz: float
    range_g: float | None
    hours: float
    n_samples: int
    n_zero_samples: int
    n_tail_samples: int
    imputed_samples: int
    bad_blocks: tuple[BadBlock, ...]
    idle_sleep: IdleSleep
    epoch_s: float
    ggir_whole_hours: bool
    ggir_temperature_ok: bool | None
    ggir_too_short: bool
    sha256: str | None = None

    @property
    def n_epochs(self) -> int:
        """Number of epochs."""
        return self.epochs.n


def samples_per_epoch(path: str | Path, rate_hz: float, epoch_s: float, exact: bool = True) -> int:
    """``rate · epoch``, which GGIR needs whole (``rollSD`` reshapes by it); rounded when not ``exact``.

    Raises
    ------
    RawFileError
        The product is not a whole number of samples (within 1e-6) when ``exact``, or below 2.
    """
    if not (math.isfinite(epoch_s) and epoch_s > 0):
        raise ValueError(f"epoch_s: expected a positive number of seconds, found {epoch_s!r}")
    n = rate_hz * epoch_s
    if (exact and abs(n - round(n)) > 1e-6) or round(n) < 2:
        raise RawFileError(path, "a sample rate × epoch length that is a whole number of samples "
                                 "(at least 2)", f"{rate_hz:g} Hz × {epoch_s:g} s = {n:g}")
    return int(round(n))


@dataclass
class _Runs:
    """Runs of at least ``min_len`` (≥ 2) bit-identical consecutive samples, counted as the chunks
    go by."""

    min_len: int
    last: np.ndarray | None = None
    open_len: int = 0
    stretches: int = 0
    samples: int = 0

    def _close(self, length: int) -> None:
        if length >= self.min_len:
            self.stretches += 1
            self.samples += length

    def add(self, acc: np.ndarray) -> None:
        """Next samples, shape (3, n)."""
        n = acc.shape[1]
        if n == 0:
            return
        same = np.empty(n, dtype=np.int8)  # sample i equals sample i - 1
        same[0] = self.last is not None and bool(np.all(acc[:, 0] == self.last))
        same[1:] = (acc[0, 1:] == acc[0, :-1]) & (acc[1, 1:] == acc[1, :-1]) & (acc[2, 1:] == acc[2, :-1])
        edges = np.diff(same, prepend=np.int8(0), append=np.int8(0))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
        lengths = ends - starts + 1  # run of samples s - 1 … e - 1
        if len(starts) and starts[0] == 0:  # continues the run open at the end of the last chunk
            lengths[0] = self.open_len + ends[0]
        else:
            self._close(self.open_len)
        still_open = bool(len(ends) and ends[-1] == n)
        closed = lengths[:-1] if still_open else lengths
        long = closed[closed >= self.min_len]
        self.stretches += len(long)
        self.samples += int(long.sum())
        self.open_len = int(lengths[-1]) if still_open else 1
        self.last = acc[:, -1].copy()

    def finish(self) -> None:
        if self.last is not None:
            self._close(self.open_len)
        self.open_len = 0


@dataclass
class _TemperatureCheck:
    """GGIR's two sample-level temperature checks, on running sums (Chan et al.'s merge)."""

    first: list[float]
    n: int = 0
    mean: float = 0.0
    m2: float = 0.0

    def add(self, temp: np.ndarray) -> None:
        if len(temp) == 0:
            return
        if len(self.first) < 10:
            self.first.extend(float(v) for v in temp[: 10 - len(self.first)])
        nb, mb = len(temp), float(np.mean(temp))
        m2b = float(np.sum((temp - mb) ** 2))
        delta = mb - self.mean
        total = self.n + nb
        self.mean += delta * nb / total
        self.m2 += m2b + delta**2 * self.n * nb / total
        self.n = total

    def ok(self) -> bool:
        if not self.first or np.mean(self.first) > TEMPERATURE_MAX_C:
            return False
        return not (self.n > 1 and math.sqrt(self.m2 / (self.n - 1)) < TEMPERATURE_MIN_SD_C)


class GgirEpochs:
    """Steps 1–3 of the module docstring, fed chunk by chunk.

    Parameters
    ----------
    per_epoch
        Samples per epoch.
    has_temperature
        Whether the chunks carry a temperature.
    min_idle_run
        Identical samples in a row that count as an idle-sleep stretch.
    """

    def __init__(self, per_epoch: int, has_temperature: bool, min_idle_run: int) -> None:
        self.per_epoch = per_epoch
        self.has_temperature = has_temperature
        self.runs = _Runs(min_idle_run)
        self.temp_check = _TemperatureCheck([])
        self.n_samples = self.n_zero = self.n_kept = 0
        self._left = (np.zeros((3, 0)), np.zeros(0), np.zeros(0))
        self._parts: list[tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]] = []

    def add(self, chunk: Samples) -> None:
        """Take the next samples (in time order)."""
        acc, t = chunk.acc_g, chunk.time_s
        n = acc.shape[1]
        self.n_samples += n
        self.runs.add(acc)
        zero = (acc[0] == 0.0) & (acc[1] == 0.0) & (acc[2] == 0.0)
        temp = chunk.temperature_c if self.has_temperature and chunk.temperature_c is not None else None
        if zero.any():
            keep = ~zero
            self.n_zero += int(zero.sum())
            acc, t = acc[:, keep], t[keep]
            temp = None if temp is None else temp[keep]
        if temp is not None:
            self.temp_check.add(temp)
        self.n_kept += acc.shape[1]
        left_acc, left_temp, left_t = self._left
        acc_all = np.concatenate([left_acc, acc], axis=1)
        t_all = np.concatenate([left_t, t])
        temp_all = np.concatenate([left_temp, temp]) if temp is not None else None
        m = acc_all.shape[1] // self.per_epoch
        used = m * self.per_epoch
        if m:
            block = acc_all[:, :used].reshape(3, m, self.per_epoch)
            mean = block.mean(axis=2)
            sd = np.sqrt(np.sum((block - mean[:, :, None]) ** 2, axis=2) / (self.per_epoch - 1))
            tm = temp_all[:used].reshape(m, self.per_epoch).mean(axis=1) if temp_all is not None else None
            self._parts.append((mean.T.copy(), sd.T.copy(), tm, t_all[:used:self.per_epoch].copy()))
        self._left = (acc_all[:, used:].copy(), np.zeros(0) if temp_all is None else temp_all[used:].copy(),
                      t_all[used:].copy())

    def finish(self, keep_epochs: int | None) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, np.ndarray]:
        """Means, sds (shape (n, 3), g), temperatures (shape (n,), °C, or None) and start times
        (shape (n,), s) of the first ``keep_epochs`` epochs (all when None)."""
        self.runs.finish()
        mean = np.concatenate([p[0] for p in self._parts]) if self._parts else np.zeros((0, 3))
        sd = np.concatenate([p[1] for p in self._parts]) if self._parts else np.zeros((0, 3))
        t = np.concatenate([p[3] for p in self._parts]) if self._parts else np.zeros(0)
        temps = [p[2] for p in self._parts if p[2] is not None]
        temp = np.concatenate(temps) if temps else (np.zeros(0) if self.has_temperature else None)
        k = len(mean) if keep_epochs is None else min(keep_epochs, len(mean))
        return mean[:k], sd[:k], None if temp is None else temp[:k], t[:k]


def whole_hour_epochs(n_kept: int, rate_hz: float, per_epoch: int) -> int:
    """Epochs GGIR makes from ``n_kept`` samples: those of the whole hours (step 2)."""
    per_hour = int(round(GGIR_BLOCK_S * rate_hz))
    return (n_kept // per_hour) * per_hour // per_epoch


def read_raw_epochs(path: str | Path, epoch_s: float = GGIR_EPOCH_S, *,
                    ggir_whole_hours: bool = True, csv_hints: Hints | None = None) -> RawEpochs:
    """Read a raw wearable file and summarise it into epochs as GGIR's ``g.calibrate`` does.

    Parameters
    ----------
    path
        An Axivity ``.cwa``, GENEActiv ``.bin``, ActiGraph ``.gt3x`` (each read in blocks by
        ofbe's own readers) or a csv of samples ofbe's generic reader reads.
    epoch_s
        Epoch length, s (GGIR: 10); ``sample rate × epoch_s`` must be a whole number.
    ggir_whole_hours
        True (GGIR): epochs only from whole hours of samples, the rest left out; False: every
        whole epoch.
    csv_hints
        For a csv without a manifest: what to tell its detection (``ofbe-session init``'s
        ``--rate``, ``--unit``…) where the file alone does not settle it.

    Returns
    -------
    RawEpochs
        The epochs and the file's metadata. A file too short or too still for a calibration is
        not an error: its epochs go to :func:`~ofbe_data.freeliving.ggir.ggir_calibrate`, which
        says so in its QC message.

    Raises
    ------
    RawFileError
        Not a file of those formats, or one its reader cannot read (the message names the file,
        and the byte offset where there is one).
    RawFormatError, ManifestError, DetectionError
        A csv that the generic reader, its manifest or the detection refuse.
    OSError
        The file cannot be opened.
    """
    p = Path(path)
    wearable = open_wearable(p, csv_hints)
    info = wearable.info
    per_epoch = samples_per_epoch(p, info.sample_rate_hz, epoch_s, wearable.exact_rate)
    maker = GgirEpochs(per_epoch, info.has_temperature, per_epoch)
    first_t: float | None = None
    for chunk in wearable.chunks():
        if first_t is None and len(chunk.time_s) and wearable.absolute_clock:
            first_t = float(chunk.time_s[0])
        maker.add(chunk)
    too_short = maker.n_samples < 2 * GGIR_BLOCK_S * info.sample_rate_hz + 1
    keep = None
    if ggir_whole_hours:
        keep = 0 if too_short else whole_hour_epochs(maker.n_kept, info.sample_rate_hz, per_epoch)
    mean, sd, temp, t = maker.finish(keep)
    epochs = EpochTable(path=str(p), mean_g=mean, sd_g=sd, temperature_c=temp, time_s=t)
    idle = IdleSleep(stretches=maker.runs.stretches, samples=maker.runs.samples,
                     epochs=int(np.sum(np.all(sd == 0.0, axis=1))),
                     gap_stretches=wearable.gap_stretches, gap_samples=wearable.gap_samples)
    return RawEpochs(
        epochs=epochs, path=str(p), format=info.format, device=info.device, serial=info.serial,
        start_utc=None if first_t is None else utc_iso(first_t, info.utc_offset_s),
        start_local=None if first_t is None else local_iso(first_t),
        sample_rate_hz=info.sample_rate_hz, range_g=info.range_g,
        hours=maker.n_samples / info.sample_rate_hz / 3600.0, n_samples=maker.n_samples,
        n_zero_samples=maker.n_zero, n_tail_samples=maker.n_kept - epochs.n * per_epoch,
        imputed_samples=wearable.imputed_samples, bad_blocks=wearable.bad_blocks, idle_sleep=idle,
        epoch_s=float(epoch_s), ggir_whole_hours=ggir_whole_hours,
        ggir_temperature_ok=maker.temp_check.ok() if info.has_temperature else None, ggir_too_short=too_short,
        sha256=wearable.sha256,
    )
