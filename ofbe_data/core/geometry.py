"""3-vector geometry shared by the simulator and the labeller: products without BLAS, unit
vectors, roll and pitch.

Products of 3-vectors and 3×3 matrices without BLAS, for values that are written to files.

``A @ B`` goes through BLAS, whose kernel is chosen by the processor (and by
``OPENBLAS_CORETYPE``): one kernel fuses multiply and add, another does not, so the last bit
of a result depends on the machine. When such a result is written to a file (a count, a
truth value, a label), the file's bytes depend on the machine too. The functions here spell
every product out as separate, correctly rounded multiplications and additions in a fixed
order, so the result is the same on every machine. Inner dimension is 3 everywhere; the cost
is a few elementwise array operations.
"""

from __future__ import annotations

import numpy as np


def mul3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` for an inner dimension of 3, summed in the order k = 0, 1, 2.

    Parameters
    ----------
    a
        (..., 3) vector(s) or (..., n, 3) matrix (matrices).
    b
        (3,) vector or (3, m) matrix.

    Returns
    -------
    ndarray
        ``a @ b``: shape (...) for a vector ``b``, (..., m) or (..., n, m) for a matrix.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.shape[-1] != 3 or b.shape[0] != 3 or b.ndim > 2:
        raise ValueError(f"mul3 needs (..., 3) @ (3,) or (3, m), got {a.shape} @ {b.shape}")
    if b.ndim == 1:
        out = a[..., 0] * b[0] + a[..., 1] * b[1]
        out += a[..., 2] * b[2]
        return out
    out = a[..., 0, None] * b[0] + a[..., 1, None] * b[1]
    out += a[..., 2, None] * b[2]
    return out


def dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product ``Σ_k a[..., k]·b[..., k]`` of (..., 3) arrays (fixed order)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    out = a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]
    out += a[..., 2] * b[..., 2]
    return out


def norm3(v: np.ndarray) -> np.ndarray:
    """Euclidean norm of (..., 3) vectors, same on every machine (``np.linalg.norm`` of a
    1-D array is a BLAS dot product)."""
    return np.sqrt(dot3(v, v))


VERTICAL = np.array([0.0, 0.0, 1.0])
"""Unit specific-force direction of a level, z-up sensor."""


def unit(v: np.ndarray) -> np.ndarray:
    """``v / ‖v‖`` for a (3,) vector; raises ``ValueError`` for a zero vector."""
    v = np.asarray(v, dtype=np.float64)
    n = float(norm3(v))
    if not n > 0.0:
        raise ValueError(f"cannot normalise a zero-length vector {v.tolist()}")
    return v / n


def roll_pitch(u: np.ndarray) -> tuple[float, float]:
    """Roll and pitch (degrees) of a specific-force direction.

    The inverse of ``u = [−sin θ, sin φ·cos θ, cos φ·cos θ]`` (roll φ about x, pitch θ
    about y, z up at zero).

    Parameters
    ----------
    u
        (3,) specific-force direction (any length).

    Returns
    -------
    roll_deg, pitch_deg
        Roll in (−180, 180], pitch in [−90, 90].
    """
    u = unit(u)
    roll = np.degrees(np.arctan2(u[1], u[2]))
    pitch = np.degrees(np.arcsin(np.clip(-u[0], -1.0, 1.0)))
    return float(roll), float(pitch)
