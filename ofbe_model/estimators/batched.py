"""The physics solvers of :mod:`~ofbe_model.estimators.physics` run on many windows at once.

``won2009`` and the three ``ls-trf`` variants solve one small problem per window: tens to
hundreds of iterations, each a handful of 3×3 operations on sums over the window's samples.
Window by window, the time went to Python and to the set-up of each ``lstsq`` and
``least_squares`` call, not to arithmetic. Here the same iterations run for a batch of
windows in lockstep, every window with its own state and its own stopping mask, so that
each step is a few array operations over the batch:

- :func:`won_iterations` (:func:`won2009_batch`) is Won & Golnaraghi's iteration, each step
  ``lstsq``'s least squares solution, the sums over the samples taken from the window's
  centred moments once (no pass over the samples per iteration);
- :class:`BatchedTRF` (:func:`ls_trf_batch`: ``as-written``, ``min-norm``) is scipy's Trust
  Region Reflective algorithm as scipy runs it for an unbounded problem
  (``trf_no_bounds``, exact trust-region solver, ``x_scale = 1``): the same outer and inner
  iterations, radius updates and termination tests, one residual evaluation per window and
  round;
- :class:`~ofbe_model.estimators.batched_bounds._TRFBounds` (:func:`~ofbe_model.estimators.
  batched_bounds.ls_trf_bounded_batch`: ``bounded``) is scipy's ``trf_bounds`` on the same
  evaluations: Coleman–Li scaling, ``select_step`` (trust-region, reflected and Cauchy
  steps), strictly feasible iterates. A window it cannot follow (a branch where scipy would
  raise) is marked, and :class:`~ofbe_model.estimators.physics.LSTRF` solves it with scipy.

Where scipy and numpy decompose the T×3 Jacobian (or design) itself, these solvers
decompose a 3×3 factor of it, formed in a basis whose first axis is the mean direction of
the samples, so that the two small singular values (≈ σ/g of the large one: the flat valley
of the cost) keep the digits an SVD of the T×3 matrix would give them. The estimates agree
with the per-window solvers to rounding (about 1e-10 m/s² after hundreds of iterations
along the valley, 1e-15 where the problem is well conditioned), the TRF solvers with
scipy's evaluation counts (tests/ofbe_model/estimators/test_batched_estimators.py and
benchmarks/benchmark_speed.py --reference compare them window by window).

Where the time goes: an ``ls-trf`` evaluation is one pass of a dozen array operations over
the window's T×3 samples (≈ 20 ns per sample: residuals, unit vectors, Σ v vᵀ as six dot
products, Jᵀf), and scipy's path fixes the count: ``as-written`` slides along the valley for
100–300 evaluations per window (a third stop at ``max_nfev`` = 300), so its time is
evaluations × T × that cost; ``bounded`` reaches the box in 20–150.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

EPS = float(np.finfo(np.float64).eps)
BATCH_WINDOWS = 64
"""Windows solved together (memory: about 10 × BATCH_WINDOWS × T × 3 doubles)."""

FTOL = XTOL = GTOL = 1e-8  # scipy.optimize.least_squares' defaults
_TR_RTOL, _TR_MAX_ITER = 0.01, 10  # scipy's solve_lsq_trust_region defaults


def window_batches(n: int, size: int | None = None) -> list[slice]:
    """Slices of at most ``size`` (None: BATCH_WINDOWS) of n windows."""
    step = BATCH_WINDOWS if size is None else size
    return [slice(i, min(i + step, n)) for i in range(0, n, step)]


def component_major(windows: np.ndarray, rows: slice) -> np.ndarray:
    """(n, 3, T) float64 copy of (N, T, 3) windows[rows]: each component contiguous."""
    return np.ascontiguousarray(np.asarray(windows[rows], dtype=np.float64).transpose(0, 2, 1))


def _map_batches(windows: np.ndarray, g: np.ndarray, solve: Callable[[np.ndarray, np.ndarray], np.ndarray],
                 ) -> np.ndarray:
    n = int(np.asarray(windows).shape[0])
    out = np.empty((n, 3))
    for rows in window_batches(n):
        out[rows] = solve(component_major(windows, rows), np.asarray(g[rows], dtype=np.float64))
    return out


# ----------------------------------------------------------------------------- won2009


def _svd_from_moments(cov: np.ndarray, e1: np.ndarray, c: np.ndarray, t: int,
                      ) -> tuple[np.ndarray, np.ndarray]:
    """Singular values (descending) and right singular vectors of the (n, T, 3) matrices
    with rows e_i + c, from the centred moments cov = Σ e eᵀ and e1 = Σ e.

    The Gram matrix Σ (e_i + c)(e_i + c)ᵀ is formed in a basis Q₀ whose first axis is c:
    there it is T‖c‖²·e₁e₁ᵀ plus terms of the size of the spread of the rows, each accurate
    to its own size, and its Cholesky factor R keeps that accuracy; the SVD of the 3×3 R
    gives the singular values and, through Q₀, the right singular vectors, as accurately as
    an SVD of the T×3 matrix itself.
    """
    size = np.sqrt(np.einsum("nk,nk->n", c, c))
    with np.errstate(divide="ignore", invalid="ignore"):
        q0 = _basis(c / size[:, None])
    q0 = np.where(np.isfinite(q0), q0, np.eye(3))
    gram = np.einsum("nki,nkl,nlj->nij", q0, cov, q0)
    e1r = np.einsum("nki,nk->ni", q0, e1)
    gram[:, 0, :] += size[:, None] * e1r
    gram[:, :, 0] += size[:, None] * e1r
    gram[:, 0, 0] += t * size * size
    _, sv, vt = np.linalg.svd(_cholesky3(gram))
    return sv, np.einsum("nik,njk->nij", q0, vt)


def won2009_batch(windows: np.ndarray, g: np.ndarray, *, tol: float = 1e-6, max_iter: int = 500,
                  rcond: float | None = None) -> np.ndarray:
    """:func:`~ofbe_model.estimators.physics.won2009_solve` of every window, (N, 3) m/s².

    Parameters
    ----------
    windows
        (N, T, 3) specific force, m/s² (float32 or float64).
    g
        (N,) local gravity, m/s².
    tol, max_iter, rcond
        As for the per-window solver.
    """
    return _map_batches(windows, np.asarray(g, dtype=np.float64),
                        lambda f, gb: won_iterations(f, gb, tol, max_iter, rcond)[0])


def won_iterations(f: np.ndarray, g: np.ndarray, tol: float, max_iter: int, rcond: float | None,
                   conds: list[list[float]] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Won & Golnaraghi's iterations on (n, 3, T) windows (component-major, float64).

    Every step solves 2·u_i·δ = ‖u_i‖² − g² in least squares, u_i = f_i − b. With u_i =
    e_i + c (e_i the samples less the window mean μ, c = μ − b) the normal equations of the
    design A = 2·U and right-hand side r are

        AᵀA = 4·(C + E₁cᵀ + cE₁ᵀ + T·ccᵀ)
        Aᵀr = 2·(M₃ + 2·C·c + κ·E₁ + S₂·c + 2·(E₁·c)·c + T·κ·c),  κ = ‖c‖² − g²,

    with the moments C = Σ e eᵀ, E₁ = Σ e (zero but for rounding), S₂ = Σ ‖e‖² and
    M₃ = Σ e ‖e‖², taken once: no pass over the samples per iteration. The step is
    ``lstsq``'s: through the singular values s and right singular vectors V of A
    (:func:`_svd_from_moments`), δ = Σ_k v_k·(v_kᵀAᵀr)/s_k² over the s_k above
    rcond·s_max (rcond None: machine epsilon × T, numpy's default).

    Every window's numbers come from its own data alone (reductions by index, no BLAS), so
    a window gives the same bits alone or in any batch.

    Parameters
    ----------
    f
        (n, 3, T) windows.
    g
        (n,) local gravity, m/s².
    tol, max_iter, rcond
        As for :func:`~ofbe_model.estimators.physics.won2009_solve`.
    conds
        When given, a list per window that receives s_max/s_min of each of its iterations.

    Returns
    -------
    b
        (n, 3) estimates, m/s².
    n_iter
        (n,) iterations done.
    converged
        (n,) whether the last step was shorter than ``tol``.
    """
    n, _, t = f.shape
    mu = f.mean(axis=2)
    e = f - mu[:, :, None]
    cov = np.einsum("nkt,nlt->nkl", e, e)
    e1 = e.sum(axis=2)
    e2 = np.einsum("nkt,nkt->nt", e, e)
    m3 = np.einsum("nkt,nt->nk", e, e2)
    s2 = e2.sum(axis=1)
    del e, e2
    cut = EPS * max(t, 3) if rcond is None else float(rcond)
    g2 = g * g
    b = np.zeros((n, 3))
    n_iter = np.zeros(n, dtype=np.int64)
    converged = np.zeros(n, dtype=bool)
    live = np.arange(n)
    for _ in range(max_iter):
        if live.size == 0:
            break
        c = mu[live] - b[live]
        kappa = np.einsum("nk,nk->n", c, c) - g2[live]
        e1c = np.einsum("nk,nk->n", e1[live], c)
        cov_c = np.einsum("nkl,nl->nk", cov[live], c)
        atr = 2.0 * (m3[live] + 2.0 * cov_c + kappa[:, None] * e1[live] + s2[live][:, None] * c
                     + 2.0 * e1c[:, None] * c + t * kappa[:, None] * c)
        sv, vec = _svd_from_moments(cov[live], e1[live], c, t)
        if conds is not None:
            with np.errstate(divide="ignore"):
                ratio = np.where(sv[:, 2] > 0, sv[:, 0] / sv[:, 2], np.inf)
            for i, k in enumerate(live):
                conds[k].append(float(ratio[i]))
        keep = sv > cut * sv[:, :1]
        coef = np.einsum("nkj,nk->nj", vec, atr)
        coef = np.divide(coef, 4.0 * sv * sv, out=np.zeros_like(coef), where=keep)
        delta = np.einsum("nkj,nj->nk", vec, coef)
        b[live] += delta
        n_iter[live] += 1
        short = np.sqrt(np.einsum("nk,nk->n", delta, delta)) < tol
        converged[live[short]] = True
        live = live[~short]
    return b, n_iter, converged


