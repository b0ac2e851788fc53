"""Standard errors of a pose fit that cover the error, not only the white noise (methods.md §8).

Error model
    The mean m_k (m/s², sensor frame) of static pose k is off by

        e_k = w_k + d_c(k) + p_k,

    - w_k, white noise: per-axis variance W_k = std_k²/n_k, measured from the pose's own samples;
    - d_c, pose-to-pose error: in-run drift, settling, handling; one random 3-vector per
      *cluster* c, the consecutive poses of one recording in one direction (the still seconds
      either side of a tap and the stretch between the taps share the drift of that
      placement), independent between clusters, variance τ² per axis;
    - p_k, placement (the six-face rung only): a face pose is its face up to a small rotation,
      g·ε_k with ε_k across gravity, variance σ_p² (rad²) per direction. Ferraris' formulas
      read it as non-orthogonality; the pair sums m₊ᵢ + m₋ᵢ, whose components across gravity
      should equal the other axes' offsets, show it.

    The fits are linear to first order in these errors (θ̂ − θ ≈ Θ·e), so
    cov(θ̂) = Θ·(W + τ²·Z + σ_p²·P)·Θᵀ, with Z the cluster structure and P the face poses'
    placement (:func:`propagate`). A model that leaves map parameters out (``offset``,
    ``scale-offset``) adds their leak, S·C·Sᵀ with S = J⁺·J_missing, C their covariance from
    the richer fit that determines them or, where none does, the sensor model's
    (:data:`SCALE_PRIOR`, :data:`ANGLE_PRIOR_DEG`). The fit's estimate and residuals are unchanged.

Estimating τ² and σ_p² (method of moments)
    τ² comes from the residuals after projecting out everything the ``full`` model (with the
    fit's temperature slope) could explain with a condition up to the ladder's 1000
    (:data:`RANK_TOLERANCE`), so that a scale error or non-orthogonality that a simpler model
    leaves out does not count as noise: on six faces the ``offset`` model's residuals are the
    scale errors, which do not move its offsets (opposite faces cancel them). With y = Q·r,
    Q the projector, τ̂² = (yᵀVy − tr(V·Q W Qᵀ))/tr(V²), V = Q·C·Qᵀ (MINQUE with identity
    weights, Rao 1971); its effective degrees of freedom ν = 2τ₀⁴/var(τ̂²) at τ₀ =
    :data:`DRIFT_PRIOR_MG` count how well the residuals tell a drift of that size. Where
    ν < :data:`MIN_TAU_DOF` (six faces only, each placed once: every residual is explained by
    some model of the ladder, or only repeats inside one placement are left) the poses cannot
    tell drift from the model, and τ is the sensor model's in-run drift, :data:`DRIFT_PRIOR_MG`;
    the fit's reason says so. σ_p² comes from the six components of the pair sums across
    gravity, less what W and τ² put there, corrected for the squareness test that let them
    through (:func:`untruncated_variance`).

Why not a sandwich or a bootstrap over poses: with 18 placements and 9 unknowns the cluster
sandwich has 9 residual degrees of freedom shared by 9 parameters and is biased low, and a
bootstrap over six faces has nothing to resample; the two-parameter error model pools all
residuals, keeps each pose's white noise as measured (a 1 s pose beside a tap is 5× noisier
than the 35 s one between the taps), and says where it had to assume.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import ldl
from scipy.optimize import brentq, nnls
from scipy.sparse import csr_array

from ofbe_data.labelling.conventions import ANGLE_NAMES
from ofbe_data.labelling.multiposition._error_model import DRIFT_PRIOR_MG, MG, MIN_TAU_DOF, ErrorModel
from ofbe_data.labelling.multiposition._fit import (
    TEMPERATURE,
    PoseFit,
    base_model,
    has_temperature,
    map_from_params,
    parameter_names,
    residual_jacobian,
    temperature_offsets,
)

SCALE_PRIOR = 0.01
"""σ of a scale error a model leaves out (docs/sensor-model.md: 1 % per axis)."""

ANGLE_PRIOR_DEG = 0.3
"""σ of a non-orthogonality angle a model leaves out, degrees (docs/sensor-model.md: 0.3°)."""

CLUSTER_TOLERANCE_DEG = 5.0
"""Consecutive poses of one recording within this angle of each other share one cluster."""

VISIBLE = 1e-6
"""Eigenvalues of the projected cluster structure below this fraction of a pose's own are not seen."""

