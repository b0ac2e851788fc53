"""Estimators on simulated windows with known truth: what one window can and cannot tell.

Windows are f_i = A·u·g + b + n_i with the ADXL345's white noise (σ = 0.0361 m/s² on x, y and
0.052 on z, T = 3000 samples), fixed seeds. The along-gravity component of b is observable
from one window; the two tangential ones are not (docs/estimators.md), and each test checks
exactly the behaviour the docs claim, with tolerances from the noise.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial.transform import Rotation

from ofbe_data.labelling.orientation import nearest_axis
from ofbe_model.estimators.base import EstimatorError, estimator_names, make_estimator
from ofbe_model.estimators.common import GRAVITY_PRIOR_FORMAT, MG, nearest_axes
from ofbe_model.estimators.oracle import Oracle
from ofbe_model.estimators.physics import LSTRF, LevelMean, Won2009, won2009_solve
from ofbe_model.estimators.priors import (
    GravityPrior,
    PriorMean,
    condition_on_norm,
    direction_prior,
    mixture_moments,
)

G = 9.795382950829522
"""Local gravity of the simulator's default site, m/s²."""
T = 3000
SIGMA = np.array([0.0361, 0.0361, 0.052])
"""White noise per sample, m/s² (x, y, z)."""
SIGMA_MEAN = SIGMA / np.sqrt(T)
"""Noise of a window mean, m/s²."""
BOUNDS = np.array([150.0, 150.0, 250.0]) * MG
OURS = ("gravity-prior", "level-mean", "ls-trf", "oracle", "prior-mean", "won2009")


# ----------------------------------------------------------------------------- generators


def tilted_units(rng: np.random.Generator, n: int, min_deg: float, max_deg: float) -> np.ndarray:
    """(n, 3) unit up directions tilted min_deg…max_deg from +z, random azimuth."""
    tilt = np.radians(rng.uniform(min_deg, max_deg, n))
    az = rng.uniform(0.0, 2.0 * np.pi, n)
    return np.stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)], axis=1)


def sphere_units(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 3) directions uniform on the sphere (random tilts)."""
    v = rng.standard_normal((n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def make_windows(rng: np.random.Generator, u: np.ndarray, b: np.ndarray, A: np.ndarray | None = None,
                 sigma: np.ndarray | float = SIGMA) -> np.ndarray:
    """(n, T, 3) windows f = A·u·g + b + N(0, σ²); A per window (n, 3, 3) or shared (3, 3)."""
    A = np.eye(3) if A is None else np.asarray(A)
    mean = G * (np.einsum("nij,nj->ni", A, u) if A.ndim == 3 else u @ A.T) + b
    return mean[:, None, :] + rng.standard_normal((len(u), T, 3)) * sigma


def make_meta(devices) -> pd.DataFrame:
    return pd.DataFrame({"device": list(devices), "g_local": np.full(len(devices), G)})


def rmse(err: np.ndarray) -> float:
    """sqrt(mean ‖e‖²), the paper's vector RMSE."""
    return float(np.sqrt(np.mean(np.sum(err**2, axis=1))))


