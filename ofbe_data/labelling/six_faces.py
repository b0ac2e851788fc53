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
from ofbe_data.labelling.multiposition import (
    PoseFit,
    _check_g,
    _check_means,
    _nan_fit,
    condition_number,
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
    m = _check_means(means)
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


def _six_face_params(faces: np.ndarray, g: float) -> np.ndarray:
    b, a = ferraris_solution(faces, g)
    s, angles = imutk_from_matrix(a)
    return np.concatenate([b, s, angles])


def fit_six_faces(means: np.ndarray, g: float, weights: np.ndarray | None = None) -> PoseFit:
    """The ``full`` model from six square cube faces (see the module notes, "Six square faces").

    b and A come from :func:`ferraris_solution` on the face poses (:func:`six_faces`); ``params``
    are imu_tk's b, s and angles of A's triangular part. Every pose's norm residual
    |A⁻¹ (m_k − b)| − g gives σ̂ with K − 6 degrees of freedom (the six faces fix the twelve
    unknowns; their own norm residuals are second order), and the covariances follow from
    the face means' (σ̂² each component): cov(θ) = σ̂²·J·Jᵀ with J = ∂θ/∂(face means),
    var(A_ij) = σ̂²/(2g²).

    Returns
    -------
    PoseFit
        ``how`` :data:`SIX_FACES`; ``determined`` False with the reason when the poses are not
        six faces, the faces are not square (:data:`SQUARE_TOLERANCE_DEG`), or no pose is left
        for the residual.
    """
    m = _check_means(means)
    g = _check_g(g)
    k = m.shape[0]
    index, why = six_faces(m, weights)
    if index is None:
        return replace(_nan_fit("full", k, float("nan"), float("nan"), why), how=SIX_FACES)
    faces = m[index]
    tilt = face_tilt_deg(faces, g)
    if not tilt <= SQUARE_TOLERANCE_DEG:
        return replace(_nan_fit("full", k, float("nan"), float("nan"),
                                f"opposite faces {tilt:.2f}° from opposite (at most "
                                f"{SQUARE_TOLERANCE_DEG:g}°)"),
                       how=SIX_FACES)
    b, a = ferraris_solution(faces, g)
    v = np.linalg.solve(a, (m - b).T).T
    norms = np.sqrt(np.sum(v * v, axis=1))
    r = norms - g
    residual_rms = float(np.sqrt(np.mean(r * r)))
    condition = max(span_condition(m), condition_number(a))
    dof = k - 6
    if dof < 1:
        return replace(_nan_fit("full", k, residual_rms, condition,
                                "7 poses needed for the six-face fit (the faces and one more), found 6"),
                       how=SIX_FACES)
    sigma2 = float(np.sum(r * r)) / dof
    x = _six_face_params(faces, g)
    step = 1e-6 * g
    jac = np.empty((x.size, faces.size))
    for j in range(faces.size):
        hi, lo = faces.copy(), faces.copy()
        hi.flat[j] += step
        lo.flat[j] -= step
        jac[:, j] = (_six_face_params(hi, g) - _six_face_params(lo, g)) / (2.0 * step)
    nan3 = np.full(3, np.nan)
    return PoseFit("full", b, a, nan3, float("nan"), x, sigma2 * jac @ jac.T, v / norms[:, None],
                   residual_rms, condition, k, dof, True, "", how=SIX_FACES,
                   matrix_se=np.full((3, 3), np.sqrt(sigma2 / 2.0) / g))
