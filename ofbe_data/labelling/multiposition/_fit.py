"""The calibration model ladder fitted to the static poses of one power cycle (methods.md §8).

A device rests in K static poses within one power cycle. Pose k's mean specific force m_k
(m/s², sensor frame) satisfies, with A the device's 3×3 map, b its zero-g offset and u_k the
unit direction of gravity in the pose,

    m_k = g · A · u_k + b,        |u_k| = 1,        so   |A⁻¹ (m_k − b)| = g,

with g the local gravity magnitude. No reference tells the directions u_k; the norm
constraint alone determines b (and A up to a rotation) once the poses span enough directions.

Parametrisation (imu_tk's, Tedaldi et al. 2014, "body frame" case)
    The fit works on the *input-referred* map M = A⁻¹ = T·K with K = diag(s) and
    T = [[1, −α_yz, α_zy], [0, 1, −α_zx], [0, 0, 1]], and minimises imu_tk's accelerometer
    cost Σ_k (|T·K·(m_k − b)| − g)². M and therefore A = M⁻¹ are upper triangular, which
    fixes the rotation that gravity cannot see as imu_tk does: the frame's z axis is the
    sensor's z sensitive axis and the frame's y–z plane holds its y axis (f_z = A_zz·a_z,
    f_y = A_yy·a_y + A_yz·a_z). The angles are small-angle entries of T, in radians. b is the offset in
    the sensor's output (imu_tk's ``bias_vec_``, imucal's ``b_a``, ofbe's ``offset``).

The ladder
    ``offset`` (3: b; s = 1, α = 0), ``scale-offset`` (6: b, s), ``full`` (9: b, s, α_yz,
    α_zy, α_zx). Any of them ``+temperature`` adds a per-axis bias slope c (m/s² per °C):
    the offset at pose k is b + c·(τ_k − τ₀), τ₀ the poses' mean temperature.

Six square faces
    Poses on the six faces only leave the norms blind to non-orthogonality;
    ``_six_faces`` fits ``full`` from them as imucal's Ferraris
    calibration does, and ``_ladder`` chooses among the fits.

Uncertainty
    :func:`fit_poses` alone gives cov = σ̂²·(JᵀJ)⁻¹ with σ̂² = Σ r_k² / (K − P) (every pose
    independent, one noise level). The labels use ``_errors``
    instead (the ladder, :func:`ofbe_data.labelling.multiposition.choose_fit`): each pose's white noise
    as measured, a pose-to-pose error shared by the poses of one placement and estimated from
    the residuals the full model cannot explain, and the six faces' placement. A model is
    fitted only with at least one pose more than it has unknowns (``dof`` ≥ 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from ofbe_data.labelling.conventions import ANGLE_NAMES, imutk_matrix, matrix_from_imutk
from ofbe_data.labelling.multiposition._error_model import ErrorModel

BASE_MODELS: dict[str, int] = {"offset": 3, "scale-offset": 6, "full": 9}
"""The ladder's models and their number of unknowns, simplest first."""

TEMPERATURE = "+temperature"
"""Suffix of a model with a per-axis bias temperature slope (3 more unknowns)."""

MODELS: dict[str, int] = {**BASE_MODELS, **{m + TEMPERATURE: n + 3 for m, n in BASE_MODELS.items()}}
"""Every fittable model and its number of unknowns."""

REDUNDANT_POSES = 1
"""Poses required beyond the number of unknowns (so that the residual measures the noise)."""

MIN_TEMPERATURE_SPAN_C = 5.0
"""Recorded temperature span over the poses, °C, from which a temperature slope is tried."""



