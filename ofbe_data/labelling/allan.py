"""Allan deviation of stationary accelerometer recordings (a thin wrapper of allantools).

The overlapping Allan deviation (NIST SP 1065, eq. 11) is computed per axis by
:func:`allantools.oadev` with ``data_type="freq"``: the samples are treated as the
"frequency" series, so the deviation comes out in the samples' unit (m/s²).

For white noise of per-sample rms σ sampled at f_s, ``ADEV(τ) = σ/√(τ·f_s) = N/√τ``, a
line of slope −1/2 on log-log axes, with the noise density (IEEE Std 952 velocity-random-walk
coefficient, the value of the line at τ = 1 s)

    N = σ/√f_s   [m/s²/√Hz],   equivalently   σ = N·√f_s.

This is the convention of the ADXL345 datasheet (290 µg/√Hz ↔ ≈2.9 mg rms at 100 Hz); it
equals the *two-sided* power spectral density level, the one-sided level being √2·N. A
rate random walk (slow bias drift) adds a branch of slope +1/2 at long τ.

Segments of unequal length (the poses of a multi-position calibration) are pooled τ by τ by
:func:`pooled_allan_deviation`: each τ over every segment that holds at least three clusters
of it, so the longest segment sets the longest τ.

The standard error of a mean of k independent white-noise samples is σ/√k, which is why a
few thousand samples are needed before the mean settles to a fraction of a mg
(:func:`samples_for_resolution`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import allantools
import numpy as np

PER_DECADE = 10
"""Default number of averaging times per decade."""
STOP_RATIO = 4
"""Default longest averaging time is N/STOP_RATIO samples (Stable32's stop ratio for OADEV)."""
WHITE_FIT_DECADES = 1.0
"""Default span of the white-noise fit, decades above the shortest τ."""
MIN_CLUSTERS = 3
"""Default fewest clusters (segment length / τ) a segment must hold at a τ to enter
:func:`pooled_allan_deviation` there."""


@dataclass(frozen=True)
class AllanResult:
    """Overlapping Allan deviation of one recording (or pooled recordings) per axis.

    Attributes
    ----------
    taus_s
        (M,) averaging times τ = m/f_s, s, increasing.
    adev
        (M, K) overlapping Allan deviation per axis, m/s² (K = 3 for an (N, 3) recording,
        1 for an (N,) one).
    n_terms
        (M,) number of second differences summed at each τ (``N + 1 − 2m``; summed over
        recordings when pooled by :func:`combine` or :func:`pooled_allan_deviation`).
    fs_hz
        Sampling rate, Hz.
    n_segments
        (M,) number of recordings pooled at each τ, where they differ from τ to τ
        (:func:`pooled_allan_deviation`); None for one recording or :func:`combine`.
    """

    taus_s: np.ndarray
    adev: np.ndarray
    n_terms: np.ndarray
    fs_hz: float
    n_segments: np.ndarray | None = None


@dataclass(frozen=True)
class WhiteNoiseFit:
    """White-noise level fitted on the τ^(−1/2) branch of an Allan deviation.

    Attributes
    ----------
    density
        (K,) noise density N per axis, m/s²/√Hz (ADEV(τ) = N/√τ).
    sigma_sample
        (K,) implied per-sample rms σ = N·√f_s at the result's sampling rate, m/s².
    slope
        (K,) free least-squares slope of log ADEV vs log τ over the fitted taus
        (≈ −0.5 when white noise dominates there; a diagnostic, not used for N).
    tau_max_s
        Longest τ used in the fit, s.
    n_taus
        Number of averaging times used in the fit.
    """

    density: np.ndarray
    sigma_sample: np.ndarray
    slope: np.ndarray
    tau_max_s: float
    n_taus: int


def default_taus(n_samples: int, fs_hz: float, per_decade: int = PER_DECADE,
                 stop_ratio: int = STOP_RATIO) -> np.ndarray:
    """Log-spaced averaging times on whole sample multiples.

    ``m`` runs from 1 to ``n_samples // stop_ratio`` with about ``per_decade`` values per
    decade (rounded to integers, duplicates removed), and τ = m/f_s. With the default stop
    ratio 4 the longest τ still averages over ~N/2 second differences, though only about
    four independent ones, so the last points scatter by tens of percent. Pass the same
    taus (e.g. from the shortest recording) to every :func:`allan_deviation` call whose
    results are to be pooled by :func:`combine`.

    Parameters
    ----------
    n_samples
        Number of samples N of the recording.
    fs_hz
        Sampling rate, Hz.
    per_decade
        Averaging times per decade.
    stop_ratio
        The longest averaging factor is ``n_samples // stop_ratio`` (≥ 2).

    Returns
    -------
    ndarray, shape (M,)
        Averaging times, s, increasing, each an exact m/f_s.
    """
    if not (math.isfinite(fs_hz) and fs_hz > 0.0):
        raise ValueError(f"fs_hz: expected a positive sampling rate, found {fs_hz!r}")
    if per_decade < 1:
        raise ValueError(f"per_decade: expected a positive integer, found {per_decade!r}")
    if stop_ratio < 2:
        raise ValueError(f"stop_ratio: expected an integer ≥ 2, found {stop_ratio!r}")
    m_max = int(n_samples) // int(stop_ratio)
    if m_max < 1:
        raise ValueError(f"n_samples: expected at least {stop_ratio} samples, found {n_samples}")
    count = max(1, int(math.ceil(per_decade * math.log10(m_max)))) + 1
    m = np.unique(np.round(np.logspace(0.0, math.log10(m_max), count)).astype(np.int64))
    return m / float(fs_hz)


def allan_deviation(x: np.ndarray, fs_hz: float, taus_s: np.ndarray | None = None) -> AllanResult:
    """Overlapping Allan deviation per axis, by :func:`allantools.oadev`.

    Parameters
    ----------
    x
        (N, K) or (N,) samples, m/s² (any unit; the deviation has the same unit). The mean is
        irrelevant (allantools removes it before integrating).
    fs_hz
        Sampling rate, Hz.
    taus_s
        (M,) wanted averaging times, s. Each is rounded to a whole number of samples
        m = round(τ·f_s); duplicates and those outside 1 ≤ m ≤ (N − 1)/2 are dropped, so
        the returned ``taus_s`` are the ones actually used. Default:
        :func:`default_taus` (about 10 per decade from 1/f_s to N/(4·f_s)).

    Returns
    -------
    AllanResult
        ``adev`` has shape (M, K) (K = 1 for a 1-D input).

    Raises
    ------
    ValueError
        For a non-finite sample, fewer than 4 samples, a bad rate, or no usable τ.
    """
    data = np.asarray(x, dtype=np.float64)
    if data.ndim == 1:
        data = data[:, np.newaxis]
    if data.ndim != 2 or data.shape[0] < 4 or data.shape[1] < 1:
        raise ValueError(f"x: expected an (N,) or (N, K) array with N ≥ 4, found shape {np.shape(x)}")
    if not np.all(np.isfinite(data)):
        raise ValueError("x: expected finite samples, found NaN or infinity")
    if not (math.isfinite(fs_hz) and fs_hz > 0.0):
        raise ValueError(f"fs_hz: expected a positive sampling rate, found {fs_hz!r}")
    n = data.shape[0]
    if taus_s is None:
        wanted = default_taus(n, fs_hz)
    else:
        wanted = np.asarray(taus_s, dtype=np.float64).ravel()
        m = np.round(wanted * fs_hz)
        wanted = np.unique(m[(m >= 1) & (m <= (n - 1) // 2)]) / float(fs_hz)
    if wanted.size == 0:
        raise ValueError(f"taus_s: expected at least one τ between {1 / fs_hz:g} s and "
                         f"{((n - 1) // 2) / fs_hz:g} s, found none")
    columns = []
    taus_used = n_terms = None
    for k in range(data.shape[1]):
        taus_k, adev_k, _err, ns_k = allantools.oadev(data[:, k], rate=fs_hz, data_type="freq",
                                                      taus=wanted)
        if taus_used is None:
            taus_used, n_terms = np.asarray(taus_k, dtype=np.float64), np.asarray(ns_k, dtype=np.int64)
        columns.append(np.asarray(adev_k, dtype=np.float64))
    return AllanResult(taus_s=taus_used, adev=np.stack(columns, axis=1), n_terms=n_terms,
                       fs_hz=float(fs_hz))


def combine(results: Sequence[AllanResult]) -> AllanResult:
    """Pool several recordings of one device into one Allan deviation curve.

    At each τ the Allan variances are averaged with weights ``n_terms`` (the number of
    second differences each recording contributed), which is the overlapping estimator
    over all the recordings' second differences together; ``n_terms`` of the result is
    their sum.

    Parameters
    ----------
    results
        Results with identical ``taus_s``, sampling rate and number of axes (compute them
        with one explicit ``taus_s``, see :func:`default_taus`).

    Returns
    -------
    AllanResult

    Raises
    ------
    ValueError
        For no results, or results whose taus, rates or axis counts differ.
    """
    results = list(results)
    if not results:
        raise ValueError("results: expected at least one AllanResult, found none")
    first = results[0]
    for i, r in enumerate(results[1:], start=1):
        if r.taus_s.shape != first.taus_s.shape or not np.allclose(r.taus_s, first.taus_s,
                                                                   rtol=1e-12, atol=0.0):
            raise ValueError(
                f"results[{i}].taus_s: expected the taus of results[0] ({first.taus_s.size} values "
                f"{first.taus_s[0]:g}…{first.taus_s[-1]:g} s), found {r.taus_s.size} values "
                f"{r.taus_s[0]:g}…{r.taus_s[-1]:g} s; compute every recording with the same taus_s")
        if r.fs_hz != first.fs_hz:
            raise ValueError(f"results[{i}].fs_hz: expected {first.fs_hz:g} Hz, found {r.fs_hz:g} Hz")
        if r.adev.shape != first.adev.shape:
            raise ValueError(f"results[{i}].adev: expected shape {first.adev.shape}, found {r.adev.shape}")
    weights = np.stack([r.n_terms for r in results]).astype(np.float64)  # (R, M)
    avar = np.stack([r.adev**2 for r in results])  # (R, M, K)
    total = weights.sum(axis=0)
    pooled = np.einsum("rm,rmk->mk", weights, avar) / total[:, np.newaxis]
    return AllanResult(taus_s=first.taus_s.copy(), adev=np.sqrt(pooled),
                       n_terms=total.astype(np.int64), fs_hz=first.fs_hz)


def pooled_allan_deviation(segments: Sequence[np.ndarray], fs_hz: float, taus_s: np.ndarray | None = None,
                           min_clusters: int = MIN_CLUSTERS) -> AllanResult:
    """Overlapping Allan deviation of segments of unequal length, each τ pooled over every
    segment long enough for it.

    Segment i enters the average at τ = m/f_s only when it holds at least ``min_clusters``
    clusters of m samples (``n_i ≥ min_clusters·m``); there its Allan variance counts with the
    weight of its ``n_terms`` (``n_i + 1 − 2m`` second differences), i.e. the overlapping
    estimator over the second differences of all the segments that hold the τ, and the
    result's ``n_terms`` is their sum, so a confidence limit with ν = ``n_terms``/m degrees of
    freedom counts the clusters of exactly the segments pooled. Short segments thus refine the
    short τ and no longer cut the analysis short: the longest τ is set by the longest segment
    (:func:`combine`, by contrast, needs every recording at every τ, so the shortest one sets
    the range).

    Parameters
    ----------
    segments
        (n_i, K) or (n_i,) samples per segment (same K for all, any unit; the deviation has
        the same unit). Each segment's mean is irrelevant (poses of a multi-position
        calibration may be pooled).
    fs_hz
        Their common sampling rate, Hz.
    taus_s
        (M,) wanted averaging times, s, rounded to whole samples. Default: :func:`default_taus`
        of the longest segment with stop ratio ``min_clusters``. Those no segment holds
        ``min_clusters`` times are dropped.
    min_clusters
        Fewest clusters a segment must hold at a τ to be pooled there (≥ 2).

    Returns
    -------
    AllanResult
        With ``n_segments`` the number of segments pooled at each τ.

    Raises
    ------
    ValueError
        For no segment, a non-finite sample, segments of different widths, a bad rate, or no
        τ that any segment holds ``min_clusters`` times.
    """
    segs = [np.asarray(s, dtype=np.float64) for s in segments]
    if not segs:
        raise ValueError("segments: expected at least one segment, found none")
    if min_clusters < 2:
        raise ValueError(f"min_clusters: expected an integer ≥ 2, found {min_clusters!r}")
    segs = [s[:, np.newaxis] if s.ndim == 1 else s for s in segs]
    widths = {s.shape[1] if s.ndim == 2 else -1 for s in segs}
    if len(widths) != 1 or -1 in widths:
        raise ValueError(f"segments: expected (n, K) arrays of one width K, found shapes "
                         f"{sorted({np.shape(s) for s in segments})}")
    if not (math.isfinite(fs_hz) and fs_hz > 0.0):
        raise ValueError(f"fs_hz: expected a positive sampling rate, found {fs_hz!r}")
    longest = max(s.shape[0] for s in segs)
    if taus_s is None:
        wanted_m = np.rint(default_taus(longest, fs_hz, stop_ratio=min_clusters) * fs_hz)
    else:
        wanted_m = np.rint(np.asarray(taus_s, dtype=np.float64).ravel() * fs_hz)
    wanted_m = np.unique(wanted_m[(wanted_m >= 1) & (wanted_m <= longest // min_clusters)]).astype(np.int64)
    if wanted_m.size == 0:
        raise ValueError(f"taus_s: expected a τ that the longest segment ({longest} samples) holds "
                         f"{min_clusters} times, found none")
    k = next(iter(widths))
    weighted = np.zeros((wanted_m.size, k))
    terms = np.zeros(wanted_m.size, dtype=np.int64)
    count = np.zeros(wanted_m.size, dtype=np.int64)
    for s in segs:
        held = wanted_m <= s.shape[0] // min_clusters
        if s.shape[0] < 4 or not held.any():
            continue
        r = allan_deviation(s, fs_hz, wanted_m[held] / float(fs_hz))
        idx = np.searchsorted(wanted_m, np.rint(r.taus_s * fs_hz).astype(np.int64))
        weighted[idx] += r.n_terms[:, np.newaxis] * r.adev**2
        terms[idx] += r.n_terms
        count[idx] += 1
    keep = terms > 0
    return AllanResult(taus_s=wanted_m[keep] / float(fs_hz),
                       adev=np.sqrt(weighted[keep] / terms[keep, np.newaxis]),
                       n_terms=terms[keep], fs_hz=float(fs_hz), n_segments=count[keep])


def white_noise_level(result: AllanResult, decades: float = WHITE_FIT_DECADES) -> WhiteNoiseFit:
    """Fit the white-noise density on the τ^(−1/2) branch at short τ.

    Over the taus within ``decades`` of the shortest one, ``log ADEV = log N − ½·log τ`` is
    fitted by least squares with the slope fixed at −1/2, i.e. ``log N`` is the mean of
    ``log(ADEV(τ)·√τ)`` (each τ weighted equally). Fit only where white noise dominates:
    quantisation, drift or a warm-up transient bend the curve away from the −1/2 line, and
    the returned free slope shows it.

    Parameters
    ----------
    result
        Allan deviation, m/s².
    decades
        Span of the fit above the shortest τ, decades (> 0; at least two taus are used).

    Returns
    -------
    WhiteNoiseFit
        ``density`` N in m/s²/√Hz and ``sigma_sample`` = N·√f_s in m/s², per axis.
    """
    if not decades > 0.0:
        raise ValueError(f"decades: expected a positive span, found {decades!r}")
    taus = result.taus_s
    if taus.size < 2:
        raise ValueError(f"result.taus_s: expected at least 2 averaging times, found {taus.size}")
    tau_max = taus[0] * 10.0**decades * (1.0 + 1e-9)
    use = np.flatnonzero(taus <= tau_max)
    if use.size < 2:
        use = np.arange(2)
    log_tau = np.log(taus[use])
    log_adev = np.log(result.adev[use, :])  # (U, K)
    log_n = np.mean(log_adev + 0.5 * log_tau[:, np.newaxis], axis=0)
    centred = log_tau - log_tau.mean()
    slope = centred @ (log_adev - log_adev.mean(axis=0)) / (centred @ centred)
    density = np.exp(log_n)
    return WhiteNoiseFit(density=density, sigma_sample=density * math.sqrt(result.fs_hz),
                         slope=np.asarray(slope, dtype=np.float64), tau_max_s=float(taus[use[-1]]),
                         n_taus=int(use.size))


def samples_for_resolution(sigma_sample: float, target: float) -> int:
    """Number of white-noise samples whose mean has a standard error at most ``target``.

    The standard error of a mean of k independent samples of rms σ is σ/√k, so
    k = ⌈(σ/target)²⌉. For σ = 3.5 mg and a target of 0.05 mg that is 4900 samples (33 s at
    150 Hz); the ≈4500 samples after which the paper's running mean converges leave
    3.5/√4500 ≈ 0.052 mg. Drift (the +1/2 branch of the Allan curve) is ignored: beyond the
    Allan minimum more samples stop helping.

    Parameters
    ----------
    sigma_sample
        Per-sample white-noise rms (any unit, e.g. m/s² or mg).
    target
        Wanted standard error of the mean, same unit.

    Returns
    -------
    int
        k ≥ 1.
    """
    if not (math.isfinite(sigma_sample) and sigma_sample >= 0.0):
        raise ValueError(f"sigma_sample: expected a finite non-negative rms, found {sigma_sample!r}")
    if not (math.isfinite(target) and target > 0.0):
        raise ValueError(f"target: expected a positive standard error, found {target!r}")
    ratio = sigma_sample / target
    return max(1, math.ceil(ratio * ratio * (1.0 - 1e-12)))
