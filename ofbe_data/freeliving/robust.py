"""A robust fit of one model of ofbe's calibration ladder to a recording's still epochs.

A still epoch is a pose (:mod:`ofbe_data.labelling.multiposition._fit`): its mean m_k (g, raw
axes) satisfies, with the device's map A = (T·K)⁻¹, its offset b and the offset's drift c per
°C about the reference temperature τ₀,

    |T·K·(m_k − b − c·(τ_k − τ₀))| = 1 g,

so the residual of epoch k is r_k = |T·K·(m_k − b − c·Δτ_k)| − 1 (g). The parameters, their
order and the Jacobian are the bench's (:func:`~ofbe_data.labelling.multiposition.parameter_names`,
:func:`~ofbe_data.labelling.multiposition.residual_jacobian`, with g = 1); the unweighted fit
of :func:`~ofbe_data.labelling.multiposition.fit_poses` is the start.

Robust weights (iteratively re-weighted least squares)
    A wearable's "still" epochs are not all still: a hand that turns slowly, a car, a bus
    pass the standard-deviation rule and move the mean off the sphere by tens of mg. The fit
    is therefore an M-estimate: Huber's ψ (c = :data:`HUBER_C`, convex, a unique solution)
    re-weighted to convergence, then Tukey's bisquare (c = :data:`BISQUARE_C`) from there,
    whose weight falls to 0 beyond c robust standard deviations, so that such epochs do not
    pull the fit at all. The robust standard deviation σ is 1.4826 × the median absolute
    deviation of the residuals (re-estimated at each Huber step, then held).

Standard errors (jackknife over postures)
    Consecutive still epochs in one orientation (a night on one side, an hour at a desk)
    share what is wrong with them (the strap, the posture, a slow drift), so they are not
    independent. They form a *posture*
    (:func:`~ofbe_data.labelling.multiposition.pose_clusters`: consecutive epochs within 5°),
    and the covariance is the one-step jackknife of the M-estimate over postures
    (:func:`jackknife_covariance`; the cluster-robust "CR3" sandwich): leave each posture out,
    move the estimate by one Newton step, and take the spread of the moves. The plain
    cluster sandwich (CR1) is biased low with few postures: on simulated wear with 50 postures
    of 3–30 epochs and 12 parameters its normalised errors had a standard deviation of 1.19
    (2.2 with 25), the jackknife's 0.88 (0.75 with 25; 0.98 with 150). The labelling's pose-error model
    (:mod:`ofbe_data.labelling.multiposition._errors`) builds n × n matrices, out of reach for the
    10⁴–10⁵ epochs of a week, and the jackknife needs no model of the errors at all. A model
    is determined only with more postures than parameters
    (:func:`~ofbe_data.labelling.multiposition.min_poses`, postures for poses) and a condition
    number within the labelling's limit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ofbe_data.labelling.multiposition import (
    PoseFit,
    fit_poses,
    has_temperature,
    jacobian_condition,
    map_from_params,
    min_poses,
    n_unknowns,
    pose_clusters,
    residual_jacobian,
    span_condition,
)

HUBER_C = 1.345
"""Huber's tuning constant (95 % efficiency under Gaussian errors)."""
BISQUARE_C = 4.685
"""Tukey's bisquare tuning constant (95 % efficiency); an epoch beyond c·σ has weight 0."""
MAD_TO_SD = 1.4826
"""The median absolute deviation of Gaussian errors times this is their standard deviation."""
MIN_SCALE_G = 1e-9
"""Smallest robust standard deviation used, g (exact synthetic data would give 0)."""
MAX_ITERATIONS = 200
"""Re-weighting steps of each phase at most."""
TOLERANCE = 1e-12
"""A phase stops when no parameter moves by more than this (g, dimensionless, rad, g/°C)."""
MAX_CONDITION = 1000.0
"""Largest condition number of a fitted model (the labelling's limit, ``choose_fit``)."""
POSTURE_TOLERANCE_DEG = 5.0
"""Consecutive still epochs within this angle of each other belong to one posture."""


