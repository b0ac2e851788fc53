"""scipy's Trust Region Reflective algorithm with bounds (``trf_bounds``) for many windows at once.

The ``bounded`` ``ls-trf`` variant solves min_b Σ_i (‖f_i − b‖ − g)² inside a box, one window
at a time through ``scipy.optimize.least_squares``. :class:`_TRFBounds` runs scipy's
``trf_bounds`` (``tr_solver="exact"``, which scipy picks for a dense Jacobian, ``x_scale =
1``, linear loss) for a batch of windows in lockstep, as :class:`~ofbe_model.estimators.
batched.BatchedTRF` does ``trf_no_bounds``: every window its own state and stopping mask, one
residual evaluation per window and round, the same outer and inner iterations as scipy:

- the Coleman–Li scaling v (distance to the bound the anti-gradient points at, else 1),
  d = √v, C = diag(g·∂v) and the "hat" problem J_h = J·diag(d), g_h = d·g;
- the exact trust-region solve on the SVD of [J_h; √C], formed from the 3×3 factor R of
  J (J·Q₀ = Q·R, see :class:`~ofbe_model.estimators.batched.BatchedTRF`) as the SVD of the 6×3
  matrix [R·Q₀ᵀ·diag(d); √C]: the same singular values, right singular vectors and Uᵀf;
- ``select_step``: the trust-region step when it stays inside the box, else the best of
  the step stopped short of the bound (θ = max(0.995, 1 − ‖v·g‖∞)), the reflected step and
  the constrained Cauchy step, each scored by the quadratic model;
- ``make_strictly_feasible`` (next float inside), the radius update on ‖step_h‖ and
  scipy's ftol/xtol/gtol tests (the gradient test on v·g).

The estimates agree with scipy's to rounding (tests/ofbe_model/estimators/test_batched_estimators.py,
benchmarks/benchmark_speed.py --reference). One branch is not batched: where scipy's
``intersect_trust_region`` would raise (the step stopped at the bound outside the trust
region, which rounding alone cannot cause) the window is marked and left to the caller,
which solves it with scipy itself (:meth:`~ofbe_model.estimators.physics.LSTRF.predict`).
"""

from __future__ import annotations

import numpy as np

from ofbe_model.estimators.batched import (
    FTOL,
    GTOL,
    XTOL,
    BatchedTRF,
    component_major,
    forward3,
    window_batches,
)

BATCH_WINDOWS = 128
"""Windows solved together (memory: about 10 × BATCH_WINDOWS × T × 3 doubles). Twice the
unbounded solvers' batch: each round's step selection costs more here, and the windows
stop after a few tens of evaluations but at very different counts, so fewer, fuller
rounds pay (≈ 20 % less time than batches of 64 on the benchmark's windows)."""


