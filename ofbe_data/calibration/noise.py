"""The raw recordings behind labels: their start times and the noise of their stationary segments.

A label row names its raw file (``raw_file``, relative to the session folder), the file's
SHA-256 and the stationary interval used (``segment_start_s``/``segment_end_s`` on the
device's clock). Given the campaign's raw folder, :class:`RawFiles` reads those files with
the toolkit's validating readers (the format from the session's manifest) and checks that
they are the bytes that were labelled.

Noise for Kalibr (:func:`noise_from_segments`): the overlapping Allan deviation of every
stationary segment of a (device, power cycle), pooled tau by tau over the segments that hold
at least :data:`MIN_CLUSTERS` clusters of it
(:func:`ofbe_data.labelling.allan.pooled_allan_deviation`: the longest segment sets the longest
tau, the short poses of a multi-position calibration add to the short tau only), gives the
white-noise density N from the tau^(−1/2) branch, ADEV(tau) = N/√tau, i.e. the deviation read at
tau = 1 s (σ(1 s) = N, m/s²/√Hz; σ_sample = N·√f_s). A bias random walk K
(m/s³/√Hz, ADEV(tau) = K·√(tau/3)) is read only where the curve is seen to turn up: the Allan
minimum at tau ≥ :data:`RW_MIN_TAU_S` with at least :data:`RW_MIN_TAUS` averaging times beyond it,
and a free slope beyond the minimum within :data:`RW_SLOPE` (+1/2 expected). Otherwise only an
upper bound is known (:func:`random_walk_bound`): the largest K that the Allan curve's upper
:data:`RW_BOUND_CONFIDENCE` confidence limit allows at any tau (χ² with the degrees of freedom
of the clusters pooled at that tau), since a random walk alone would put ADEV(tau) at
K·√(tau/3) or more.

The same analysis runs on a recording's gyroscope columns where it has them
(:meth:`~ofbe_data.io.recording.Recording.gyro`, rad/s): N in rad/s/√Hz, K in rad/s²/√Hz.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from datetime import UTC
from pathlib import Path

import numpy as np
from scipy import stats

from ofbe_data.calibration.results import (
    TIME_RAW,
    CalibrationExportError,
    CalibrationResult,
    CalibrationSourceError,
    Collected,
    Segment,
    attach_file_times,
)
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.manifest import SessionManifest, load_manifest
from ofbe_data.io.recording import Recording
from ofbe_data.labelling.allan import AllanResult, pooled_allan_deviation, white_noise_level
from ofbe_data.labelling.labels import sha256_file

MIN_CLUSTERS = 3
"""Fewest clusters (segment length / tau) a segment must hold at a tau to be pooled there; the
longest tau analysed is a third of the longest segment."""
RW_MIN_TAU_S = 2.0
"""The Allan minimum must lie at tau ≥ this many seconds for a random walk to be read beyond it."""
RW_MIN_TAUS = 3
"""Averaging times needed beyond the minimum to see the +1/2 branch."""
RW_SLOPE = (0.1, 1.0)
"""Accepted free log-log slope of the Allan deviation beyond its minimum (+1/2 expected; less
just past the crossover, where white noise still adds, and one realisation's long-τ points
scatter by tens of percent)."""
RW_ABOVE_WHITE = 2.0
"""The deviation at the longest τ must be this many times the white-noise line N/√τ (a
white-noise curve's last points scatter by tens of percent, not by a factor of 2)."""
RW_BOUND_CONFIDENCE = 0.95
"""One-sided confidence of the Allan deviation used for the random-walk upper bound."""
MIN_SEGMENT_SAMPLES = 16
"""Fewest samples a stationary segment needs to enter the Allan analysis."""


class NoiseAnalysisError(CalibrationExportError):
    """The stationary segments cannot give a noise density (too short, none, not found)."""


@dataclass(frozen=True)
class NoiseEstimate:
    """Accelerometer noise of one (device, power cycle) from its stationary segments.

    Attributes
    ----------
    density
        (3,) white-noise density N per axis, m/s²/√Hz (ADEV at tau = 1 s on the −1/2 line).
    fit_taus_s
        (shortest, longest) tau of the white-noise fit, s.
    fit_slope
        (3,) free slope over the fitted taus (≈ −0.5 where white noise dominates).
    random_walk
        (3,) K per axis, m/s³/√Hz, or None when not measurable.
    random_walk_note
        How K was read, or why it was not.
    random_walk_bound
        (3,) upper bound on K per axis (:func:`random_walk_bound`), always computed.
    fs_hz
        Sampling rate used, Hz.
    n_segments, total_s, shortest_s
        Segments pooled, their total and shortest durations, s.
    longest_tau_s
        Longest tau analysed, s.
    longest_tau_segments
        Segments long enough to be pooled at the longest tau.
    """

    density: tuple[float, float, float]
    fit_taus_s: tuple[float, float]
    fit_slope: tuple[float, float, float]
    random_walk: tuple[float, float, float] | None
    random_walk_note: str
    random_walk_bound: tuple[float, float, float]
    fs_hz: float
    n_segments: int
    total_s: float
    shortest_s: float
    longest_tau_s: float
    longest_tau_segments: int = 1


def _slope(taus: np.ndarray, adev: np.ndarray) -> float:
    x = np.log(taus) - np.log(taus).mean()
    y = np.log(adev)
    return float(x @ (y - y.mean()) / (x @ x))


def random_walk_level(result: AllanResult, white: np.ndarray
                      ) -> tuple[tuple[float, float, float] | None, str]:
    """Bias random walk K per axis from the +1/2 branch beyond the Allan minimum, or why not.

    Allan variances of independent noises add, so beyond the minimum
    ``K² = (ADEV(τ)² − N²/τ) · 3/τ`` (white level ``white`` = N taken out), averaged over the
    taus there. The branch must be seen: the minimum at τ ≥ :data:`RW_MIN_TAU_S` with
    :data:`RW_MIN_TAUS` taus beyond it, a free slope there within :data:`RW_SLOPE`, and the
    longest τ at least :data:`RW_ABOVE_WHITE` times above the white-noise line.

    Returns
    -------
    (K, note)
        K (3,) in the deviation's unit per √s (m/s³/√Hz for m/s²) or None, and a sentence.
    """
    taus, adev = result.taus_s, result.adev
    values, slopes = [], []
    for k in range(adev.shape[1]):
        axis = "xyz"[k] if adev.shape[1] == 3 else str(k)
        i = int(np.argmin(adev[:, k]))
        beyond = np.arange(i + 1, taus.size)
        if beyond.size < RW_MIN_TAUS:
            return None, (f"no +1/2 branch: the Allan deviation still falls at the longest tau analysed "
                          f"({taus[-1]:.3g} s, {MIN_CLUSTERS} clusters of the longest segment); "
                          "recordings several times longer than the Allan minimum are needed")
        if taus[i] < RW_MIN_TAU_S:
            return None, (f"the Allan minimum of axis {axis} lies at tau = {taus[i]:.3g} s, below "
                          f"{RW_MIN_TAU_S:g} s: too early to be the white-noise/random-walk crossover")
        slope = _slope(taus[beyond], adev[beyond, k])
        above = adev[-1, k] / (white[k] / math.sqrt(taus[-1]))
        if not (RW_SLOPE[0] <= slope <= RW_SLOPE[1] and above >= RW_ABOVE_WHITE):
            return None, (f"beyond the Allan minimum (tau = {taus[i]:.3g} s) axis {axis} rises with slope "
                          f"{slope:.2f} to {above:.2f} times the white-noise line, not the +1/2 branch of "
                          f"a random walk (slope {RW_SLOPE[0]:g}..{RW_SLOPE[1]:g}, at least "
                          f"{RW_ABOVE_WHITE:g} times the line)")
        excess = np.maximum(adev[beyond, k] ** 2 - white[k] ** 2 / taus[beyond], 0.0) * 3.0 / taus[beyond]
        values.append(float(np.mean(np.sqrt(excess))))
        slopes.append(slope)
    return (values[0], values[1], values[2]), (
        "K^2 = (ADEV(tau)^2 - N^2/tau) * 3/tau averaged over the +1/2 branch beyond the Allan minimum "
        "(slopes " + ", ".join(f"{s:.2f}" for s in slopes) + ")")


def random_walk_bound(result: AllanResult, confidence: float = RW_BOUND_CONFIDENCE
                      ) -> tuple[float, float, float]:
    """Upper bound on the bias random walk K per axis that the Allan curve allows.

    Allan variances of independent noises add, so a random walk K alone gives
    ``ADEV(τ) ≥ K·√(τ/3)`` at every τ: ``K ≤ min_τ ADEV_up(τ)·√(3/τ)``. ``ADEV_up`` is the
    one-sided upper confidence limit of the estimate, ``ADEV·√(ν/χ²_ν(1 − confidence))`` with
    ν = ``n_terms``/m equivalent degrees of freedom (about the number of independent
    clusters, counted over the segments pooled at that τ: ``n_terms`` sums their second
    differences, :func:`~ofbe_data.labelling.allan.pooled_allan_deviation`; at least 1), so the
    bound holds for a curve that scattered low. The bound comes from the τ where the curve's
    upper limit is lowest relative to √(τ/3): usually a long τ still held by several segments;
    it shrinks as 1/√τ with longer recordings.

    Parameters
    ----------
    result
        Allan deviation (m/s² or rad/s).
    confidence
        One-sided confidence of the limit, in (0, 1).

    Returns
    -------
    tuple
        (3,) bound per axis, in the deviation's unit per √s (m/s³/√Hz, rad/s²/√Hz).
    """
    m = np.maximum(np.rint(result.taus_s * result.fs_hz), 1.0)
    nu = np.maximum(result.n_terms / m, 1.0)
    upper = result.adev * np.sqrt(nu / stats.chi2.ppf(1.0 - confidence, nu))[:, None]
    bound = np.min(upper * np.sqrt(3.0 / result.taus_s)[:, None], axis=0)
    return (float(bound[0]), float(bound[1]), float(bound[2]))


def noise_from_segments(segments: Sequence[np.ndarray], fs_hz: float, what: str = "segments"
                        ) -> NoiseEstimate:
    """Noise density (and random walk where visible) of stationary segments of one device.

    Parameters
    ----------
    segments
        (n_i, 3) stationary samples, m/s², one array per segment.
    fs_hz
        Their (common) sampling rate, Hz.
    what
        Names the data in error messages.

    Raises
    ------
    NoiseAnalysisError
        No segment, or one too short for the analysis.
    """
    segs = [np.asarray(s, dtype=np.float64) for s in segments]
    if not segs:
        raise NoiseAnalysisError(f"{what}: expected stationary segments, found none")
    shortest = min(s.shape[0] for s in segs)
    if shortest < MIN_SEGMENT_SAMPLES:
        raise NoiseAnalysisError(f"{what}: expected stationary segments of at least {MIN_SEGMENT_SAMPLES} "
                                 f"samples, found one of {shortest}")
    try:
        pooled = pooled_allan_deviation(segs, fs_hz, min_clusters=MIN_CLUSTERS)
        white = white_noise_level(pooled)
    except ValueError as exc:
        raise NoiseAnalysisError(f"{what}: {exc}") from None
    k, note = random_walk_level(pooled, white.density)
    return NoiseEstimate(
        density=tuple(float(v) for v in white.density), fit_taus_s=(float(pooled.taus_s[0]), white.tau_max_s),
        fit_slope=tuple(float(v) for v in white.slope), random_walk=k, random_walk_note=note,
        random_walk_bound=random_walk_bound(pooled),
        fs_hz=float(fs_hz), n_segments=len(segs), total_s=sum(s.shape[0] for s in segs) / fs_hz,
        shortest_s=shortest / fs_hz, longest_tau_s=float(pooled.taus_s[-1]),
        longest_tau_segments=int(pooled.n_segments[-1]) if pooled.n_segments is not None else len(segs))


class RawFiles:
    """The raw recordings of a campaign folder, read once each and checked against the labels.

    Parameters
    ----------
    raw_dir
        ``raw/<campaign>``: one folder per session with its ``session.yaml``.
    """

    def __init__(self, raw_dir: str | Path) -> None:
        self.raw_dir = Path(raw_dir)
        if not self.raw_dir.is_dir():
            raise CalibrationSourceError(f"{self.raw_dir}: expected the campaign's raw folder (--raw), "
                                         "found no such folder")
        self._manifests: dict[str, SessionManifest] = {}
        self._recordings: dict[tuple[str, str, str], Recording] = {}

    def manifest(self, session: str) -> SessionManifest:
        if session not in self._manifests:
            folder = self.raw_dir / session
            if not (folder / "session.yaml").is_file():
                raise CalibrationSourceError(f"{folder}: expected the raw session folder of labelled session "
                                             f"{session!r} (is --raw the campaign's raw folder?), found none")
            self._manifests[session] = load_manifest(folder)
        return self._manifests[session]

    def recording(self, seg: Segment, device: str) -> Recording:
        """The raw file of a label row, read by its manifest's format, its hash checked."""
        key = (seg.session, seg.raw_file, device)  # one file may hold two devices' columns
        if key not in self._recordings:
            m = self.manifest(seg.session)
            path = self.raw_dir / seg.session / seg.raw_file
            if device not in m.devices:
                raise CalibrationSourceError(f"{m.path}: expected device {device!r} of the labels, found "
                                             f"devices {', '.join(sorted(m.devices))}")
            if not path.is_file():
                raise CalibrationSourceError(f"{path}: expected the labelled raw file, found no such file")
            if seg.raw_sha256 and sha256_file(path) != seg.raw_sha256:
                raise CalibrationSourceError(f"{path}: expected the bytes that were labelled (SHA-256 "
                                             f"{seg.raw_sha256[:12]}…), found a different file")
            self._recordings[key] = read_device_file(path, m.devices[device])
        return self._recordings[key]

    def segment_samples(self, seg: Segment, device: str) -> np.ndarray:
        """(n, 3) m/s² of the row's stationary interval (device clock, both ends included)."""
        rec = self.recording(seg, device)
        return rec.acc[_inside(rec, seg)]

    def segment_gyro(self, seg: Segment, device: str) -> np.ndarray | None:
        """(n, 3) rad/s of the row's stationary interval, or None when the file has no gyroscope
        columns (or they hold a non-finite value there)."""
        rec = self.recording(seg, device)
        gyro = rec.gyro()
        if gyro is None:
            return None
        part = gyro[_inside(rec, seg)]
        return part if np.all(np.isfinite(part)) else None


def _inside(rec: Recording, seg: Segment) -> np.ndarray:
    return (rec.t >= seg.start_s - 1e-9) & (rec.t <= seg.end_s + 1e-9)


def noise_of(result: CalibrationResult, raw: RawFiles) -> NoiseEstimate:
    """The noise of a labels result from the stationary segments of its raw files."""
    if not result.segments:
        raise NoiseAnalysisError(f"{result.sources[0].path if result.sources else '?'}: {result.what}: "
                                 "expected raw_file and segment_start_s/segment_end_s columns, found none")
    fs = result.fs_hz
    if fs is None or not math.isfinite(fs) or fs <= 0:
        raise NoiseAnalysisError(f"{result.what}: expected a measured sample rate (fs_hz), found {fs!r}")
    samples = [raw.segment_samples(s, result.device) for s in result.segments]
    return noise_from_segments(samples, fs, f"{raw.raw_dir}: {result.what}")


def gyro_noise_of(result: CalibrationResult, raw: RawFiles) -> NoiseEstimate | None:
    """The gyroscope noise of a labels result from the same stationary segments, rad/s, or None
    when any of its raw files has no (finite) gyroscope columns there."""
    if not result.segments or result.fs_hz is None:
        return None
    samples = [raw.segment_gyro(s, result.device) for s in result.segments]
    if any(s is None for s in samples):
        return None
    return noise_from_segments([s for s in samples if s is not None], result.fs_hz,
                               f"{raw.raw_dir}: {result.what} (gyroscope)")


def attach_raw_times(collected: Collected, raw: RawFiles | None) -> Collected:
    """Times of every result: the earliest UTC start stamp of its raw files when ``raw`` is
    given and every file has one, else :func:`~ofbe_data.calibration.results.attach_file_times`."""
    collected = attach_file_times(collected)
    if raw is None or collected.kind != "labels":
        return collected
    out = []
    for r in collected.results:
        stamps = [raw.recording(s, r.device).start_utc for s in r.segments]
        if stamps and all(t is not None for t in stamps):
            when = min(stamps)
            when = when if when.tzinfo else when.replace(tzinfo=UTC)
            when = when.astimezone(UTC)
            r = replace(r, time_utc=when, time_source=TIME_RAW)
        out.append(r)
    return replace(collected, results=tuple(out))
