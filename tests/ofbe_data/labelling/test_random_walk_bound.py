"""Issue 33, item 5: Kalibr's ``accelerometer_random_walk`` upper bound on multi-position data.

A multi-position calibration holds stationary segments of very different lengths (0.5 s of
handling between poses up to 40 s poses). The bound used to take every τ from three clusters of
the *shortest* segment, so the analysis stopped at a fraction of a second and the bound was
~32 times the one allantools gives on the same segments. Now each τ is pooled over the
segments long enough for it (:func:`ofbe_data.labelling.allan.pooled_allan_deviation`).

The independent reference is allantools' own code end to end: ``allantools.oadev`` of each
segment at its octave taus, the Allan variances of the segments pooled at each τ with its own
counts as weights, the equivalent degrees of freedom from Greenhall's algorithm
(``allantools.edf_greenhall``, white FM, overlapping) summed over those segments, and
``allantools.confidence_interval`` (90 % two-sided: its upper end is the one-sided 95 % limit,
ofbe's confidence); K ≤ min over τ of the upper limit · √(3/τ).
"""

from __future__ import annotations

import math

import allantools
import numpy as np
import pytest

from ofbe_data.calibration.noise import RW_BOUND_CONFIDENCE, noise_from_segments

FS = 100.0
"""Sample rate of the simulated segments, Hz."""
SIGMA = 0.03
"""Per-sample white noise, m/s² (N = σ/√f_s = 0.003 m/s²/√Hz)."""
LENGTHS_S = (0.7, 1.1, 2.0, 2.4, 3.1, 40.0, 36.0, 2.2, 1.6, 38.5, 0.9, 33.0)
"""Stationary segments of one power cycle: short handling poses and long poses, as in the
multi-position campaign (0.5 to 41 s)."""


def _segments(seed: int, k: float) -> list[np.ndarray]:
    """White noise σ plus a bias random walk K (m/s³/√Hz) per segment, each at its own
    orientation (a different mean, which the Allan deviation ignores)."""
    rng = np.random.default_rng(seed)
    out = []
    for length in LENGTHS_S:
        n = int(round(length * FS))
        walk = np.cumsum(k / math.sqrt(FS) * rng.standard_normal((n, 3)), axis=0)
        out.append(rng.normal(0.0, 5.0, 3) + SIGMA * rng.standard_normal((n, 3)) + walk)
    return out


def allantools_bound(segments: list[np.ndarray], fs: float, confidence: float = RW_BOUND_CONFIDENCE
                     ) -> np.ndarray:
    """The random-walk upper bound per axis from allantools' own deviation, EDF and confidence
    interval, pooled per τ over the segments allantools computes that τ for."""
    bound = []
    for axis in range(segments[0].shape[1]):
        pooled: dict[int, list[float]] = {}
        for seg in segments:
            x = seg[:, axis]
            taus, devs, _errs, counts = allantools.oadev(x, rate=fs, data_type="freq", taus="octave")
            for tau, dev, count in zip(taus, devs, counts, strict=True):
                m = int(round(tau * fs))
                edf = allantools.edf_greenhall(alpha=0, d=2, m=m, N=len(x) + 1, overlapping=True)
                acc = pooled.setdefault(m, [0.0, 0.0, 0.0])
                acc[0] += dev * dev * count
                acc[1] += count
                acc[2] += edf
        ci = 2.0 * confidence - 1.0  # two-sided interval whose upper end is the one-sided limit
        bound.append(min(allantools.confidence_interval(math.sqrt(sv / n), edf, ci=ci)[1]
                         * math.sqrt(3.0 * fs / m) for m, (sv, n, edf) in pooled.items()))
    return np.array(bound)


@pytest.mark.parametrize("k", [4e-4, 3e-3])
def test_bound_is_within_two_of_allantools_and_above_the_true_walk(k: float) -> None:
    """Six seeds, a walk hidden under the white noise (crossover √3·N/K = 13 s) and one that
    dominates the long τ (1.7 s): the bound is within a factor 2 of allantools' on every axis,
    and above the true K on every axis of every seed (measured: 1.02 to 1.30 times allantools',
    1.2 to 3.4 times K)."""
    ratios, over = [], []
    for seed in range(6):
        segs = _segments(seed, k)
        noise = noise_from_segments(segs, FS)
        ours = np.array(noise.random_walk_bound)
        ratios.append(ours / allantools_bound(segs, FS))
        over.append(ours / k)
        # the longest pose sets the longest τ (a third of 40 s), held by that pose alone
        assert noise.longest_tau_s == pytest.approx(40.0 / 3, abs=0.01)
        assert noise.longest_tau_segments == 1 and noise.shortest_s == pytest.approx(0.7)
    ratios_a, over_a = np.array(ratios), np.array(over)
    assert np.all((ratios_a > 0.5) & (ratios_a < 2.0)), ratios_a
    assert np.all(over_a >= 1.0), over_a


def test_short_poses_no_longer_cut_the_analysis_short() -> None:
    """The shortest pose (0.7 s) used to end every τ at 0.23 s; the long poses now carry the
    analysis to 13 s, and the bound shrinks accordingly (white noise alone: about N·√(3)/τ_max
    times a confidence factor, not N·√3/0.23 s)."""
    rng = np.random.default_rng(7)
    segs = [SIGMA * rng.standard_normal((int(round(length * FS)), 3)) for length in LENGTHS_S]
    noise = noise_from_segments(segs, FS)
    density = SIGMA / math.sqrt(FS)
    short_tau_bound = density / (0.7 / 3) * math.sqrt(3.0)  # the old analysis' last τ, no margin
    assert noise.longest_tau_s > 13.0
    assert max(noise.random_walk_bound) < short_tau_bound / 10
    assert min(noise.random_walk_bound) > density / noise.longest_tau_s * math.sqrt(3.0)
