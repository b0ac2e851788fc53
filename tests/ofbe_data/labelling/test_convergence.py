import numpy as np
import pytest

from ofbe_data.labelling.convergence import convergence_index, running_mean


def test_running_mean():
    np.testing.assert_allclose(running_mean([2.0, 4.0, 6.0]), [2.0, 3.0, 4.0])


def test_hand_computed_example():
    # m = 0, 1/2, 2/3, 3/4, 4/5 → d_2..d_5 = 1/2, 1/6, 1/12, 1/20; mean of the last two
    # first drops below 0.1 at k = 5 ((1/12 + 1/20) / 2 = 0.0667; at k = 4 it is 0.125)
    x = np.array([0.0, 1.0, 1.0, 1.0, 1.0, 1.0])
    assert convergence_index(x, window=2, threshold=0.1) == 5
    assert convergence_index(x, window=2, threshold=0.13) == 4


def test_constant_signal_converges_as_soon_as_the_window_is_full():
    assert convergence_index(np.full(200, 9.81)) == 41


def test_too_short_or_never_converging_gives_minus_one():
    assert convergence_index(np.zeros(40)) == -1
    rng = np.random.default_rng(0)
    assert convergence_index(rng.normal(0.0, 1.0, 3000)) == -1


def test_white_noise_scaling():
    # mean |d_k| ≈ σ·sqrt(2/π)/k, so the averaged step reaches the threshold near
    # k* = σ·0.798/threshold; the noisy 40-step average first crosses it earlier (about
    # 0.77·k*, a first-passage effect), and the index scales linearly with σ
    rng = np.random.default_rng(1)
    sigma = 0.03
    k1 = np.mean([convergence_index(rng.normal(0.0, sigma, 12000)) for _ in range(80)])
    k2 = np.mean([convergence_index(rng.normal(0.0, sigma / 2, 12000)) for _ in range(80)])
    k_star = sigma * np.sqrt(2 / np.pi) / 5e-6
    assert 0.68 * k_star < k1 < 0.86 * k_star
    assert k1 / k2 == pytest.approx(2.0, rel=0.08)


def test_axis_statistics_leave_out_unconverged() -> None:
    from ofbe_data.labelling.convergence import axis_statistics

    s = axis_statistics(np.array([4000, 5000, -1, 4500]))
    assert (s.n, s.n_not_converged, s.mean, s.min, s.max) == (4, 1, 4500.0, 4000.0, 5000.0)
    assert s.std == pytest.approx(500.0)
    none = axis_statistics(np.array([-1, -1]))
    assert none.n_not_converged == 2 and np.isnan(none.mean)


def test_recommendation_rounds_up_and_rejects_nonsense() -> None:
    from ofbe_data.labelling.convergence import axis_statistics, recommend_min_samples

    s = axis_statistics(np.array([4401, 4463]))
    assert recommend_min_samples(s) == 4500
    assert recommend_min_samples(s, round_to=1) == 4432
    assert recommend_min_samples(s, "mean+std") == 4500
    with pytest.raises(ValueError, match="statistic: expected one of mean, mean"):
        recommend_min_samples(s, "mode")
    with pytest.raises(ValueError, match="no recording converged"):
        recommend_min_samples(axis_statistics(np.array([-1])))