def split_along(m: np.ndarray, e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Components of e (n, 3) along h = m/‖m‖ and the length of the rest (tangential)."""
    h = m / np.linalg.norm(m, axis=1, keepdims=True)
    along = np.sum(e * h, axis=1)
    return along, np.linalg.norm(e - along[:, None] * h, axis=1)


def sphere_residual(m: np.ndarray, b_hat: np.ndarray) -> np.ndarray:
    """‖m − b̂‖ − g: how far an estimate is from the norm constraint, m/s²."""
    return np.linalg.norm(m - b_hat, axis=1) - G


# ----------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def tilted():
    """Eight windows tilted 15–75°, biases N(0, 12 mg) per axis (the simulator's factory
    spread on x, y; small enough that the sphere's curvature term ‖b_⊥‖²/(2g) stays below
    0.5 mg: at 20 mg per axis it reaches 1 mg)."""
    rng = np.random.default_rng(20250301)
    u = tilted_units(rng, 8, 15.0, 75.0)
    b = rng.normal(0.0, 12.0 * MG, (8, 3))
    X = make_windows(rng, u, b)
    return X, b, make_meta(["dut"] * 8), X.mean(axis=1)


@pytest.fixture(scope="module")
def informative():
    """Four devices with distinct offsets (N(0, 80 mg)) and a small turn-on spread
    (4, 4, 12 mg), random tilts, A = I; 60 training and 60 test windows per device."""
    rng = np.random.default_rng(77)
    devices = ["d0", "d1", "d2", "d3"]
    offset = {d: rng.normal(0.0, 80.0 * MG, 3) for d in devices}
    spread = np.array([4.0, 4.0, 12.0]) * MG

    def draw(n_per: int):
        dev = np.repeat(devices, n_per)
        b = np.array([offset[d] for d in dev]) + rng.standard_normal((len(dev), 3)) * spread
        return make_windows(rng, sphere_units(rng, len(dev)), b), b, make_meta(dev)

    return draw(60), draw(60)


def write_truth(folder: Path, devices: dict[str, dict[str, np.ndarray]], kind: str, turn_on: np.ndarray,
                drift: float, sessions: int = 2) -> None:
    """A truth folder in the simulator's ofbe-truth/1 layout (device-level fields only, plus an
    empty recordings table)."""
    folder.mkdir(parents=True, exist_ok=True)
    for s in range(1, sessions + 1):
        data = {"format": "ofbe-truth/1", "campaign": "synthetic", "session": f"syn-pc{s:03d}", "kind": kind,
                "power_cycle": s, "g_local": G,
                "devices": {d: {"role": "dut", "model": "ADXL345", "A_effective": p["A"].tolist(),
                                "offset_device": p["offset"].tolist(), "turn_on_sigma": turn_on.tolist(),
                                "drift_sigma": drift, "noise_rms": SIGMA.tolist()}
                            for d, p in devices.items()},
                "recordings": {}}
        (folder / f"syn-pc{s:03d}.json").write_text(json.dumps(data), encoding="utf-8")


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    """A rotated-like synthetic campaign whose generating distribution the oracle knows: two
    devices with A = (I + 1 % scale)·(1.5° misalignment), factory offsets (12, 12, 20 mg),
    turn-on 5 mg, drift 0.3 mg, random tilts; labels b_app = m_true − g·u."""
    rng = np.random.default_rng(4242)
    turn_on, drift = np.full(3, 5.0 * MG), 0.3 * MG
    devices = {}
    for d in ("sparkfun-1", "sparkfun-2"):
        A = (np.eye(3) + np.diag(rng.normal(0.0, 0.01, 3))) @ Rotation.from_rotvec(
            rng.normal(0.0, np.radians(1.5), 3)).as_matrix()
        devices[d] = {"A": A, "offset": rng.normal(0.0, 1.0, 3) * np.array([12.0, 12.0, 20.0]) * MG}
    truth = tmp_path_factory.mktemp("truth") / "_truth"
    write_truth(truth, devices, "rotated", turn_on, drift)

    def draw(n_per: int):
        dev = np.repeat(list(devices), n_per)
        u = sphere_units(rng, len(dev))
        A = np.stack([devices[d]["A"] for d in dev])
        b = (np.stack([devices[d]["offset"] for d in dev])
             + rng.standard_normal((len(dev), 3)) * np.sqrt(turn_on**2 + drift**2))
        X = make_windows(rng, u, b, A=A)
        y = G * np.einsum("nij,nj->ni", A, u) + b - G * u
        return X, y, make_meta(dev)

    return truth, draw(100), draw(30)


# ----------------------------------------------------------------------------- registry


def test_registry_lists_every_estimator():
    assert set(OURS) <= set(estimator_names())


def test_make_estimator_parameters_and_errors():
    est = make_estimator("ls-trf", variant="bounded")
    assert isinstance(est, LSTRF) and est.variant == "bounded" and est.bounds_mg == (150.0, 150.0, 250.0)
    with pytest.raises(EstimatorError, match="expected one of .*found 'ls-svd'"):
        make_estimator("ls-svd")
    with pytest.raises(EstimatorError, match="estimator ls-trf: .*unexpected keyword argument 'ridg'"):
        make_estimator("ls-trf", ridg=1.0)
    with pytest.raises(EstimatorError, match="expected one of as-written, bounded, min-norm, found 'plain'"):
        make_estimator("ls-trf", variant="plain")
    with pytest.raises(EstimatorError, match="ridge: expected a finite number > 0"):
        make_estimator("ls-trf", ridge=0.0)
    with pytest.raises(EstimatorError, match="rcond"):
        make_estimator("won2009", rcond=2.0)
    with pytest.raises(EstimatorError, match="min_std_mg"):
        make_estimator("gravity-prior", min_std_mg=-1.0)


@pytest.mark.parametrize(("name", "params"), [
    ("level-mean", {}),
    ("ls-trf", {"variant": "bounded", "bounds_mg": (100.0, 100.0, 200.0), "max_nfev": 50}),
    ("ls-trf", {"variant": "min-norm", "ridge": 0.05, "x0": (0.1, 0.0, -0.1)}),
    ("won2009", {"tol": 1e-5, "max_iter": 20, "rcond": 1e-2}),
    ("prior-mean", {}),
    ("gravity-prior", {"per_device": False, "min_std_mg": 1.0, "direction_model": True}),
    ("oracle", {"truth_dir": "somewhere/_truth"}),
])
def test_get_params_round_trip(name, params):
    est = make_estimator(name, **params)
    got = est.get_params()
    assert {k: got[k] for k in params} == params
    again = make_estimator(name, **got)
    assert type(again) is type(est) and again.get_params() == got
    assert repr(again) == repr(est)


def test_bad_inputs_are_estimator_errors(tilted):
    X, _, meta, _ = tilted
    for est in (LevelMean(), LSTRF(), Won2009()):
        with pytest.raises(EstimatorError, match=r"shape \(N, T, 3\)"):
            est.predict(X[:, :, :2], meta)
        with pytest.raises(EstimatorError, match="expected 8 rows"):
            est.predict(X, meta.iloc[:3])
        with pytest.raises(EstimatorError, match="g_local"):
            est.predict(X, meta.assign(g_local=-1.0))


@pytest.mark.parametrize("est", [PriorMean(), GravityPrior(), Oracle(truth_dir="nowhere")])
def test_predict_before_fit_refuses(tilted, est):
    X, _, meta, _ = tilted
    with pytest.raises(EstimatorError, match="call fit first"):
        est.predict(X, meta)


# ----------------------------------------------------------------------------- level-mean


def test_nearest_axes_matches_nearest_axis():
    m = np.random.default_rng(3).normal(size=(200, 3))
    assert np.array_equal(nearest_axes(m), np.array([nearest_axis(r) for r in m]))


def test_level_mean_exact_on_a_level_sensor_without_noise():
    rng = np.random.default_rng(1)
    axes = np.vstack([np.eye(3), -np.eye(3)])
    b = rng.uniform(-0.5, 0.5, (6, 3))  # |b| up to 51 mg per axis, far from the next axis
    X = make_windows(rng, axes, b, sigma=0.0)
    got = LevelMean().predict(X, make_meta(["dut"] * 6))
    assert np.max(np.abs(got - b)) < 1e-12


def test_level_mean_within_three_sigma_with_noise():
    rng = np.random.default_rng(2)
    n = 200
    axes = np.vstack([np.eye(3), -np.eye(3)])[rng.integers(0, 6, n)]
    b = rng.normal(0.0, 20.0 * MG, (n, 3))
    got = LevelMean().predict(make_windows(rng, axes, b), make_meta(["dut"] * n))
    z = (got - b) / SIGMA_MEAN
    assert np.mean(np.abs(z) < 3.0) >= 0.99 and np.max(np.abs(z)) < 4.5
    assert np.all((z.std(axis=0) > 0.9) & (z.std(axis=0) < 1.1))


# ----------------------------------------------------------------------------- ls-trf and won2009


def ls_hessian(f: np.ndarray, b: np.ndarray) -> np.ndarray:
    """∇²Σ(‖f_i − b‖ − g)² = 2Σ[h_i h_iᵀ + r_i (I − h_i h_iᵀ)/‖f_i − b‖], (3, 3)."""
    d = f - b
    n = np.linalg.norm(d, axis=1)
    h = d / n[:, None]
    w = (n - G) / n
    return 2.0 * (h.T @ h + np.sum(w) * np.eye(3) - (h * w[:, None]).T @ h)


def test_the_cost_is_flat_along_the_sphere(tilted):
    """docs/estimators.md: without noise ∇²C = 2T·hhᵀ (eigenvalues 0, 0, 2T) and every b on
    ‖m − b‖ = g has zero cost; with noise the tangential curvature is ~1e-5 of the radial."""
    X, b, _, m = tilted
    u = (m[0] - b[0]) / np.linalg.norm(m[0] - b[0])
    f = np.repeat((G * u + b[0])[None, :], T, axis=0)
    eig = np.linalg.eigvalsh(ls_hessian(f, b[0]))
    assert np.allclose(eig, [0.0, 0.0, 2.0 * T], rtol=0, atol=1e-8)
    other = f[0] - G * tilted_units(np.random.default_rng(12), 1, 40.0, 40.0)[0]  # 40° away on the sphere
    assert np.sum((np.linalg.norm(f - other, axis=1) - G) ** 2) < 1e-20
    h = m[0] / np.linalg.norm(m[0])
    eig = np.linalg.eigvalsh(ls_hessian(X[0], (np.linalg.norm(m[0]) - G) * h))
    assert abs(eig[2] - 2.0 * T) < 1.0 and np.max(np.abs(eig[:2])) < 1e-4 * 2.0 * T


def test_ls_trf_min_norm_recovers_the_along_gravity_component_only(tilted):
    X, b, meta, m = tilted
    got = LSTRF().predict(X, meta)
    along, _ = split_along(m, got - b)
    assert np.max(np.abs(along)) < 1.0 * MG  # h·b recovered
    assert np.max(np.abs(sphere_residual(m, got))) < 1.0 * MG
    _, tangential = split_along(m, got)
    assert np.max(tangential) < 1.0 * MG  # the minimum-norm point: no tangential part (x0 = 0)
    h = m / np.linalg.norm(m, axis=1, keepdims=True)
    min_norm_point = (np.linalg.norm(m, axis=1) - G)[:, None] * h
    assert np.max(np.linalg.norm(got - min_norm_point, axis=1)) < 1.0 * MG
    _, true_tangential = split_along(m, b)
    _, err_tangential = split_along(m, got - b)
    assert np.allclose(err_tangential, true_tangential, atol=1.0 * MG)  # so the tangential error is b_⊥


def test_ls_trf_as_written_wanders_along_the_valley(tilted):
    X, b, meta, m = tilted
    got = LSTRF(variant="as-written").predict(X, meta)
    assert np.max(np.abs(sphere_residual(m, got))) < 1.0 * MG  # it lands on the valley...
    _, tangential = split_along(m, got - b)
    assert np.min(tangential) > 100.0 * MG  # ...far from the truth along it
    # the same window tilted the other way ends elsewhere: the answer is the noise's, not b's
    assert np.ptp(np.linalg.norm(got, axis=1)) > 1.0


def test_ls_trf_as_written_lands_metres_per_second_squared_away_on_level_data():
    rng = np.random.default_rng(5)
    b = np.array([[0.1, -0.2, 0.15]])
    X = make_windows(rng, np.array([[0.0, 0.0, 1.0]]), b)
    got = LSTRF(variant="as-written").predict(X, make_meta(["dut"]))
    assert np.linalg.norm(got - b) > 1.0
    assert abs(sphere_residual(X.mean(axis=1), got)[0]) < 1.0 * MG


def test_a_tiny_ridge_does_not_pin_the_valley(tilted):
    """ridge = 1e-6 (relative to T) is below the noise anisotropy's pull Δσ²/g²."""
    X, b, meta, m = tilted
    _, tangential = split_along(m, LSTRF(ridge=1e-6).predict(X, meta) - b)
    assert np.median(tangential) > 100.0 * MG