RANK_TOLERANCE = 1e-3
"""Singular values of the full model's column-scaled Jacobian below this fraction of the largest
span no residual that model could plausibly explain (1/1000, the ladder's condition limit): the
norms of near-faces see the angles only through the faces' small tilts, and a residual of noise
size there would take angles of degrees."""


@dataclass(frozen=True)
class PoseNoise:
    """What is known of each pose's error before the fit.

    Attributes
    ----------
    white
        (K, 3) (m/s²)², each pose mean's white-noise variance per axis (std²/n), or None
        (unknown: the pose-to-pose term takes all of it).
    clusters
        (K,) int, poses with equal numbers share one pose-to-pose error.
    """

    white: np.ndarray | None
    clusters: np.ndarray

    @classmethod
    def independent(cls, k: int) -> PoseNoise:
        """No sample statistics, every pose its own cluster."""
        return cls(None, np.arange(k))


def pose_clusters(recordings: list[str], means: np.ndarray,
                  tolerance_deg: float = CLUSTER_TOLERANCE_DEG) -> np.ndarray:
    """(K,) cluster numbers: a pose joins the previous pose's cluster when both are in one
    recording and within ``tolerance_deg`` of each other (poses in time order per recording)."""
    m = np.asarray(means, dtype=np.float64).reshape(-1, 3)
    unit = m / np.maximum(np.sqrt(np.sum(m * m, axis=1, keepdims=True)), np.finfo(float).tiny)
    cos_tol = float(np.cos(np.radians(tolerance_deg)))
    out = np.zeros(m.shape[0], dtype=np.int64)
    for k in range(1, m.shape[0]):
        same = recordings[k] == recordings[k - 1] and float(unit[k] @ unit[k - 1]) >= cos_tol
        out[k] = out[k - 1] if same else out[k - 1] + 1
    return out


def pose_noise(std: np.ndarray, n_samples: np.ndarray, recordings: list[str], means: np.ndarray) -> PoseNoise:
    """:class:`PoseNoise` from the poses' per-axis standard deviations (K, 3) m/s², sample counts
    (K,) and recording ids, poses in time order per recording."""
    s = np.asarray(std, dtype=np.float64).reshape(-1, 3)
    n = np.asarray(n_samples, dtype=np.float64).reshape(-1, 1)
    white = s * s / np.maximum(n, 1.0)
    return PoseNoise(white if np.all(np.isfinite(white)) else None, pose_clusters(recordings, means))


def column_space_basis(jac: np.ndarray) -> np.ndarray:
    """(K, R) U, an orthonormal basis of the column space of ``jac`` (K, P) (its columns scaled to
    unit norm; singular values below :data:`RANK_TOLERANCE` of the largest left out)."""
    norms = np.sqrt(np.sum(jac * jac, axis=0))
    scaled = jac / np.where(norms > 0, norms, 1.0)
    u, sv, _ = np.linalg.svd(scaled, full_matrices=False)
    return u[:, sv > RANK_TOLERANCE * (sv[0] if sv.size and sv[0] > 0 else 1.0)]


def column_space_projector(jac: np.ndarray) -> np.ndarray:
    """(K, K) I − U·Uᵀ, U an orthonormal basis of the column space of ``jac`` (K, P)
    (:func:`column_space_basis`)."""
    basis = column_space_basis(jac)
    return np.eye(jac.shape[0]) - basis @ basis.T


def _cluster_matrix(clusters: np.ndarray, dim: int = 1) -> np.ndarray:
    """(dim·K, dim·K) 1 where two coordinates belong to poses of one cluster and one axis."""
    c = np.asarray(clusters)
    return np.kron((c[:, None] == c[None, :]).astype(np.float64), np.eye(dim))


