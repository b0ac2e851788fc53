"""Small pure functions for the sensor physics of the simulator.

Frames: the plate (or reference) frame and each sensor frame are right-handed. A resting
ideal accelerometer reads the specific force, which points *up* with magnitude g_local.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter
from scipy.spatial.transform import Rotation

from ofbe_data.core.geometry import mul3, norm3

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