def ls_trf_bounded_batch(windows: np.ndarray, g: np.ndarray, lower: np.ndarray, upper: np.ndarray, *,
                         x0: np.ndarray | None = None, max_nfev: int | None = None,
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`~ofbe_model.estimators.physics.ls_trf_solve` with bounds (no ridge) for every
    window.

    Parameters
    ----------
    windows
        (N, T, 3) specific force, m/s².
    g
        (N,) local gravity, m/s².
    lower, upper
        (3,) bounds on b, m/s² (±inf: none on that component; lower < upper).
    x0
        (3,) start inside the bounds, m/s² (None: zero).
    max_nfev
        Residual evaluations per window (None: scipy's default, 300).

    Returns
    -------
    b
        (N, 3) estimates, m/s².
    nfev
        (N,) residual evaluations used, as scipy's ``nfev``.
    ok
        (N,) False where the window met the branch that is not batched (its b is not
        scipy's: solve it per window).
    """
    lo = np.broadcast_to(np.asarray(lower, dtype=np.float64), (3,)).copy()
    hi = np.broadcast_to(np.asarray(upper, dtype=np.float64), (3,)).copy()
    start = np.zeros(3) if x0 is None else np.asarray(x0, dtype=np.float64).reshape(3)
    limit = 300 if max_nfev is None else int(max_nfev)
    gg = np.asarray(g, dtype=np.float64)
    n = int(np.asarray(windows).shape[0])
    b, nfev, ok = np.empty((n, 3)), np.empty(n, dtype=np.int64), np.empty(n, dtype=bool)
    for rows in window_batches(n, BATCH_WINDOWS):
        trf = _TRFBounds(component_major(windows, rows), gg[rows], lo, hi, start, limit)
        b[rows] = trf.run()
        nfev[rows], ok[rows] = trf.nfev, trf.ok
    return b, nfev, ok


# ----------------------------------------------------------------------------- scipy's helpers, by rows


def _strictly_feasible(x: np.ndarray, lb: np.ndarray, ub: np.ndarray, rstep: float) -> np.ndarray:
    """scipy's ``make_strictly_feasible`` for (k, 3) points."""
    out = x.copy()
    if rstep == 0:
        lower, upper = x <= lb, x >= ub
        inside_lb = np.broadcast_to(np.nextafter(lb, ub), x.shape)
        inside_ub = np.broadcast_to(np.nextafter(ub, lb), x.shape)
    else:
        lo_dist, up_dist = x - lb, ub - x
        lower = np.isfinite(lb) & (lo_dist <= np.minimum(up_dist, rstep * np.maximum(1, np.abs(lb))))
        upper = np.isfinite(ub) & (up_dist <= np.minimum(lo_dist, rstep * np.maximum(1, np.abs(ub))))
        with np.errstate(invalid="ignore"):  # infinite bounds: never used
            inside_lb = np.broadcast_to(lb + rstep * np.maximum(1, np.abs(lb)), x.shape)
            inside_ub = np.broadcast_to(ub - rstep * np.maximum(1, np.abs(ub)), x.shape)
    lower &= ~upper  # scipy marks the upper bound last
    out[lower] = inside_lb[lower]
    out[upper] = inside_ub[upper]
    tight = (out < lb) | (out > ub)
    out[tight] = np.broadcast_to(0.5 * (lb + ub), x.shape)[tight]
    return out


def _cl_scaling(x: np.ndarray, grad: np.ndarray, lb: np.ndarray, ub: np.ndarray,
                ) -> tuple[np.ndarray, np.ndarray]:
    """scipy's ``CL_scaling_vector`` for (k, 3) points and gradients: v and ∂v/∂x."""
    v = np.ones_like(x)
    dv = np.zeros_like(x)
    to_ub = (grad < 0) & np.isfinite(ub)
    v = np.where(to_ub, ub - x, v)
    dv[to_ub] = -1.0
    to_lb = (grad > 0) & np.isfinite(lb)
    v = np.where(to_lb, x - lb, v)
    dv[to_lb] = 1.0
    return v, dv


def _to_bound(x: np.ndarray, s: np.ndarray, lb: np.ndarray, ub: np.ndarray,
              ) -> tuple[np.ndarray, np.ndarray]:
    """scipy's ``step_size_to_bound`` for (k, 3) points and directions: the step t ≥ 0 to the
    first bound along s, and which components hit it (−1 lower, 1 upper, 0 none)."""
    moving = s != 0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        steps = np.where(moving, np.maximum((lb - x) / s, (ub - x) / s), np.inf)
    t = steps.min(axis=1)
    return t, (steps == t[:, None]) * np.sign(s).astype(int)


def _min_quadratic(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray,
                   c: np.ndarray | float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """scipy's ``minimize_quadratic_1d`` by rows: argmin and min of t·(a·t + b) + c over
    [lo, hi], candidates in scipy's order (lo, hi, the vertex where inside)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        ext = -0.5 * b / a
    vertex = (a != 0) & (lo < ext) & (ext < hi)
    ext = np.where(vertex, ext, 0.0)
    t = np.stack([lo + 0.0 * a, hi + 0.0 * a, ext], axis=1)
    y = t * (a[:, None] * t + b[:, None]) + np.asarray(c)[..., None]
    y[:, 2] = np.where(vertex, y[:, 2], np.inf)
    i = np.argmin(y, axis=1)
    rows = np.arange(a.size)
    return t[rows, i], y[rows, i]


def _intersect_tr(x: np.ndarray, s: np.ndarray, delta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The positive root t of ‖x + t·s‖ = Δ by rows (scipy's ``intersect_trust_region``),
    and whether scipy would have raised (s = 0 or x outside the region)."""
    a = np.einsum("nk,nk->n", s, s)
    b = np.einsum("nk,nk->n", x, s)
    c = np.einsum("nk,nk->n", x, x) - delta**2
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.sqrt(b * b - a * c)
        q = -(b + np.copysign(d, b))
        t1, t2 = q / a, c / q
    return np.maximum(t1, t2), (a == 0) | (c > 0)


def _norm(v: np.ndarray) -> np.ndarray:
    return np.sqrt(np.einsum("nk,nk->n", v, v))


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("nk,nk->n", a, b)


def _model(jh: np.ndarray, diag: np.ndarray, g_h: np.ndarray, s_h: np.ndarray) -> np.ndarray:
    """scipy's ``evaluate_quadratic`` by rows: ½·(‖J_h·s_h‖² + Σ C·s_h²) + g_h·s_h, with
    ‖J_h·s_h‖ = ‖jh·s_h‖ for the (k, 3, 3) factor jh = R·Q₀ᵀ·diag(d)."""
    js = np.einsum("nij,nj->ni", jh, s_h)
    return 0.5 * (_dot(js, js) + _dot(s_h * diag, s_h)) + _dot(s_h, g_h)


def _line(jh: np.ndarray, diag: np.ndarray, g_h: np.ndarray, s_h: np.ndarray,
          s0: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """scipy's ``build_quadratic_1d`` by rows along s_h (from s0): a, b (and c)."""
    v = np.einsum("nij,nj->ni", jh, s_h)
    a = 0.5 * (_dot(v, v) + _dot(s_h * diag, s_h))
    b = _dot(g_h, s_h)
    if s0 is None:
        return a, b
    u = np.einsum("nij,nj->ni", jh, s0)
    b = b + _dot(u, v) + _dot(s0 * diag, s_h)
    c = 0.5 * _dot(u, u) + _dot(g_h, s0) + 0.5 * _dot(s0 * diag, s0)
    return a, b, c


class _TRFBounds(BatchedTRF):
    """scipy's ``trf_bounds`` for a batch of problems min_b Σ_i (‖f_i − b‖ − g)², lb ≤ b ≤ ub.

    Besides :class:`~ofbe_model.estimators.batched.BatchedTRF`'s state (x, cost, gradient, R, Q₀,
    radius Δ, α, nfev), each window keeps what scipy computes at the top of an outer
    iteration: d, C = diag_h, g_h, θ and the SVD (s, V, Uᵀf) of [J_h; √C].
    """

    def __init__(self, f: np.ndarray, g: np.ndarray, lb: np.ndarray, ub: np.ndarray, start: np.ndarray,
                 max_nfev: int) -> None:
        self.lb, self.ub = lb, ub
        x0 = _strictly_feasible(start[None, :], lb, ub, 1e-10)[0]
        self._setup(f, g, 0.0, x0, max_nfev)
        n = f.shape[0]
        self.m = f.shape[2]  # scipy's rank threshold uses J's rows, not [J_h; √C]'s
        self.cost, self.grad, self.r, self.q0, _, _ = self._point(np.arange(n), self.x)
        v, _ = _cl_scaling(self.x, self.grad, lb, ub)
        delta = _norm(self.x / v**0.5)
        self.delta = np.where(delta == 0.0, 1.0, delta)
        self.d, self.diag_h, self.g_h = np.ones((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
        self.jh = np.zeros((n, 3, 3))  # R·Q₀ᵀ·diag(d): J_h = Q·jh
        self.s, self.vec, self.uf = np.zeros((n, 3)), np.zeros((n, 3, 3)), np.zeros((n, 3))
        self.theta = np.zeros(n)
        self.ok = np.ones(n, dtype=bool)

    def _top(self, idx: np.ndarray) -> np.ndarray:
        """The top of scipy's outer iteration for windows idx: the gradient and budget tests
        (returns the windows that stop) and, for the others, the hat problem and its SVD."""
        x, grad = self.x[idx], self.grad[idx]
        v, dv = _cl_scaling(x, grad, self.lb, self.ub)
        g_norm = np.abs(grad * v).max(axis=1)
        stop = (g_norm < GTOL) | (self.nfev[idx] >= self.max_nfev)
        go, v, dv, grad, g_norm = idx[~stop], v[~stop], dv[~stop], grad[~stop], g_norm[~stop]
        d = v**0.5
        diag_h = grad * dv
        r, q0 = self.r[go], self.q0[go]
        # J_h = J·diag(d) = Q·(R·Q₀ᵀ·diag(d)); [J_h; √C] = blockdiag(Q, I)·[R·Q₀ᵀ·diag(d); √C]
        top = np.einsum("nij,nkj->nik", r, q0) * d[:, None, :]
        m = np.concatenate([top, np.einsum("nk,kl->nkl", diag_h**0.5, np.eye(3))], axis=1)
        u_m, sv, vt = np.linalg.svd(m, full_matrices=False)
        qf = forward3(r, np.einsum("nki,nk->ni", q0, grad))  # Qᵀf
        self.d[go], self.diag_h[go], self.g_h[go], self.jh[go] = d, diag_h, d * grad, top
        self.s[go], self.vec[go] = sv, vt.transpose(0, 2, 1)
        self.uf[go] = np.einsum("nkj,nk->nj", u_m[:, :3], qf)
        self.theta[go] = np.maximum(0.995, 1.0 - g_norm)
        return idx[stop]

    def _select(self, idx: np.ndarray, p_h: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """scipy's ``select_step`` for windows idx: step, step_h and predicted reduction."""
        lb, ub = self.lb, self.ub
        x, d, delta, theta, g_h = self.x[idx], self.d[idx], self.delta[idx], self.theta[idx], self.g_h[idx]
        jh, diag = self.jh[idx], self.diag_h[idx]
        p = d * p_h
        inside = np.all((x + p >= lb) & (x + p <= ub), axis=1)
        # the trust-region step, stopped at the bound, and the reflected direction
        p_stride, hits = _to_bound(x, p, lb, ub)
        r_h = np.where(hits != 0, -p_h, p_h)
        r = d * r_h
        p = p * p_stride[:, None]
        p_h_b = p_h * p_stride[:, None]
        to_tr, raised = _intersect_tr(p_h_b, r_h, delta)
        raised &= ~inside
        to_bound, _ = _to_bound(x + p, r, lb, ub)
        r_stride = np.minimum(to_bound, to_tr)
        pos = r_stride > 0
        with np.errstate(divide="ignore", invalid="ignore"):
            r_lo = np.where(pos, (1 - theta) * p_stride / r_stride, 0.0)
        r_hi = np.where(pos, np.where(r_stride == to_bound, theta * to_bound, to_tr), -1.0)
        reflect = r_lo <= r_hi
        a, b, c = _line(jh, diag, g_h, r_h, p_h_b)
        r_stride, r_value = _min_quadratic(a, b, r_lo, r_hi, c)
        r_value = np.where(reflect, r_value, np.inf)
        r_h = r_h * r_stride[:, None] + p_h_b
        r = r_h * d
        # the step stopped short of the bound
        p = p * theta[:, None]
        p_h_b = p_h_b * theta[:, None]
        p_value = _model(jh, diag, g_h, p_h_b)
        # the constrained Cauchy step
        ag_h = -g_h
        ag = d * ag_h
        with np.errstate(divide="ignore"):
            to_tr = delta / _norm(ag_h)
        to_bound, _ = _to_bound(x, ag, lb, ub)
        ag_stride = np.where(to_bound < to_tr, theta * to_bound, to_tr)
        a, b = _line(jh, diag, g_h, ag_h)
        ag_stride, ag_value = _min_quadratic(a, b, np.zeros_like(a), ag_stride)
        ag_h = ag_h * ag_stride[:, None]
        ag = ag * ag_stride[:, None]
        pick_p = (p_value < r_value) & (p_value < ag_value)
        pick_r = ~pick_p & (r_value < p_value) & (r_value < ag_value)
        step = np.where(pick_p[:, None], p, np.where(pick_r[:, None], r, ag))
        step_h = np.where(pick_p[:, None], p_h_b, np.where(pick_r[:, None], r_h, ag_h))
        value = np.where(pick_p, p_value, np.where(pick_r, r_value, ag_value))
        # inside the box: the trust-region step itself
        p_in = d * p_h
        step = np.where(inside[:, None], p_in, step)
        step_h = np.where(inside[:, None], p_h, step_h)
        value = np.where(inside, _model(jh, diag, g_h, p_h), value)
        self.ok[idx[raised]] = False
        return step, step_h, -value

    def run(self) -> np.ndarray:
        """Every window to scipy's stop (or to a mark in ``ok``); the (n, 3) estimates, m/s²."""
        n = self.x.shape[0]
        done = np.zeros(n, dtype=bool)
        top = np.ones(n, dtype=bool)
        while True:
            t = np.flatnonzero(top & ~done)
            if t.size:
                done[self._top(t)] = True
            done |= ~self.ok
            idx = np.flatnonzero(~done)
            if idx.size == 0:
                return self.x
            # inner iteration: a trust-region step, the step selection, one evaluation
            step, step_h, predicted = self._select(idx, self._step(idx))
            x_new = _strictly_feasible(self.x[idx] + step, self.lb, self.ub, 0.0)
            cost_new, grad_new, r_new, q0_new, _, finite = self._point(idx, x_new)
            self.nfev[idx] += 1
            step_h_norm = _norm(step_h)
            delta = self.delta[idx]
            bad = ~finite
            actual = self.cost[idx] - cost_new
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(predicted > 0, actual / predicted,
                                 np.where((predicted == 0) & (actual == 0), 1.0, 0.0))
            delta_new = np.where(ratio < 0.25, 0.25 * step_h_norm,
                                 np.where((ratio > 0.75) & (step_h_norm > 0.95 * delta), 2.0 * delta, delta))
            ftol_ok = (actual < FTOL * self.cost[idx]) & (ratio > 0.25)
            xtol_ok = _norm(step) < XTOL * (XTOL + _norm(self.x[idx]))
            terminated = ~bad & (ftol_ok | xtol_ok)
            keep_going = ~bad & ~terminated
            with np.errstate(divide="ignore", invalid="ignore"):
                self.alpha[idx] = np.where(keep_going, self.alpha[idx] * (delta / delta_new), self.alpha[idx])
            self.delta[idx] = np.where(bad, 0.25 * step_h_norm, np.where(keep_going, delta_new, delta))
            accepted = ~bad & (actual > 0)
            a = idx[accepted]
            self.x[a], self.cost[a] = x_new[accepted], cost_new[accepted]
            self.grad[a], self.r[a], self.q0[a] = grad_new[accepted], r_new[accepted], q0_new[accepted]
            leave = accepted | terminated | (self.nfev[idx] >= self.max_nfev)
            done[idx[terminated]] = True
            top[:] = False
            top[idx[leave & ~terminated]] = True