def _count_below(matrix: np.ndarray, shift: float) -> int:
    """How many eigenvalues of the symmetric ``matrix`` (N, N) lie below ``shift``: the negative
    inertia of ``matrix − shift·I`` from its LDLᵀ factorisation (Sylvester's law of inertia;
    Bunch–Kaufman, N³/3 operations against an eigen-decomposition's ~9 N³)."""
    _, d, _ = ldl(matrix - shift * np.eye(matrix.shape[0]), lower=True, hermitian=True, check_finite=False)
    count, k, n = 0, 0, d.shape[0]
    while k < n:
        if k + 1 < n and d[k + 1, k] != 0.0:  # a 2×2 pivot: count its negative eigenvalues
            count += int(np.sum(np.linalg.eigvalsh(d[k:k + 2, k:k + 2]) < 0.0))
            k += 2
        else:
            count += int(d[k, k] < 0.0)
            k += 1
    return count


ROUNDOFF = 1e-10
"""Eigenvalues of the projected cluster structure below this fraction of a pose's own are zero
but for rounding (a projector's null space): the fast path of :func:`estimate_tau2` applies when
every eigenvalue below :data:`VISIBLE` is below this."""

FAST_FROM = 200
"""Residuals from which :func:`estimate_tau2` tries its path without an eigen-decomposition."""


def _sandwich(left: np.ndarray, middle: np.ndarray, basis: np.ndarray | None) -> np.ndarray:
    """``left @ middle @ left.T`` (N, N) for a ``middle`` (D, D) that is mostly zeros (a cluster
    structure, a diagonal). With ``basis`` (N, R), ``left`` is I − basis·basisᵀ and the product
    is middle − X·basisᵀ − basis·Xᵀ + basis·(basisᵀ·middle·basis)·basisᵀ, X = middle·basis:
    no (N, N) product at all; else one instead of two."""
    if basis is None and np.count_nonzero(middle) > 4 * middle.shape[0]:
        return left @ middle @ left.T
    sparse = csr_array(middle)
    if basis is not None:
        x = np.asarray(sparse @ basis)
        core = basis.T @ x
        out = sparse.toarray() - x @ basis.T
        out -= basis @ x.T
        out += (basis @ core) @ basis.T
        return out
    half = np.asarray((sparse.T @ left.T).T)
    return half @ left.T


