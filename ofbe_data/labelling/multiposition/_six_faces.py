"""The ``full`` calibration model from six square cube faces (imucal's Ferraris formulas).

Poses on the six faces of a cube only (however often each is repeated) leave the norms
blind to the non-orthogonality: opposite faces give one norm equation. What they add is
that opposite faces are opposite: u₋ = −u₊. Then, as imucal's Ferraris calibration does,
each axis' offset is the mean of its own component over its two faces,
b_i = (m₊ᵢ,ᵢ + m₋ᵢ,ᵢ)/2 (second-order insensitive to how the cube sits), and A's columns are
the half-differences, A·e_i = (m₊ᵢ − m₋ᵢ)/(2g): a full A (nine entries, the cube's frame).
:func:`fit_six_faces` does this where the norm fit of ``full`` is not determined, every
signed axis has a pose within :data:`FACE_TOLERANCE_DEG`, and the faces are square: the
components of the pair sums that should equal the other axes' offsets do so within
:data:`SQUARE_TOLERANCE_DEG` of tilt (a tilt θ between opposite faces moves b_i by about
g·θ²/4, 0.08 mg at 1°). The longest pose of each face is used (ties: the earliest); the
other poses give the residual.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ofbe_data.labelling.conventions import imutk_from_matrix
from ofbe_data.labelling.multiposition._errors import (
    PoseNoise,
    column_space_projector,
    placement_structure,
    six_face_errors,
)
from ofbe_data.labelling.multiposition._fit import (
    PoseFit,
    check_g,
    check_means,
    condition_number,
    nan_fit,
    residual_jacobian,
    span_condition,
)

FACE_TOLERANCE_DEG = 15.0
"""A pose whose mean lies within this angle of a signed sensor axis is on that cube face."""

SQUARE_TOLERANCE_DEG = 1.0
"""Largest tilt between opposite faces (from the pair sums) for :func:`fit_six_faces`."""

SIX_FACES = "six square faces"
""":attr:`PoseFit.how` of :func:`fit_six_faces` (``norms`` for the norm-constrained fit)."""


FACE_ORDER = ("+x", "-x", "+y", "-y", "+z", "-z")
"""Order of the faces in :func:`six_faces` and :func:`ferraris_solution`."""


def six_faces(means: np.ndarray, weights: np.ndarray | None = None) -> tuple[np.ndarray | None, str]:
    """The pose used for each cube face, or why the poses are not six faces.

    Parameters
    ----------
    means
        (K, 3) m/s², pose means.
    weights
        (K,) e.g. samples per pose; the heaviest pose on a face is used (ties: the earliest).
        None: the earliest.

    Returns
    -------
    (index, reason)
        (6,) pose indices in :data:`FACE_ORDER` and ``""``, or None and a sentence.
    """
    m = check_means(means)
    w = np.ones(m.shape[0]) if weights is None else np.asarray(weights, dtype=np.float64)
    unit = m / np.maximum(np.sqrt(np.sum(m * m, axis=1, keepdims=True)), np.finfo(float).tiny)
    axis = np.argmax(np.abs(unit), axis=1)
    cosine = np.abs(unit[np.arange(m.shape[0]), axis])
    on_face = cosine >= np.cos(np.radians(FACE_TOLERANCE_DEG))
    index = []
    missing = []
    for name in FACE_ORDER:
        i, sign = "xyz".index(name[1]), 1.0 if name[0] == "+" else -1.0
        here = np.flatnonzero(on_face & (axis == i) & (np.sign(unit[:, i]) == sign))
        if here.size == 0:
            missing.append(name)
            continue
        index.append(int(here[np.argmax(w[here])]))  # argmax: the first of equal weights
    if missing:
        return None, (f"no pose within {FACE_TOLERANCE_DEG:g}° of face{'s' if len(missing) > 1 else ''} "
                      + ", ".join(missing))
    return np.array(index), ""


def ferraris_solution(faces: np.ndarray, g: float) -> tuple[np.ndarray, np.ndarray]:
    """Offset and map from the six face means, as imucal's Ferraris calibration computes them.

    Parameters
    ----------
    faces
        (6, 3) m/s², the means of the faces in :data:`FACE_ORDER`.
    g
        m/s².

    Returns
    -------
    (b, A)
        b (3,) m/s² with b_i = (m₊ᵢ,ᵢ + m₋ᵢ,ᵢ)/2; A (3, 3) with columns (m₊ᵢ − m₋ᵢ)/(2g).
    """
    f = np.asarray(faces, dtype=np.float64)
    plus, minus = f[0::2], f[1::2]
    return 0.5 * np.diag(plus + minus), ((plus - minus) / (2.0 * g)).T


def face_tilt_deg(faces: np.ndarray, g: float) -> float:
    """Largest angle between a face and the opposite of its opposite face, degrees.

    The pair sum m₊ᵢ + m₋ᵢ = 2b + g·A·(u₊ + u₋): its components other than i should be 2b_j,
    as the other pairs give them; what is left is g·A·(u₊ + u₋) ≈ g·θ across gravity.
    """
    f = np.asarray(faces, dtype=np.float64)
    b, _ = ferraris_solution(f, g)
    left = 0.5 * (f[0::2] + f[1::2]) - b
    np.fill_diagonal(left, 0.0)
    return float(np.degrees(2.0 * np.max(np.sqrt(np.sum(left * left, axis=1))) / g))


def _outputs(means: np.ndarray, index: np.ndarray, g: float) -> dict[str, np.ndarray]:
    """The six-face fit's outputs from all pose means (K, 3) m/s² and the face poses ``index`` (6,):
    ``params`` (b, imu_tk's s and angles), ``matrix`` (A row-major), ``left`` (the pair sums'
    six components across gravity less the other axes' offsets, m/s²) and ``residuals`` (each
    pose's |A⁻¹(m_k − b)| − g, m/s²)."""
    faces = means[index]
    b, a = ferraris_solution(faces, g)
    s, angles = imutk_from_matrix(a)
    left = 0.5 * (faces[0::2] + faces[1::2]) - b
    v = np.linalg.solve(a, (means - b).T).T
    return {"params": np.concatenate([b, s, angles]), "matrix": a.ravel(),
            "left": left[~np.eye(3, dtype=bool)], "residuals": np.sqrt(np.sum(v * v, axis=1)) - g}


def _derivatives(means: np.ndarray, index: np.ndarray, g: float) -> dict[str, np.ndarray]:
    """Each output of :func:`_outputs` differentiated with respect to the flattened means, (N, 3K):
    by central differences (step 1e-6·g) in the face poses' coordinates, the only ones b and A
    depend on, and analytically for every other pose's own residual, ∂r_k/∂m_k = (v_k/|v_k|)ᵀ·A⁻¹
    with v_k = A⁻¹(m_k − b)."""
    step = 1e-6 * g
    base = _outputs(means, index, g)
    out = {name: np.zeros((value.size, means.size)) for name, value in base.items()}
    for j in (3 * np.asarray(index)[:, None] + np.arange(3)).ravel():
        hi, lo = means.copy(), means.copy()
        hi.flat[j] += step
        lo.flat[j] -= step
        up, down = _outputs(hi, index, g), _outputs(lo, index, g)
        for name in out:
            out[name][:, j] = (up[name] - down[name]) / (2.0 * step)
    b, a = ferraris_solution(means[index], g)
    inverse = np.linalg.inv(a)
    v = (means - b) @ inverse.T
    own = (v / np.linalg.norm(v, axis=1, keepdims=True)) @ inverse
    for k in sorted(set(range(means.shape[0])) - {int(i) for i in index}):
        out["residuals"][k, 3 * k:3 * k + 3] = own[k]
    return out


def fit_six_faces(means: np.ndarray, g: float, weights: np.ndarray | None = None,
                  noise: PoseNoise | None = None) -> PoseFit:
    """The ``full`` model from six square cube faces (see the module notes, "Six square faces").

    b and A come from :func:`ferraris_solution` on the face poses (:func:`six_faces`); ``params``
    are imu_tk's b, s and angles of A's triangular part. The covariances follow from the pose
    means' errors by ``_errors``: white noise, pose-to-pose error
    (from the residuals of the poses beyond the faces, projected off everything the full
    model's norms could explain, or assumed where they cannot tell it) and the faces'
    placement, which Ferraris' half-differences read as non-orthogonality (from the pair sums'
    components across gravity). ``residual_rms`` and ``dof`` (K − 6) are those of every
    pose's norm residual |A⁻¹ (m_k − b)| − g.

    Parameters
    ----------
    means
        (K, 3) m/s², pose means.
    g
        m/s².
    weights
        (K,) samples per pose (each face's heaviest pose is used), or None.
    noise
        The poses' white noise and clusters, or None (unknown, every pose alone).

    Returns
    -------
    PoseFit
        ``how`` :data:`SIX_FACES`, ``error_model`` set; ``determined`` False with the reason
        when the poses are not six faces, the faces are not square
        (:data:`SQUARE_TOLERANCE_DEG`), or no pose is left for the residual.
    """
    m = check_means(means)
    g = check_g(g)
    k = m.shape[0]
    index, why = six_faces(m, weights)
    if index is None:
        return replace(nan_fit("full", k, float("nan"), float("nan"), why), how=SIX_FACES)
    faces = m[index]
    tilt = face_tilt_deg(faces, g)
    if not tilt <= SQUARE_TOLERANCE_DEG:
        return replace(nan_fit("full", k, float("nan"), float("nan"),
                                f"opposite faces {tilt:.2f}° from opposite (at most "
                                f"{SQUARE_TOLERANCE_DEG:g}°)"),
                       how=SIX_FACES)
    b, a = ferraris_solution(faces, g)
    out = _outputs(m, index, g)
    r = out["residuals"]
    residual_rms = float(np.sqrt(np.mean(r * r)))
    condition = max(span_condition(m), condition_number(a))
    dof = k - 6
    if dof < 1:
        return replace(nan_fit("full", k, residual_rms, condition,
                                "7 poses needed for the six-face fit (the faces and one more), found 6"),
                       how=SIX_FACES)
    x = out["params"]
    projector = column_space_projector(residual_jacobian(x, m, np.zeros(k), g, "full"))
    covs, model = six_face_errors(out, _derivatives(m, index, g), projector,
                                  placement_structure(m, index, b, g),
                                  PoseNoise.independent(k) if noise is None else noise,
                                  g * float(np.radians(SQUARE_TOLERANCE_DEG)) / 2.0)
    v = np.linalg.solve(a, (m - b).T).T
    nan3 = np.full(3, np.nan)
    directions = v / np.linalg.norm(v, axis=1)[:, None]
    return PoseFit("full", b, a, nan3, float("nan"), x, covs["params"], directions, residual_rms, condition,
                   k, dof, True, "", how=SIX_FACES,
                   matrix_se=np.sqrt(np.maximum(np.diag(covs["matrix"]), 0.0)).reshape(3, 3),
                   error_model=model)