@dataclass(frozen=True)
class PoseFit:
    """Result of :func:`fit_poses`.

    Attributes
    ----------
    model
        The model fitted (a key of :data:`MODELS`).
    offset
        (3,) m/s², the zero-g offset b in the sensor frame (at ``temp_ref_c`` with a
        temperature model); NaN when not determined.
    matrix
        (3, 3) the output-referred map A (f = A·a + b) the fit used: the identity for
        ``offset``, diagonal for ``scale-offset``, upper triangular for ``full``; NaN when not
        determined. Which entries were *fitted* is :func:`fitted_entries`.
    temp_slope
        (3,) m/s² per °C, the bias temperature slope; NaN without a temperature model.
    temp_ref_c
        °C, the temperature at which ``offset`` holds (the poses' mean); NaN without one.
    params
        (P,) the fitted unknowns in the order of :func:`parameter_names`.
    covariance
        (P, P) their covariance σ̂²·(JᵀJ)⁻¹; NaN when not determined.
    directions
        (K, 3) unit specific-force direction u_k of each pose, the normalised
        A⁻¹ (m_k − b(τ_k)); NaN when not determined.
    residual_rms
        m/s², root mean square of |A⁻¹ (m_k − b(τ_k))| − g over the poses; NaN when too few poses.
    condition
        The larger of two condition numbers: the column-scaled Jacobian's at the solution
        (:func:`jacobian_condition`; its square is the normal matrix's) and the centred pose
        means' (:func:`span_condition`); NaN when too few poses.
    n_poses
        K, the number of poses given.
    dof
        K − P, the residual's degrees of freedom.
    determined
        Whether the poses determine the model.
    reason
        Empty when determined; otherwise why not.
    how
        ``norms`` (imu_tk's norm-constrained fit) or ``six square faces``
        (:func:`ofbe_data.labelling.multiposition._six_faces.fit_six_faces`).
    matrix_se
        (3, 3) standard errors of ``matrix``'s entries where the fit gives them directly (the
        six-face fit's A is general, not a function of ``params``); None: derive them from
        ``params`` and ``covariance``.
    error_model
        The terms of ``_errors`` behind ``covariance``; None: the
        plain σ̂²·(JᵀJ)⁻¹ (every pose alone, white noise of one variance).
    """

    model: str
    offset: np.ndarray
    matrix: np.ndarray
    temp_slope: np.ndarray
    temp_ref_c: float
    params: np.ndarray
    covariance: np.ndarray
    directions: np.ndarray
    residual_rms: float
    condition: float
    n_poses: int
    dof: int
    determined: bool
    reason: str
    how: str = "norms"
    matrix_se: np.ndarray | None = None
    error_model: ErrorModel | None = None

    @property
    def scale(self) -> np.ndarray:
        """(3,) each axis' gain along its own sensitive direction, ‖A_i,:‖ (imucal's K_a)."""
        return np.sqrt(np.sum(self.matrix * self.matrix, axis=1))

    @property
    def rss(self) -> float:
        """Residual sum of squares, (m/s²)²."""
        return self.residual_rms ** 2 * self.n_poses


def base_model(model: str) -> str:
    """``full+temperature`` → ``full``."""
    return model.removesuffix(TEMPERATURE)


def has_temperature(model: str) -> bool:
    """Whether ``model`` fits a bias temperature slope."""
    return model.endswith(TEMPERATURE)


def n_unknowns(model: str) -> int:
    """Number of unknowns of ``model`` (raises ValueError for an unknown name)."""
    if model not in MODELS:
        raise ValueError(f"unknown model {model!r}; expected one of: {', '.join(MODELS)}")
    return MODELS[model]


def min_poses(model: str) -> int:
    """Smallest number of poses that determines ``model`` (unknowns + one redundant pose).

    Returns
    -------
    int
        4 for ``offset``, 7 for ``scale-offset``, 10 for ``full`` (3 more with temperature).
    """
    return n_unknowns(model) + REDUNDANT_POSES


def parameter_names(model: str) -> list[str]:
    """Names of the unknowns of ``model`` in the fit's order.

    ``offset_x…z`` (m/s²), ``imutk_s_x…z`` (imu_tk's input-referred scales, 1/gain),
    ``imutk_mis_yz``, ``imutk_mis_zy``, ``imutk_mis_zx`` (rad), ``temp_slope_x…z``
    (m/s² per °C).
    """
    base = base_model(model)
    names = [f"offset_{a}" for a in "xyz"]
    if base in ("scale-offset", "full"):
        names += [f"imutk_s_{a}" for a in "xyz"]
    if base == "full":
        names += [f"imutk_mis_{n}" for n in ANGLE_NAMES]
    if has_temperature(model):
        names += [f"temp_slope_{a}" for a in "xyz"]
    n_unknowns(model)
    return names


def check_means(means: np.ndarray) -> np.ndarray:
    m = np.asarray(means, dtype=np.float64)
    if m.ndim != 2 or m.shape[1] != 3:
        raise ValueError(f"means must have shape (K, 3), got {m.shape}")
    if not np.all(np.isfinite(m)):
        raise ValueError("means must be finite")
    return m


def check_g(g: float) -> float:
    if not np.isfinite(g) or g <= 0:
        raise ValueError(f"g must be a positive finite number, got {g!r}")
    return float(g)