def test_ls_trf_bounded_stays_within_the_datasheet_bounds(tilted):
    X, b, meta, m = tilted
    got = LSTRF(variant="bounded").predict(X, meta)
    assert np.all(np.abs(got) <= BOUNDS + 1e-12)
    assert np.max(np.abs(sphere_residual(m, got))) < 1.0 * MG
    at_bound = np.isclose(np.abs(got), BOUNDS, rtol=0, atol=1e-6)
    assert np.mean(at_bound.any(axis=1)) >= 0.75  # it slides until it meets the box
    _, tangential = split_along(m, got - b)
    assert np.median(tangential) > 50.0 * MG


def test_ls_trf_respects_x0_and_max_nfev(tilted):
    X, _, meta, m = tilted
    x0 = (0.05, -0.05, 0.0)
    got = LSTRF(x0=x0, ridge=1.0).predict(X[:2], meta.iloc[:2])
    h = m[:2] / np.linalg.norm(m[:2], axis=1, keepdims=True)
    tang = got - np.sum(got * h, axis=1)[:, None] * h
    tang_x0 = np.asarray(x0) - np.sum(np.asarray(x0) * h, axis=1)[:, None] * h
    assert np.max(np.linalg.norm(tang - tang_x0, axis=1)) < 1.0 * MG  # the valley point nearest x0
    res = LSTRF(variant="as-written", max_nfev=5).solve_window(X[0], G)
    assert res.nfev <= 6 and res.status == 0