def estimate_tau2(y: np.ndarray, q_map: np.ndarray, known: np.ndarray, cluster: np.ndarray,
                  white_known: bool, exact_spectrum: bool = False,
                  projector_basis: np.ndarray | None = None) -> tuple[float, float]:
    """τ² (m/s²)² and the effective degrees of freedom of its estimate from projected residuals.

    The estimate is MINQUE's with identity weights, τ̂² = (yᵀVy − tr(V·Q_W))/tr(V²), with
    V = Q_map·cluster·Q_mapᵀ (its eigenvalues below :data:`VISIBLE` of the cluster structure's
    largest dropped: a cluster seen only through the noise in its poses' directions is not
    seen) and Q_W = Q_map·known·Q_mapᵀ. Its degrees of freedom are ν = 2·τ₀⁴/var(τ̂²) at
    τ₀ = :data:`DRIFT_PRIOR_MG`: how well the residuals would tell a pose-to-pose error of that
    size through the white noise.

    The eigenvalues below :data:`VISIBLE` are most often only the projector's null space, zero
    but for rounding. From :data:`FAST_FROM` residuals on, V is used as it is, without its
    eigen-decomposition, when the count of its eigenvalues below :data:`VISIBLE` (an LDLᵀ
    factorisation, :func:`_count_below`) is the null space's dimension (``projector_basis``
    given) or the count below :data:`ROUNDOFF` (a second one): what the decomposition would
    drop is then zero but for rounding, and the numbers are the same to ~1e-12 relative
    (``benchmarks/tau2_speed.py``: 1949 poses, several times faster). Otherwise, or with
    ``exact_spectrum``, the eigen-decomposition drops them.

    Parameters
    ----------
    y
        (N,) projected residuals, y = Q_map·e.
    q_map
        (N, D) the linear map from the pose errors (D coordinates) to ``y``.
    known
        (D, D) covariance of the pose errors that is known (the white noise).
    cluster
        (D, D) the pose-to-pose term's structure (τ² times it is its covariance).
    white_known
        False: a per-coordinate independent variance is estimated too where some cluster
        holds several poses (MINQUE with two components, non-negative).
    exact_spectrum
        Always drop the eigenvalues below :data:`VISIBLE` through the eigen-decomposition (the
        reference the fast path is checked against).
    projector_basis
        (N, R) orthonormal U where ``q_map`` is the projector I − U·Uᵀ (N = D), or None: V and
        Q_W are then formed without (N, N) products, and one factorisation decides.

    Returns
    -------
    (tau2, dof)
    """
    scale = max(float(np.max(np.diag(cluster))), np.finfo(float).tiny)
    v_c: np.ndarray | None = None
    v_k: np.ndarray | None = None
    if not exact_spectrum and q_map.shape[0] >= FAST_FROM:
        v = _sandwich(q_map, cluster, projector_basis)
        dropped = _count_below(v, VISIBLE * scale)
        null = (projector_basis.shape[1] if projector_basis is not None
                else _count_below(v, ROUNDOFF * scale))
        if dropped == null < q_map.shape[0]:
            v_c, v_k = v, _sandwich(q_map, known, projector_basis)
    if v_c is None or v_k is None:
        lam, vec = np.linalg.eigh(q_map @ cluster @ q_map.T)
        keep = lam > VISIBLE * scale
        if not np.any(keep):
            return 0.0, 0.0
        v_c = (vec[:, keep] * lam[keep]) @ vec[:, keep].T
        v_k = q_map @ known @ q_map.T
    prior = (DRIFT_PRIOR_MG * MG) ** 2
    sigma_y = v_k + prior * v_c
    vs = v_c @ sigma_y
    norm2 = float(np.sum(v_c * v_c))
    dof = prior ** 2 * norm2 ** 2 / float(np.sum(vs * vs.T))
    if white_known or np.allclose(cluster, np.diag(np.diag(cluster))):
        tau2 = (float(y @ v_c @ y) - float(np.sum(v_c * v_k))) / norm2
        return max(tau2, 0.0), dof
    v_i = q_map @ q_map.T
    comps = (v_i, v_c)
    lhs = np.array([[float(np.sum(a * b)) for b in comps] for a in comps])
    rhs = np.array([float(y @ a @ y) for a in comps])
    theta, _ = nnls(lhs, rhs)
    return float(theta[1]), dof


def _tau2_used(tau2: float, dof: float) -> tuple[float, bool]:
    """τ² from the residuals where they have :data:`MIN_TAU_DOF` degrees of freedom for it, else
    the prior (an estimate from one or two redundant placements is no estimate)."""
    if dof >= MIN_TAU_DOF:
        return tau2, False
    return (DRIFT_PRIOR_MG * MG) ** 2, True


def missing_names(model: str) -> list[str]:
    """The ``full`` model's map parameters that ``model`` leaves out (imu_tk's s, angles)."""
    base = base_model(model)
    names = [f"imutk_s_{a}" for a in "xyz"] if base == "offset" else []
    return names + ([f"imutk_mis_{n}" for n in ANGLE_NAMES] if base != "full" else [])


def prior_missing_covariance(names: list[str]) -> np.ndarray:
    """(N, N) diagonal covariance of left-out map parameters from the sensor model:
    :data:`SCALE_PRIOR` for imu_tk's scales, :data:`ANGLE_PRIOR_DEG` for its angles."""
    angle = float(np.radians(ANGLE_PRIOR_DEG))
    return np.diag([SCALE_PRIOR ** 2 if n.startswith("imutk_s_") else angle ** 2 for n in names])