@dataclass(frozen=True, eq=False)
class RobustFit:
    """One model fitted robustly to still epochs (:func:`fit_robust`).

    Attributes
    ----------
    fit
        The fit in the bench's terms: ``offset`` b (3,) g, ``matrix`` A (3, 3), ``temp_slope``
        c (3,) g/°C (NaN without temperature), ``temp_ref_c`` τ₀ °C, ``params`` and their
        ``covariance`` (:func:`jackknife_covariance`), ``condition``, ``determined`` and ``reason``;
        ``residual_rms`` is the weighted rms of the residuals, g.
    weights
        Shape (n,): each epoch's final robust weight, 0 to 1 (zeros when not determined).
    scale_g
        The robust standard deviation σ of the residuals, g.
    postures
        Shape (n,): the posture (cluster) number of each epoch.
    iterations
        Re-weighting steps taken (both phases).
    """

    fit: PoseFit
    weights: np.ndarray
    scale_g: float
    postures: np.ndarray
    iterations: int

    @property
    def n_postures(self) -> int:
        """Number of postures among the epochs."""
        return int(np.unique(self.postures).size)


def norm_residuals(params: np.ndarray, means_g: np.ndarray, dtemp_c: np.ndarray, model: str) -> np.ndarray:
    """r_k = |T·K·(m_k − b − c·Δτ_k)| − 1, g: shape (n,) from ``means_g`` (n, 3) g and
    ``dtemp_c`` (n,) °C about the reference, for ``params`` of ``model``."""
    x = np.asarray(params, dtype=np.float64)
    drift = dtemp_c[:, None] * x[-3:] if has_temperature(model) else 0.0
    v = (means_g - x[:3] - drift) @ np.linalg.inv(map_from_params(x, model)).T
    return np.sqrt(np.sum(v * v, axis=1)) - 1.0


def robust_scale(residuals: np.ndarray) -> float:
    """1.4826 × the median absolute deviation of ``residuals`` (g), at least :data:`MIN_SCALE_G`."""
    r = np.asarray(residuals, dtype=np.float64)
    return max(MAD_TO_SD * float(np.median(np.abs(r - np.median(r)))), MIN_SCALE_G)