def test_won2009_noise_free_is_rank_deficient_and_gives_the_minimum_norm_point():
    u = tilted_units(np.random.default_rng(6), 1, 30.0, 30.0)
    b = np.array([0.1, -0.15, 0.2])
    f = np.repeat((G * u[0] + b)[None, :], T, axis=0)
    res = won2009_solve(f, G)
    m = f.mean(axis=0)
    h = m / np.linalg.norm(m)
    assert res.converged and res.n_iter <= 10
    assert res.cond[0] > 1e12  # rank 1: lstsq drops the other directions, δ is minimum-norm
    assert np.allclose(res.b, (np.linalg.norm(m) - G) * h, rtol=0, atol=1e-9)


def test_won2009_with_noise_wanders_unless_truncated(tilted):
    X, b, meta, m = tilted
    solved = [Won2009().solve_window(X[i], G) for i in range(len(X))]
    got = np.array([r.b for r in solved])
    conds = np.concatenate([r.cond for r in solved])
    assert np.all((conds > 150.0) & (conds < 400.0))  # ≈ g/σ: ill-conditioned, but not cut by lstsq
    assert np.max(np.abs(sphere_residual(m, got))) < 1.0 * MG
    _, tangential = split_along(m, got - b)
    assert np.min(tangential) > 100.0 * MG
    assert np.array_equal(Won2009().predict(X, meta), got)
    cut = Won2009(rcond=1e-2).predict(X, meta)
    along, _ = split_along(m, cut - b)
    assert np.max(np.abs(along)) < 1.0 * MG
    _, tangential_cut = split_along(m, cut)
    assert np.max(tangential_cut) < 0.1 * MG


