"""Estimators from the physics of one window alone: ``level-mean`` (mean − g·nearest axis), ``ls-
trf`` (the norm-constrained least squares, three variants) and ``won2009`` (Won & Golnaraghi's
iterative linear solve).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from ofbe_model.estimators.base import Estimator, EstimatorError, check_inputs, register
from ofbe_model.estimators.batched import ls_trf_batch, won2009_batch, won_iterations
from ofbe_model.estimators.batched_bounds import ls_trf_bounded_batch
from ofbe_model.estimators.common import (
    LS_VARIANTS,
    MG,
    as_float_tuple,
    g_local_column,
    is_int,
    is_real,
    nearest_axes,
    window_means,
)

# ----------------------------------------------------------------------------- level-mean


@register
class LevelMean(Estimator):
    """``level-mean``: the window mean minus g_local along the nearest signed axis.

    b̂ = m − g·e, e = ±e_k with k = argmax |m_k| (:func:`nearest_axes`). Exact when the
    sensor is levelled (one axis along gravity); a tilt θ leaks g·sin θ into the estimate
    (asin(0.05) = 2.87° for 50 mg). No fit, no uncertainty.
    """

    name: ClassVar[str] = "level-mean"
    order: ClassVar[int] = 10
    needs_fit: ClassVar[bool] = False
    per_window: ClassVar[bool] = True
    """Each window's estimate depends on that window and its g_local alone (the benchmark
    runner then predicts every fold's test windows in one call)."""

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Bias estimates, (N, 3) m/s²."""
        check_inputs(windows, meta)
        m = window_means(windows)
        return m - g_local_column(meta)[:, None] * nearest_axes(m)


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


def _row_norms(d: np.ndarray) -> np.ndarray:
    """``np.linalg.norm(d, axis=1)`` of (T, 3) rows with the same bits (numpy sums the squares
    as (x² + y²) + z²), without numpy's per-row loop over three elements."""
    sq = d * d
    out = sq[:, 0] + sq[:, 1]
    out += sq[:, 2]
    return np.sqrt(out, out=out)


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
        r = _row_norms(f - b) - g
        return np.concatenate([r, w * (b - start)]) if w else r

    def jacobian(b: np.ndarray) -> np.ndarray:
        d = f - b
        jac = -d / _row_norms(d)[:, None]
        return np.vstack([jac, eye_w]) if w else jac

    lo = -np.inf if lower is None else np.asarray(lower, dtype=np.float64)
    hi = np.inf if upper is None else np.asarray(upper, dtype=np.float64)
    from scipy.optimize import least_squares  # here: importing the estimators (for --help) stays light

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
    order: ClassVar[int] = 20
    needs_fit: ClassVar[bool] = False
    per_window: ClassVar[bool] = True  # see LevelMean.per_window

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
        x0 = as_float_tuple(self.x0, 3, "ls-trf x0 (m/s²)")
        if self.max_nfev is not None and not (is_int(self.max_nfev) and self.max_nfev > 0):
            raise EstimatorError(f"ls-trf max_nfev: expected a positive integer or None, "
                                 f"found {self.max_nfev!r}")
        kw: dict[str, Any] = {"x0": x0, "max_nfev": self.max_nfev}
        if self.variant == "min-norm":
            if not (is_real(self.ridge) and math.isfinite(self.ridge) and self.ridge > 0):
                raise EstimatorError(f"ls-trf ridge: expected a finite number > 0, found {self.ridge!r}")
            kw["ridge_weight"] = float(self.ridge) * n_samples
        elif self.variant == "bounded":
            bound = as_float_tuple(self.bounds_mg, 3, "ls-trf bounds_mg") * MG
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
        """Bias estimates, (N, 3) m/s²: scipy's TRF per window, run for all windows at once
        (:func:`~ofbe_model.estimators.batched.ls_trf_batch` without bounds, :func:`~ofbe_model.
        estimators.batched_bounds.ls_trf_bounded_batch` with them: the same iterations). A
        window the bounded batch could not follow is solved by scipy itself."""
        check_inputs(windows, meta)
        g = g_local_column(meta)
        kw = self._solver_kwargs(np.asarray(windows).shape[1])
        if self.variant != "bounded":
            return ls_trf_batch(windows, g, ridge_weight=kw.get("ridge_weight", 0.0), x0=kw["x0"],
                                max_nfev=kw["max_nfev"])
        out, _, ok = ls_trf_bounded_batch(windows, g, kw["lower"], kw["upper"], x0=kw["x0"],
                                          max_nfev=kw["max_nfev"])
        for i in np.flatnonzero(~ok):
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
    the T samples; b += δ; stop when ‖δ‖ < tol. This is Gauss–Newton on the algebraic cost
    Σ(‖f_i − b‖² − g²)², which has the same flat valley as ``ls-trf``. The design 2·U is
    rank 1 without noise (the least squares step is then the minimum-norm δ: the
    along-gravity step only); with noise its two small singular values are ≈ 2σ√T,
    condition number ≈ g/σ ≈ 200–300 for the ADXL345, not small enough for ``lstsq``'s
    default cut-off, so the tangential steps follow the noise. ``rcond`` = 1e-2 cuts them.

    The step is ``numpy.linalg.lstsq``'s (the least squares solution through the singular
    values of the design, those at most rcond·s_max dropped), computed from the window's
    centred moments once instead of from the T×3 design at every iteration
    (:func:`~ofbe_model.estimators.batched.won_iterations`, which :class:`Won2009` runs for
    all windows at once with the same bits per window); it agrees with ``lstsq`` to
    rounding.

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
        Relative cut-off for small singular values, as ``lstsq``'s (None: numpy's default,
        machine epsilon × T).

    Returns
    -------
    WonResult
    """
    x = np.ascontiguousarray(np.asarray(f, dtype=np.float64).T)[None]
    conds: list[list[float]] = [[]]
    b, n_iter, converged = won_iterations(x, np.array([float(g)]), tol, max_iter, rcond, conds)
    return WonResult(b[0], int(n_iter[0]), bool(converged[0]), np.asarray(conds[0]))


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
    order: ClassVar[int] = 30
    needs_fit: ClassVar[bool] = False
    per_window: ClassVar[bool] = True  # see LevelMean.per_window

    def __init__(self, tol: float = 1e-6, max_iter: int = 500, rcond: float | None = None) -> None:
        self.tol = tol
        self.max_iter = max_iter
        self.rcond = rcond
        self._check()

    def _check(self) -> None:
        if not (is_real(self.tol) and math.isfinite(self.tol) and self.tol > 0):
            raise EstimatorError(f"won2009 tol: expected a number > 0 (m/s²), found {self.tol!r}")
        if not (is_int(self.max_iter) and self.max_iter > 0):
            raise EstimatorError(f"won2009 max_iter: expected a positive integer, found {self.max_iter!r}")
        if self.rcond is not None and not (is_real(self.rcond) and 0 <= self.rcond < 1):
            raise EstimatorError(f"won2009 rcond: expected None or a number in [0, 1), found {self.rcond!r}")

    def solve_window(self, window: np.ndarray, g: float) -> WonResult:
        """The full solver result of one (T, 3) window, m/s² (for diagnostics)."""
        self._check()
        return won2009_solve(window, g, tol=self.tol, max_iter=self.max_iter, rcond=self.rcond)

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Bias estimates, (N, 3) m/s²: :func:`won2009_solve`'s iterations for all windows at
        once (:func:`~ofbe_model.estimators.batched.won2009_batch`)."""
        check_inputs(windows, meta)
        self._check()
        return won2009_batch(windows, g_local_column(meta), tol=self.tol, max_iter=self.max_iter,
                             rcond=self.rcond)
