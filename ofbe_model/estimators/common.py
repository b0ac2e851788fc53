"""The physics and prior baselines, the new gravity-prior estimator and the simulator oracle.

Registered names (methods.md §Estimators, docs/estimators.md):

- ``level-mean`` (:class:`LevelMean`): window mean − g_local·(nearest signed axis);
- ``ls-trf`` (:class:`LSTRF`): min over b of Σ(‖f_i − b‖ − g)² by scipy's TRF, in three
  honest variants (``as-written``, ``bounded``, ``min-norm``);
- ``won2009`` (:class:`Won2009`): iterative linear solve of 2·u_i·δ = ‖u_i‖² − g²;
- ``prior-mean`` (:class:`PriorMean`): the training-label mean per device;
- ``gravity-prior`` (:class:`GravityPrior`): along-gravity component from the norm of the
  window mean, tangential components from a Gaussian prior learned on the labels;
- ``oracle`` (:class:`Oracle`): the posterior mean under the simulator's true device
  distributions (simulated data only; the one estimator that reads truth files).

Conventions: a window is (T, 3) specific force in m/s², sensor frame; a batch is (N, T, 3);
biases and standard deviations are (N, 3) m/s². ``g`` is the local gravity magnitude from
``meta["g_local"]``, m/s². ``h`` is the unit direction of the window's mean specific force
(the measured "up"). A single stationary window determines only the bias component along
``h``; the maths of that, and what each estimator does about it, is in docs/estimators.md.

The maths lives in small pure functions (:func:`window_means`, :func:`nearest_axes`,
:func:`ls_trf_solve`, :func:`won2009_solve`, :func:`condition_on_norm`,
:func:`mixture_moments`, :func:`gaussian_prior`, :func:`floor_cov`, :func:`direction_prior`,
:func:`read_truth_devices`); the classes wire them to the
:class:`~ofbe_model.base.Estimator` interface.
"""

from __future__ import annotations

import json
import math
import numbers
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd
from scipy.optimize import least_squares

from ofbe_data.atomic import write_bytes_atomic
from ofbe_data.gravity import G0
from ofbe_model.base import Estimator, EstimatorError, check_inputs, register

__all__ = [
    "GRAVITY_PRIOR_FORMAT",
    "LS_VARIANTS",
    "MG",
    "TRUTH_FORMAT",
    "GravityPrior",
    "LSResult",
    "LSTRF",
    "LevelMean",
    "Oracle",
    "PriorMean",
    "TruthDevice",
    "Won2009",
    "WonResult",
    "condition_on_norm",
    "direction_prior",
    "floor_cov",
    "gaussian_prior",
    "ls_trf_solve",
    "mixture_moments",
    "nearest_axes",
    "read_truth_devices",
    "window_means",
    "won2009_solve",
]

MG = G0 * 1e-3
"""One milli-g in m/s² (a unit conversion with standard gravity g0 = 9.80665 m/s²)."""

LS_VARIANTS = ("as-written", "bounded", "min-norm")
"""Variants of ``ls-trf`` (docs/estimators.md)."""

GRAVITY_PRIOR_FORMAT = "ofbe-gravity-prior/1"
"""``format`` field of a saved :class:`GravityPrior` (JSON)."""

TRUTH_FORMAT = "ofbe-truth/1"
"""``format`` field of the simulator's truth files, read by :class:`Oracle` only."""

GN_ITERATIONS = 6
"""Gauss–Newton relinearisations of the norm observation in :func:`condition_on_norm`. The
first linearises at the prior mean; the linearisation error after it is ‖Δb_⊥‖²/(2g) for a
tangential correction Δb_⊥ (0.013 mg for 5 mg), and each further pass shrinks the remaining
error by about ‖Δb_⊥‖/g (5e-3 for 5 mg); six passes reach float64 round-off in practice."""


# ----------------------------------------------------------------------------- small helpers


def window_means(windows: np.ndarray) -> np.ndarray:
    """Mean specific force of each window, accumulated in float64.

    Parameters
    ----------
    windows
        (N, T, 3) m/s² (float32 or float64).

    Returns
    -------
    ndarray, shape (N, 3)
        m/s².
    """
    return np.mean(np.asarray(windows), axis=1, dtype=np.float64)


def nearest_axes(means: np.ndarray) -> np.ndarray:
    """Signed sensor axis closest to each mean reading (vectorised
    :func:`ofbe_data.orientation.nearest_axis`).

    Parameters
    ----------
    means
        (N, 3) mean specific force, any unit.

    Returns
    -------
    ndarray, shape (N, 3)
        ``±e_k`` with k = argmax |m_k| and the sign of m_k (+ for m_k = 0).
    """
    m = np.asarray(means, dtype=np.float64)
    k = np.argmax(np.abs(m), axis=1)
    rows = np.arange(m.shape[0])
    out = np.zeros_like(m)
    out[rows, k] = np.where(m[rows, k] >= 0.0, 1.0, -1.0)
    return out


def _unit_rows(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Row-wise unit vectors and norms of (N, 3) vectors."""
    n = np.linalg.norm(v, axis=1)
    return v / n[:, None], n


def _g_local(meta: pd.DataFrame) -> np.ndarray:
    """``meta["g_local"]`` as float64, checked finite and positive, m/s²."""
    try:
        g = meta["g_local"].to_numpy(dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise EstimatorError(f"meta: expected numeric g_local (m/s²), found {exc}") from None
    bad = ~(np.isfinite(g) & (g > 0.0))
    if bad.any():
        raise EstimatorError(f"meta: expected finite positive g_local (m/s²), found {g[bad][0]!r}")
    return g


def _devices(meta: pd.DataFrame) -> np.ndarray:
    """``meta["device"]`` as an array of str."""
    return meta["device"].astype(str).to_numpy()


def _as_float_tuple(value: Any, n: int, what: str) -> np.ndarray:
    """A parameter that must be n finite numbers, as a float64 array."""
    try:
        arr = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise EstimatorError(f"{what}: expected {n} numbers, found {value!r}") from None
    if arr.shape != (n,) or not np.all(np.isfinite(arr)):
        raise EstimatorError(f"{what}: expected {n} finite numbers, found {value!r}")
    return arr


def _is_int(value: Any) -> bool:
    """Whether value is an integer (numpy integers included, bool excluded)."""
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


def _is_real(value: Any) -> bool:
    """Whether value is a real number (numpy floats included, bool excluded)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool)


def _check_fitted(est: Estimator, attr: str) -> None:
    if not hasattr(est, attr):
        raise EstimatorError(f"{est.name}: expected a fitted estimator (call fit first), found it unfitted")