def huber_psi(z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Huber's ψ(z), ψ'(z) and weight ψ(z)/z at the standardised residuals ``z`` (n,)."""
    psi = np.clip(z, -HUBER_C, HUBER_C)
    slope = (np.abs(z) < HUBER_C).astype(np.float64)
    weight = np.minimum(1.0, HUBER_C / np.maximum(np.abs(z), np.finfo(float).tiny))
    return psi, slope, weight


def bisquare_psi(z: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Tukey's bisquare ψ(z) = z(1 − u)², ψ'(z) = (1 − u)(1 − 5u) and weight (1 − u)², u = (z/c)²,
    all 0 beyond |z| = c, at the standardised residuals ``z`` (n,)."""
    u = (z / BISQUARE_C) ** 2
    inside = u < 1.0
    weight = np.where(inside, (1.0 - u) ** 2, 0.0)
    return z * weight, np.where(inside, (1.0 - u) * (1.0 - 5.0 * u), 0.0), weight


def gauss_newton_step(x: np.ndarray, means_g: np.ndarray, dtemp_c: np.ndarray, model: str,
                      weights: np.ndarray) -> np.ndarray:
    """One Gauss–Newton step of Σ w_k r_k² from ``x`` (shape (P,)), by the normal equations
    (JᵀWJ)·δ = −JᵀW·r (P × P; the condition rule keeps them far from singular), halved until it
    does not raise the weighted sum (at most 30 halvings)."""
    return _step(x, norm_residuals(x, means_g, dtemp_c, model), means_g, dtemp_c, model, weights)[0]


def _step(x: np.ndarray, r: np.ndarray, means_g: np.ndarray, dtemp_c: np.ndarray, model: str,
          weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`gauss_newton_step` from ``x`` whose residuals ``r`` are known; returns the new
    parameters and their residuals (those the step's own check computed, so the iteration
    computes each once)."""
    jac = residual_jacobian(x, means_g, dtemp_c, 1.0, model)
    weighted = jac * weights[:, None]
    step = np.linalg.solve(weighted.T @ jac, -(weighted.T @ r))
    cost = float(np.sum(weights * r * r))
    for _ in range(30):
        new = x + step
        r_new = norm_residuals(new, means_g, dtemp_c, model)
        if float(np.sum(weights * r_new ** 2)) <= cost:
            return new, r_new
        step = 0.5 * step
    return x, r


def jackknife_covariance(jac: np.ndarray, psi: np.ndarray, slope: np.ndarray, scale_g: float,
                         clusters: np.ndarray) -> np.ndarray:
    """The M-estimator's covariance by the one-step jackknife over postures (module notes), (P, P).

    Leaving posture c out moves the estimate by δ_c = (H − H_c)⁻¹ s_c (one Newton step of the
    estimating equations Σ ψ(z_k) J_k = 0 without the posture's epochs), with
    H = Σ ψ'(z_k) J_kᵀ J_k, H_c its part from posture c and s_c = Σ_{k in c} σ ψ(z_k) J_k; the
    covariance is (G − 1)/G · Σ_c (δ_c − δ̄)(δ_c − δ̄)ᵀ over the G postures with an epoch of
    non-zero ψ. A posture that alone determines a parameter makes H − H_c singular and that
    parameter's error as large as it is.

    Parameters
    ----------
    jac
        Shape (n, P): ∂r_k/∂θ at the estimate.
    psi, slope
        Shape (n,): ψ(z_k) and ψ'(z_k).
    scale_g
        σ, g.
    clusters
        Shape (n,): the posture of each epoch.
    """
    n, p = jac.shape
    _, index = np.unique(clusters, return_inverse=True)
    groups = int(index.max()) + 1 if n else 0
    sums = np.zeros((groups, p))
    np.add.at(sums, index, jac * (scale_g * psi)[:, None])
    curvature = jac * slope[:, None]
    parts = np.zeros((groups, p, p))
    np.add.at(parts, index, curvature[:, :, None] * jac[:, None, :])
    active = np.any(sums != 0.0, axis=1)
    if int(active.sum()) < 2:
        return np.full((p, p), np.inf)
    left_out = np.sum(parts, axis=0)[None, :, :] - parts[active]
    moves = np.einsum("gij,gj->gi", np.linalg.pinv(left_out), sums[active])
    centred = moves - moves.mean(axis=0)
    g = centred.shape[0]
    cov = (g - 1) / g * (centred.T @ centred)
    return 0.5 * (cov + cov.T)


def _undetermined(model: str, n: int, postures: np.ndarray, reason: str, condition: float = float("nan"),
                  temp_ref_c: float = float("nan")) -> RobustFit:
    p = n_unknowns(model)
    nan3 = np.full(3, np.nan)
    fit = PoseFit(model, nan3, np.full((3, 3), np.nan), nan3.copy(), temp_ref_c, np.full(p, np.nan),
                  np.full((p, p), np.nan), np.full((n, 3), np.nan), float("nan"), condition, n, n - p, False,
                  reason)
    return RobustFit(fit, np.zeros(n), float("nan"), postures, 0)


def _reweigh(x: np.ndarray, means_g: np.ndarray, dtemp_c: np.ndarray, model: str, scale_g: float | None,
             kind: str) -> tuple[np.ndarray, float, int]:
    """One phase of re-weighting from ``x``: (parameters, σ, steps); σ re-estimated when None."""
    psi_of = huber_psi if kind == "huber" else bisquare_psi
    fixed = scale_g
    sigma = float("nan")
    r = norm_residuals(x, means_g, dtemp_c, model)
    for step in range(1, MAX_ITERATIONS + 1):
        sigma = robust_scale(r) if fixed is None else fixed
        _, _, weights = psi_of(r / sigma)
        new, r = _step(x, r, means_g, dtemp_c, model, weights)
        moved = float(np.max(np.abs(new - x)))
        x = new
        if not moved > TOLERANCE:  # also stops on NaN
            return x, sigma, step
    return x, sigma, MAX_ITERATIONS


def fit_robust(means_g: np.ndarray, model: str, temperatures_c: np.ndarray | None = None,
               max_condition: float = MAX_CONDITION, postures: np.ndarray | None = None) -> RobustFit:
    """Fit ``model`` to still epochs with robust weights and cluster-robust standard errors.

    Parameters
    ----------
    means_g
        Shape (n, 3): the still epochs' raw means, g, in time order.
    model
        A model of the ladder (:data:`~ofbe_data.labelling.multiposition.MODELS`).
    temperatures_c
        Shape (n,): their temperatures, °C; needed by the ``+temperature`` models.
    max_condition
        Largest condition number accepted (of the weighted, column-scaled Jacobian and of the
        centred means of the epochs with weight > 0).
    postures
        Shape (n,): the posture of each epoch, where the caller knows them; None: consecutive
        epochs within :data:`POSTURE_TOLERANCE_DEG` (``pose_clusters``).

    Returns
    -------
    RobustFit
        ``fit.determined`` False, with the reason, when the epochs form too few postures
        (:func:`~ofbe_data.labelling.multiposition.min_poses`), the geometry is ill-conditioned,
        or the fit is not finite.
    """
    m = np.asarray(means_g, dtype=np.float64)
    n = m.shape[0]
    if postures is None:
        postures = pose_clusters([""] * n, m, POSTURE_TOLERANCE_DEG)
    elif np.shape(postures) != (n,):
        raise ValueError(f"postures: expected shape ({n},), found {np.shape(postures)}")
    groups = int(np.unique(postures).size)
    needed = min_poses(model)
    if groups < needed:
        return _undetermined(model, n, postures,
                             f"{needed} postures needed for the {model} model, found {groups}")
    start = fit_poses(m, 1.0, model, 1e6, temperatures_c if has_temperature(model) else None)
    if not start.determined:
        return _undetermined(model, n, postures, start.reason, start.condition)
    ref = start.temp_ref_c
    dtemp = (np.asarray(temperatures_c, dtype=np.float64) - ref) if has_temperature(model) else np.zeros(n)
    x, sigma, steps = _reweigh(start.params, m, dtemp, model, None, "huber")
    x, sigma, more = _reweigh(x, m, dtemp, model, sigma, "bisquare")
    r = norm_residuals(x, m, dtemp, model)
    psi, slope, weights = bisquare_psi(r / sigma)
    jac = residual_jacobian(x, m, dtemp, 1.0, model)
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(jac))):
        return _undetermined(model, n, postures, "the robust fit did not converge to finite values")
    used = weights > 0
    span = span_condition(m[used])
    jcond = jacobian_condition(jac * np.sqrt(weights)[:, None])
    condition = max(span, jcond)
    if not condition <= max_condition:
        what = ("the still epochs do not span three dimensions" if span >= jcond
                else f"the still epochs do not determine the {model} model's parameters")
        return _undetermined(model, n, postures, f"{what} (condition {condition:.1e} > {max_condition:.0e})",
                             condition, ref)
    cov = jackknife_covariance(jac, psi, slope, sigma, postures)
    matrix = map_from_params(x, model)
    v = (m - x[:3] - (dtemp[:, None] * x[-3:] if has_temperature(model) else 0.0)) @ np.linalg.inv(matrix).T
    directions = v / np.sqrt(np.sum(v * v, axis=1, keepdims=True))
    rms = float(np.sqrt(np.sum(weights * r * r) / max(float(np.sum(weights)), np.finfo(float).tiny)))
    temp = has_temperature(model)
    slope_c = x[-3:].copy() if temp else np.full(3, np.nan)
    fit = PoseFit(model, x[:3].copy(), matrix, slope_c, ref if temp else float("nan"), x.copy(), cov,
                  directions, rms, condition, n, n - x.size, True, "")
    return RobustFit(fit, weights, sigma, postures, steps + more)
