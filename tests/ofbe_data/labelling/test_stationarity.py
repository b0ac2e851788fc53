"""The moving-variance static detector on known still and moving signals."""

from __future__ import annotations

import numpy as np

from ofbe_data.labelling.stationarity import StaticParams, check_static, longest_run, moving_variance_norm

FS = 150.0
NOISE = np.array([3.5, 3.5, 5.2]) * 9.80665e-3


def _still(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.array([0.1, -0.2, 9.79]) + rng.standard_normal((n, 3)) * NOISE


def test_moving_variance_matches_direct_computation():
    x = _still(400)
    w = 37
    v = moving_variance_norm(x, w)
    direct = np.array([x[i:i + w].var(axis=0, ddof=1).sum() for i in range(400 - w + 1)])
    np.testing.assert_allclose(v, direct, rtol=1e-9)


def test_pure_noise_is_static_throughout():
    for seed in range(5):
        check = check_static(_still(12_000, seed), FS)
        assert check.moving_samples == 0, seed
        assert np.sqrt(check.noise_floor) == np.sqrt(np.sum(NOISE**2)) * np.array(1.0).clip(0.95, 1.05) \
            or abs(np.sqrt(check.noise_floor) / np.sqrt(np.sum(NOISE**2)) - 1) < 0.05


def test_a_bump_is_found_where_it_happened():
    x = _still(12_000)
    t = np.arange(300) / FS
    x[6000:6300, 0] += 0.5 * np.sin(2 * np.pi * 8 * t) * np.exp(-t / 0.3)  # a knock on the table
    check = check_static(x, FS)
    moving = np.flatnonzero(~check.static)
    assert moving.size > 0
    assert 6000 - FS <= moving[0] <= 6000 and 6000 <= moving[-1] <= 6300 + FS


def test_a_segment_that_moves_throughout_hits_the_absolute_ceiling():
    x = _still(3000)
    x[:, 2] += 1.0 * np.sin(2 * np.pi * 3 * np.arange(3000) / FS)  # carried around
    check = check_static(x, FS, StaticParams())
    assert check.moving_samples == 3000


def test_longest_run():
    assert longest_run(np.array([0, 1, 1, 0, 1, 1, 1, 0], bool)) == (4, 7)
    assert longest_run(np.zeros(5, bool)) == (0, 0)
    assert longest_run(np.ones(5, bool)) == (0, 5)


def test_static_mask_by_slices_matches_the_gathers():
    from ofbe_data.labelling.stationarity import _static_check

    rng = np.random.default_rng(0)
    for _ in range(500):
        n = int(rng.integers(2, 300))
        window = int(rng.integers(2, n + 1))
        v = rng.random(n - window + 1) ** 4
        got = _static_check(v, n, window, StaticParams(variance_factor=float(rng.uniform(0.5, 8))))
        moving = v > got.threshold
        cover = np.concatenate(([0], np.cumsum(moving)))
        lo = np.clip(np.arange(n) - window + 1, 0, v.shape[0])
        hi = np.clip(np.arange(n) + 1, 0, v.shape[0])
        expected = (cover[hi] - cover[lo]) == 0 if moving.any() else np.ones(n, dtype=bool)
        assert np.array_equal(got.static, expected)