@dataclass(frozen=True)
class _Unpacked:
    offset: np.ndarray
    s: np.ndarray
    angles: np.ndarray
    slope: np.ndarray

    @property
    def t(self) -> np.ndarray:
        return imutk_matrix(self.angles)

    @property
    def m(self) -> np.ndarray:
        """Input-referred map M = T·K."""
        return self.t * self.s


def _unpack(x: np.ndarray, model: str) -> _Unpacked:
    base = base_model(model)
    i = 3
    s = np.ones(3)
    angles = np.zeros(3)
    if base in ("scale-offset", "full"):
        s = x[i:i + 3]
        i += 3
    if base == "full":
        angles = x[i:i + 3]
        i += 3
    slope = x[i:i + 3] if has_temperature(model) else np.zeros(3)
    return _Unpacked(x[:3], s, angles, slope)


def map_from_params(x: np.ndarray, model: str) -> np.ndarray:
    """ofbe's output-referred A = (T·K)⁻¹ from the fitted unknowns ``x`` of ``model``."""
    parts = _unpack(np.asarray(x, dtype=np.float64), model)
    return matrix_from_imutk(parts.s, parts.angles)


def _corrected(x: np.ndarray, means: np.ndarray, dtemp: np.ndarray,
               model: str) -> tuple[_Unpacked, np.ndarray, np.ndarray]:
    """(parameters, d_k = m_k − b − c·Δτ_k, v_k = M·d_k)."""
    p = _unpack(x, model)
    d = means - p.offset - dtemp[:, None] * p.slope
    return p, d, d @ p.m.T


def _residuals(x: np.ndarray, means: np.ndarray, dtemp: np.ndarray, g: float, model: str) -> np.ndarray:
    """(K,) m/s², |T·K·(m_k − b − c·Δτ_k)| − g."""
    _, _, v = _corrected(x, means, dtemp, model)
    return np.sqrt(np.sum(v * v, axis=1)) - g


def residual_jacobian(x: np.ndarray, means: np.ndarray, dtemp: np.ndarray, g: float,
                      model: str) -> np.ndarray:
    """(K, P) derivative of :func:`_residuals`: ∂|v|/∂θ = (v/|v|)ᵀ ∂v/∂θ with v = T·K·d.

    ∂v/∂b = −M, ∂v/∂c = −M·Δτ, ∂v/∂s_j = T[:, j]·d_j, and for the angles, with w = K·d:
    ∂v/∂α_yz = (−w_y, 0, 0), ∂v/∂α_zy = (w_z, 0, 0), ∂v/∂α_zx = (0, −w_z, 0).
    """
    p, d, v = _corrected(x, means, dtemp, model)
    norm = np.maximum(np.sqrt(np.sum(v * v, axis=1, keepdims=True)), np.finfo(float).tiny)
    e = v / norm
    base = base_model(model)
    m = p.m
    cols = [-(e @ m)]
    if base in ("scale-offset", "full"):
        cols.append((e @ p.t) * d)
    if base == "full":
        w = d * p.s
        cols.append(np.stack([-e[:, 0] * w[:, 1], e[:, 0] * w[:, 2], -e[:, 1] * w[:, 2]], axis=1))
    if has_temperature(model):
        cols.append(-(e @ m) * dtemp[:, None])
    return np.hstack(cols)


def condition_number(matrix: np.ndarray) -> float:
    """σ_max / σ_min of a (K, P) matrix; ``inf`` when K < P or it is rank deficient."""
    if matrix.shape[0] < matrix.shape[1]:
        return float("inf")
    sv = np.linalg.svd(matrix, compute_uv=False)
    return float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf")


def _column_scaled(jac: np.ndarray) -> np.ndarray:
    norms = np.sqrt(np.sum(jac * jac, axis=0))
    return jac / np.where(norms > 0, norms, 1.0)


def jacobian_condition(jac: np.ndarray) -> float:
    """Condition number of a residual Jacobian with its columns scaled to unit norm.

    Scaling makes it independent of the parameters' units (m/s², dimensionless scales,
    radians, m/s² per °C); its square is the condition number of the normal matrix JᵀJ.
    """
    return condition_number(_column_scaled(jac))


def span_condition(means: np.ndarray) -> float:
    """Condition number of the centred pose means, (K, 3) m − mean(m): ``inf`` when coplanar.

    Coplanar poses leave the offset's component normal to their plane undetermined, yet the
    nonlinear solution can drift off the plane to where the Jacobian looks regular; the
    centred means (the design of the linearised sphere fit, intercept removed) do not move.
    """
    return condition_number(means - means.mean(axis=0))


