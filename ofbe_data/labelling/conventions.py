"""Conversions between ofbe's calibration map and imu_tk's and imucal's, and the label columns.

ofbe is output-referred: a resting sensor reads f = A·a + b (a the specific force in m/s²,
b the zero-g offset in the sensor's output). The two tools most labs use are input-referred
for the map and output-referred for the offset, as their own code applies them:

imu_tk (``CalibratedTriad_::unbiasNormalize``)
    a = T·K·(f − B), with K = diag(s_x, s_y, s_z) and, in the body-frame case its
    accelerometer calibration fits, T = [[1, −mis_yz, mis_zy], [0, 1, −mis_zx], [0, 0, 1]].
    So A = (T·K)⁻¹ and B = b. (imu_tk's other form a = T·K·f − B' has B' = T·K·b, i.e.
    b = A·B'.) A general A is first split A = U·Q (RQ decomposition, U upper triangular
    with a positive diagonal, Q orthogonal): U is the sensor's own triad in imu_tk's frame,
    Q the rotation gravity cannot see (for a campaign fit, the mount relative to the
    reference); a multi-position fit's A is already triangular (Q = I).
imucal (``FerrarisCalibrationInfo._calibrate_acc``)
    a = R_a⁻¹·K_a⁻¹·(f − b_a), with K_a diagonal and R_a's rows unit vectors (the axes'
    sensitive directions). So A = K_a·R_a: K_a's diagonal is the row norms of A (ofbe's
    ``scale_*``), R_a = K_a⁻¹·A, and b_a = b (for data in m/s²).

All conversions are exact and invertible; tests run them both ways.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.linalg import rq

AXES = "xyz"
MATRIX_COLUMNS = tuple(f"a_{r}{c}" for r in AXES for c in AXES)
"""Label columns of the nine entries of A, row-major (``a_xy`` = A[0, 1])."""
ANGLE_NAMES = ("yz", "zy", "zx")
"""imu_tk's three non-orthogonality angles of the body-frame case, in parameter order."""
IMUTK_COLUMNS = (*(f"imutk_s_{a}" for a in AXES), *(f"imutk_mis_{n}" for n in ANGLE_NAMES))
"""Label columns of imu_tk's scales (dimensionless, input-referred) and angles (rad)."""
TEMPERATURE_COLUMNS = tuple(f"temp_slope_{a}" for a in AXES)
"""Label columns of the bias temperature slope, m/s² per °C."""


def imutk_matrix(angles: np.ndarray) -> np.ndarray:
    """imu_tk's body-frame T from (mis_yz, mis_zy, mis_zx), rad."""
    a_yz, a_zy, a_zx = np.asarray(angles, dtype=np.float64)
    return np.array([[1.0, -a_yz, a_zy], [0.0, 1.0, -a_zx], [0.0, 0.0, 1.0]])


def matrix_from_imutk(s: np.ndarray, angles: np.ndarray) -> np.ndarray:
    """ofbe's A = (T·K)⁻¹ from imu_tk's scales s (3,) and angles (3,) rad."""
    return np.linalg.inv(imutk_matrix(angles) * np.asarray(s, dtype=np.float64))


