"""The window-batched solvers against the per-window ones they replace.

``won2009`` is checked against ``numpy.linalg.lstsq`` steps (the per-window method as the
paper writes it) and every ``ls-trf`` variant, bounded too (estimates at the bound, the same
evaluation counts), against ``scipy.optimize.least_squares`` itself, window by window, on
tilted noisy windows like the paper's (the as-written variant slides metres per second
squared along the flat valley, the hardest case for agreement); the benchmark runner's
one-call prediction of every fold's test windows against predicting fold by fold.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from ofbe_model.benchmark import runner
from ofbe_model.benchmark.runner import BenchmarkParams, run_protocol
from ofbe_model.estimators import batched, batched_bounds, physics
from ofbe_model.estimators.batched import ls_trf_batch, won2009_batch
from ofbe_model.estimators.batched_bounds import ls_trf_bounded_batch
from ofbe_model.estimators.common import MG
from ofbe_model.estimators.physics import LSTRF, LevelMean, Won2009, ls_trf_solve, won2009_solve

G = 9.795382950829522
T = 3000
SIGMA = np.array([0.0361, 0.0361, 0.052])
AGREE = 1e-9
"""m/s²: the batched estimates must be the per-window ones to this (they differ by rounding,
≈ 1e-10 after 300 evaluations along the valley, ≈ 1e-15 where the problem is well posed)."""


def windows(seed: int, n: int, tilt_deg: tuple[float, float] = (5.0, 60.0), t: int = T,
            sigma: np.ndarray | float = SIGMA) -> np.ndarray:
    """(n, t, 3) resting windows: g along a random tilted up, a bias of tens of mg, noise."""
    rng = np.random.default_rng(seed)
    tilt = np.radians(rng.uniform(*tilt_deg, n))
    az = rng.uniform(0.0, 2.0 * np.pi, n)
    up = np.stack([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)], axis=1)
    b = rng.normal(0.0, 0.3, (n, 3))
    return (G * up + b)[:, None, :] + rng.standard_normal((n, t, 3)) * sigma


def meta(n: int) -> pd.DataFrame:
    return pd.DataFrame({"device": ["dut"] * n, "g_local": np.full(n, G)})


def won_lstsq(f: np.ndarray, g: float, tol: float = 1e-6, max_iter: int = 500,
              rcond: float | None = None) -> np.ndarray:
    """Won & Golnaraghi as the paper writes it: lstsq of 2·u·δ = ‖u‖² − g² per iteration."""
    b = np.zeros(3)
    for _ in range(max_iter):
        u = f - b
        delta = np.linalg.lstsq(2.0 * u, np.einsum("ij,ij->i", u, u) - g * g, rcond=rcond)[0]
        b = b + delta
        if float(np.linalg.norm(delta)) < tol:
            break
    return b


# ----------------------------------------------------------------------------- won2009


@pytest.mark.parametrize("rcond, max_iter", [(None, 500), (1e-2, 500), (None, 7)])
def test_won2009_batch_is_lstsq_step_for_step(rcond, max_iter):
    X = windows(1, 6)
    got = won2009_batch(X, np.full(6, G), rcond=rcond, max_iter=max_iter)
    want = np.array([won_lstsq(X[i], G, rcond=rcond, max_iter=max_iter) for i in range(6)])
    assert np.max(np.abs(got - want)) < AGREE
    if rcond is None and max_iter == 500:
        assert np.min(np.linalg.norm(got, axis=1)) > 0.5  # it did wander along the valley


def test_won2009_gives_the_same_bits_alone_or_in_any_batch(monkeypatch):
    X = windows(2, 7).astype(np.float32)
    g = np.full(7, G)
    alone = np.array([won2009_solve(X[i], G).b for i in range(7)])
    assert np.array_equal(won2009_batch(X, g), alone)
    monkeypatch.setattr(batched, "BATCH_WINDOWS", 3)  # batches of 3, 3 and 1
    assert np.array_equal(won2009_batch(X, g), alone)
    assert np.array_equal(Won2009().predict(X, meta(7)), alone)


def test_won2009_diagnostics_and_the_rank_deficient_window():
    res = won2009_solve(windows(3, 1)[0], G, max_iter=20)
    assert res.n_iter == 20 and not res.converged and res.cond.shape == (20,)
    assert np.all((res.cond > 150.0) & (res.cond < 400.0))  # ≈ g/σ, as lstsq's singular values
    up = np.array([0.3, -0.2, 0.9]) / np.linalg.norm([0.3, -0.2, 0.9])
    f = np.repeat((G * up + 0.1)[None, :], T, axis=0)  # no noise: the design has rank 1
    res = won2009_solve(f, G)
    assert res.converged and res.cond[0] > 1e12
    m = f.mean(axis=0)
    assert np.allclose(res.b, (np.linalg.norm(m) - G) * m / np.linalg.norm(m), rtol=0, atol=1e-9)


# ----------------------------------------------------------------------------- ls-trf


@pytest.mark.parametrize("kw", [
    {},                                                   # as-written: 300 evaluations along the valley
    {"ridge_weight": 1e-2 * T},                           # min-norm
    {"ridge_weight": 1.0, "x0": np.array([0.05, -0.05, 0.0])},
    {"max_nfev": 4},
    {"x0": np.array([0.2, 0.1, -0.1]), "max_nfev": 40},
])
def test_ls_trf_batch_is_scipys_trf(kw):
    X = windows(4, 4)
    got = ls_trf_batch(X, np.full(4, G), **kw)
    want = np.array([ls_trf_solve(X[i], G, **kw).b for i in range(4)])
    assert np.max(np.abs(got - want)) < AGREE


def test_ls_trf_batch_on_level_windows_and_small_t():
    """Level windows (the gravity-aligned campaign) and a window length far from 3000."""
    X = windows(5, 3, tilt_deg=(0.0, 0.5), t=700)
    got = ls_trf_batch(X, np.full(3, G))
    want = np.array([ls_trf_solve(X[i], G).b for i in range(3)])
    assert np.max(np.abs(got - want)) < AGREE
    assert np.min(np.linalg.norm(got, axis=1)) > 1.0  # metres per second squared away, as scipy


def test_ls_trf_batch_stops_where_scipy_stops():
    """A well-posed problem (strong ridge) ends by scipy's ftol/xtol tests after a few evaluations."""
    X = windows(6, 3)
    for i in range(3):
        res = ls_trf_solve(X[i], G, ridge_weight=1e-2 * T)
        assert res.status > 0 and res.nfev < 20
    trf = batched.BatchedTRF(batched.component_major(X, slice(0, 3)), np.full(3, G), 1e-2 * T, np.zeros(3),
                             300)
    trf.run()
    assert trf.nfev.tolist() == [ls_trf_solve(X[i], G, ridge_weight=1e-2 * T).nfev for i in range(3)]


