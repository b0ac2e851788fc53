"""Small pure functions for the sensor physics of the simulator.

Frames: the plate (or reference) frame and each sensor frame are right-handed. A resting
ideal accelerometer reads the specific force, which points *up* with magnitude g_local.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation

from ofbe_data.core.geometry import dot3, mul3, norm3

MG = 9.80665e-3
"""One milli-g in m/s² (unit conversion with standard gravity g0)."""


def plate_direction(roll_deg: float, pitch_deg: float) -> np.ndarray:
    """Unit specific-force direction in the plate frame for a plate roll and pitch.

    The plate attitude is R = Ry(pitch)·Rx(roll) (yaw is irrelevant at rest), and the
    direction is Rᵀ·e_z, so roll = pitch = 0 gives [0, 0, 1].

    Parameters
    ----------
    roll_deg, pitch_deg
        Plate roll and pitch, degrees.

    Returns
    -------
    ndarray, shape (3,)
        [−sin θ, sin φ cos θ, cos φ cos θ].
    """
    phi, theta = np.radians(roll_deg), np.radians(pitch_deg)
    return np.array([-np.sin(theta), np.sin(phi) * np.cos(theta), np.cos(phi) * np.cos(theta)])


def axis_vector(axis: str) -> np.ndarray:
    """Unit vector of a signed axis name such as ``+z`` or ``-x``."""
    vec = np.zeros(3)
    vec["xyz".index(axis[1])] = 1.0 if axis[0] == "+" else -1.0
    return vec


def small_rotation(rotvec_rad: np.ndarray) -> np.ndarray:
    """(3, 3) rotation matrix of a rotation vector, radians."""
    return Rotation.from_rotvec(np.asarray(rotvec_rad, dtype=float)).as_matrix()


def level_nominal(up_axis: str) -> np.ndarray:
    """Rotation taking the level plate's +z (up) to the device's ``up_axis`` (e.g. ``-x``)."""
    target = axis_vector(up_axis)
    z = np.array([0.0, 0.0, 1.0])
    if np.allclose(target, z):
        return np.eye(3)
    if np.allclose(target, -z):
        return np.diag([1.0, -1.0, -1.0])
    axis = np.cross(z, target)
    return small_rotation(axis / norm3(axis) * np.pi / 2)


def sensor_matrix(scale: np.ndarray, nonorth_rad: np.ndarray) -> np.ndarray:
    """The sensor's own 3×3 map A = (I + diag(scale))·T.

    T is the non-orthogonality of the sensing axes in the convention of imu_tk (the x
    axis defines the frame, three small angles): T = [[1, −α_yz, α_zy], [0, 1, −α_zx],
    [0, 0, 1]].

    Parameters
    ----------
    scale
        (3,) scale-factor errors (dimensionless).
    nonorth_rad
        (3,) angles α_yz, α_zy, α_zx, radians.

    Returns
    -------
    ndarray, shape (3, 3)
    """
    a_yz, a_zy, a_zx = nonorth_rad
    t = np.array([[1.0, -a_yz, a_zy], [0.0, 1.0, -a_zx], [0.0, 0.0, 1.0]])
    return mul3(np.eye(3) + np.diag(scale), t)


def gauss_markov(n: int, dt: float, sigma: float, tau: float, rng: np.random.Generator,
                 ) -> np.ndarray:
    """First-order Gauss–Markov process, started in its stationary distribution.

    Parameters
    ----------
    n
        Number of samples.
    dt
        Sample period, s.
    sigma
        Stationary standard deviation (output units).
    tau
        Correlation time, s.
    rng
        Random generator.

    Returns
    -------
    ndarray, shape (n,)
    """
    if n == 0 or sigma == 0.0:
        return np.zeros(n)
    phi = float(np.exp(-dt / tau))
    w = rng.standard_normal(n) * sigma * np.sqrt(1.0 - phi * phi)
    w[0] = rng.standard_normal() * sigma
    return lfilter([1.0], [1.0, -phi], w)


def tap_signal(t: np.ndarray, t_tap: float, amplitude: float, frequency_hz: float,
               decay_s: float, direction: np.ndarray) -> np.ndarray:
    """Plate vibration after a tap: a damped sinusoid along one direction.

    Parameters
    ----------
    t
        (N,) times, s.
    t_tap
        Tap time, s.
    amplitude
        Peak amplitude (output units, e.g. m/s²).
    frequency_hz, decay_s
        Ring frequency and exponential decay time.
    direction
        (3,) unit direction in the frame of the output.

    Returns
    -------
    ndarray, shape (N, 3)
        Zero before the tap and after 12 decay times.
    """
    out = np.zeros((t.shape[0], 3))
    s = t - t_tap
    live = (s >= 0.0) & (s < 12.0 * decay_s)
    if live.any():
        sl = s[live]
        env = amplitude * np.exp(-sl / decay_s) * np.sin(2.0 * np.pi * frequency_hz * sl + 0.5)
        out[live] = env[:, None] * np.asarray(direction)[None, :]
    return out


def random_unit_vectors(n: int, rng: np.random.Generator) -> np.ndarray:
    """(n, 3) directions uniform on the sphere."""
    v = rng.standard_normal((n, 3))
    return v / norm3(v)[:, None]


def spread_directions(k: int, rng: np.random.Generator, candidates: int = 16) -> np.ndarray:
    """k random directions spread over the whole sphere, in random order.

    Mitchell's best candidate: each direction after the first is, of ``candidates`` uniform
    draws, the one farthest from those already chosen (the smallest largest cosine). The set
    spans the sphere like a jig's faces do, yet no two sets are alike. Only products, sums and
    square roots (no trigonometry), so the directions are the same on every machine.

    Parameters
    ----------
    k
        Number of directions (≥ 1).
    rng
        Random generator.
    candidates
        Uniform draws per direction after the first.

    Returns
    -------
    ndarray, shape (k, 3)
        Unit vectors.
    """
    chosen = random_unit_vectors(1, rng)
    for _ in range(1, k):
        cand = random_unit_vectors(candidates, rng)
        nearest = np.max(mul3(cand, chosen.T), axis=1)
        chosen = np.vstack([chosen, cand[int(np.argmin(nearest))]])
    return chosen[rng.permutation(k)]


def rotate_about(axes: np.ndarray, angles: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Rotate vectors about unit axes by angles (Rodrigues), element by element.

    Parameters
    ----------
    axes
        (N, 3) or (3,) unit rotation axes.
    angles
        (N,) angles, radians.
    vectors
        (N, 3) or (3,) vectors.

    Returns
    -------
    ndarray, shape (N, 3)
    """
    n = np.asarray(angles).shape[0]
    axes = np.broadcast_to(np.asarray(axes, dtype=np.float64), (n, 3))
    vectors = np.broadcast_to(np.asarray(vectors, dtype=np.float64), (n, 3))
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    dot = dot3(axes, vectors)[:, None]
    return vectors * c + np.cross(axes, vectors) * s + axes * (dot * (1.0 - c))


