"""Local gravity magnitude from the site (WGS-84 normal gravity with free-air correction)."""

from __future__ import annotations

import math

#: Standard gravity, m/s². A *unit* (converts g to m/s²), never local physics.
G0 = 9.80665

# WGS-84 normal gravity (Somigliana's closed formula), NIMA TR8350.2 table 3.4.
_GAMMA_E = 9.7803253359  # normal gravity at the equator, m/s²
_K = 0.00193185265241  # Somigliana constant k = (b·γp)/(a·γe) − 1
_E2 = 0.00669437999013  # first eccentricity squared

#: Free-air gradient, s⁻² (m/s² per metre of height), raw-formats.md.
FREE_AIR_GRADIENT = -3.086e-6


def normal_gravity(latitude_deg: float) -> float:
    """WGS-84 normal gravity on the ellipsoid (Somigliana), m/s².

    Parameters
    ----------
    latitude_deg
        Geodetic latitude, degrees, in [-90, 90].

    Returns
    -------
    float
        Normal gravity magnitude at height 0, m/s².
    """
    s2 = math.sin(math.radians(latitude_deg)) ** 2
    return _GAMMA_E * (1.0 + _K * s2) / math.sqrt(1.0 - _E2 * s2)


def local_gravity(latitude_deg: float, height_m: float = 0.0) -> float:
    """Local gravity magnitude: Somigliana normal gravity plus the free-air correction.

    Parameters
    ----------
    latitude_deg
        Geodetic latitude, degrees.
    height_m
        Height above the ellipsoid, metres.

    Returns
    -------
    float
        g_local, m/s².
    """
    return normal_gravity(latitude_deg) + FREE_AIR_GRADIENT * height_m