def triangular_part(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A = U·Q with U upper triangular (positive diagonal) and Q orthogonal; returns (U, Q)."""
    u, q = rq(np.asarray(matrix, dtype=np.float64))
    signs = np.where(np.diag(u) < 0, -1.0, 1.0)
    return u * signs, signs[:, None] * q


def imutk_from_matrix(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """imu_tk's (s (3,), angles (3,) rad) of A's triangular part (see :func:`triangular_part`)."""
    u, _ = triangular_part(matrix)
    m = np.linalg.inv(u)  # = T·K, upper triangular; T has a unit diagonal
    s = np.diag(m).copy()
    t = m / s
    return s, np.array([-t[0, 1], t[0, 2], -t[1, 2]])


def imucal_from_matrix(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """imucal's (K_a (3, 3) diagonal, R_a (3, 3) unit rows) with A = K_a·R_a."""
    a = np.asarray(matrix, dtype=np.float64)
    k = np.sqrt(np.sum(a * a, axis=1))
    return np.diag(k), a / k[:, None]


def matrix_from_imucal(k_a: np.ndarray, r_a: np.ndarray) -> np.ndarray:
    """ofbe's A = K_a·R_a."""
    return np.asarray(k_a, dtype=np.float64) @ np.asarray(r_a, dtype=np.float64)


def derived_se(func: Callable[[np.ndarray], np.ndarray], x: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """Standard errors of ``func(x)`` by the delta method (central differences).

    Parameters
    ----------
    func
        Maps the (P,) parameters to (Q,) derived values.
    x
        (P,) parameters.
    cov
        (P, P) their covariance.

    Returns
    -------
    np.ndarray
        (Q,) sqrt(diag(G·cov·Gᵀ)), G the (Q, P) Jacobian of ``func`` at ``x``.
    """
    x = np.asarray(x, dtype=np.float64)
    steps = 1e-7 * np.maximum(1.0, np.abs(x))
    cols = []
    for i, h in enumerate(steps):
        up, down = x.copy(), x.copy()
        up[i] += h
        down[i] -= h
        cols.append((np.asarray(func(up)) - np.asarray(func(down))) / (2.0 * h))
    g = np.stack(cols, axis=1)
    return np.sqrt(np.maximum(np.einsum("qp,pr,qr->q", g, cov, g), 0.0))


def empty_columns() -> dict[str, float | None]:
    """Every calibration-map column of a label row, missing (None: nothing fitted)."""
    out: dict[str, float | None] = {}
    for name in (*MATRIX_COLUMNS, *(f"scale_{a}" for a in AXES), *IMUTK_COLUMNS,
                 *(f"offset_{a}" for a in AXES), *TEMPERATURE_COLUMNS):
        out[name] = None
        out[name + "_se"] = None
    out["temp_ref_c"] = None
    return out


def map_columns(matrix: np.ndarray, matrix_se: np.ndarray) -> dict[str, float]:
    """The ``a_*`` columns of a fitted map A, with the given standard errors.

    Parameters
    ----------
    matrix
        (3, 3) A.
    matrix_se
        (3, 3) standard errors of A's entries: NaN for an entry the model fixes.

    Returns
    -------
    dict
        ``a_*``/``a_*_se``; the scale and imu_tk columns need the covariance and come from
        :func:`scale_columns` and :func:`imutk_columns`.
    """
    out = {}
    for i, r in enumerate(AXES):
        for j, c in enumerate(AXES):
            out[f"a_{r}{c}"] = float(matrix[i, j])
            out[f"a_{r}{c}_se"] = float(matrix_se[i, j])
    return out


def scale_columns(to_matrix: Callable[[np.ndarray], np.ndarray], x: np.ndarray,
                  cov: np.ndarray) -> dict[str, float]:
    """``scale_*`` (the row norms of A, imucal's K_a) with their standard errors.

    Parameters
    ----------
    to_matrix
        Maps the (P,) fitted parameters to A (3, 3).
    x, cov
        The parameters and their covariance.
    """
    def scales(p: np.ndarray) -> np.ndarray:
        return imucal_from_matrix(to_matrix(p))[0].diagonal().copy()

    k, k_se = scales(x), derived_se(scales, x, cov)
    out: dict[str, float] = {}
    for i, a in enumerate(AXES):
        out[f"scale_{a}"], out[f"scale_{a}_se"] = float(k[i]), float(k_se[i])
    return out


def imutk_columns(to_matrix: Callable[[np.ndarray], np.ndarray], x: np.ndarray,
                  cov: np.ndarray) -> dict[str, float]:
    """imu_tk's ``imutk_s_*`` and ``imutk_mis_*`` of A's triangular part, with standard errors,
    for a map whose parameters are not imu_tk's own (the campaign fit's nine entries).

    Parameters
    ----------
    to_matrix
        Maps the (P,) fitted parameters to A (3, 3).
    x, cov
        The parameters and their covariance.
    """
    def imutk(p: np.ndarray) -> np.ndarray:
        s, angles = imutk_from_matrix(to_matrix(p))
        return np.concatenate([s, angles])

    t, t_se = imutk(x), derived_se(imutk, x, cov)
    out: dict[str, float] = {}
    for i, name in enumerate(IMUTK_COLUMNS):
        out[name], out[f"{name}_se"] = float(t[i]), float(t_se[i])
    return out
