import math

import numpy as np
import pytest

from ofbe_data.labelling.allan import (
    AllanResult,
    allan_deviation,
    combine,
    default_taus,
    pooled_allan_deviation,
    samples_for_resolution,
    white_noise_level,
)

FS = 150.0
SIGMA = 0.0343  # m/s², ≈3.5 mg


def _white(seed: int, n: int = 12000) -> np.ndarray:
    return np.random.default_rng(seed).normal(0.0, SIGMA, (n, 3))


def _slope(taus: np.ndarray, adev: np.ndarray) -> float:
    return float(np.polyfit(np.log(taus), np.log(adev), 1)[0])


def test_default_taus_are_whole_samples_log_spaced():
    taus = default_taus(12000, FS)
    m = taus * FS
    np.testing.assert_allclose(m, np.round(m), atol=1e-9)
    assert m[0] == 1 and m[-1] == 3000
    assert np.all(np.diff(taus) > 0)
    per_decade = taus.size / math.log10(3000)
    assert 8 <= per_decade <= 11


def test_white_noise_follows_the_minus_half_line():
    r = allan_deviation(_white(0), FS)
    assert r.adev.shape == (r.taus_s.size, 3)
    assert r.n_terms[0] == 12000 - 1  # N + 1 − 2m for m = 1
    short = r.taus_s <= 10.0 / FS
    ratio = r.adev[short] * np.sqrt(r.taus_s[short] * FS)[:, None] / SIGMA
    np.testing.assert_allclose(ratio, 1.0, atol=0.04)  # sd ≈ 1 % per point
    two_decades = r.taus_s <= 100.0 / FS
    for k in range(3):
        assert _slope(r.taus_s[two_decades], r.adev[two_decades, k]) == pytest.approx(-0.5, abs=0.05)


def test_white_noise_level_recovers_sigma():
    r = allan_deviation(_white(1), FS)
    fit = white_noise_level(r)
    np.testing.assert_allclose(fit.sigma_sample, SIGMA, rtol=0.03)  # sd ≈ 0.9 %
    np.testing.assert_allclose(fit.density, fit.sigma_sample / math.sqrt(FS), rtol=1e-12)
    np.testing.assert_allclose(fit.slope, -0.5, atol=0.05)
    assert fit.tau_max_s == pytest.approx(10.0 / FS)
    # noise density in µg/√Hz is of the ADXL345's order (290 µg/√Hz on x, y)
    assert 250 < fit.density.mean() / 9.80665 * 1e6 < 330


def test_random_walk_makes_the_long_tau_slope_rise():
    # white noise plus a rate random walk (5 % of σ per sample): the branch of slope +1/2
    # dominates beyond ≈0.2 s; 36000 samples keep the long-τ slope within ±0.06 (1 sd)
    rng = np.random.default_rng(3)
    n = 36000
    white = rng.normal(0.0, SIGMA, (n, 3))
    walk = np.cumsum(rng.normal(0.0, 0.05 * SIGMA, (n, 3)), axis=0)
    with_walk = allan_deviation(white + walk, FS)
    alone = allan_deviation(white, FS)
    long = with_walk.taus_s >= 1.0
    rising = np.mean([_slope(with_walk.taus_s[long], with_walk.adev[long, k]) for k in range(3)])
    falling = np.mean([_slope(alone.taus_s[long], alone.adev[long, k]) for k in range(3)])
    assert 0.2 < rising < 0.75
    assert falling < -0.3
    # the white branch is unchanged at short τ
    np.testing.assert_allclose(with_walk.adev[0], alone.adev[0], rtol=0.02)


def test_one_dimensional_input_and_explicit_taus():
    x = _white(4)[:, 0]
    r = allan_deviation(x, FS, taus_s=[1 / FS, 0.0101, 0.0101, 1.0, 1e6, 0.0])
    assert r.adev.shape == (3, 1)
    np.testing.assert_allclose(r.taus_s * FS, [1, 2, 150])
    with pytest.raises(ValueError, match="taus_s"):
        allan_deviation(x, FS, taus_s=[1e6])
    with pytest.raises(ValueError, match="finite"):
        allan_deviation(np.array([1.0, np.nan, 2.0, 3.0, 4.0]), FS)


def test_combine_of_identical_recordings_equals_one():
    r = allan_deviation(_white(5), FS)
    both = combine([r, r])
    np.testing.assert_allclose(both.adev, r.adev, rtol=1e-13)
    np.testing.assert_array_equal(both.taus_s, r.taus_s)
    np.testing.assert_array_equal(both.n_terms, 2 * r.n_terms)