# ----------------------------------------------------------------------------- ls-trf (no bounds)


def ls_trf_batch(windows: np.ndarray, g: np.ndarray, *, ridge_weight: float = 0.0,
                 x0: np.ndarray | None = None, max_nfev: int | None = None) -> np.ndarray:
    """:func:`~ofbe_model.estimators.physics.ls_trf_solve` without bounds for every window,
    (N, 3) m/s².

    Parameters
    ----------
    windows
        (N, T, 3) specific force, m/s².
    g
        (N,) local gravity, m/s².
    ridge_weight
        Absolute ridge weight (0: none), as for the per-window solver.
    x0
        (3,) start and ridge centre, m/s² (None: zero).
    max_nfev
        Residual evaluations per window (None: scipy's default, 300).
    """
    start = np.zeros(3) if x0 is None else np.asarray(x0, dtype=np.float64).reshape(3)
    limit = 300 if max_nfev is None else int(max_nfev)
    return _map_batches(windows, np.asarray(g, dtype=np.float64),
                        lambda f, gb: BatchedTRF(f, gb, float(ridge_weight), start, limit).run())


def _basis(h: np.ndarray) -> np.ndarray:
    """(n, 3, 3) orthonormal bases whose first column is the unit vector h (n, 3)."""
    k = np.argmin(np.abs(h), axis=1)
    e = np.zeros_like(h)
    e[np.arange(h.shape[0]), k] = 1.0
    p = e - np.einsum("nk,nk->n", e, h)[:, None] * h
    p /= np.sqrt(np.einsum("nk,nk->n", p, p))[:, None]
    q = np.stack([h[:, 1] * p[:, 2] - h[:, 2] * p[:, 1], h[:, 2] * p[:, 0] - h[:, 0] * p[:, 2],
                  h[:, 0] * p[:, 1] - h[:, 1] * p[:, 0]], axis=1)  # h × p
    return np.stack([h, p, q], axis=2)