def _full_point(params: np.ndarray, model: str) -> tuple[np.ndarray, str]:
    """The fit's parameters padded to ``full`` (s = 1, angles 0 where not fitted) and that model."""
    base = base_model(model)
    x = [params[:3], params[3:6] if base != "offset" else np.ones(3),
         params[6:9] if base == "full" else np.zeros(3)]
    if has_temperature(model):
        return np.concatenate([*x, params[-3:]]), "full" + TEMPERATURE
    return np.concatenate(x), "full"


def norm_fit_errors(fit: PoseFit, means: np.ndarray, g: float, noise: PoseNoise,
                    temperatures: np.ndarray | None = None,
                    missing_cov: np.ndarray | None = None) -> tuple[np.ndarray, ErrorModel]:
    """Covariance (P, P) of a norm-constrained fit (:func:`ofbe_data.labelling.multiposition.fit_poses`)
    under the module's error model, and the terms used.

    Pose k's error enters its residual as g_k·e_k with g_k = ∂r_k/∂m_k = −(the offset columns
    of the Jacobian J)_k, and the estimate as −J⁺·(g_k·e_k)_k; its variance is
    g_k·W_k·g_k + τ²·|g_k|² with cov(r_k, r_l) = τ²·g_k·g_l inside one cluster. A model that
    leaves map parameters out (``offset``, ``scale-offset``) adds their leak, S·C·Sᵀ with
    S = J⁺·J_missing (zero where the poses are balanced, as opposite faces are for scales)
    and C = ``missing_cov`` (:func:`missing_names` order; None: :func:`prior_missing_covariance`).
    """
    m = np.asarray(means, dtype=np.float64)
    dtemp, _ = temperature_offsets(temperatures, m.shape[0], fit.model)
    jac = residual_jacobian(fit.params, m, dtemp, g, fit.model)
    grad = -jac[:, :3]
    structure = (grad @ grad.T) * _cluster_matrix(noise.clusters)
    known = (np.diag(np.sum(grad * grad * noise.white, axis=1)) if noise.white is not None
             else np.zeros_like(structure))
    x_full, full = _full_point(fit.params, fit.model)
    jac_full = residual_jacobian(x_full, m, dtemp, g, full)
    basis = column_space_basis(jac_full)
    q = np.eye(jac_full.shape[0]) - basis @ basis.T
    r = _residuals(fit, m, dtemp, g)
    tau2, dof = estimate_tau2(q @ r, q, known, structure, noise.white is not None, projector_basis=basis)
    tau2, assumed = _tau2_used(tau2, dof)
    solve = np.linalg.pinv(jac)
    cov = propagate(solve, known + tau2 * structure)
    names = missing_names(fit.model)
    if names:
        order = parameter_names(full)
        leak = solve @ jac_full[:, [order.index(n) for n in names]]
        cov = cov + propagate(leak, prior_missing_covariance(names) if missing_cov is None else missing_cov)
    return cov, ErrorModel(float(np.sqrt(tau2)), dof, assumed)


def _residuals(fit: PoseFit, means: np.ndarray, dtemp: np.ndarray, g: float) -> np.ndarray:
    offsets = fit.offset + (dtemp[:, None] * fit.temp_slope if has_temperature(fit.model) else 0.0)
    v = np.linalg.solve(map_from_params(fit.params, fit.model), (means - offsets).T).T
    return np.sqrt(np.sum(v * v, axis=1)) - g