def test_combine_weights_by_n_terms():
    taus = default_taus(6000, FS)
    a = allan_deviation(_white(6, 12000), FS, taus)
    b = allan_deviation(_white(7, 6000), FS, taus)
    pooled = combine([a, b])
    w = a.n_terms + b.n_terms
    expected = np.sqrt((a.n_terms[:, None] * a.adev**2 + b.n_terms[:, None] * b.adev**2) / w[:, None])
    np.testing.assert_allclose(pooled.adev, expected, rtol=1e-13)


def test_combine_rejects_unequal_taus():
    a = allan_deviation(_white(8, 12000), FS)
    b = allan_deviation(_white(9, 6000), FS)  # default taus stop at 1500 samples, not 3000
    with pytest.raises(ValueError, match="same taus_s"):
        combine([a, b])
    with pytest.raises(ValueError, match="at least one"):
        combine([])
    c = AllanResult(taus_s=a.taus_s, adev=a.adev, n_terms=a.n_terms, fs_hz=100.0)
    with pytest.raises(ValueError, match="fs_hz"):
        combine([a, c])


def test_pooled_equals_combine_when_every_segment_holds_every_tau():
    segs = [_white(10, 6000), _white(11, 6600), _white(12, 7200)]
    taus = default_taus(6000, FS, stop_ratio=3)
    pooled = pooled_allan_deviation(segs, FS, taus)
    reference = combine([allan_deviation(s, FS, taus) for s in segs])
    np.testing.assert_array_equal(pooled.taus_s, reference.taus_s)
    np.testing.assert_allclose(pooled.adev, reference.adev, rtol=1e-12)
    np.testing.assert_array_equal(pooled.n_terms, reference.n_terms)
    np.testing.assert_array_equal(pooled.n_segments, 3)


def test_pooled_takes_each_segment_where_it_holds_three_clusters():
    """Issue 33: segments of 300, 1200 and 6000 samples: the longest τ is a third of the longest
    segment (not of the shortest), and each τ pools exactly the segments holding 3 clusters of it,
    weighted by their second differences, with n_terms counted over those segments only."""
    segs = [_white(13, 300), _white(14, 1200), _white(15, 6000)]
    pooled = pooled_allan_deviation(segs, FS)
    m = np.rint(pooled.taus_s * FS).astype(int)
    assert m[0] == 1 and m[-1] == 2000  # 6000 // 3, not 300 // 3
    expected_count = sum((m <= n // 3).astype(int) for n in (300, 1200, 6000))
    np.testing.assert_array_equal(pooled.n_segments, expected_count)
    assert set(pooled.n_segments.tolist()) == {1, 2, 3}
    for i in (0, int(np.argmax(pooled.n_segments == 2)), m.size - 1):
        held = [s for s in segs if s.shape[0] >= 3 * m[i]]
        parts = [allan_deviation(s, FS, [pooled.taus_s[i]]) for s in held]
        terms = sum(int(p.n_terms[0]) for p in parts)
        avar = sum(p.n_terms[0] * p.adev[0] ** 2 for p in parts) / terms
        np.testing.assert_allclose(pooled.adev[i], np.sqrt(avar), rtol=1e-12)
        assert pooled.n_terms[i] == terms == sum(s.shape[0] + 1 - 2 * m[i] for s in held)
    # white noise: every τ, whichever segments hold it, is on the −1/2 line
    ratio = pooled.adev * np.sqrt(pooled.taus_s * FS)[:, None] / SIGMA
    np.testing.assert_allclose(ratio[pooled.taus_s <= 0.5], 1.0, atol=0.1)


def test_pooled_one_dimensional_and_bad_input():
    r = pooled_allan_deviation([_white(16, 900)[:, 0], _white(17, 90)[:, 0]], FS, min_clusters=4)
    assert r.adev.shape[1] == 1 and int(round(r.taus_s[-1] * FS)) == 225
    with pytest.raises(ValueError, match="at least one segment"):
        pooled_allan_deviation([], FS)
    with pytest.raises(ValueError, match="one width"):
        pooled_allan_deviation([_white(18, 100), _white(19, 100)[:, :2]], FS)
    with pytest.raises(ValueError, match="min_clusters"):
        pooled_allan_deviation([_white(20, 100)], FS, min_clusters=1)
    with pytest.raises(ValueError, match="taus_s"):
        pooled_allan_deviation([_white(21, 100)], FS, taus_s=[10.0])


def test_samples_for_resolution():
    assert samples_for_resolution(3.5, 0.05) == 4900  # (3.5 / 0.05)² exactly
    assert samples_for_resolution(3.5, 3.5 / math.sqrt(4500)) == 4500
    assert 3.5 / math.sqrt(4500) == pytest.approx(0.0522, abs=1e-4)
    assert samples_for_resolution(1.0, 0.3) == 12  # 11.1 → 12
    assert samples_for_resolution(0.0, 1.0) == 1
    with pytest.raises(ValueError, match="target"):
        samples_for_resolution(1.0, 0.0)