def _cholesky3(a: np.ndarray) -> np.ndarray:
    """Upper-triangular R with RᵀR = a for symmetric positive semi-definite (n, 3, 3) a
    (a zero pivot gives a zero row instead of an error)."""
    r = np.zeros_like(a)
    r11 = np.sqrt(np.maximum(a[:, 0, 0], 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        r12 = np.where(r11 > 0, a[:, 0, 1] / r11, 0.0)
        r13 = np.where(r11 > 0, a[:, 0, 2] / r11, 0.0)
        r22 = np.sqrt(np.maximum(a[:, 1, 1] - r12 * r12, 0.0))
        r23 = np.where(r22 > 0, (a[:, 1, 2] - r12 * r13) / r22, 0.0)
    r33 = np.sqrt(np.maximum(a[:, 2, 2] - r13 * r13 - r23 * r23, 0.0))
    r[:, 0, 0], r[:, 0, 1], r[:, 0, 2] = r11, r12, r13
    r[:, 1, 1], r[:, 1, 2], r[:, 2, 2] = r22, r23, r33
    return r


def forward3(r: np.ndarray, b: np.ndarray) -> np.ndarray:
    """y with Rᵀ·y = b for upper-triangular (n, 3, 3) R (a zero pivot gives 0 there)."""
    y = np.zeros_like(b)
    with np.errstate(divide="ignore", invalid="ignore"):
        y[:, 0] = np.where(r[:, 0, 0] > 0, b[:, 0] / r[:, 0, 0], 0.0)
        y[:, 1] = np.where(r[:, 1, 1] > 0, (b[:, 1] - r[:, 0, 1] * y[:, 0]) / r[:, 1, 1], 0.0)
        y[:, 2] = np.where(r[:, 2, 2] > 0,
                           (b[:, 2] - r[:, 0, 2] * y[:, 0] - r[:, 1, 2] * y[:, 1]) / r[:, 2, 2], 0.0)
    return y


class BatchedTRF:
    """scipy's ``trf_no_bounds`` (``tr_solver="exact"``, ``x_scale=1``, linear loss) for a
    batch of problems min_b Σ_i (‖f_i − b‖ − g)² [+ w²‖b − x0‖²], one function evaluation
    per window and round.

    Each window walks the same path as in scipy: the outer iteration (gradient test,
    evaluation budget, decomposition at the current point), the inner loop of trust-region
    steps until the cost decreases, the radius update and the termination tests. Windows in
    the inner loop keep their decomposition; windows whose step was accepted take a new one.

    The decomposition. scipy takes the SVD of the T×3 Jacobian J, whose rows are the unit
    vectors −u_i = −(f_i − b)/‖f_i − b‖, all close to one direction; J has one singular
    value ≈ √T and two ≈ √T·σ/g, and where b slides along the cost's flat valley the steps
    are made of the small two. Forming JᵀJ and taking its eigenvalues would lose the digits
    scipy keeps (an error of ε·T on eigenvalues of ≈ T·σ²/g²). So Σ u uᵀ is formed in a
    basis Q₀ whose first axis is the samples' mean direction, where every entry is accurate
    to its own size; its Cholesky factor R (J·Q₀ = Q·R for some orthonormal Q) keeps that
    accuracy, and the SVD of the 3×3 R (stacked on w·Q₀ with a ridge) gives J's singular
    values, its right singular vectors (through Q₀) and scipy's Uᵀf (through Qᵀf = R⁻ᵀ·Q₀ᵀJᵀf)
    as precisely as an SVD of J itself.
    """

    def __init__(self, f: np.ndarray, g: np.ndarray, ridge_weight: float, start: np.ndarray,
                 max_nfev: int) -> None:
        self._setup(f, g, ridge_weight, start, max_nfev)
        n = f.shape[0]
        # at the current point: cost, gradient Jᵀf, the factor R and its basis Q₀, and the
        # SVD of the Jacobian as the subproblem uses it: s (descending), V and Uᵀf
        ev = self._evaluate(np.arange(n), self.x)
        self.cost, self.grad, self.r, self.q0, self.s, self.vec, self.uf = ev[:7]
        norm0 = np.sqrt(np.einsum("nk,nk->n", self.x, self.x))
        self.delta = np.where(norm0 == 0.0, 1.0, norm0)

    def _setup(self, f: np.ndarray, g: np.ndarray, ridge_weight: float, start: np.ndarray,
               max_nfev: int) -> None:
        """The problem's data, buffers, the start (x = start) and the counters."""
        self.f, self.g = f, g
        n, _, t = f.shape
        self.mean = f.mean(axis=2)
        self._buf_d = np.empty_like(f)
        self._buf_norm = np.empty((n, t))
        self._buf_res = np.empty((n, t))
        self.w2 = ridge_weight if ridge_weight > 0.0 else 0.0
        self.w = float(np.sqrt(self.w2))
        self.start = start
        self.m = t + (3 if self.w2 else 0)
        self.max_nfev = max_nfev
        self.x = np.repeat(start[None, :], n, axis=0)
        self.nfev = np.ones(n, dtype=np.int64)
        self.alpha = np.zeros(n)

    def _evaluate(self, idx: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, ...]:
        """At points x of windows idx: cost, gradient Jᵀf, R, Q₀, s, V, Uᵀf and whether the
        residuals are finite (:meth:`_point`, then the SVD the subproblem uses)."""
        cost, grad, r, q0, g_rot, finite = self._point(idx, x)
        # J·Q₀ = Q·R, so Qᵀf = R⁻ᵀ·Q₀ᵀJᵀf; with a ridge the Jacobian [J; w·I] is, rotated,
        # blockdiag(Q, I)·[R; w·Q₀]. The SVD of that 3×3 (6×3) matrix, U·S·Vᵀ, gives J's
        # singular values, its right singular vectors Q₀·V and scipy's Uᵀf as Uᵀ·[Qᵀf; w·Δx]
        qf = forward3(r, g_rot)
        if self.w2:
            dx = x - self.start
            m = np.concatenate([r, self.w * q0], axis=1)
            z = np.concatenate([qf, self.w * dx], axis=1)
            cost += 0.5 * self.w2 * np.einsum("nk,nk->n", dx, dx)
            grad += self.w2 * dx
        else:
            m, z = r, qf
        u_m, sv, vt = np.linalg.svd(m, full_matrices=False)
        vec = np.matmul(q0, vt.transpose(0, 2, 1))
        return cost, grad, r, q0, sv, vec, np.einsum("nkj,nk->nj", u_m, z), finite

    def _point(self, idx: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, ...]:
        """The data term at points x (k, 3) of windows idx: cost ½Σr², gradient Jᵀf, the
        factor R and basis Q₀ (J·Q₀ = Q·R), Q₀ᵀ·Jᵀf, and whether the residuals are finite.

        The unit vectors u_i = (f_i − b)/‖f_i − b‖ are all close to h = (μ − b)/‖μ − b‖, the
        mean direction of the samples: Σ u uᵀ is formed from v_i = u_i − h, whose entries are
        of the size of the noise and keep their digits, as T·hhᵀ + h·(Σv)ᵀ + (Σv)·hᵀ + Σ v vᵀ,
        in a basis Q₀ whose first axis is h. There every entry is accurate to its own size
        (the small block is Σ v vᵀ's, rotated), as Jᵀf = −Σ u·r = −(Σ v·r + h·Σ r) is."""
        k = idx.size
        t = self.f.shape[2]
        h = self.mean[idx] - x
        size = np.sqrt(np.einsum("nk,nk->n", h, h))
        with np.errstate(divide="ignore", invalid="ignore"):
            h /= size[:, None]
            q0 = _basis(h)
        q0 = np.where(np.isfinite(q0), q0, np.eye(3))
        h = q0[:, :, 0]
        # f_i − b, then v_i, (k, 3, T), in buffers kept between evaluations
        f = self.f if k == self.f.shape[0] else self.f[idx]
        d, norm, res = self._buf_d[:k], self._buf_norm[:k], self._buf_res[:k]
        np.subtract(f, x[:, :, None], out=d)
        np.multiply(d[:, 0], d[:, 0], out=norm)  # (x² + y²) + z², as scipy's residuals sum them
        np.multiply(d[:, 1], d[:, 1], out=res)
        norm += res
        np.multiply(d[:, 2], d[:, 2], out=res)
        norm += res
        np.sqrt(norm, out=norm)
        np.subtract(norm, self.g[idx][:, None], out=res)
        finite = np.isfinite(res).all(axis=1)
        cost = 0.5 * np.einsum("nt,nt->n", res, res)
        d /= norm[:, None, :]  # u_i (J's rows are −u_i)
        d -= h[:, :, None]  # v_i
        vv = np.empty((k, 3, 3))
        for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)):
            vv[:, i, j] = vv[:, j, i] = np.einsum("nt,nt->n", d[:, i], d[:, j])
        sv1 = d.sum(axis=2)
        gram = vv + h[:, :, None] * sv1[:, None, :] + sv1[:, :, None] * h[:, None, :]
        gram = np.einsum("nki,nkl,nlj->nij", q0, gram, q0)
        gram[:, 0, 0] += t
        grad = -(np.matmul(d, res[:, :, None])[:, :, 0] + h * res.sum(axis=1)[:, None])
        g_rot = np.einsum("nki,nk->ni", q0, grad)  # Q₀ᵀ·Jᵀf
        return cost, grad, _cholesky3(gram), q0, g_rot, finite

    def _quadratic(self, idx: np.ndarray, step: np.ndarray) -> np.ndarray:
        """‖J·step‖² (with a ridge, of [J; w·I]) at the current points of windows idx."""
        js = np.einsum("nij,nj->ni", self.r[idx], np.einsum("nki,nk->ni", self.q0[idx], step))
        out = np.einsum("ni,ni->n", js, js)
        if self.w2:
            out += self.w2 * np.einsum("nk,nk->n", step, step)
        return out

    def _step(self, idx: np.ndarray) -> np.ndarray:
        """scipy's ``solve_lsq_trust_region`` for windows idx: the step; updates alpha."""
        s, vec, uf, delta = self.s[idx], self.vec[idx], self.uf[idx], self.delta[idx]
        alpha = self.alpha[idx].copy()
        suf = s * uf
        lam = s**2
        full_rank = s[:, 2] > EPS * self.m * s[:, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            p_gn = -np.einsum("nkj,nj->nk", vec, uf / s)
        gn = full_rank & (np.sqrt(np.einsum("nk,nk->n", p_gn, p_gn)) <= delta)
        step = np.where(gn[:, None], p_gn, 0.0)
        alpha[gn] = 0.0
        todo = np.flatnonzero(~gn)
        if todo.size:
            step[todo], alpha[todo] = self._lm_step(lam[todo], vec[todo], suf[todo], delta[todo],
                                                    alpha[todo], full_rank[todo])
        self.alpha[idx] = alpha
        return step

    @staticmethod
    def _phi(alpha: np.ndarray, suf: np.ndarray, lam: np.ndarray, delta: np.ndarray
             ) -> tuple[np.ndarray, np.ndarray]:
        denom = lam + alpha[:, None]
        p_norm = np.sqrt(np.sum((suf / denom) ** 2, axis=1))
        return p_norm - delta, -np.sum(suf**2 / denom**3, axis=1) / p_norm

    def _lm_step(self, lam: np.ndarray, vec: np.ndarray, suf: np.ndarray, delta: np.ndarray,
                 alpha: np.ndarray, full_rank: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        upper = np.sqrt(np.sum(suf**2, axis=1)) / delta
        lower = np.zeros_like(delta)
        if full_rank.any():
            phi0, dphi0 = self._phi(np.zeros(int(full_rank.sum())), suf[full_rank], lam[full_rank],
                                    delta[full_rank])
            lower[full_rank] = -phi0 / dphi0
        restart = ~full_rank & (alpha == 0.0)
        alpha = np.where(restart, np.maximum(0.001 * upper, np.sqrt(lower * upper)), alpha)
        live = np.ones(delta.shape, dtype=bool)
        for _ in range(_TR_MAX_ITER):
            i = np.flatnonzero(live)
            if i.size == 0:
                break
            a, lo, up, dl = alpha[i], lower[i], upper[i], delta[i]
            a = np.where((a < lo) | (a > up), np.maximum(0.001 * up, np.sqrt(lo * up)), a)
            phi, dphi = self._phi(a, suf[i], lam[i], dl)
            up = np.where(phi < 0, a, up)
            ratio = phi / dphi
            lo = np.maximum(lo, a - ratio)
            a = a - (phi + dl) * ratio / dl
            alpha[i], lower[i], upper[i] = a, lo, up
            live[i] = ~(np.abs(phi) < _TR_RTOL * dl)
        p = -np.einsum("nkj,nj->nk", vec, suf / (lam + alpha[:, None]))
        p *= (delta / np.sqrt(np.einsum("nk,nk->n", p, p)))[:, None]
        return p, alpha

    def run(self) -> np.ndarray:
        n = self.x.shape[0]
        done = np.zeros(n, dtype=bool)
        # windows at the top of an outer iteration (need the gradient test and a decomposition)
        top = np.ones(n, dtype=bool)
        while True:
            # outer iteration: gradient test, evaluation budget, decomposition
            t = np.flatnonzero(top & ~done)
            if t.size:
                g_norm = np.abs(self.grad[t]).max(axis=1)
                stop = (g_norm < GTOL) | (self.nfev[t] >= self.max_nfev)
                done[t[stop]] = True
            idx = np.flatnonzero(~done)
            if idx.size == 0:
                return self.x
            # inner iteration: a trust-region step and one evaluation
            step = self._step(idx)
            predicted = -(0.5 * self._quadratic(idx, step) + np.einsum("nk,nk->n", self.grad[idx], step))
            x_new = self.x[idx] + step
            cost_new, grad_new, r_new, q0_new, s_new, vec_new, uf_new, finite = self._evaluate(idx, x_new)
            self.nfev[idx] += 1
            step_norm = np.sqrt(np.einsum("nk,nk->n", step, step))
            delta = self.delta[idx]
            # non-finite residuals: shrink and try again (while evaluations are left)
            bad = ~finite
            delta_bad = 0.25 * step_norm
            # scipy's update_tr_radius and check_termination
            actual = self.cost[idx] - cost_new
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.where(predicted > 0, actual / predicted,
                                 np.where((predicted == 0) & (actual == 0), 1.0, 0.0))
            delta_new = np.where(ratio < 0.25, 0.25 * step_norm,
                                 np.where((ratio > 0.75) & (step_norm > 0.95 * delta), 2.0 * delta, delta))
            x_norm = np.sqrt(np.einsum("nk,nk->n", self.x[idx], self.x[idx]))
            ftol_ok = (actual < FTOL * self.cost[idx]) & (ratio > 0.25)
            xtol_ok = step_norm < XTOL * (XTOL + x_norm)
            terminated = ~bad & (ftol_ok | xtol_ok)
            keep_going = ~bad & ~terminated
            with np.errstate(divide="ignore", invalid="ignore"):
                self.alpha[idx] = np.where(keep_going, self.alpha[idx] * (delta / delta_new), self.alpha[idx])
            self.delta[idx] = np.where(bad, delta_bad, np.where(keep_going, delta_new, delta))
            accepted = ~bad & (actual > 0)
            a = idx[accepted]
            self.x[a], self.cost[a] = x_new[accepted], cost_new[accepted]
            self.grad[a], self.r[a], self.q0[a] = grad_new[accepted], r_new[accepted], q0_new[accepted]
            self.s[a], self.vec[a], self.uf[a] = s_new[accepted], vec_new[accepted], uf_new[accepted]
            # windows that leave the inner loop: accepted, terminated or out of evaluations;
            # the rest try another step from the same decomposition
            out_of_budget = self.nfev[idx] >= self.max_nfev
            leave = accepted | terminated | out_of_budget
            done[idx[terminated]] = True
            top[:] = False
            top[idx[leave & ~terminated]] = True