def test_lstrf_predict_batches_every_variant():
    X = windows(7, 3)
    m = meta(3)
    for variant in ("as-written", "min-norm", "bounded"):
        est = LSTRF(variant=variant)
        want = np.array([est.solve_window(X[i], G).b for i in range(3)])
        assert np.max(np.abs(est.predict(X, m) - want)) < AGREE, variant


# ----------------------------------------------------------------------------- ls-trf with bounds

BOX = np.array([150.0, 150.0, 250.0]) * MG  # the ADXL345 datasheet limits, m/s²


@pytest.mark.parametrize("seed, lower, upper, kw", [
    (10, -BOX, BOX, {}),                                          # the bounded variant
    (10, -BOX, BOX, {"x0": np.array([0.2, -0.1, 0.3])}),
    (10, -BOX, BOX, {"max_nfev": 5}),                             # stops on the budget
    (10, np.array([-np.inf, -0.5, -1.0]), np.array([0.3, np.inf, 1.0]), {}),  # one-sided
    (12, -0.2 * np.ones(3), 0.2 * np.ones(3), {}),                # a tight box: up to 3 active
])
def test_ls_trf_bounded_batch_is_scipys_trf_bounds(seed, lower, upper, kw):
    """Every window walks scipy's reflective path: the same evaluations, the same estimate
    to rounding, at the bound where scipy's is."""
    X = windows(seed, 6)
    got, nfev, ok = ls_trf_bounded_batch(X, np.full(6, G), lower, upper, **kw)
    ref = [ls_trf_solve(X[i], G, lower=lower, upper=upper, **kw) for i in range(6)]
    want = np.array([r.b for r in ref])
    assert ok.all()
    assert np.max(np.abs(got - want)) < AGREE
    assert nfev.tolist() == [r.nfev for r in ref]
    assert np.all((got >= lower) & (got <= upper))
    if "max_nfev" not in kw:  # windows end on the box: some components at a bound
        at_bound = (np.abs(want - lower) < 1e-9) | (np.abs(want - upper) < 1e-9)
        assert at_bound.any(axis=1).sum() >= 4
        assert np.array_equal(at_bound, (np.abs(got - lower) < 1e-9) | (np.abs(got - upper) < 1e-9))