# ----------------------------------------------------------------------------- priors


def test_prior_mean_learns_device_means(informative):
    (X, y, meta), (Xt, _, mt) = informative
    pm = PriorMean().fit(X, y, meta)
    for d in ("d0", "d3"):
        assert np.allclose(pm.means_[d], y[meta["device"] == d].mean(axis=0), rtol=0, atol=1e-15)
        assert np.allclose(pm.stds_[d], y[meta["device"] == d].std(axis=0, ddof=1), rtol=0, atol=1e-15)
    unseen = mt.assign(device="new-board")
    assert np.allclose(pm.predict(Xt, unseen), pm.overall_, rtol=0, atol=0)
    assert np.allclose(pm.predict_std(Xt, unseen), pm.overall_std_, rtol=0, atol=0)


def test_condition_on_norm_first_pass_is_the_closed_form():
    rng = np.random.default_rng(8)
    m = G * sphere_units(rng, 5) + rng.normal(0.0, 0.1, (5, 3))
    L = rng.normal(0.0, 0.05, (3, 3))
    cov = L @ L.T + 1e-4 * np.eye(3)
    var = 1e-6
    got, post, _ = condition_on_norm(m, G, np.zeros(3), cov, var, n_iter=1)
    h = m / np.linalg.norm(m, axis=1, keepdims=True)
    y = np.linalg.norm(m, axis=1) - G
    for i in range(5):
        s = h[i] @ cov @ h[i] + var
        assert np.allclose(got[i], cov @ h[i] * y[i] / s, rtol=0, atol=1e-15)
        assert np.allclose(post[i], cov - np.outer(cov @ h[i], cov @ h[i]) / s, rtol=0, atol=1e-15)
    # iterated: a fixed point, where the norm residual is shrunk by σ²/(hᵀΣh + σ²) ≈ 4e-4
    full, _, _ = condition_on_norm(m, G, np.zeros(3), cov, var)
    more, _, _ = condition_on_norm(m, G, np.zeros(3), cov, var, n_iter=12)
    assert np.max(np.abs(full - more)) < 1e-10  # corrections of 10–20 mg here: slowest convergence
    assert np.all(np.abs(np.linalg.norm(m - full, axis=1) - G) < 1e-3 * np.abs(y))


