"""The counting shortcuts of labelling decide exactly what the computations they skip would."""

from __future__ import annotations

import numpy as np
import pytest

from ofbe_data.io.gravity import G0
from ofbe_data.labelling.checks import norm_problem, typical_norm_problem, typical_reading
from ofbe_data.labelling.stationarity import StaticParams, check_static, column_mean, is_still


def _signals() -> list[np.ndarray]:
    rng = np.random.default_rng(7)
    n = 3000
    still = rng.normal([0.1, -0.2, G0], 0.01, size=(n, 3))
    bump = still.copy()
    bump[1400:1460] += rng.normal(0.0, 0.3, size=(60, 3))
    small_bump = still.copy()  # a peak near the factor × median threshold
    small_bump[1000:1200] *= np.array([1.0, 1.0, 1.0]) + rng.normal(0.0, 2e-3, size=(200, 3))
    moving = rng.normal([0.0, 0.0, G0], 1.0, size=(n, 3))
    counts = np.rint(still / G0 * 256.0) / 256.0 * G0  # quantised, many equal values
    constant = np.tile([0.0, 0.0, G0], (n, 1))
    nan = still.copy()
    nan[5] = np.nan
    half_wrong = still.copy()
    half_wrong[: n // 2] *= 3.0  # the median norm right at the edge
    return [still, bump, small_bump, moving, counts, constant, nan, half_wrong, still[:150], still[:7],
            still * 1000.0, still / G0]


@pytest.mark.parametrize("k", range(12))
@pytest.mark.parametrize("params", [StaticParams(), StaticParams(variance_factor=1.05),
                                    StaticParams(max_std_mps2=0.012), StaticParams(window_s=0.1)])
def test_is_still_agrees_with_the_static_detector(k: int, params: StaticParams) -> None:
    x = _signals()[k]
    for fs in (150.0, 1000.0):
        expected = check_static(x, fs, params).moving_samples == 0
        assert is_still(x, fs, params) == expected
        assert is_still(x, fs, params, column_mean(x)) == expected


@pytest.mark.parametrize("k", range(12))
@pytest.mark.parametrize("g, deviation", [(G0, 0.3), (9.78, 0.01), (G0, 2.0), (3.0 * G0, 0.3)])
def test_typical_norm_problem_agrees_with_the_median(k: int, g: float, deviation: float) -> None:
    x = _signals()[k]
    assert typical_norm_problem(x, g, deviation) == norm_problem(typical_reading(x), g, deviation)


def test_column_mean_has_the_bits_of_numpy_mean() -> None:
    x = _signals()[1]
    assert column_mean(x).tobytes() == x.mean(axis=0).tobytes()


@pytest.mark.parametrize("k", [0, 1, 3, 4, 5, 8])
def test_shared_centred_sums_give_the_same_bits(k: int) -> None:
    from ofbe_data.labelling.stationarity import centred_sums
    from ofbe_data.labelling.sync import highpass

    x = _signals()[k]
    t = np.arange(x.shape[0]) / 150.0
    centred = centred_sums(x)
    a, b = check_static(x, 150.0), check_static(x, 150.0, StaticParams(), *centred)
    assert a.static.tobytes() == b.static.tobytes()
    assert (a.noise_floor, a.threshold, a.peak) == (b.noise_floor, b.threshold, b.peak) or np.isnan(a.peak)
    assert highpass(t, x, 0.25).tobytes() == highpass(t, x, 0.25, centred).tobytes()
