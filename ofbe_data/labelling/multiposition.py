"""Zero-g offset (and diagonal scale) from the static poses of one multi-position session.

A device rests in K static poses within one power cycle. Pose k's mean specific force m_k
(m/s², sensor frame) satisfies, for a sensor with a diagonal scale map A = diag(s) and a
zero-g offset b,

    m_k = g · A · u_k + b,        |u_k| = 1,        so   |A⁻¹ (m_k − b)| = g,

with g the local gravity magnitude. No reference device tells the directions u_k; the
norm constraint alone determines b (and s) once the poses span enough directions. This
is methods.md §Labelling item 8 (the norm-constrained least squares over the static
segments of a power cycle).

Two models are fitted with ``scipy.optimize.least_squares`` and an analytic Jacobian:

``offset``
    3 unknowns b (A = I): minimise Σ_k (|m_k − b| − g)².
``scale-offset``
    6 unknowns, the diagonal scale s and b: minimise Σ_k (|(m_k − b) / s| − g)².

A model is reported as determined only with at least one pose more than it has unknowns
(4 for ``offset``, 7 for ``scale-offset``), so that the residual measures something, and
only when the geometry is well conditioned: the Jacobian at the solution, and the centred
pose means (which catch coplanar poses, see :func:`span_condition`). Otherwise the estimate
is NaN and ``reason`` says why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

MODELS: dict[str, int] = {"offset": 3, "scale-offset": 6}
"""Fitted models and their number of unknowns."""

REDUNDANT_POSES = 1
"""Poses required beyond the number of unknowns."""


@dataclass(frozen=True)
class PoseFit:
    """Result of :func:`fit_poses`.

    Attributes
    ----------
    model
        ``offset`` or ``scale-offset``.
    offset
        (3,) m/s², the zero-g offset b in the sensor frame; NaN when not determined.
    scale
        (3,) dimensionless diagonal scale factors s (ones for the ``offset`` model); NaN
        when not determined.
    directions
        (K, 3) unit specific-force direction u_k of each pose in the sensor frame, the
        normalised A⁻¹ (m_k − b); NaN when not determined.
    residual_rms
        m/s², root mean square of |A⁻¹ (m_k − b)| − g over the poses; NaN when too few poses.
    condition
        The larger of two condition numbers: the residual Jacobian's at the solution
        (:func:`jacobian_condition`) and the centred pose means' (:func:`span_condition`);
        NaN when too few poses.
    n_poses
        K, the number of poses given.
    determined
        Whether the poses determine the model.
    reason
        Empty when determined; otherwise why not.
    """

    model: str
    offset: np.ndarray
    scale: np.ndarray
    directions: np.ndarray
    residual_rms: float
    condition: float
    n_poses: int
    determined: bool
    reason: str


def min_poses(model: str) -> int:
    """Smallest number of poses that determines ``model`` (unknowns + one redundant pose).

    Parameters
    ----------
    model
        ``offset`` or ``scale-offset``.

    Returns
    -------
    int
        4 for ``offset``, 7 for ``scale-offset``.
    """
    return _n_unknowns(model) + REDUNDANT_POSES


def _n_unknowns(model: str) -> int:
    if model not in MODELS:
        raise ValueError(f"unknown model {model!r}; expected one of: {', '.join(MODELS)}")
    return MODELS[model]


def _check_means(means: np.ndarray) -> np.ndarray:
    m = np.asarray(means, dtype=np.float64)
    if m.ndim != 2 or m.shape[1] != 3:
        raise ValueError(f"means must have shape (K, 3), got {m.shape}")
    if not np.all(np.isfinite(m)):
        raise ValueError("means must be finite")
    return m


def _check_g(g: float) -> float:
    if not np.isfinite(g) or g <= 0:
        raise ValueError(f"g must be a positive finite number, got {g!r}")
    return float(g)


def sphere_centre(means: np.ndarray, g: float) -> np.ndarray:
    """Linearised least-squares sphere centre, the start of the nonlinear fit.

    |m_k|² = 2 m_k·b + (g² − |b|²) is linear in b and c = g² − |b|²; this solves it for
    (b, c) by (minimum-norm) linear least squares and returns b, ignoring the coupling
    between b and c.

    Parameters
    ----------
    means
        (K, 3) m/s², pose mean specific forces.
    g
        m/s², gravity magnitude (enters only through c, so it does not change b).

    Returns
    -------
    np.ndarray
        (3,) m/s², the centre.
    """
    m = _check_means(means)
    _check_g(g)
    design = np.hstack([2.0 * m, np.ones((m.shape[0], 1))])
    rhs = np.sum(m * m, axis=1)
    solution = np.linalg.lstsq(design, rhs, rcond=None)[0]
    return solution[:3]


def _unpack(x: np.ndarray, model: str) -> tuple[np.ndarray, np.ndarray]:
    """(offset, scale) from the parameter vector ``[b]`` or ``[b, s]``."""
    if model == "offset":
        return x[:3], np.ones(3)
    return x[:3], x[3:6]


def _residuals(x: np.ndarray, means: np.ndarray, g: float, model: str) -> np.ndarray:
    """(K,) m/s², |(m_k − b) / s| − g."""
    b, s = _unpack(x, model)
    return np.linalg.norm((means - b) / s, axis=1) - g


def _jacobian(x: np.ndarray, means: np.ndarray, g: float, model: str) -> np.ndarray:
    """(K, 3) or (K, 6) derivative of :func:`_residuals` with respect to ``[b]`` or ``[b, s]``.

    With v = (m − b)/s: ∂|v|/∂b_i = −v_i / (s_i |v|) and ∂|v|/∂s_i = −v_i² / (s_i |v|).
    """
    b, s = _unpack(x, model)
    v = (means - b) / s
    norm = np.maximum(np.linalg.norm(v, axis=1, keepdims=True), np.finfo(float).tiny)
    d_b = -v / (s * norm)
    if model == "offset":
        return d_b
    return np.hstack([d_b, -v * v / (s * norm)])


def condition_number(matrix: np.ndarray) -> float:
    """σ_max / σ_min of a matrix with at least as many rows as columns.

    Parameters
    ----------
    matrix
        (K, P) matrix.

    Returns
    -------
    float
        The 2-norm condition number; ``inf`` when K < P or the matrix is rank deficient.
    """
    if matrix.shape[0] < matrix.shape[1]:
        return float("inf")
    sv = np.linalg.svd(matrix, compute_uv=False)
    return float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")


def jacobian_condition(x: np.ndarray, means: np.ndarray, g: float, model: str) -> float:
    """Condition number of the residual Jacobian at ``x``, in consistent units.

    The offset columns are dimensionless; the scale columns are taken per unit of g·s (an
    acceleration, like b), so that no column is small merely because of its unit.

    Parameters
    ----------
    x
        (3,) or (6,) parameters ``[b]`` or ``[b, s]``, b in m/s².
    means
        (K, 3) m/s², pose means.
    g
        m/s², gravity magnitude.
    model
        ``offset`` or ``scale-offset``.

    Returns
    -------
    float
        The condition number (``inf`` when rank deficient).
    """
    jac = _jacobian(x, means, g, model)
    if model != "offset":
        jac = np.hstack([jac[:, :3], jac[:, 3:] / g])
    return condition_number(jac)


def span_condition(means: np.ndarray) -> float:
    """Condition number of the centred pose means, (K, 3) m − mean(m): ``inf`` when coplanar.

    Coplanar poses leave the offset's component normal to their plane undetermined, yet the
    nonlinear solution can drift off the plane to where the Jacobian looks regular; the
    centred means (the design of the linearised sphere fit, intercept removed) do not move.
    """
    return condition_number(means - means.mean(axis=0))


START_DECIMALS = 6
"""Decimal places (m/s², 1e-6 ≈ 0.1 µg) to which the linear start of the pose fit is rounded.