def propagate(sensitivity: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """S·Σ·Sᵀ, symmetrised: (N, D) sensitivity, (D, D) covariance → (N, N)."""
    out = sensitivity @ covariance @ sensitivity.T
    return 0.5 * (out + out.T)


def placement_structure(means: np.ndarray, faces: np.ndarray, offset: np.ndarray, g: float) -> np.ndarray:
    """(3K, 3K) covariance per rad² of placement: g²·(I − u·uᵀ) on each face pose's block,
    u the unit direction of m − b (``faces``: (6,) pose indices)."""
    m = np.asarray(means, dtype=np.float64)
    out = np.zeros((3 * m.shape[0], 3 * m.shape[0]))
    for k in faces:
        u = m[k] - offset
        u = u / np.linalg.norm(u)
        out[3 * k:3 * k + 3, 3 * k:3 * k + 3] = g * g * (np.eye(3) - np.outer(u, u))
    return out


def untruncated_variance(left: np.ndarray, limit: float) -> float:
    """Per-component variance v of the pair sums' components across gravity, (m/s²)², from
    ``left`` (6,) (pairs x, y, z, two components each) that passed the squareness test
    |left_pair| ≤ ``limit``: each pair's |left|² is 2v·Exp(1) truncated at limit², whose mean is
    2v − c²·q/(1 − q) with q = exp(−c²/(2v)); solved for v (a plain mean would be low by ~20 %
    where the test refuses one session in six). Three truncated pairs cannot tell a v beyond
    c²/2 (their mean nears c²/2, that of a uniform |left|², however large v is): v is at most
    that, a pair's untruncated rms at the limit."""
    r2 = float(np.mean(left.reshape(3, 2) ** 2) * 2.0)
    c2 = limit * limit
    if not np.isfinite(c2) or r2 <= 0:
        return r2 / 2.0

    def truncated_mean(v: float) -> float:
        q = float(np.exp(-c2 / (2.0 * v)))
        return 2.0 * v - c2 * q / (1.0 - q) - r2

    top = 0.5 * c2
    if truncated_mean(top) <= 0:
        return top
    return float(brentq(truncated_mean, 1e-6 * r2, top, xtol=1e-12 * r2))


def six_face_errors(outputs: dict[str, np.ndarray], derivatives: dict[str, np.ndarray],
                    rich_projector: np.ndarray, placement: np.ndarray,
                    noise: PoseNoise, square_limit: float = float("inf")) -> tuple[dict[str, np.ndarray],
                                                                                  ErrorModel]:
    """Covariances of the six-face fit's outputs under the module's error model.

    Parameters
    ----------
    outputs
        ``left`` (6,) m/s², the pair sums' components across gravity less the other axes'
        offsets, and ``residuals`` (K,) m/s², every pose's norm residual under the fit.
    derivatives
        Each output's (N, 3K) derivative with respect to the flattened pose means: ``params``
        (9: b, s, angles), ``matrix`` (9: A row-major), ``left`` (6) and ``residuals`` (K).
    rich_projector
        (K, K) the projector off the full model's norm Jacobian at the fit.
    placement
        (3K, 3K) :func:`placement_structure`.
    noise
        The poses' white noise and clusters.
    square_limit
        m/s², the largest |left| of a pair the squareness test lets through
        (:func:`untruncated_variance`); inf: none.

    Returns
    -------
    (covariances, model)
        ``params`` (9, 9) and ``matrix`` (9, 9) covariances, and the terms used.
    """
    dim = placement.shape[0]
    known = np.diag(noise.white.ravel()) if noise.white is not None else np.zeros((dim, dim))
    structure = _cluster_matrix(noise.clusters, 3)
    q_map = rich_projector @ derivatives["residuals"]
    tau2, dof = estimate_tau2(rich_projector @ outputs["residuals"], q_map, known, structure,
                              noise.white is not None)
    tau2, assumed = _tau2_used(tau2, dof)
    left, left_map = outputs["left"], derivatives["left"]
    seen_noise = float(np.trace(propagate(left_map, known + tau2 * structure)))
    rest = left.size * untruncated_variance(left, square_limit) - seen_noise
    seen = float(np.trace(propagate(left_map, placement)))
    sigma_p2 = max(rest, 0.0) / seen if seen > 0 else 0.0
    total = known + tau2 * structure + sigma_p2 * placement
    covs = {name: propagate(derivatives[name], total) for name in ("params", "matrix")}
    return covs, ErrorModel(float(np.sqrt(tau2)), dof, assumed, float(np.sqrt(sigma_p2)))
