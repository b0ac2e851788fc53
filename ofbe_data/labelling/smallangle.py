"""How far a levelled calibration goes wrong when the sensor is tilted (paper §4).

A *levelled calibration* assumes the sensor rests level, z up, and takes the bias as
``mean − g·e_z``. If the sensor is actually tilted by roll φ (about x) and pitch θ (about y),
its mean reads ``g·u(φ, θ) + b`` with

    u(φ, θ) = [−sin θ, sin φ·cos θ, cos φ·cos θ]

(the convention of :func:`ofbe_data.labelling.orientation.roll_pitch`), so gravity leaks into the
bias estimate by ``leak = g·(u − e_z)``. Expressed in units of g the leak depends on the
geometry only:

- ``"max-axis"`` (default, the paper's measure): the largest per-axis error,
  ``max_k |u_k − e_{z,k}|``. A single-axis tilt α gives ``sin α`` (the tangential axis
  dominates the ``1 − cos α`` of the vertical one), so a limit L is reached at
  ``asin(L)``: 2.866° for 50 mg. With equal roll and pitch α the x leak is still
  ``sin α``, so the combined per-axis threshold is the same angle.
- ``"norm"``: the length of the leak vector, ``‖u − e_z‖ = 2·sin(γ/2)`` with γ the total
  tilt (``cos γ = cos φ·cos θ``). It is never smaller than the max-axis measure; for a
  single-axis tilt it reaches L at ``2·asin(L/2)`` (2.865° for 50 mg), for equal roll and
  pitch at a per-axis angle about 1/√2 of that (2.03°).

Everything here is pure numpy/scipy; the figures are drawn by
:mod:`ofbe_data.reports.small_angle`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

Measure = Literal["max-axis", "norm"]
"""Error measure of a leak vector (see the module docstring)."""
Direction = Literal["pitch", "roll", "combined"]
"""Tilt direction for :func:`threshold_angle`: pitch only, roll only, or equal roll and pitch."""

MEASURES: tuple[str, ...] = ("max-axis", "norm")
DIRECTIONS: tuple[str, ...] = ("pitch", "roll", "combined")

PAPER_LIMIT_G = 0.05
"""The paper's tolerance on the bias error of a levelled calibration: 50 mg, in g."""

_VERTICAL = np.array([0.0, 0.0, 1.0])
_MAX_TILT_DEG = 90.0  # thresholds are searched in [0°, 90°]


def gravity_direction(roll_deg: float | np.ndarray, pitch_deg: float | np.ndarray) -> np.ndarray:
    """Unit specific-force direction of a sensor tilted by roll and pitch.

    ``u = [−sin θ, sin φ·cos θ, cos φ·cos θ]``: the exact inverse of
    :func:`ofbe_data.labelling.orientation.roll_pitch` for pitch in (−90°, 90°).

    Parameters
    ----------
    roll_deg
        Roll φ about x, degrees; any shape broadcastable with ``pitch_deg``.
    pitch_deg
        Pitch θ about y, degrees.

    Returns
    -------
    ndarray, shape (..., 3)
        Unit vectors in the sensor frame; the leading shape is the broadcast shape of the
        two inputs (``(3,)`` for two scalars).
    """
    phi = np.radians(np.asarray(roll_deg, dtype=np.float64))
    theta = np.radians(np.asarray(pitch_deg, dtype=np.float64))
    phi, theta = np.broadcast_arrays(phi, theta)
    cos_t = np.cos(theta)
    return np.stack([-np.sin(theta), np.sin(phi) * cos_t, np.cos(phi) * cos_t], axis=-1)


def _check_measure(measure: str) -> None:
    if measure not in MEASURES:
        raise ValueError(f"measure: expected one of {', '.join(MEASURES)}, found {measure!r}")