def test_mixture_moments_follow_the_law_of_total_variance():
    means = np.array([[[0.0, 0.0, 0.0], [1.0, 2.0, 0.0]]])
    covs = np.array([[np.eye(3), 2.0 * np.eye(3)]])
    mean, cov, w = mixture_moments(np.log([[0.25, 0.75]]), means, covs)
    assert np.allclose(w, [[0.25, 0.75]]) and np.allclose(mean, [[0.75, 1.5, 0.0]])
    d0, d1 = means[0, 0] - mean[0], means[0, 1] - mean[0]
    want = 0.25 * (np.eye(3) + np.outer(d0, d0)) + 0.75 * (2.0 * np.eye(3) + np.outer(d1, d1))
    assert np.allclose(cov[0], want, rtol=0, atol=1e-15)


def test_gravity_prior_beats_prior_mean_and_is_calibrated(informative):
    (X, y, meta), (Xt, yt, mt) = informative
    pm = PriorMean().fit(X, y, meta)
    gp = GravityPrior().fit(X, y, meta)
    err_pm, err_gp = pm.predict(Xt, mt) - yt, gp.predict(Xt, mt) - yt
    assert rmse(err_gp) < 0.8 * rmse(err_pm)  # measured 9.28 vs 13.70 mg (0.68)
    z = err_gp / gp.predict_std(Xt, mt)
    assert np.all((z.std(axis=0) > 0.7) & (z.std(axis=0) < 1.4))
    # the component along the true up u = (m − b)/‖m − b‖ comes from the data: its error is
    # the window noise (0.08 mg) plus the curvature ‖e_⊥‖²/(2g) of the tangential error
    along, _ = split_along(Xt.mean(axis=1) - yt, err_gp)
    assert np.sqrt(np.mean(along**2)) < 0.3 * MG
    assert 0.05 * MG < gp.obs_std_ < 0.2 * MG  # ≈ σ_h/√T = 0.08 mg


def test_gravity_prior_unknown_device_uses_the_mixture(informative):
    (X, y, meta), (Xt, yt, mt) = informative
    gp = GravityPrior().fit(X, y, meta)
    unseen = mt.assign(device="new-board")
    got = gp.predict(Xt, unseen)
    pooled = GravityPrior(per_device=False).fit(X, y, meta)
    assert np.allclose(got, pooled.predict(Xt, mt), rtol=0, atol=1e-15)
    err_pm = PriorMean().fit(X, y, meta).predict(Xt, unseen) - yt
    assert rmse(got - yt) < 0.6 * rmse(err_pm)  # measured 36.9 vs 159.2 mg
    z = (got - yt) / gp.predict_std(Xt, unseen)
    assert np.all((z.std(axis=0) > 0.7) & (z.std(axis=0) < 1.4))


@pytest.mark.parametrize("params", [{}, {"direction_model": True, "per_device": False}])
def test_gravity_prior_save_load_round_trip(informative, tmp_path, params):
    (X, y, meta), (Xt, _, mt) = informative
    gp = GravityPrior(**params).fit(X, y, meta)
    path = tmp_path / "gp.json"
    gp.save(path)
    back = GravityPrior.load(path)
    assert back.get_params() == gp.get_params()
    assert back.to_dict() == gp.to_dict()
    assert np.array_equal(back.predict(Xt, mt), gp.predict(Xt, mt))
    assert np.array_equal(back.predict_std(Xt, mt), gp.predict_std(Xt, mt))
    assert json.loads(path.read_text(encoding="utf-8"))["format"] == GRAVITY_PRIOR_FORMAT
    assert [p.name for p in tmp_path.iterdir()] == ["gp.json"]  # atomic: no temporary left


