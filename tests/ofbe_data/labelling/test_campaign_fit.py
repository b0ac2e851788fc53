"""The campaign fit on exact synthetic data, and its refusals."""

from __future__ import annotations

import numpy as np
import pytest

from ofbe_data.labelling.campaign_fit import CampaignFitParams, design_matrix, fit_device
from ofbe_data.simulator.physics import random_unit_vectors

G = 9.7946


def _campaign(n_cycles: int, per_cycle: int, seed: int = 0, noise: float = 0.0):
    rng = np.random.default_rng(seed)
    A = np.eye(3) + rng.normal(0, 0.01, (3, 3))
    b = rng.normal(0, 0.15, (n_cycles, 3))
    u = random_unit_vectors(n_cycles * per_cycle, rng)
    cycle = np.repeat(np.arange(n_cycles) + 1, per_cycle)
    mean = G * u @ A.T + b[cycle - 1] + rng.normal(0, noise, u.shape)
    return A, b, u, mean, cycle


def test_design_matrix_reproduces_the_model():
    A, b, u, mean, cycle = _campaign(4, 3)
    X = design_matrix(u, cycle - 1, 4, G)
    np.testing.assert_allclose(X @ np.concatenate([A.ravel(), b.ravel()]), mean.ravel(), atol=1e-12)


def test_exact_data_give_exact_map_and_offsets():
    A, b, u, mean, cycle = _campaign(29, 3)
    fit = fit_device("d", u, mean, cycle, G)
    assert fit.determined and fit.reason == "" and fit.condition < 20
    np.testing.assert_allclose(fit.A, A, atol=1e-10)
    for j in range(29):
        np.testing.assert_allclose(fit.offsets[j + 1], b[j], atol=1e-10)
    assert fit.residual_rms < 1e-10


def test_noisy_offsets_within_the_noise():
    A, b, u, mean, cycle = _campaign(29, 3, seed=1, noise=0.4e-3 * 9.80665)
    fit = fit_device("d", u, mean, cycle, G)
    err = np.array([fit.offsets[j + 1] - b[j] for j in range(29)])
    assert np.sqrt(np.mean(err**2)) < 1.5 * 0.4e-3 * 9.80665
    assert fit.residual_rms == pytest.approx(0.4e-3 * 9.80665 * np.sqrt(1 - (9 + 87) / 261), rel=0.2)


def test_one_orientation_per_power_cycle_does_not_determine_the_map():
    _, _, u, mean, cycle = _campaign(40, 1)
    fit = fit_device("d", u, mean, cycle, G)
    assert not fit.determined and fit.A is None and fit.offsets == {}
    assert fit.reason.startswith("the orientations do not determine A: condition number inf > 1000")


def test_too_few_recordings_are_refused():
    _, _, u, mean, cycle = _campaign(3, 3)
    fit = fit_device("d", u, mean, cycle, G, CampaignFitParams(min_recordings=12))
    assert fit.reason == ("9 labelled recordings, the fit needs at least 12 "
                          "(label the whole campaign together)")
    assert fit.to_dict()["condition"] is None