# ----------------------------------------------------------------------------- level-mean


@register
class LevelMean(Estimator):
    """``level-mean``: the window mean minus g_local along the nearest signed axis.

    b̂ = m − g·e, e = ±e_k with k = argmax |m_k| (:func:`nearest_axes`). Exact when the
    sensor is levelled (one axis along gravity); a tilt θ leaks g·sin θ into the estimate
    (asin(0.05) = 2.87° for 50 mg). No fit, no uncertainty.
    """

    name: ClassVar[str] = "level-mean"
    needs_fit: ClassVar[bool] = False

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Bias estimates, (N, 3) m/s²."""
        check_inputs(windows, meta)
        m = window_means(windows)
        return m - _g_local(meta)[:, None] * nearest_axes(m)


# ----------------------------------------------------------------------------- ls-trf


@dataclass(frozen=True)
class LSResult:
    """One ``ls-trf`` solve.

    Attributes
    ----------
    b
        (3,) bias estimate, m/s².
    nfev
        Residual evaluations used.
    status
        scipy's termination status (> 0: a convergence test passed; 0: ``max_nfev`` reached).
    cost
        Final ½·Σ residual², (m/s²)² (the ridge term included for ``min-norm``).
    """

    b: np.ndarray
    nfev: int
    status: int
    cost: float


def ls_trf_solve(f: np.ndarray, g: float, *, ridge_weight: float = 0.0,
                 lower: np.ndarray | None = None, upper: np.ndarray | None = None,
                 x0: np.ndarray | None = None, max_nfev: int | None = None) -> LSResult:
    """min over b of Σ_i (‖f_i − b‖ − g)² [+ ridge_weight·‖b − x0‖²] by TRF, started at x0.

    Residuals r_i = ‖f_i − b‖ − g with the analytic Jacobian ∂r_i/∂b = −(f_i − b)ᵀ/‖f_i − b‖;
    with a ridge, three more residuals √ridge_weight·(b − x0) with Jacobian √ridge_weight·I.

    Parameters
    ----------
    f
        (T, 3) specific force samples, m/s².
    g
        Local gravity, m/s².
    ridge_weight
        Absolute ridge weight (dimensionless; ``LSTRF`` passes ridge·T). 0: none.
    lower, upper
        (3,) bounds on b, m/s² (None: unbounded).
    x0
        (3,) start and ridge centre, m/s² (None: zero).
    max_nfev
        Residual evaluations allowed (None: scipy's default, 100·3).

    Returns
    -------
    LSResult
    """
    f = np.asarray(f, dtype=np.float64)
    start = np.zeros(3) if x0 is None else np.asarray(x0, dtype=np.float64)
    w = math.sqrt(ridge_weight) if ridge_weight > 0.0 else 0.0
    eye_w = w * np.eye(3)

    def residuals(b: np.ndarray) -> np.ndarray:
        r = np.linalg.norm(f - b, axis=1) - g
        return np.concatenate([r, w * (b - start)]) if w else r

    def jacobian(b: np.ndarray) -> np.ndarray:
        d = f - b
        jac = -d / np.linalg.norm(d, axis=1)[:, None]
        return np.vstack([jac, eye_w]) if w else jac

    lo = -np.inf if lower is None else np.asarray(lower, dtype=np.float64)
    hi = np.inf if upper is None else np.asarray(upper, dtype=np.float64)
    res = least_squares(residuals, start, jac=jacobian, method="trf", bounds=(lo, hi), max_nfev=max_nfev)
    return LSResult(np.asarray(res.x, dtype=np.float64), int(res.nfev), int(res.status), float(res.cost))


@register
class LSTRF(Estimator):
    """``ls-trf``: the paper's norm-constrained least squares, per window (paper §2.3.1).

    b̂ = argmin_b Σ_i (‖f_i − b‖ − g)² by ``scipy.optimize.least_squares(method="trf")``
    from x0, with the analytic Jacobian (:func:`ls_trf_solve`). One stationary window only
    fixes the sphere ‖m − b‖ = g (m the window mean); along it the cost is flat to first
    order and tilts only with the anisotropy of the noise (docs/estimators.md), so:

    - ``as-written``: x0, no bounds, no ridge. Slides along the valley towards the sensor's
      lowest-noise axis and lands metres per second squared away (tested).
    - ``bounded``: the ADXL345 datasheet limits |b_x|, |b_y| ≤ 150 mg, |b_z| ≤ 250 mg
      (``bounds_mg``, converted with g0). Slides until it meets the box.
    - ``min-norm`` (default): adds the ridge residual √(ridge·T)·(b − x0), so the solution is
      the point of the valley nearest x0: for x0 = 0, (‖m‖ − g)·h. The ridge is relative to
      the T data residuals; the default 1e-2 trades an along-gravity shrinkage of ridge/(1 +
      ridge) ≈ 1 % of h·b against a tangential pull of at most Δσ²/(2·g·ridge) ≈ 0.7 mg
      from the noise anisotropy Δσ² = σ_z² − σ_x² of the ADXL345 (docs/estimators.md; a
      ridge of 1e-6·T does not beat that pull and wanders like ``as-written``).

    Parameters
    ----------
    variant
        One of :data:`LS_VARIANTS`.
    ridge
        ``min-norm`` ridge relative to T (the weight is ridge·T), dimensionless, > 0.
    bounds_mg
        ``bounded`` limits (x, y, z) on |b|, mg (g0 = 9.80665 m/s²).
    x0
        Start (and ridge centre), (x, y, z) m/s².
    max_nfev
        Residual evaluations allowed per window (None: scipy's default 300).
    """

    name: ClassVar[str] = "ls-trf"
    needs_fit: ClassVar[bool] = False

    def __init__(self, variant: str = "min-norm", ridge: float = 1e-2,
                 bounds_mg: tuple[float, float, float] = (150.0, 150.0, 250.0),
                 x0: tuple[float, float, float] = (0.0, 0.0, 0.0), max_nfev: int | None = None) -> None:
        self.variant = variant
        self.ridge = ridge
        self.bounds_mg = bounds_mg
        self.x0 = x0
        self.max_nfev = max_nfev
        self._solver_kwargs(3000)  # validate early: make_estimator reports bad parameters

    def _solver_kwargs(self, n_samples: int) -> dict[str, Any]:
        """Keyword arguments of :func:`ls_trf_solve` for windows of n_samples samples."""
        if self.variant not in LS_VARIANTS:
            raise EstimatorError(f"ls-trf variant: expected one of {', '.join(LS_VARIANTS)}, "
                                 f"found {self.variant!r}")
        x0 = _as_float_tuple(self.x0, 3, "ls-trf x0 (m/s²)")
        if self.max_nfev is not None and not (_is_int(self.max_nfev) and self.max_nfev > 0):
            raise EstimatorError(f"ls-trf max_nfev: expected a positive integer or None, "
                                 f"found {self.max_nfev!r}")
        kw: dict[str, Any] = {"x0": x0, "max_nfev": self.max_nfev}
        if self.variant == "min-norm":
            if not (_is_real(self.ridge) and math.isfinite(self.ridge) and self.ridge > 0):
                raise EstimatorError(f"ls-trf ridge: expected a finite number > 0, found {self.ridge!r}")
            kw["ridge_weight"] = float(self.ridge) * n_samples
        elif self.variant == "bounded":
            bound = _as_float_tuple(self.bounds_mg, 3, "ls-trf bounds_mg") * MG
            if np.any(bound <= 0):
                raise EstimatorError(f"ls-trf bounds_mg: expected three limits > 0, found {self.bounds_mg!r}")
            if np.any(np.abs(x0) >= bound):
                raise EstimatorError(f"ls-trf x0: expected a start inside the bounds ±{bound.tolist()} m/s², "
                                     f"found {x0.tolist()}")
            kw["lower"], kw["upper"] = -bound, bound
        return kw

    def solve_window(self, window: np.ndarray, g: float) -> LSResult:
        """The full solver result of one (T, 3) window, m/s² (for diagnostics)."""
        w = np.asarray(window, dtype=np.float64)
        return ls_trf_solve(w, g, **self._solver_kwargs(w.shape[0]))

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Bias estimates, (N, 3) m/s² (one TRF solve per window)."""
        check_inputs(windows, meta)
        g = _g_local(meta)
        kw = self._solver_kwargs(np.asarray(windows).shape[1])
        out = np.empty((len(g), 3))
        for i in range(len(g)):
            out[i] = ls_trf_solve(np.asarray(windows[i], dtype=np.float64), float(g[i]), **kw).b
        return out


# ----------------------------------------------------------------------------- won2009


@dataclass(frozen=True)
class WonResult:
    """One ``won2009`` solve.

    Attributes
    ----------
    b
        (3,) bias estimate, m/s².
    n_iter
        Linear solves done.
    converged
        Whether the last step was shorter than the tolerance.
    cond
        Condition number s_max/s_min of the design 2·U at each iteration, (n_iter,).
    """

    b: np.ndarray
    n_iter: int
    converged: bool
    cond: np.ndarray


def won2009_solve(f: np.ndarray, g: float, *, tol: float = 1e-6, max_iter: int = 500,
                  rcond: float | None = None) -> WonResult:
    """Won & Golnaraghi's iterative linear solve for the bias (paper §2.3.2), from b = 0.

    Each iteration: u_i = f_i − b; solve 2·u_i·δ = ‖u_i‖² − g² for δ in least squares over
    the T samples (``numpy.linalg.lstsq``); b += δ; stop when ‖δ‖ < tol. This is
    Gauss–Newton on the algebraic cost Σ(‖f_i − b‖² − g²)², which has the same flat valley
    as ``ls-trf``. The design 2·U is rank 1 without noise (lstsq then gives the minimum-norm
    δ: the along-gravity step only); with noise its two small singular values are ≈ 2σ√T,
    condition number ≈ g/σ ≈ 200–300 for the ADXL345, not small enough for lstsq's default
    cut-off, so the tangential steps follow the noise. ``rcond`` = 1e-2 cuts them.

    Parameters
    ----------
    f
        (T, 3) specific force samples, m/s².
    g
        Local gravity, m/s².
    tol
        Step length that stops the iteration, m/s².
    max_iter
        Most linear solves.
    rcond
        ``lstsq``'s relative cut-off for small singular values (None: numpy's default,
        machine epsilon × T).

    Returns
    -------
    WonResult
    """
    f = np.asarray(f, dtype=np.float64)
    b = np.zeros(3)
    conds: list[float] = []
    converged = False
    g2 = g * g
    for _ in range(max_iter):
        u = f - b
        rhs = np.einsum("ij,ij->i", u, u) - g2
        delta, _, _, sv = np.linalg.lstsq(2.0 * u, rhs, rcond=rcond)
        conds.append(float(sv[0] / sv[-1]) if sv[-1] > 0 else math.inf)
        b = b + delta
        if float(np.linalg.norm(delta)) < tol:
            converged = True
            break
    return WonResult(b, len(conds), converged, np.asarray(conds))


@register
class Won2009(Estimator):
    """``won2009``: iterative linear least squares on 2·u_i·δ = ‖u_i‖² − g² (paper §2.3.2).

    See :func:`won2009_solve`. Like ``ls-trf`` as written, it recovers the norm constraint
    ‖m − b‖ = g but not the tangential components: with the default ``rcond`` it drifts
    along the valley for hundreds of iterations (docs/estimators.md).

    Parameters
    ----------
    tol
        Step length that stops the iteration, m/s².
    max_iter
        Most linear solves per window.
    rcond
        ``lstsq`` cut-off (None: numpy's default, the method as written; 1e-2: drop the
        noise-only directions, giving the minimum-norm answer like ``ls-trf`` min-norm).
    """

    name: ClassVar[str] = "won2009"
    needs_fit: ClassVar[bool] = False

    def __init__(self, tol: float = 1e-6, max_iter: int = 500, rcond: float | None = None) -> None:
        self.tol = tol
        self.max_iter = max_iter
        self.rcond = rcond
        self._check()

    def _check(self) -> None:
        if not (_is_real(self.tol) and math.isfinite(self.tol) and self.tol > 0):
            raise EstimatorError(f"won2009 tol: expected a number > 0 (m/s²), found {self.tol!r}")
        if not (_is_int(self.max_iter) and self.max_iter > 0):
            raise EstimatorError(f"won2009 max_iter: expected a positive integer, found {self.max_iter!r}")
        if self.rcond is not None and not (_is_real(self.rcond) and 0 <= self.rcond < 1):
            raise EstimatorError(f"won2009 rcond: expected None or a number in [0, 1), found {self.rcond!r}")

    def solve_window(self, window: np.ndarray, g: float) -> WonResult:
        """The full solver result of one (T, 3) window, m/s² (for diagnostics)."""
        self._check()
        return won2009_solve(window, g, tol=self.tol, max_iter=self.max_iter, rcond=self.rcond)

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Bias estimates, (N, 3) m/s²."""
        check_inputs(windows, meta)
        self._check()
        g = _g_local(meta)
        out = np.empty((len(g), 3))
        for i in range(len(g)):
            out[i] = won2009_solve(windows[i], float(g[i]), tol=self.tol, max_iter=self.max_iter,
                                   rcond=self.rcond).b
        return out


# ----------------------------------------------------------------------------- prior-mean


@register
class PriorMean(Estimator):
    """``prior-mean``: the mean training label of the window's device.

    What a regressor that ignores the signal can learn. Unseen devices get the mean over all
    training labels. :meth:`predict_std` is the per-device sample standard deviation of the
    labels (ddof = 1; the overall one for unseen devices and for devices with one label).

    Attributes
    ----------
    means_
        ``{device: (3,) m/s²}``.
    stds_
        ``{device: (3,) m/s²}``.
    overall_, overall_std_
        (3,) m/s² over all training labels.
    """

    name: ClassVar[str] = "prior-mean"
    needs_fit: ClassVar[bool] = True

    def fit(self, windows: np.ndarray, labels: np.ndarray, meta: pd.DataFrame) -> PriorMean:
        """Learn the per-device label means and standard deviations."""
        check_inputs(windows, meta, labels)
        y = np.asarray(labels, dtype=np.float64)
        if y.shape[0] == 0:
            raise EstimatorError("prior-mean: expected at least one training window, found none")
        dev = _devices(meta)
        self.overall_ = y.mean(axis=0)
        self.overall_std_ = y.std(axis=0, ddof=1) if y.shape[0] > 1 else np.zeros(3)
        self.means_ = {}
        self.stds_ = {}
        for d in sorted(set(dev)):
            yd = y[dev == d]
            self.means_[d] = yd.mean(axis=0)
            self.stds_[d] = yd.std(axis=0, ddof=1) if yd.shape[0] > 1 else self.overall_std_.copy()
        return self

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """The device's mean training label per window, (N, 3) m/s²."""
        check_inputs(windows, meta)
        _check_fitted(self, "means_")
        return np.array([self.means_.get(d, self.overall_) for d in _devices(meta)]).reshape(-1, 3)

    def predict_std(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """The device's training-label standard deviation per window, (N, 3) m/s²."""
        check_inputs(windows, meta)
        _check_fitted(self, "stds_")
        return np.array([self.stds_.get(d, self.overall_std_) for d in _devices(meta)]).reshape(-1, 3)


# ----------------------------------------------------------------------------- gravity-prior maths


def gaussian_prior(labels: np.ndarray, min_std: float) -> tuple[np.ndarray, np.ndarray]:
    """Mean and covariance of labels, with every eigenvalue floored at min_std².

    Parameters
    ----------
    labels
        (n, 3) m/s², n ≥ 1.
    min_std
        Smallest standard deviation along any direction, m/s² (> 0 keeps the covariance
        positive definite; with one label the covariance is min_std²·I).

    Returns
    -------
    mean
        (3,) m/s².
    cov
        (3, 3) (m/s²)², symmetric positive definite.
    """
    y = np.asarray(labels, dtype=np.float64)
    mean = y.mean(axis=0)
    cov = np.cov(y, rowvar=False, ddof=1) if y.shape[0] > 1 else np.zeros((3, 3))
    return mean, floor_cov(cov, min_std)


def floor_cov(cov: np.ndarray, min_std: float) -> np.ndarray:
    """A symmetric 3×3 covariance with every eigenvalue raised to at least min_std².

    Parameters
    ----------
    cov
        (3, 3), (m/s²)².
    min_std
        m/s².

    Returns
    -------
    ndarray, shape (3, 3)
        Symmetric positive definite (for min_std > 0).
    """
    vals, vecs = np.linalg.eigh(0.5 * (np.asarray(cov, dtype=np.float64) + np.asarray(cov).T))
    out = (vecs * np.maximum(vals, min_std * min_std)) @ vecs.T
    return 0.5 * (out + out.T)


def direction_prior(labels: np.ndarray, h: np.ndarray, min_std: float, ridge: float,
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A Gaussian prior whose mean is linear in the window's up direction h.

    μ(h) = ȳ + C·(h − h̄), C = Y_cᵀH_c (H_cᵀH_c + ridge·n·I)⁻¹ by ridge regression of the
    centred labels on the centred directions; the covariance is that of the residuals
    (n − 4 degrees of freedom), floored like :func:`floor_cov`. On a rotated campaign C
    learns the apparent bias's orientation-dependent part (A − I)·g; directions that the
    training windows do not span stay at C = 0 through the ridge.

    Parameters
    ----------
    labels
        (n, 3) m/s².
    h
        (n, 3) unit up directions of the training windows.
    min_std
        Floor of the residual standard deviation, m/s².
    ridge
        Ridge relative to n (dimensionless, > 0).

    Returns
    -------
    mean
        (3,) ȳ, m/s².
    slope
        (3, 3) C, m/s² per unit of h.
    centre
        (3,) h̄.
    cov
        (3, 3) residual covariance, (m/s²)².
    """
    y = np.asarray(labels, dtype=np.float64)
    h = np.asarray(h, dtype=np.float64)
    n = y.shape[0]
    mean, centre = y.mean(axis=0), h.mean(axis=0)
    yc, hc = y - mean, h - centre
    slope = np.linalg.solve(hc.T @ hc + ridge * n * np.eye(3), hc.T @ yc).T
    resid = yc - hc @ slope.T
    cov = resid.T @ resid / max(n - 4, 1)
    return mean, slope, centre, floor_cov(cov, min_std)


def condition_on_norm(m: np.ndarray, g: np.ndarray | float, mu: np.ndarray, cov: np.ndarray,
                      obs_var: np.ndarray | float, n_iter: int = GN_ITERATIONS,
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gaussian posterior of a bias b given that the window mean m satisfies ‖m − b‖ = g.

    Prior b ~ N(μ, Σ); observation ‖m − b‖ = g + ε, ε ~ N(0, σ²). Linearised at b_k with
    h = (m − b_k)/‖m − b_k‖ (the measured up), the observation reads hᵀb = y_k with
    y_k = ‖m − b_k‖ − g + hᵀb_k, and Gaussian conditioning gives

        μ_post = μ + Σh·(y_k − hᵀμ)/(hᵀΣh + σ²),   Σ_post = Σ − Σhhᵀ Σ/(hᵀΣh + σ²).

    The first pass linearises at b_0 = μ (the plain formula with y = ‖m − μ‖ − g + hᵀμ,
    which equals ‖m‖ − g ≈ hᵀb for μ = 0); further passes relinearise at the new mean
    (iterated Kalman update = Gauss–Newton for the MAP on the sphere).

    Parameters
    ----------
    m
        (N, 3) window means, m/s².
    g
        (N,) or scalar local gravity, m/s².
    mu
        (3,) or (N, 3) prior means, m/s².
    cov
        (3, 3) or (N, 3, 3) prior covariances, (m/s²)².
    obs_var
        (N,) or scalar σ² of the norm observation, (m/s²)².
    n_iter
        Linearisations (≥ 1).

    Returns
    -------
    mean
        (N, 3) posterior means, m/s².
    cov
        (N, 3, 3) posterior covariances, (m/s²)².
    loglik
        (N,) log density of the observation under the prior, log N(‖m − μ‖ − g; 0, hᵀΣh + σ²)
        at the first linearisation (for mixture weights).
    """
    m = np.asarray(m, dtype=np.float64)
    n = m.shape[0]
    mu_n = np.broadcast_to(np.asarray(mu, dtype=np.float64), (n, 3))
    cov_n = np.broadcast_to(np.asarray(cov, dtype=np.float64), (n, 3, 3))
    g_n = np.broadcast_to(np.asarray(g, dtype=np.float64), (n,))
    var_n = np.broadcast_to(np.asarray(obs_var, dtype=np.float64), (n,))
    b = mu_n.copy()
    loglik = np.zeros(n)
    ch = np.zeros((n, 3))
    s = np.ones(n)
    for k in range(max(1, n_iter)):
        h, r = _unit_rows(m - b)
        innovation = r - g_n + np.einsum("ni,ni->n", h, b - mu_n)
        ch = np.einsum("nij,nj->ni", cov_n, h)
        s = np.einsum("ni,ni->n", h, ch) + var_n
        if k == 0:
            loglik = -0.5 * (innovation**2 / s + np.log(2.0 * np.pi * s))
        b = mu_n + ch * (innovation / s)[:, None]
    post = cov_n - np.einsum("ni,nj->nij", ch, ch) / s[:, None, None]
    return b, 0.5 * (post + np.swapaxes(post, 1, 2)), loglik


def mixture_moments(log_weights: np.ndarray, means: np.ndarray, covs: np.ndarray,
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean and covariance of Gaussian mixtures (law of total variance).

    Parameters
    ----------
    log_weights
        (N, K) unnormalised log weights.
    means
        (N, K, 3) component means.
    covs
        (N, K, 3, 3) component covariances.

    Returns
    -------
    mean
        (N, 3).
    cov
        (N, 3, 3): Σ_k w_k·(C_k + (μ_k − μ̄)(μ_k − μ̄)ᵀ).
    weights
        (N, K) normalised weights.
    """
    lw = np.asarray(log_weights, dtype=np.float64)
    w = np.exp(lw - lw.max(axis=1, keepdims=True))
    w /= w.sum(axis=1, keepdims=True)
    mean = np.einsum("nk,nki->ni", w, means)
    d = means - mean[:, None, :]
    cov = np.einsum("nk,nkij->nij", w, covs + np.einsum("nki,nkj->nkij", d, d))
    return mean, cov, w


# ----------------------------------------------------------------------------- gravity-prior


@register
class GravityPrior(Estimator):
    """``gravity-prior``: along-gravity bias from the norm, tangential bias from a learned prior.

    Per window, m is the mean specific force and h = m/‖m‖. The norm of m observes one
    number, ‖m − b‖ = g (to first order hᵀb = ‖m‖ − g), with noise variance σ_y². The prior
    of the window's device is N(μ_d, Σ_d), learned on the training labels; the estimate is
    the Gaussian posterior (:func:`condition_on_norm`): the component along h comes from the
    data, the two tangential ones from the prior, and :meth:`predict_std` = sqrt(diag Σ_post).

    A device not seen in :meth:`fit` (or every device when ``per_device`` is False) gets a
    Gaussian mixture over the training devices' priors with weights ∝ (training windows of
    the device) × N(‖m − μ_d‖ − g; 0, hᵀΣ_d h + σ_y²), each component conditioned on the
    window; the estimate and std are the mixture's mean and covariance (law of total
    variance, :func:`mixture_moments`).

    Learned in :meth:`fit`: μ_d, Σ_d = the labels' mean and covariance per device, every
    eigenvalue floored at (``min_std_mg``)²; σ_y = the RMS over the training windows of the
    exact residual ‖m_j − y_j‖ − g_j at the label y_j (window noise along h plus label
    noise), floored at ``min_obs_std_mg``.

    With ``direction_model`` (an option beyond methods.md, off by default) the prior mean is
    linear in the window's up direction, μ_d(h) = μ_d + C_d·(h − h̄_d), and Σ_d is the
    residual covariance (:func:`direction_prior`): on a rotated campaign the apparent bias
    contains (A − I)·u·g, which a constant prior can only treat as spread.

    Parameters
    ----------
    per_device
        Use the window's device prior when the device was seen in training.
    min_std_mg
        Floor of the prior standard deviation along any direction, mg.
    min_obs_std_mg
        Floor of σ_y, mg.
    direction_model
        Make the prior mean linear in h (see above).
    direction_ridge
        Ridge of that regression, relative to the number of training windows.

    Attributes
    ----------
    means_
        ``{device: (3,) m/s²}``: the training-label mean μ_d.
    slopes_
        ``{device: (3, 3) m/s²}``: C_d (zero without ``direction_model``).
    centres_
        ``{device: (3,)}``: h̄_d (zero without ``direction_model``).
    covs_
        ``{device: (3, 3) (m/s²)²}``.
    counts_
        ``{device: training windows}``.
    obs_std_
        σ_y, m/s².
    """

    name: ClassVar[str] = "gravity-prior"
    needs_fit: ClassVar[bool] = True

    def __init__(self, per_device: bool = True, min_std_mg: float = 0.5, min_obs_std_mg: float = 0.05,
                 direction_model: bool = False, direction_ridge: float = 1e-6) -> None:
        self.per_device = per_device
        self.min_std_mg = min_std_mg
        self.min_obs_std_mg = min_obs_std_mg
        self.direction_model = direction_model
        self.direction_ridge = direction_ridge
        self._check_params()

    def _check_params(self) -> None:
        for key in ("per_device", "direction_model"):
            flag = getattr(self, key)
            if not isinstance(flag, bool):
                raise EstimatorError(f"gravity-prior {key}: expected true or false, found {flag!r}")
        for key in ("min_std_mg", "min_obs_std_mg", "direction_ridge"):
            v = getattr(self, key)
            if not (_is_real(v) and math.isfinite(v) and v > 0):
                raise EstimatorError(f"gravity-prior {key}: expected a finite number > 0, found {v!r}")

    def fit(self, windows: np.ndarray, labels: np.ndarray, meta: pd.DataFrame) -> GravityPrior:
        """Learn the device priors and the observation noise."""
        check_inputs(windows, meta, labels)
        self._check_params()
        y = np.asarray(labels, dtype=np.float64)
        if y.shape[0] == 0:
            raise EstimatorError("gravity-prior: expected at least one training window, found none")
        if not np.all(np.isfinite(y)):
            raise EstimatorError("gravity-prior: expected finite labels, found NaN or infinity")
        m = window_means(windows)
        g = _g_local(meta)
        dev = _devices(meta)
        resid = np.linalg.norm(m - y, axis=1) - g
        self.obs_std_ = max(float(np.sqrt(np.mean(resid**2))), self.min_obs_std_mg * MG)
        h, _ = _unit_rows(m)
        self.means_, self.slopes_, self.centres_, self.covs_, self.counts_ = {}, {}, {}, {}, {}
        for d in sorted(set(dev)):
            rows = dev == d
            if self.direction_model:
                prior = direction_prior(y[rows], h[rows], self.min_std_mg * MG, self.direction_ridge)
                self.means_[d], self.slopes_[d], self.centres_[d], self.covs_[d] = prior
            else:
                self.means_[d], self.covs_[d] = gaussian_prior(y[rows], self.min_std_mg * MG)
                self.slopes_[d], self.centres_[d] = np.zeros((3, 3)), np.zeros(3)
            self.counts_[d] = int(np.sum(rows))
        return self

    def _prior_mean(self, d: str, h: np.ndarray) -> np.ndarray:
        """Device d's prior mean for windows with up directions h (n, 3): (n, 3) m/s²."""
        return self.means_[d] + (h - self.centres_[d]) @ self.slopes_[d].T

    def _posterior(self, windows: np.ndarray, meta: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
        """Posterior means (N, 3) and covariances (N, 3, 3) of every window."""
        check_inputs(windows, meta)
        _check_fitted(self, "means_")
        m = window_means(windows)
        g = _g_local(meta)
        dev = _devices(meta)
        var = self.obs_std_**2
        h, _ = _unit_rows(m)
        mean = np.empty((m.shape[0], 3))
        cov = np.empty((m.shape[0], 3, 3))
        known = np.isin(dev, list(self.means_)) if self.per_device else np.zeros(len(dev), dtype=bool)
        for d in sorted(set(dev[known])):
            rows = dev == d
            mean[rows], cov[rows], _ = condition_on_norm(m[rows], g[rows], self._prior_mean(d, h[rows]),
                                                         self.covs_[d], var)
        rest = ~known
        if rest.any():
            names = sorted(self.means_)
            parts = [condition_on_norm(m[rest], g[rest], self._prior_mean(d, h[rest]), self.covs_[d], var)
                     for d in names]
            logw = np.stack([np.log(self.counts_[d]) + p[2] for d, p in zip(names, parts, strict=True)],
                            axis=1)
            mean[rest], cov[rest], _ = mixture_moments(logw, np.stack([p[0] for p in parts], axis=1),
                                                       np.stack([p[1] for p in parts], axis=1))
        return mean, cov

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Posterior mean bias per window, (N, 3) m/s²."""
        return self._posterior(windows, meta)[0]

    def predict_std(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Posterior standard deviation per window and axis, (N, 3) m/s²."""
        cov = self._posterior(windows, meta)[1]
        return np.sqrt(np.clip(np.einsum("nii->ni", cov), 0.0, None))

    # --------------------------------------------------------------------- persistence

    def to_dict(self) -> dict[str, Any]:
        """The fitted estimator as plain JSON-ready data (floats round-trip exactly).

        Returns
        -------
        dict
            ``{"format": "ofbe-gravity-prior/1", "params": {...}, "obs_std": σ_y (m/s²),
            "devices": {device: {"count": int, "mean": [3] m/s², "cov": [[3]×3] (m/s²)²,
            "slope": [[3]×3] m/s², "centre": [3]}}}``.
        """
        _check_fitted(self, "means_")
        return {
            "format": GRAVITY_PRIOR_FORMAT,
            "params": self.get_params(),
            "obs_std": float(self.obs_std_),
            "devices": {d: {"count": int(self.counts_[d]), "mean": self.means_[d].tolist(),
                            "cov": self.covs_[d].tolist(), "slope": self.slopes_[d].tolist(),
                            "centre": self.centres_[d].tolist()} for d in sorted(self.means_)},
        }

    @classmethod
    def from_dict(cls, data: Any, source: str = "gravity-prior data") -> GravityPrior:
        """A fitted estimator from :meth:`to_dict`'s output.

        Raises
        ------
        EstimatorError
            Naming ``source``, the field, what was expected and what was found.
        """
        def bad(field: str, expected: str, found: Any) -> EstimatorError:
            text = repr(found)
            return EstimatorError(f"{source}: {field}: expected {expected}, found "
                                  f"{text[:80] + '…' if len(text) > 80 else text}")

        if not isinstance(data, dict):
            raise bad("top level", f"a JSON object of format {GRAVITY_PRIOR_FORMAT}", type(data).__name__)
        if data.get("format") != GRAVITY_PRIOR_FORMAT:
            raise bad("format", repr(GRAVITY_PRIOR_FORMAT), data.get("format"))
        params = data.get("params")
        if not isinstance(params, dict):
            raise bad("params", "an object of parameters", params)
        try:
            est = cls(**params)
        except (TypeError, EstimatorError) as exc:
            raise bad("params", "gravity-prior parameters", str(exc)) from None
        obs_std = data.get("obs_std")
        if not (_is_real(obs_std) and math.isfinite(obs_std) and obs_std > 0):
            raise bad("obs_std", "a finite number > 0 (m/s²)", obs_std)
        devices = data.get("devices")
        if not isinstance(devices, dict) or not devices:
            raise bad("devices", "a non-empty object of device priors", devices)
        means, covs, counts, slopes, centres = {}, {}, {}, {}, {}
        for d, entry in devices.items():
            if not isinstance(entry, dict):
                raise bad(f"devices.{d}", "an object with count, mean, cov, slope, centre", entry)
            try:
                mean = np.asarray(entry.get("mean"), dtype=np.float64)
                cov = np.asarray(entry.get("cov"), dtype=np.float64)
                slope = np.asarray(entry.get("slope"), dtype=np.float64)
                centre = np.asarray(entry.get("centre"), dtype=np.float64)
            except (TypeError, ValueError):
                raise bad(f"devices.{d}", "numeric mean [3], cov [3][3], slope [3][3], centre [3]",
                          entry) from None
            count = entry.get("count")
            shapes = (("mean", mean, (3,)), ("slope", slope, (3, 3)), ("centre", centre, (3,)))
            for field, arr, shape in shapes:
                if arr.shape != shape or not np.all(np.isfinite(arr)):
                    raise bad(f"devices.{d}.{field}", f"finite numbers of shape {shape}", entry.get(field))
            if cov.shape != (3, 3) or not np.all(np.isfinite(cov)) or not np.allclose(cov, cov.T) \
                    or np.linalg.eigvalsh(cov).min() <= 0:
                raise bad(f"devices.{d}.cov", "a symmetric positive definite 3×3 matrix ((m/s²)²)",
                          entry.get("cov"))
            if not (_is_int(count) and count > 0):
                raise bad(f"devices.{d}.count", "a positive integer", count)
            means[d], covs[d], counts[d], slopes[d], centres[d] = mean, cov, count, slope, centre
        est.obs_std_ = float(obs_std)
        est.means_, est.covs_, est.counts_, est.slopes_, est.centres_ = means, covs, counts, slopes, centres
        return est

    def save(self, path: str | Path) -> None:
        """Write :meth:`to_dict` as JSON to ``path``, atomically (no pickle).

        Parameters
        ----------
        path
            Target file (its folder must exist), conventionally ``*.json``.
        """
        text = json.dumps(self.to_dict(), indent=1, sort_keys=True, allow_nan=False) + "\n"
        write_bytes_atomic(path, text.encode("utf-8"))

    @classmethod
    def load(cls, path: str | Path) -> GravityPrior:
        """A fitted estimator saved by :meth:`save`.

        Raises
        ------
        EstimatorError
            The file cannot be read, is not UTF-8 JSON, or is not a gravity-prior of format
            ``ofbe-gravity-prior/1`` (the message names the file, what was expected and what
            was found). Nothing in the file is ever executed.
        """
        path = Path(path)
        try:
            raw = path.read_bytes()
        except OSError as exc:
            raise EstimatorError(f"{path}: expected a saved gravity-prior ({GRAVITY_PRIOR_FORMAT} JSON), "
                                 f"found an unreadable file ({exc.strerror or exc})") from None
        try:
            data = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise EstimatorError(f"{path}: expected a saved gravity-prior ({GRAVITY_PRIOR_FORMAT} JSON), "
                                 f"found a file that is not JSON ({exc})") from None
        return cls.from_dict(data, source=str(path))


# ----------------------------------------------------------------------------- oracle


@dataclass(frozen=True)
class TruthDevice:
    """A DUT's campaign-level parameters from the simulator's truth files.

    Attributes
    ----------
    A
        (3, 3) effective map ``A_effective`` (sensor map × mount misalignment).
    offset
        (3,) fixed factory offset ``offset_device``, m/s².
    delta_cov
        (3, 3) prior covariance of the per-recording offset change (turn-on + drift),
        diag(turn_on_sigma² + drift_sigma²), (m/s²)².
    noise_var
        (3,) white-noise variance per sample, noise_rms², (m/s²)².
    drift_var
        drift_sigma², (m/s²)²: the in-run drift's variance over a recording.
    """

    A: np.ndarray
    offset: np.ndarray
    delta_cov: np.ndarray
    noise_var: np.ndarray
    drift_var: float


def _truth_device(entry: dict[str, Any], where: str) -> TruthDevice:
    """One ``devices[dev]`` entry of a truth file as a :class:`TruthDevice`."""
    try:
        A = np.asarray(entry["A_effective"], dtype=np.float64)
        offset = np.asarray(entry["offset_device"], dtype=np.float64)
        turn_on = np.asarray(entry["turn_on_sigma"], dtype=np.float64)
        drift = float(entry["drift_sigma"])
        noise = np.asarray(entry["noise_rms"], dtype=np.float64)
    except (KeyError, TypeError, ValueError) as exc:
        raise EstimatorError(f"{where}: expected A_effective, offset_device, turn_on_sigma, drift_sigma, "
                             f"noise_rms, found a problem with {exc}") from None
    if A.shape != (3, 3) or offset.shape != (3,) or turn_on.shape != (3,) or noise.shape != (3,):
        raise EstimatorError(f"{where}: expected A_effective 3×3 and 3-vectors, found shapes {A.shape}, "
                             f"{offset.shape}, {turn_on.shape}, {noise.shape}")
    if abs(np.linalg.det(A)) < 1e-6:
        raise EstimatorError(f"{where}: expected an invertible A_effective, found det {np.linalg.det(A):.3g}")
    return TruthDevice(A, offset, np.diag(turn_on**2 + drift**2), noise**2, drift**2)


def read_truth_devices(truth_dir: str | Path) -> tuple[str, dict[str, TruthDevice]]:
    """The campaign kind and every DUT's device-level parameters from ``<truth_dir>/*.json``.

    Only device-level fields are read (``kind``, ``devices[dev]``): never a recording's
    offset, apparent bias or direction.

    Parameters
    ----------
    truth_dir
        The simulator's truth folder of one campaign (``ofbe-truth/1`` files).

    Returns
    -------
    kind
        The campaign's session kind (``rotated``, ``gravity-aligned``...).
    devices
        ``{device: TruthDevice}`` for every device with an ``A_effective`` (the DUTs).

    Raises
    ------
    EstimatorError
        No such folder, no truth file, a file that is not ``ofbe-truth/1`` JSON, mixed
        kinds, or a device whose parameters differ between files.
    """
    folder = Path(truth_dir)
    if not folder.is_dir():
        raise EstimatorError(f"oracle: expected the simulator's truth folder, found no folder {folder}")
    files = sorted(folder.glob("*.json"))
    if not files:
        raise EstimatorError(f"{folder}: expected {TRUTH_FORMAT} truth files (*.json), found none")
    kind: str | None = None
    devices: dict[str, TruthDevice] = {}
    for path in files:
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise EstimatorError(f"{path}: expected a {TRUTH_FORMAT} JSON truth file, found {exc}") from None
        if not isinstance(data, dict) or data.get("format") != TRUTH_FORMAT:
            found = data.get("format") if isinstance(data, dict) else type(data).__name__
            raise EstimatorError(f"{path}: format: expected {TRUTH_FORMAT!r}, found {found!r}")
        k = data.get("kind")
        if not isinstance(k, str):
            raise EstimatorError(f"{path}: kind: expected a session kind, found {k!r}")
        if kind is not None and k != kind:
            raise EstimatorError(f"{path}: kind: expected {kind!r} like the other truth files, found {k!r}")
        kind = k
        entries = data.get("devices")
        if not isinstance(entries, dict):
            raise EstimatorError(f"{path}: devices: expected an object, found {type(entries).__name__}")
        for d, entry in entries.items():
            if not isinstance(entry, dict) or "A_effective" not in entry:
                continue  # the reference IMU: no A_effective, not a DUT
            dev = _truth_device(entry, f"{path}: devices.{d}")
            old = devices.get(d)
            if old is not None and not (np.allclose(old.A, dev.A, rtol=0, atol=1e-12)
                                        and np.allclose(old.offset, dev.offset, rtol=0, atol=1e-12)):
                raise EstimatorError(f"{path}: devices.{d}: expected the same A_effective and offset_device "
                                     f"as the other truth files (one campaign), found different values")
            devices[d] = dev
    if not devices:
        raise EstimatorError(f"{folder}: expected DUT devices (with A_effective) in the truth files, "
                             f"found none")
    assert kind is not None
    return kind, devices


@register
class Oracle(Estimator):
    """``oracle``: the posterior mean under the simulator's true device distributions.

    Simulated data only: :meth:`fit` reads the campaign's truth folder (``ofbe-truth/1``,
    :func:`read_truth_devices`), keeping per device only the campaign-level parameters: the
    effective map A, the factory offset o, the turn-on and drift spread and the noise. A
    recording's own offset or apparent bias is never read. The simulator's model is
    m = A·u·g + o + δ + n̄ with u the nominal direction and δ ~ N(0, diag(σ_on² + σ_drift²));
    the label is b_app = m − g·u. Per window of mean m of device d:

    - ``gravity-aligned`` campaigns: u is a point mass on the signed axes, so u = the nearest
      signed axis of m and b̂ = m − g·u: the oracle equals ``level-mean`` there (up to the
      noise of the window mean, which nothing can remove).
    - otherwise (orientations spread over the sphere): v = A⁻¹(m − o) = g·u + A⁻¹δ + noise;
      with e = A⁻¹δ ~ N(0, A⁻¹Σ_δA⁻ᵀ) the constraint ‖v − e‖ = g is conditioned on exactly
      as in :func:`condition_on_norm` (at e = 0 its first pass is δ̂ = Σh(‖v‖ − g)/(hᵀΣh + σ²)
      with h = A⁻ᵀv/‖v‖ in δ terms), with σ² = ĥᵀA⁻¹ diag(noise_rms²/T) A⁻ᵀĥ; then
      û = (v − ê)/‖v − ê‖ and b̂ = m − g·û.

    :meth:`predict_std`: sqrt of diag(Σ_post(e) + diag(noise_rms²)/T) (the posterior spread
    of the offset change, approximately mapped, plus the noise of the window mean);
    sqrt(noise_rms²/T + drift_sigma²) on gravity-aligned campaigns (the window's mean bias
    differs from the recording's by the in-run drift, bounded by its spread).

    Parameters
    ----------
    truth_dir
        The simulator's truth folder of the campaign (``raw/<campaign>/_truth``).

    Attributes
    ----------
    kind_
        The campaign's kind.
    devices_
        ``{device: TruthDevice}``.
    """

    name: ClassVar[str] = "oracle"
    needs_fit: ClassVar[bool] = True

    def __init__(self, truth_dir: str | None = None) -> None:
        self.truth_dir = truth_dir

    def fit(self, windows: np.ndarray, labels: np.ndarray, meta: pd.DataFrame) -> Oracle:
        """Read the truth folder (the windows and labels are not used)."""
        check_inputs(windows, meta, labels)
        if self.truth_dir is None:
            raise EstimatorError("oracle: expected truth_dir (the simulator's truth folder), found None; "
                                 "the oracle exists on simulated data only")
        self.kind_, self.devices_ = read_truth_devices(self.truth_dir)
        self._known(_devices(meta))
        return self

    def _known(self, dev: np.ndarray) -> None:
        missing = sorted(set(dev) - set(self.devices_))
        if missing:
            have = ", ".join(sorted(self.devices_))
            raise EstimatorError(f"oracle: expected devices of the truth folder ({have}), "
                                 f"found {', '.join(missing)}")

    def _posterior(self, windows: np.ndarray, meta: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
        """Estimates (N, 3) m/s² and their standard deviations (N, 3) m/s²."""
        check_inputs(windows, meta)
        _check_fitted(self, "devices_")
        dev = _devices(meta)
        self._known(dev)
        n_samples = np.asarray(windows).shape[1]
        m = window_means(windows)
        g = _g_local(meta)
        est = np.empty_like(m)
        std = np.empty_like(m)
        for d in sorted(set(dev)):
            rows = dev == d
            td = self.devices_[d]
            noise_var = td.noise_var / n_samples
            if self.kind_ == "gravity-aligned":
                est[rows] = m[rows] - g[rows, None] * nearest_axes(m[rows])
                std[rows] = np.sqrt(noise_var + td.drift_var)
                continue
            a_inv = np.linalg.inv(td.A)
            v = (m[rows] - td.offset) @ a_inv.T
            cov_e = a_inv @ td.delta_cov @ a_inv.T
            noise_e = a_inv @ np.diag(noise_var) @ a_inv.T
            hv, _ = _unit_rows(v)
            obs_var = np.einsum("ni,ij,nj->n", hv, noise_e, hv)
            e_hat, e_cov, _ = condition_on_norm(v, g[rows], np.zeros(3), cov_e, obs_var)
            u, _ = _unit_rows(v - e_hat)
            est[rows] = m[rows] - g[rows, None] * u
            std[rows] = np.sqrt(np.clip(np.einsum("nii->ni", e_cov), 0.0, None) + noise_var)
        return est, std

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Posterior-mean apparent bias per window, (N, 3) m/s²."""
        return self._posterior(windows, meta)[0]

    def predict_std(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Approximate posterior standard deviation per window and axis, (N, 3) m/s²."""
        return self._posterior(windows, meta)[1]