def test_gravity_prior_load_rejects_bad_files(informative, tmp_path):
    (X, y, meta), _ = informative
    bad = tmp_path / "model.json"
    bad.write_bytes(b"\x80PK\x03\x04 not json")
    with pytest.raises(EstimatorError, match=r"model\.json: expected a saved gravity-prior .*not JSON"):
        GravityPrior.load(bad)
    bad.write_text('{"format": "ofbe-keras/3"}', encoding="utf-8")
    with pytest.raises(EstimatorError, match=r"model\.json: format: expected 'ofbe-gravity-prior/1', "
                                             r"found 'ofbe-keras/3'"):
        GravityPrior.load(bad)
    data = GravityPrior().fit(X, y, meta).to_dict()
    data["devices"]["d0"]["cov"] = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]]
    bad.write_text(json.dumps(data), encoding="utf-8")
    with pytest.raises(EstimatorError, match=r"devices\.d0\.cov: expected a symmetric positive definite"):
        GravityPrior.load(bad)
    with pytest.raises(EstimatorError, match="unreadable"):
        GravityPrior.load(tmp_path / "missing.json")
    with pytest.raises(EstimatorError, match="call fit first"):
        GravityPrior().to_dict()


def test_direction_prior_recovers_a_linear_mean():
    rng = np.random.default_rng(9)
    h = sphere_units(rng, 400)
    C = rng.normal(0.0, 0.2, (3, 3))
    y = np.array([0.1, -0.2, 0.3]) + h @ C.T + rng.normal(0.0, 0.01, (400, 3))
    mean, slope, centre, cov = direction_prior(y, h, 1e-4, 1e-6)
    assert np.allclose(slope, C, atol=0.005)
    assert np.allclose(mean + (h - centre) @ slope.T, y, atol=0.05)
    assert np.allclose(np.sqrt(np.diag(cov)), 0.01, rtol=0.15)


# ----------------------------------------------------------------------------- oracle


@pytest.mark.slow
def test_oracle_is_never_beaten_beyond_noise(campaign):
    truth, (X, y, meta), (Xt, yt, mt) = campaign
    methods = {
        "level-mean": LevelMean(), "ls-trf": LSTRF(), "ls-trf/bounded": LSTRF(variant="bounded"),
        "ls-trf/as-written": LSTRF(variant="as-written"), "won2009": Won2009(),
        "won2009/rcond": Won2009(rcond=1e-2), "prior-mean": PriorMean(), "gravity-prior": GravityPrior(),
        "gravity-prior/mixture": GravityPrior(per_device=False),
        "gravity-prior/direction": GravityPrior(direction_model=True),
    }
    oracle = Oracle(truth_dir=str(truth)).fit(X, y, meta)
    best = rmse(oracle.predict(Xt, mt) - yt)
    scores = {}
    for name, est in methods.items():
        if est.needs_fit:
            est.fit(X, y, meta)
        scores[name] = rmse(est.predict(Xt, mt) - yt)
    in_mg = {k: round(v / MG, 2) for k, v in scores.items()}
    assert all(best <= s + 0.5 * MG for s in scores.values()), (best / MG, in_mg)
    # the oracle's error is the unobservable tangential turn-on offset: ≈ √2·5 mg
    assert 4.0 * MG < best < 9.0 * MG
    assert scores["gravity-prior/direction"] < 0.6 * scores["gravity-prior"]
    z = (oracle.predict(Xt, mt) - yt) / oracle.predict_std(Xt, mt)
    assert np.all((z.std(axis=0) > 0.7) & (z.std(axis=0) < 1.4))