def sphere_centre(means: np.ndarray, g: float) -> np.ndarray:
    """Linearised least-squares sphere centre, the start of the nonlinear fit.

    |m_k|² = 2 m_k·b + (g² − |b|²) is linear in b and c = g² − |b|²; this solves it for
    (b, c) by (minimum-norm) linear least squares and returns b.

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
    m = check_means(means)
    check_g(g)
    design = np.hstack([2.0 * m, np.ones((m.shape[0], 1))])
    rhs = np.sum(m * m, axis=1)
    return np.linalg.lstsq(design, rhs, rcond=None)[0][:3]


START_DECIMALS = 6
"""Decimal places (m/s², 1e-6 ≈ 0.1 µg) to which the linear start of the pose fit is rounded.

The nonlinear fit stops within its tolerances, so its result moves by ~1e-9 m/s² with the
start; the linear start comes from LAPACK, whose last bits depend on the BLAS kernel. Rounded,
the start is the same on every machine and so is the fit (and the label file's bytes).
"""


def _start(means: np.ndarray, g: float, model: str) -> np.ndarray:
    b0 = np.round(sphere_centre(means, g), START_DECIMALS)
    x = [b0]
    base = base_model(model)
    if base in ("scale-offset", "full"):
        gain = float(np.mean(np.sqrt(np.sum((means - b0) ** 2, axis=1)))) / g
        x.append(np.full(3, 1.0 / gain if gain > 0 else 1.0))
    if base == "full":
        x.append(np.zeros(3))
    if has_temperature(model):
        x.append(np.zeros(3))
    return np.concatenate(x)


def temperature_offsets(temperatures: np.ndarray | None, k: int, model: str) -> tuple[np.ndarray, float]:
    """(Δτ_k, τ₀): pose temperatures about their mean (zeros and NaN without a temperature model)."""
    if not has_temperature(model):
        return np.zeros(k), float("nan")
    if temperatures is None:
        raise ValueError(f"the {model} model needs the poses' temperatures")
    tau = np.asarray(temperatures, dtype=np.float64)
    if tau.shape != (k,) or not np.all(np.isfinite(tau)):
        raise ValueError(f"temperatures must be {k} finite values, got {tau.shape}")
    ref = float(np.round(np.mean(tau), 6))
    return tau - ref, ref


def temperature_problem(temperatures: np.ndarray | None, k: int, min_span_c: float = MIN_TEMPERATURE_SPAN_C
                        ) -> str | None:
    """Why ``k`` poses' temperatures cannot determine a bias temperature slope, or None when they can.

    A slope needs a temperature for every pose (a pose whose samples have none leaves the
    temperature models out, never the pose) and temperatures that differ by ``min_span_c`` at
    least across the poses (and by more than nothing: a constant temperature has no slope).

    Parameters
    ----------
    temperatures
        (K,) °C per pose, NaN where a pose has none; None when no pose has one.
    k
        Number of poses.
    min_span_c
        Smallest span of the poses' temperatures, °C.

    Returns
    -------
    str or None
        The reason, one clause (``temperature spans 0.0 °C across the poses (31.2 °C); a
        +temperature model needs 5 °C at least``).
    """
    model = f"a {TEMPERATURE} model"
    tau = None if temperatures is None else np.asarray(temperatures, dtype=np.float64).reshape(-1)
    if tau is None or not np.any(np.isfinite(tau)):
        return (f"no pose has a temperature (no temperature column mapped, or every cell of it empty or "
                f"NaN); {model} needs one for every pose")
    missing = int((~np.isfinite(tau)).sum())
    if missing:
        return (f"{missing} of {k} poses {'has' if missing == 1 else 'have'} no temperature (every "
                f"temperature cell of {'its' if missing == 1 else 'their'} samples empty or NaN); {model} "
                "needs one for every pose")
    span = float(np.ptp(tau))
    if span > 0.0 and span >= min_span_c:
        return None
    lo, hi = float(tau.min()), float(tau.max())
    where = f"{lo:.1f} °C" if f"{lo:.1f}" == f"{hi:.1f}" else f"{lo:.1f} to {hi:.1f} °C"
    need = f"{min_span_c:g} °C at least" if min_span_c > 0 else "poses at different temperatures"
    return f"temperature spans {span:.1f} °C across the poses ({where}); {model} needs {need}"


def nan_fit(model: str, k: int, residual_rms: float, condition: float, reason: str) -> PoseFit:
    p = n_unknowns(model)
    nan3 = np.full(3, np.nan)
    return PoseFit(model, nan3, np.full((3, 3), np.nan), nan3.copy(), float("nan"), np.full(p, np.nan),
                   np.full((p, p), np.nan), np.full((k, 3), np.nan), residual_rms, condition, k, k - p, False,
                   reason)


def fit_poses(means: np.ndarray, g: float, model: str = "offset", max_condition: float = 1e6,
              temperatures: np.ndarray | None = None) -> PoseFit:
    """Fit one model of the ladder to static poses by imu_tk's norm-constrained least squares.

    Parameters
    ----------
    means
        (K, 3) m/s², mean specific force of each static pose in the sensor frame, all
        from one power cycle.
    g
        m/s², local gravity magnitude (> 0).
    model
        A key of :data:`MODELS`.
    max_condition
        Largest acceptable ``condition`` (see :class:`PoseFit`). The default 1e6 rejects only
        (numerically) degenerate geometry; labelling uses 1000. Six faces or random
        orientations give 1–10; twelve coplanar poses with 0.3 mg of noise out of their plane
        give thousands.
    temperatures
        (K,) °C, each pose's mean temperature; needed by the ``+temperature`` models only.

    Returns
    -------
    PoseFit
        ``determined=False`` with NaN estimates and a ``reason`` when there are fewer than
        :func:`min_poses` poses or the condition number exceeds ``max_condition``.

    Raises
    ------
    ValueError
        If ``means`` is not a finite (K, 3) array, ``g`` is not positive and finite,
        ``model`` is unknown, ``max_condition`` is not positive, or a temperature model is
        asked for without finite temperatures.
    """
    p = n_unknowns(model)
    m = check_means(means)
    g = check_g(g)
    if not max_condition > 0:
        raise ValueError(f"max_condition must be positive, got {max_condition!r}")
    k = m.shape[0]
    needed = p + REDUNDANT_POSES
    if k < needed:
        return nan_fit(model, k, float("nan"), float("nan"),
                        f"{needed} poses needed for the {model} model, found {k}")
    dtemp, ref = temperature_offsets(temperatures, k, model)
    if has_temperature(model) and not np.ptp(dtemp) > 0:  # a slope of a constant temperature
        return nan_fit(model, k, float("nan"), float("nan"), str(temperature_problem(temperatures, k, 0.0)))
    solution = least_squares(_residuals, _start(m, g, model), jac=residual_jacobian, method="lm",
                             args=(m, dtemp, g, model), xtol=1e-12, ftol=1e-12, gtol=1e-12)
    x = solution.x
    r = _residuals(x, m, dtemp, g, model)
    residual_rms = float(np.sqrt(np.mean(r * r)))
    jac = residual_jacobian(x, m, dtemp, g, model)
    span = span_condition(m)
    jcond = jacobian_condition(jac)
    condition = max(span, jcond)
    if not condition <= max_condition:
        what = ("poses do not span three dimensions" if base_model(model) == "offset" or span >= jcond
                else f"poses do not determine the {model} model's parameters")
        return nan_fit(model, k, residual_rms, condition,
                        f"{what} (condition {condition:.1e} > {max_condition:.0e})")
    dof = k - p
    sigma2 = float(np.sum(r * r)) / dof
    covariance = sigma2 * np.linalg.pinv(jac.T @ jac)
    parts = _unpack(x, model)
    matrix = map_from_params(x, model)
    _, _, v = _corrected(x, m, dtemp, model)
    directions = v / np.sqrt(np.sum(v * v, axis=1, keepdims=True))
    slope = parts.slope.copy() if has_temperature(model) else np.full(3, np.nan)
    return PoseFit(model, parts.offset.copy(), matrix, slope, ref, x.copy(), covariance, directions,
                   residual_rms, condition, k, dof, True, "")


def apparent_biases(means: np.ndarray, fit: PoseFit, g: float) -> np.ndarray:
    """Apparent bias of each pose: what a one-position calibration would remove there.

    b_app_k = m_k − g·u_k, which equals b + (A − I)·u_k·g.

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
    m = check_means(means)
    g = check_g(g)
    if m.shape != fit.directions.shape:
        raise ValueError(f"means have shape {m.shape}, the fit has {fit.directions.shape[0]} poses")
    return m - g * fit.directions