def test_ls_trf_bounded_batch_on_level_windows_and_small_t():
    X = windows(11, 4, tilt_deg=(0.0, 0.5), t=700).astype(np.float32)
    got, nfev, ok = ls_trf_bounded_batch(X, np.full(4, G), -BOX, BOX)
    ref = [ls_trf_solve(np.asarray(X[i], dtype=np.float64), G, lower=-BOX, upper=BOX) for i in range(4)]
    assert ok.all() and nfev.tolist() == [r.nfev for r in ref]
    assert np.max(np.abs(got - np.array([r.b for r in ref]))) < AGREE


def test_lstrf_bounded_falls_back_to_scipy_for_a_window_it_cannot_follow(monkeypatch):
    """A window marked by the batch (scipy's intersect_trust_region would raise) is solved
    by scipy itself; the others keep the batch's estimates."""
    X = windows(13, 4)
    real = batched_bounds._TRFBounds._select

    def select(self, idx, p_h):
        out = real(self, idx, p_h)
        self.ok[idx[idx == 2]] = False
        return out

    monkeypatch.setattr(batched_bounds._TRFBounds, "_select", select)
    solved: list[int] = []
    real_solve = physics.ls_trf_solve

    def counting(f, g, **kw):
        solved.append(len(f))
        return real_solve(f, g, **kw)

    monkeypatch.setattr(physics, "ls_trf_solve", counting)
    est = LSTRF(variant="bounded")
    got = est.predict(X, meta(4))
    assert solved == [T]  # window 2 alone, per window
    want = np.array([real_solve(X[i], G, lower=-BOX, upper=BOX).b for i in range(4)])
    assert np.array_equal(got[2], want[2])
    assert np.max(np.abs(got - want)) < AGREE


def test_batches_split_anywhere(monkeypatch):
    X = windows(8, 5)
    g = np.full(5, G)
    whole = ls_trf_batch(X, g, ridge_weight=30.0)
    bounded = ls_trf_bounded_batch(X, g, -BOX, BOX)[0]
    monkeypatch.setattr(batched, "BATCH_WINDOWS", 2)
    monkeypatch.setattr(batched_bounds, "BATCH_WINDOWS", 3)
    assert np.max(np.abs(ls_trf_batch(X, g, ridge_weight=30.0) - whole)) < 1e-13
    assert np.max(np.abs(ls_trf_bounded_batch(X, g, -BOX, BOX)[0] - bounded)) < 1e-13


# ----------------------------------------------------------------------------- the runner


def fake_dataset(n_rec: int = 12, per_rec: int = 2) -> SimpleNamespace:
    """What run_protocol reads of a dataset: meta, X, y, info (two devices, 3 folds)."""
    n = n_rec * per_rec
    rec = np.repeat(np.arange(n_rec), per_rec)
    meta_df = pd.DataFrame({
        "campaign": "fake", "device": np.where(rec % 2 == 0, "d1", "d2"), "window_id": np.arange(n),
        "window_index": np.tile(np.arange(per_rec), n_rec), "g_local": G,
        "fold_grouped": rec % 3, "bias_x": 0.0, "bias_y": 0.0, "bias_z": 0.0})
    return SimpleNamespace(meta=meta_df, X=windows(9, n, t=400).astype(np.float32),
                           y=np.zeros((n, 3)), info={"kind": "rotated"})


def test_run_protocol_predicts_per_window_methods_once_with_the_same_numbers(monkeypatch):
    ds = fake_dataset()
    monkeypatch.setattr(runner, "load_dataset", lambda _: ds)
    calls: list[int] = []
    real = Won2009.predict

    def counting(self, X, m):
        calls.append(len(X))
        return real(self, X, m)

    monkeypatch.setattr(Won2009, "predict", counting)
    params = BenchmarkParams(methods=("level-mean", "won2009", "ls-trf"))
    pred, seconds = run_protocol("fake", "grouped", params, progress=False, scheduler="processes")
    assert calls == [12]  # every test signal (window 0 of each recording) in one call
    assert set(seconds) == {"level-mean", "won2009", "ls-trf"}
    blind = ds.meta.drop(columns=["bias_x", "bias_y", "bias_z"])
    for (method, fold), rows in pred.groupby(["method", "fold"]):
        idx = rows["window_id"].to_numpy()
        est = {"level-mean": LevelMean(), "won2009": Won2009(), "ls-trf": LSTRF()}[method]
        alone = est.predict(ds.X[idx], blind.iloc[idx].reset_index(drop=True))
        got = rows[["yhat_x", "yhat_y", "yhat_z"]].to_numpy()
        tol = 0.0 if method != "ls-trf" else 1e-13
        assert np.max(np.abs(got - alone)) <= tol, (method, fold)
        assert math.isnan(rows["std_x"].iloc[0])