def leak_g(roll_deg: float | np.ndarray, pitch_deg: float | np.ndarray,
           measure: Measure = "max-axis") -> np.ndarray:
    """Gravity leak of a levelled calibration at a tilt, in units of g.

    Parameters
    ----------
    roll_deg, pitch_deg
        Tilt, degrees; broadcastable shapes.
    measure
        ``"max-axis"``: ``max_k |u_k − e_{z,k}|``; ``"norm"``: ``‖u − e_z‖``.

    Returns
    -------
    ndarray
        The broadcast shape of the inputs (0-d for two scalars), in g (dimensionless).
    """
    _check_measure(measure)
    leak = gravity_direction(roll_deg, pitch_deg) - _VERTICAL
    if measure == "max-axis":
        return np.max(np.abs(leak), axis=-1)
    return np.linalg.norm(leak, axis=-1)


def leak_surface(roll_deg: np.ndarray, pitch_deg: np.ndarray,
                 measure: Measure = "max-axis") -> np.ndarray:
    """Gravity leak over a roll × pitch grid, in units of g.

    Parameters
    ----------
    roll_deg
        (R,) roll values, degrees.
    pitch_deg
        (P,) pitch values, degrees.
    measure
        ``"max-axis"`` (the largest per-axis leak) or ``"norm"`` (the leak vector's length);
        see :func:`leak_g`.

    Returns
    -------
    ndarray, shape (P, R)
        ``surface[i, j]`` is the leak at pitch ``pitch_deg[i]`` and roll ``roll_deg[j]``
        (the layout :func:`matplotlib.pyplot.contourf` expects for x = roll, y = pitch).
    """
    roll = np.asarray(roll_deg, dtype=np.float64)
    pitch = np.asarray(pitch_deg, dtype=np.float64)
    if roll.ndim != 1 or pitch.ndim != 1:
        raise ValueError(f"roll_deg, pitch_deg: expected 1-D arrays, found shapes {roll.shape}, "
                         f"{pitch.shape}")
    return leak_g(roll[np.newaxis, :], pitch[:, np.newaxis], measure)


def _tilt(direction: str, angle_deg: float) -> tuple[float, float]:
    """(roll, pitch) of a tilt by ``angle_deg`` in ``direction``."""
    if direction == "pitch":
        return 0.0, angle_deg
    if direction == "roll":
        return angle_deg, 0.0
    return angle_deg, angle_deg


def threshold_angle(limit_g: float = PAPER_LIMIT_G, direction: Direction = "pitch",
                    measure: Measure = "max-axis") -> float:
    """Smallest tilt at which the gravity leak reaches a limit.

    Found by :func:`scipy.optimize.brentq` on ``leak_g(tilt) − limit_g`` over [0°, 90°], on
    which every leak measure grows monotonically with the tilt.

    Parameters
    ----------
    limit_g
        Tolerated leak, in g (0.05 = 50 mg).
    direction
        ``"pitch"`` (roll 0), ``"roll"`` (pitch 0) or ``"combined"`` (equal roll and pitch;
        the returned angle is the per-axis angle, not the total tilt).
    measure
        Leak measure, see :func:`leak_g`.

    Returns
    -------
    float
        The threshold angle, degrees. For ``"max-axis"`` and a single-axis direction it is
        ``degrees(asin(limit_g))`` (2.8660° for 50 mg) to brentq's tolerance (~1e-12).

    Raises
    ------
    ValueError
        For an unknown direction or measure, or a limit that is not positive or is not
        reached within 90° of tilt.
    """
    _check_measure(measure)
    if direction not in DIRECTIONS:
        raise ValueError(f"direction: expected one of {', '.join(DIRECTIONS)}, found {direction!r}")
    if not (math.isfinite(limit_g) and limit_g > 0.0):
        raise ValueError(f"limit_g: expected a positive finite number, found {limit_g!r}")

    def excess(angle_deg: float) -> float:
        roll, pitch = _tilt(direction, angle_deg)
        return float(leak_g(roll, pitch, measure)) - limit_g

    from scipy.optimize import brentq  # here: the module's leak measures (MEASURES) stay light to import

    top = excess(_MAX_TILT_DEG)
    if top < 0.0:
        raise ValueError(f"limit_g: expected a leak reached within {_MAX_TILT_DEG:g}° of {direction} "
                         f"tilt ({measure} leak there is {top + limit_g:.4f} g), found {limit_g!r}")
    return float(brentq(excess, 0.0, _MAX_TILT_DEG, xtol=1e-13, rtol=4 * np.finfo(float).eps))