The nonlinear fit stops within its tolerances, so its result moves by ~1e-9 m/s² with the
start; the linear start comes from LAPACK, whose last bits depend on the BLAS kernel. Rounded,
the start is the same on every machine and so is the fit (and the label file's bytes).
"""


def _start(means: np.ndarray, g: float, model: str) -> np.ndarray:
    b0 = np.round(sphere_centre(means, g), START_DECIMALS)
    if model == "offset":
        return b0
    ratio = float(np.mean(np.linalg.norm(means - b0, axis=1))) / g
    return np.concatenate([b0, np.full(3, ratio if ratio > 0 else 1.0)])


def _nan_fit(model: str, k: int, residual_rms: float, condition: float, reason: str) -> PoseFit:
    return PoseFit(model, np.full(3, np.nan), np.full(3, np.nan), np.full((k, 3), np.nan),
                   residual_rms, condition, k, False, reason)


def fit_poses(means: np.ndarray, g: float, model: str = "offset", max_condition: float = 1e6) -> PoseFit:
    """Norm-constrained least-squares fit of the zero-g offset (and scale) to static poses.

    Parameters
    ----------
    means
        (K, 3) m/s², mean specific force of each static pose in the sensor frame, all
        from one power cycle.
    g
        m/s², local gravity magnitude (> 0).
    model
        ``offset`` (3 unknowns b) or ``scale-offset`` (6 unknowns: diagonal scale s, b).
    max_condition
        Largest acceptable ``condition`` (see :class:`PoseFit`). The default 1e6 rejects only
        (numerically) degenerate geometry. Noise makes near-degenerate conditions finite:
        twelve coplanar poses with 0.3 mg of noise out of their plane give about 3e3 (offset)
        and 4e5 (scale-offset, whose estimate is then meaningless), while six faces or
        random orientations give 1–2. Pass about 1e3 or less to reject such pose sets too.

    Returns
    -------
    PoseFit
        ``determined=False`` with NaN estimates and a ``reason`` when there are fewer than
        :func:`min_poses` poses or the condition number exceeds ``max_condition``.

    Raises
    ------
    ValueError
        If ``means`` is not a finite (K, 3) array, ``g`` is not positive and finite,
        ``model`` is unknown or ``max_condition`` is not positive.
    """
    n_unknowns = _n_unknowns(model)
    m = _check_means(means)
    g = _check_g(g)
    if not max_condition > 0:
        raise ValueError(f"max_condition must be positive, got {max_condition!r}")
    k = m.shape[0]
    needed = n_unknowns + REDUNDANT_POSES
    if k < needed:
        return _nan_fit(model, k, float("nan"), float("nan"),
                        f"{needed} poses needed for the {model} model, found {k}")
    solution = least_squares(_residuals, _start(m, g, model), jac=_jacobian, method="lm",
                             args=(m, g, model), xtol=1e-12, ftol=1e-12, gtol=1e-12)
    x = solution.x
    residual_rms = float(np.sqrt(np.mean(_residuals(x, m, g, model) ** 2)))
    span = span_condition(m)
    jac = jacobian_condition(x, m, g, model)
    condition = max(span, jac)
    if not condition <= max_condition:
        what = ("poses do not span three dimensions" if model == "offset" or span >= jac
                else "poses do not determine scale and offset")
        return _nan_fit(model, k, residual_rms, condition,
                        f"{what} (condition {condition:.1e} > {max_condition:.0e})")
    b, s = _unpack(x, model)
    v = (m - b) / s
    directions = v / np.linalg.norm(v, axis=1, keepdims=True)
    return PoseFit(model, b.copy(), s.copy(), directions, residual_rms, condition, k, True, "")


def apparent_biases(means: np.ndarray, fit: PoseFit, g: float) -> np.ndarray:
    """Apparent bias of each pose: what a one-position calibration would remove there.

    b_app_k = m_k − g·u_k, which equals b + (A − I)·u_k·g for A = diag(scale).

    Parameters
    ----------
    means
        (K, 3) m/s², the pose means the fit was made from.
    fit
        The :func:`fit_poses` result for those means.
    g
        m/s², local gravity magnitude.

    Returns
    -------
    np.ndarray
        (K, 3) m/s², NaN where the fit is not determined.

    Raises
    ------
    ValueError
        If ``means`` is not a finite (K, 3) array matching ``fit.directions`` or ``g`` is
        not positive and finite.
    """
    m = _check_means(means)
    g = _check_g(g)
    if m.shape != fit.directions.shape:
        raise ValueError(f"means have shape {m.shape}, the fit has {fit.directions.shape[0]} poses")
    return m - g * fit.directions