def test_oracle_on_the_simulators_own_truth_files(examples):
    """The committed tiny campaigns' truth: noise-free windows at each recording's mean
    reading (offset_model: A_effective·u_nominal·g + offset)."""
    cases = (("tiny-rotated", False), ("tiny-multi-position", False), ("tiny-gravity-aligned", True))
    for campaign, exact in cases:
        folder = examples / campaign / "_truth"
        rows = []
        for path in sorted(folder.glob("*.json")):
            data = json.loads(path.read_text(encoding="utf-8"))
            for rec in data["recordings"].values():
                for d, t in rec["devices"].items():
                    if "apparent_bias" in t:
                        A = np.asarray(data["devices"][d]["A_effective"])
                        mean = A @ np.asarray(t["u_nominal"]) * data["g_local"] + np.asarray(t["offset"])
                        delta = np.asarray(t["offset"]) - np.asarray(data["devices"][d]["offset_device"])
                        rows.append((d, data["g_local"], mean, np.asarray(t["apparent_bias"]), delta))
        meta = pd.DataFrame({"device": [r[0] for r in rows], "g_local": [r[1] for r in rows]})
        X = np.repeat(np.array([r[2] for r in rows])[:, None, :], 10, axis=1)
        labels = np.array([r[3] for r in rows])
        oracle = Oracle(truth_dir=str(folder)).fit(X, labels, meta)
        got = oracle.predict(X, meta)
        err = np.linalg.norm(got - labels, axis=1)
        if exact:  # gravity-aligned: u is an axis, the oracle is level-mean
            assert oracle.kind_ == "gravity-aligned"
            assert np.array_equal(got, LevelMean().predict(X, meta))
            assert np.max(err) < 1e-10  # the truth files round to 1e-12
        else:  # only the tangential part of the recording's offset change δ stays unknown
            delta = np.linalg.norm([r[4] for r in rows], axis=1)
            assert len(rows) >= 4 and np.all(err <= 1.05 * delta + 1e-6)


def test_oracle_reads_only_device_level_truth(examples, tmp_path):
    folder = examples / "tiny-rotated" / "_truth"
    stripped = tmp_path / "_truth"
    shutil.copytree(folder, stripped)
    for path in stripped.glob("*.json"):
        data = json.loads(path.read_text(encoding="utf-8"))
        data["recordings"] = {}  # no recording's offset, apparent bias or direction
        path.write_text(json.dumps(data), encoding="utf-8")
    rng = np.random.default_rng(10)
    u = sphere_units(rng, 6)
    X = make_windows(rng, u, rng.normal(0.0, 0.1, (6, 3)))
    meta = make_meta(["sparkfun-1", "sparkfun-2"] * 3)
    full = Oracle(truth_dir=str(folder)).fit(X, np.zeros((6, 3)), meta)
    bare = Oracle(truth_dir=str(stripped)).fit(X, np.zeros((6, 3)), meta)
    assert np.array_equal(full.predict(X, meta), bare.predict(X, meta))


def test_oracle_refuses_without_truth(campaign, tmp_path):
    truth, (X, y, meta), _ = campaign
    X, y, meta = X[:2], y[:2], meta.iloc[:2]
    with pytest.raises(EstimatorError, match="expected truth_dir .*found None"):
        Oracle().fit(X, y, meta)
    with pytest.raises(EstimatorError, match="found no folder"):
        Oracle(truth_dir=str(tmp_path / "absent")).fit(X, y, meta)
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(EstimatorError, match=r"expected ofbe-truth/1 truth files \(\*\.json\), found none"):
        Oracle(truth_dir=str(empty)).fit(X, y, meta)
    (empty / "x.json").write_text("not json", encoding="utf-8")
    with pytest.raises(EstimatorError, match=r"x\.json: expected a ofbe-truth/1 JSON truth file"):
        Oracle(truth_dir=str(empty)).fit(X, y, meta)
    (empty / "x.json").write_text('{"format": "ofbe-simulation/1"}', encoding="utf-8")
    with pytest.raises(EstimatorError, match=r"x\.json: format: expected 'ofbe-truth/1'"):
        Oracle(truth_dir=str(empty)).fit(X, y, meta)
    with pytest.raises(EstimatorError, match="expected devices of the truth folder .*found sparkfun-9"):
        Oracle(truth_dir=str(truth)).fit(X, y, meta.assign(device="sparkfun-9"))
    oracle = Oracle(truth_dir=str(truth)).fit(X, y, meta)
    with pytest.raises(EstimatorError, match="found sparkfun-9"):
        oracle.predict(X, meta.assign(device="sparkfun-9"))