def symmetric_grid(range_deg: float, step_deg: float) -> np.ndarray:
    """A grid from ``−range_deg`` to ``+range_deg`` with spacing close to ``step_deg``.

    Parameters
    ----------
    range_deg
        Half-width, degrees (> 0).
    step_deg
        Wanted spacing, degrees (> 0, ≤ 2·range). The point count is
        ``round(2·range/step) + 1`` so that the grid ends exactly on ±range and contains 0
        whenever the count is odd; the actual spacing differs from ``step_deg`` only when
        2·range is not a multiple of it.

    Returns
    -------
    ndarray, shape (n,)
        Degrees, symmetric about 0 (``grid == −grid[::-1]`` exactly).
    """
    if not (math.isfinite(range_deg) and range_deg > 0.0):
        raise ValueError(f"range_deg: expected a positive number, found {range_deg!r}")
    if not (math.isfinite(step_deg) and 0.0 < step_deg <= 2.0 * range_deg):
        raise ValueError(f"step_deg: expected a number in (0, {2.0 * range_deg:g}], found {step_deg!r}")
    n = int(round(2.0 * range_deg / step_deg)) + 1
    half = np.linspace(-range_deg, range_deg, n)
    return 0.5 * (half - half[::-1])  # exact antisymmetry (linspace alone is not)


@dataclass(frozen=True)
class SmallAngleResult:
    """The small-angle analysis: leak surface and thresholds.

    Attributes
    ----------
    roll_deg
        (R,) roll grid, degrees.
    pitch_deg
        (P,) pitch grid, degrees.
    surface_g
        (P, R) leak in g at each (pitch, roll), see :func:`leak_surface`.
    limit_g
        Tolerated leak, g.
    measure
        Leak measure used for the surface and the thresholds.
    threshold_deg
        Threshold angle per direction (``"pitch"``, ``"roll"``, ``"combined"``), degrees;
        ``"combined"`` is the per-axis angle of an equal roll and pitch tilt.
    """

    roll_deg: np.ndarray
    pitch_deg: np.ndarray
    surface_g: np.ndarray
    limit_g: float
    measure: Measure
    threshold_deg: dict[str, float]

    @property
    def asin_limit_deg(self) -> float:
        """The closed form of the single-axis max-axis threshold, ``degrees(asin(limit_g))``."""
        return math.degrees(math.asin(self.limit_g)) if self.limit_g <= 1.0 else math.nan


def analyse(range_deg: float = 10.0, step_deg: float = 0.05, limit_g: float = PAPER_LIMIT_G,
            measure: Measure = "max-axis") -> SmallAngleResult:
    """Leak surface over a symmetric roll × pitch grid and the thresholds of every direction.

    Parameters
    ----------
    range_deg
        Grid half-width, degrees (the grid spans −range…+range on both axes).
    step_deg
        Grid spacing, degrees (see :func:`symmetric_grid`).
    limit_g
        Tolerated leak, g.
    measure
        Leak measure, see :func:`leak_g`.

    Returns
    -------
    SmallAngleResult
    """
    grid = symmetric_grid(range_deg, step_deg)
    thresholds = {d: threshold_angle(limit_g, d, measure) for d in DIRECTIONS}
    return SmallAngleResult(roll_deg=grid, pitch_deg=grid.copy(),
                            surface_g=leak_surface(grid, grid, measure), limit_g=float(limit_g),
                            measure=measure, threshold_deg=thresholds)
