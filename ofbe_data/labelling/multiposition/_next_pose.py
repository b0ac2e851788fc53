"""Which pose to record next: the full model's expected uncertainty and the orientations that
shrink it most (methods.md §8, "Next pose").

A multi-position fit (``_fit``) estimates the unknowns θ of
the model |T·K·(m_k − b)| = g from the pose means m_k. Linearised at a point θ₀, with J the
(K, P) Jacobian of the residuals and σ the noise of one residual, the estimate's covariance
is σ²·(JᵀJ)⁻¹ — it depends on the poses and θ₀ only, not on the measured residuals, so it
can be predicted for poses not yet recorded: a pose with gravity's reaction along the unit
sensor-frame direction u reads m = g·A·u + b (A the output-referred map of θ₀, b its offset)
and adds one row to J.

Candidates are the 26 directions of a cube's faces, edges and corners, the orientations a
lab can set by hand against a box or a corner. :func:`next_poses` picks them greedily: while
the poses leave the model undetermined it maximises log det(JᵀJ + εI) (D-optimal, which
fills the missing directions of parameter space first); once determined it minimises the
largest expected standard error (minimax), each error expressed in m/s² (offsets as they
are, scales and angles times g: the specific-force error each causes at 1 g).

The norms' expectation here only *chooses* the poses (σ, the noise of one residual, only
scales it). What the poses determine and the standard errors stated, now or expected once the
chosen poses are added, are the label's own, with its error model
(``_advice``), so that ``check`` and ``ofbe-label`` say the same
thing about the same poses.

All functions are pure and deterministic: ties are broken by the fixed candidate order of
:func:`cube_directions`.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ofbe_data.labelling.multiposition._fit import (
    BASE_MODELS,
    fit_poses,
    map_from_params,
    n_unknowns,
    parameter_names,
    residual_jacobian,
)

MG = 9.80665e-3
"""m/s² per mg (one thousandth of standard gravity)."""

SINGULAR_CONDITION = 1e12
"""Condition number of the column-scaled normal matrix JᵀJ beyond which the poses do not
determine the model (the Jacobian's own condition is its square root, 1e6)."""

ZERO_COLUMN = 1e-10
"""A Jacobian column of norm at most this fraction of the largest is zero (rounding only): the
column scaling would otherwise blow rounding errors up to a unit column of random direction."""

NULL_COMPONENT = 1e-6
"""Norm of a parameter's component in the near-null space above which it is undetermined."""

LOGDET_RIDGE = 1e-9
"""ε of the D-optimal criterion log det(JᵀJ + εI) used while JᵀJ is singular."""

TIE_TOLERANCE = 1e-9
"""Relative difference below which two candidates' scores tie (the first in order wins)."""

LADDER = ("full", "scale-offset", "offset")
"""Fits tried, richest first, for the linearisation point."""


def _check_model(model: str) -> str:
    if model not in BASE_MODELS:
        raise ValueError(f"model must be one of {', '.join(BASE_MODELS)} (no temperature term), "
                         f"got {model!r}")
    return model


def _means(means: np.ndarray) -> np.ndarray:
    m = np.asarray(means, dtype=np.float64).reshape(-1, 3)
    if not np.all(np.isfinite(m)):
        raise ValueError("means must be finite")
    return m


def cube_directions() -> np.ndarray:
    """The 26 unit directions of a cube's faces, edges and corners, in a fixed order.

    Returns
    -------
    np.ndarray
        (26, 3): the vectors with components in {−1, 0, 1}, not all zero, normalised;
        faces (6) first, then edges (12), then corners (8), each group in descending
        lexicographic order of its components (``+x`` first, ``−x−y−z`` last).
    """
    vectors = [v for v in itertools.product((1, 0, -1), repeat=3) if any(v)]
    vectors.sort(key=lambda v: sum(c != 0 for c in v))  # stable: keeps the descending order within a group
    out = np.array(vectors, dtype=np.float64)
    return out / np.sqrt(np.sum(out * out, axis=1, keepdims=True))


def direction_name(u: np.ndarray) -> str:
    """``+x+y`` for the direction (1, 1, 0)/√2: the signs of u's non-zero components."""
    v = np.asarray(u, dtype=np.float64)
    scale = float(np.max(np.abs(v)))
    return "".join(f"{'+' if c > 0 else '-'}{a}" for a, c in zip("xyz", v, strict=True)
                   if scale > 0 and abs(c) > 1e-9 * scale) or "0"


def describe_direction(u: np.ndarray) -> str:
    """Words for a pose whose specific force (gravity's reaction, +g at rest) lies along ``u``.

    A resting accelerometer reads +g along the axis that points up, so u_x > 0 means the
    sensor's +x axis points up. Each axis is given with its angle above (``up``) or below
    (``down``) the horizontal, asin(u_i/|u|).

    Parameters
    ----------
    u
        (3,) direction in the sensor frame (need not be normalised).

    Returns
    -------
    str
        E.g. ``+x+y (x up 45°, y up 45°, z level)``; ``+z (z straight up, x level, y level)``.
    """
    v = np.asarray(u, dtype=np.float64)
    v = v / float(np.linalg.norm(v))
    words = []
    for a, c in zip("xyz", v, strict=True):
        deg = math.degrees(math.asin(min(1.0, abs(float(c)))))
        if deg < 0.5:
            words.append(f"{a} level")
        elif deg > 89.5:
            words.append(f"{a} straight {'up' if c > 0 else 'down'}")
        else:
            words.append(f"{a} {'up' if c > 0 else 'down'} {deg:.0f}°")
    words.sort(key=lambda w: w.endswith("level"))  # the tilted axes first
    return f"{direction_name(v)} ({', '.join(words)})"


def linearisation_point(means: np.ndarray, g: float, max_condition: float = 1000.0,
                        model: str = "full") -> tuple[np.ndarray, str]:
    """A point at which to linearise ``model``: the richest well-conditioned fit of the poses.

    Tries ``full``, ``scale-offset`` and ``offset`` (:func:`fit_poses` with
    ``max_condition``) and takes the first determined. A poorer fit fills the unknowns it
    does not estimate with the ideal values: imu_tk scales s = 1 (``offset``) and angles 0.
    When not even the offset is determined: the ideal sensor, b = 0 and A = I (the centre of
    a sphere through poses that do not determine its offset
    (:func:`_fit.sphere_centre`) is any point
    of a line or plane: with three poses the minimum-norm one made the advice repeat them).

    A loose ``max_condition`` is not advised: a full fit of poses near the six faces can
    converge to offsets of metres per second squared and angles of radians (condition ~1e5),
    which is no point to predict from; the labelling limit (1000) keeps to sound fits.

    Parameters
    ----------
    means
        (K, 3) m/s², the pose means.
    g
        m/s², local gravity magnitude.
    max_condition
        Largest :attr:`PoseFit.condition` of a fit used.
    model
        The model whose parameter vector is returned (``full``, ``scale-offset``, ``offset``).

    Returns
    -------
    tuple of (np.ndarray, str)
        The (P,) parameters of ``model`` in :func:`parameter_names` order, and what gave
        them: the fitted model's name, or ``"ideal sensor"``.
    """
    _check_model(model)
    m = _means(means)
    b = np.zeros(3)
    s = np.ones(3)
    angles = np.zeros(3)
    source = "ideal sensor"
    for candidate in LADDER:
        fit = fit_poses(m, g, candidate, max_condition)
        if fit.determined:
            b = fit.params[:3]
            if candidate in ("scale-offset", "full"):
                s = fit.params[3:6]
            if candidate == "full":
                angles = fit.params[6:9]
            source = candidate
            break
    x = np.concatenate([b, s, angles])[:n_unknowns(model)]
    return x.copy(), source


def pose_jacobian(means: np.ndarray, g: float, x: np.ndarray, model: str = "full") -> np.ndarray:
    """(K, P) Jacobian of the pose residuals of ``model`` at the parameters ``x``."""
    _check_model(model)
    m = _means(means)
    return residual_jacobian(np.asarray(x, dtype=np.float64), m, np.zeros(m.shape[0]), g, model)


def predicted_means(directions: np.ndarray, g: float, x: np.ndarray, model: str = "full") -> np.ndarray:
    """(N, 3) m/s², m = g·A·u + b of poses with specific force along the unit ``directions``."""
    _check_model(model)
    u = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    x = np.asarray(x, dtype=np.float64)
    return g * u @ map_from_params(x, model).T + x[:3]


@dataclass(frozen=True)
class Expectation:
    """Expected uncertainty of a model's parameters from a set of poses (:func:`expectation`).

    Attributes
    ----------
    covariance
        (P, P) σ²·(JᵀJ)⁻¹ over the determined parameters; an undetermined parameter has
        ``inf`` on the diagonal and NaN elsewhere in its row and column.
    se
        (P,) the standard errors, √diag, in the parameters' units (m/s², dimensionless, rad);
        ``inf`` where undetermined.
    undetermined
        (P,) bool, the parameters the poses leave undetermined.
    condition
        Condition number of the column-scaled JᵀJ (``inf`` when singular).
    """

    covariance: np.ndarray
    se: np.ndarray
    undetermined: np.ndarray
    condition: float

    @property
    def determined(self) -> bool:
        """Whether the poses determine every parameter (condition ≤ :data:`SINGULAR_CONDITION`)."""
        return bool(self.condition <= SINGULAR_CONDITION and not self.undetermined.any())


def expectation_from_jacobian(jac: np.ndarray, sigma: float = 1.0) -> Expectation:
    """σ²·(JᵀJ)⁻¹ of a residual Jacobian, with its undetermined parameters marked.

    The columns are scaled to unit norm (so that the units do not matter); singular values
    of the scaled J below σ_max/√:data:`SINGULAR_CONDITION` span the near-null space, and a
    parameter with a component of norm > :data:`NULL_COMPONENT` in it is undetermined. The
    others' covariance is the pseudo-inverse over the remaining singular values.

    Parameters
    ----------
    jac
        (K, P) residual Jacobian.
    sigma
        Noise of one residual (m/s²).

    Returns
    -------
    Expectation
    """
    j = np.asarray(jac, dtype=np.float64)
    if j.ndim != 2 or j.shape[1] < 1:
        raise ValueError(f"jac must have shape (K, P) with P ≥ 1, got {j.shape}")
    p = j.shape[1]
    norms = np.sqrt(np.sum(j * j, axis=0))
    norms[norms <= ZERO_COLUMN * (float(np.max(norms)) if norms.size else 0.0)] = 0.0
    j = np.where(norms > 0, j, 0.0)
    unit = np.where(norms > 0, norms, 1.0)
    if j.shape[0]:
        _, sv, vt = np.linalg.svd(j / unit, full_matrices=True)
    else:
        sv, vt = np.zeros(0), np.eye(p)
    sv = np.concatenate([sv, np.zeros(p - sv.size)])
    keep = sv > sv[0] / math.sqrt(SINGULAR_CONDITION) if sv[0] > 0 else np.zeros(p, dtype=bool)
    condition = float(sv[0] ** 2 / sv[-1] ** 2) if sv[-1] > 0 else float("inf")
    null = vt[~keep]
    undetermined = (np.sqrt(np.sum(null * null, axis=0)) > NULL_COMPONENT) | (norms == 0)
    v = vt[keep]
    cov = sigma ** 2 * ((v.T / sv[keep] ** 2) @ v) / np.outer(unit, unit)
    cov[undetermined, :] = np.nan
    cov[:, undetermined] = np.nan
    cov[undetermined, undetermined] = np.inf
    se = np.sqrt(np.diag(cov))
    return Expectation(cov, se, undetermined, condition)


def expected_covariance(means: np.ndarray, g: float, x: np.ndarray, model: str = "full",
                        sigma: float = 1.0) -> np.ndarray:
    """(P, P) expected covariance σ²·(JᵀJ)⁻¹ of ``model`` fitted to poses ``means`` near ``x``.

    Parameters
    ----------
    means
        (K, 3) m/s², the pose means.
    g
        m/s², local gravity magnitude.
    x
        (P,) the linearisation point in :func:`parameter_names` order
        (e.g. :func:`linearisation_point`).
    model
        ``full``, ``scale-offset`` or ``offset``.
    sigma
        m/s², the noise of one residual (1 gives the covariance per unit σ²).

    Returns
    -------
    np.ndarray
        (P, P); an undetermined parameter has ``inf`` on the diagonal and NaN elsewhere in
        its row and column (see :func:`expectation_from_jacobian`).
    """
    return expectation_from_jacobian(pose_jacobian(means, g, x, model), sigma).covariance


def se_in_mps2(se: np.ndarray, g: float, model: str = "full") -> np.ndarray:
    """Standard errors as the specific-force error each causes at 1 g, m/s².

    Offsets (m/s²) as they are; imu_tk scales (dimensionless) and angles (rad) times g.
    """
    _check_model(model)
    out = np.asarray(se, dtype=np.float64).copy()
    out[3:] *= g
    return out


def largest_se(jac: np.ndarray, g: float, sigma: float, model: str = "full") -> float:
    """The largest of :func:`se_in_mps2` of a Jacobian's expected errors, m/s² (``inf`` when
    the model is undetermined)."""
    e = expectation_from_jacobian(jac, sigma)
    if not e.determined:
        return float("inf")
    return float(np.max(se_in_mps2(e.se, g, model)))


def _first_best(scores: list[float], maximise: bool) -> int:
    """Index of the best score; scores within :data:`TIE_TOLERANCE` of it tie, the first wins."""
    values = np.array([(-s if maximise else s) for s in scores])
    best = float(np.min(values))
    tol = TIE_TOLERANCE * max(1.0, abs(best))
    return int(np.flatnonzero(values <= best + tol)[0])


def _greedy(jac: np.ndarray, rows: np.ndarray, g: float, sigma: float, n: int, model: str,
            d_optimal: bool) -> list[tuple[int, float]]:
    """Greedy choice of ``n`` distinct candidate rows: (index, largest SE after it) per step.

    Each step adds the chosen row to the design, and a candidate chosen once is not offered
    again. ``d_optimal`` False: minimax once some candidate makes the model determined, log det
    while none does; True: log det throughout.
    """
    ridge = LOGDET_RIDGE * np.eye(jac.shape[1])
    free = list(range(rows.shape[0]))
    out: list[tuple[int, float]] = []
    for _ in range(n):
        trials = [np.vstack([jac, rows[k]]) for k in free]
        worst = [largest_se(t, g, sigma, model) for t in trials]
        if not d_optimal and any(math.isfinite(w) for w in worst):
            pick = _first_best(worst, maximise=False)
        else:
            pick = _first_best([float(np.linalg.slogdet(t.T @ t + ridge)[1]) for t in trials], maximise=True)
        jac = trials[pick]
        out.append((free.pop(pick), worst[pick]))
    return out


def next_poses(means: np.ndarray, g: float, x: np.ndarray, sigma: float, n: int = 3,
               model: str = "full") -> list[tuple[np.ndarray, float]]:
    """The next ``n`` orientations to record, chosen greedily from :func:`cube_directions`.

    At each step every candidate u adds the Jacobian row of its predicted mean
    (:func:`predicted_means`) to the poses' J. If some candidates make the model
    determined, the one with the smallest :func:`largest_se` wins (minimax); otherwise the
    one with the largest log det(JᵀJ + εI), ε = :data:`LOGDET_RIDGE` (D-optimal). Ties go to
    the first candidate in order. Each candidate is chosen at most once, so the ``n`` poses are
    ``n`` distinct directions, at least 35° apart (the smallest angle between two cube
    directions): a pose advised twice would only average its noise, which a longer pose does.

    Greedy minimax is myopic when the poses determine the model only barely (six faces
    held slightly tilted: angle errors of tens of degrees): one pose cannot fix a weak
    subspace of three dimensions, so each step shaves the worst parameter a little (on the
    simulator's six faces, 48 mg after three poses where three D-optimal poses give
    0.6 mg). So the pure D-optimal greedy sequence is computed too, and taken when its
    final largest SE is smaller.

    Parameters
    ----------
    means
        (K, 3) m/s², the poses recorded so far.
    g
        m/s², local gravity magnitude.
    x
        (P,) the linearisation point (:func:`linearisation_point`).
    sigma
        m/s², the noise of one residual.
    n
        How many poses to choose, at most the 26 candidates.
    model
        ``full``, ``scale-offset`` or ``offset``.

    Returns
    -------
    list of (np.ndarray, float)
        Per chosen pose, in order: its unit direction u (3,) (specific force, i.e. the up
        direction, in the sensor frame) and the largest expected SE in m/s² once it and
        the poses before it are added (``inf`` while undetermined).
    """
    _check_model(model)
    candidates = cube_directions()
    if not 0 <= n <= candidates.shape[0]:
        raise ValueError(f"n must be between 0 and {candidates.shape[0]} (distinct cube directions), got {n}")
    if n == 0:
        return []
    x = np.asarray(x, dtype=np.float64)
    jac = pose_jacobian(means, g, x, model)
    rows = pose_jacobian(predicted_means(candidates, g, x, model), g, x, model)
    chosen = _greedy(jac, rows, g, sigma, n, model, d_optimal=False)
    d_opt = _greedy(jac, rows, g, sigma, n, model, d_optimal=True)
    if d_opt[-1][1] < chosen[-1][1] * (1.0 - TIE_TOLERANCE):
        chosen = d_opt
    return [(candidates[k].copy(), w) for k, w in chosen]


def readable_se(se: np.ndarray, model: str = "full") -> list[str]:
    """The standard errors as text in readable units: offsets in mg, scales in ppm, angles
    in degrees (``inf`` where undetermined), one string per parameter group."""
    _check_model(model)
    se = np.asarray(se, dtype=np.float64)

    def fmt(values: np.ndarray) -> str:
        return ", ".join(f"{v:.3g}" for v in values)

    out = [f"offset x, y, z {fmt(se[:3] / MG)} mg"]
    if se.size >= 6:
        out.append(f"scale x, y, z {fmt(se[3:6] * 1e6)} ppm")
    if se.size >= 9:
        names = "/".join(n.removeprefix("imutk_mis_") for n in parameter_names("full")[6:9])
        out.append(f"mis {names} {fmt(np.degrees(se[6:9]))}°")
    return out