def minimum_jerk(s: np.ndarray) -> np.ndarray:
    """Minimum-jerk profile 10s³ − 15s⁴ + 6s⁵ of s in [0, 1]: 0 → 1 with zero velocity and
    acceleration at both ends (how a hand moves an object from rest to rest)."""
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


def jolt_signal(tau: np.ndarray, jolt: dict[str, Any], end: float) -> np.ndarray:
    """(N, 3) m/s², a hand's jolt starting at tau = 0: a half-sine pulse and a ringing.

    Parameters
    ----------
    tau
        (N,) s, time since the jolt (zero output before it).
    jolt
        ``length`` (s), ``pulse`` (m/s²), ``pulse_dir`` (3,), ``ring`` (m/s²), ``ring_dir``
        (3,), ``ring_hz``, ``decay_s``.
    end
        s (same origin as ``tau``): the jolt is faded out by then (a cosine taper over
        0.05 s), so that the device comes to rest smoothly.

    Returns
    -------
    ndarray, shape (N, 3)
    """
    length = jolt["length"]
    on = (tau >= 0.0) & (tau <= length)
    pulse = np.where(on, jolt["pulse"] * np.sin(np.pi * np.clip(tau, 0.0, length) / length), 0.0)
    after = np.maximum(tau, 0.0)
    ring = np.where(tau >= 0.0, jolt["ring"] * np.exp(-after / jolt["decay_s"])
                    * np.sin(2.0 * np.pi * jolt["ring_hz"] * after), 0.0)
    taper = 0.5 - 0.5 * np.cos(np.pi * np.clip((end - tau) / 0.05, 0.0, 1.0))
    return (pulse[:, None] * np.asarray(jolt["pulse_dir"]) + ring[:, None] * np.asarray(jolt["ring_dir"])) \
        * taper[:, None]
