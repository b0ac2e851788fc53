"""Orientation maths: Rodrigues' rotation, gravity directions, roll and pitch.

Conventions (raw-formats.md): a resting accelerometer reads the specific force, which
points up; ``u`` is its unit direction in a given frame. The vertical is ``e_z = [0, 0, 1]``.
"""

from __future__ import annotations

import numpy as np

from ofbe_data.core.geometry import VERTICAL, dot3, mul3, norm3, roll_pitch, unit

__all__ = ["VERTICAL", "apparent_bias", "nearest_axis", "rodrigues", "rodrigues_label",
           "roll_pitch", "rotation_to_vertical", "skew", "unit"]

def skew(k: np.ndarray) -> np.ndarray:
    """Cross-product matrix ``[k]×`` of a (3,) vector, so that ``skew(k) @ v == k × v``."""
    return np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])


def rodrigues(axis: np.ndarray, angle_rad: float) -> np.ndarray:
    """Rotation matrix by Rodrigues' formula.

    ``R = I + sin θ·K + (1 − cos θ)·K²`` with ``K = [k]×`` for the unit axis ``k``.

    Parameters
    ----------
    axis
        (3,) rotation axis (normalised here).
    angle_rad
        Right-handed rotation angle θ, rad.

    Returns
    -------
    ndarray, shape (3, 3)
    """
    K = skew(unit(axis))
    return np.eye(3) + np.sin(angle_rad) * K + (1.0 - np.cos(angle_rad)) * mul3(K, K)


def rotation_to_vertical(u: np.ndarray) -> np.ndarray:
    """The smallest rotation R with ``R @ û = e_z`` (Rodrigues' formula).

    The axis is ``k = û × e_z / ‖û × e_z‖`` and the angle ``θ = arccos(û · e_z)``. When û is
    (anti)parallel to e_z the axis is undefined: R = I for û = e_z, and a half turn about
    x for û = −e_z.

    Parameters
    ----------
    u
        (3,) specific-force direction (any length), in the frame R rotates from.

    Returns
    -------
    ndarray, shape (3, 3)
    """
    u = unit(u)
    cross = np.cross(u, VERTICAL)
    s = float(norm3(cross))
    c = float(np.clip(dot3(u, VERTICAL), -1.0, 1.0))
    if s < 1e-12:
        return np.eye(3) if c > 0 else rodrigues(np.array([1.0, 0.0, 0.0]), np.pi)
    return rodrigues(cross / s, float(np.arctan2(s, c)))


def nearest_axis(m: np.ndarray) -> np.ndarray:
    """Signed sensor axis closest to a mean reading: ``±e_k`` with k = argmax |m_k|.

    Parameters
    ----------
    m
        (3,) mean specific force, any unit.

    Returns
    -------
    ndarray, shape (3,)
        A unit axis vector with the sign of ``m`` along it.
    """
    m = np.asarray(m, dtype=np.float64)
    k = int(np.argmax(np.abs(m)))
    out = np.zeros(3)
    out[k] = 1.0 if m[k] >= 0 else -1.0
    return out


def apparent_bias(mean: np.ndarray, u: np.ndarray, g: float) -> np.ndarray:
    """The apparent bias ``b_app = mean − g·u`` (the paper's label).

    Parameters
    ----------
    mean
        (3,) mean specific force over the stationary segment, m/s², sensor frame.
    u
        (3,) unit specific-force direction in the sensor frame.
    g
        Local gravity magnitude, m/s².

    Returns
    -------
    ndarray, shape (3,)
        m/s², sensor frame.
    """
    return np.asarray(mean, dtype=np.float64) - g * np.asarray(u, dtype=np.float64)


def rodrigues_label(dut_mean: np.ndarray, ref_mean: np.ndarray, reference_to_sensor: np.ndarray,
                    g: float) -> tuple[np.ndarray, np.ndarray]:
    """The paper's reference-aided label, step by step.

    The reference's mean specific force gives the gravity direction ``û_ref``; Rodrigues'
    rotation ``R`` takes it to the vertical. Through the nominal mount ``N``
    (``reference_to_sensor``) the DUT mean is brought into that levelled frame,
    ``a = R·Nᵀ·m_dut``; the label is ``a − g·e_z`` rotated back into the sensor frame,
    ``N·Rᵀ·(a − g·e_z)``. This equals ``m_dut − g·N·û_ref`` (tested).

    Parameters
    ----------
    dut_mean
        (3,) DUT mean over the stationary segment, m/s², sensor frame.
    ref_mean
        (3,) reference mean over the same segment, m/s², reference frame.
    reference_to_sensor
        (3, 3) nominal rotation from the reference frame to the DUT sensor frame.
    g
        Local gravity magnitude, m/s².

    Returns
    -------
    bias
        (3,) apparent bias, m/s², sensor frame.
    u
        (3,) the gravity direction used, unit, sensor frame (``N·û_ref``).
    """
    N = np.asarray(reference_to_sensor, dtype=np.float64)
    R = rotation_to_vertical(ref_mean)
    levelled = mul3(R, mul3(N.T, np.asarray(dut_mean, dtype=np.float64)))
    bias = mul3(N, mul3(R.T, levelled - g * VERTICAL))
    return bias, mul3(N, unit(ref_mean))
