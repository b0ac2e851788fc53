"""The precision at which computed floats are written, so that files have the same bytes on
every machine.

A value that went through LAPACK or BLAS (a least-squares fit, a condition number) can
differ in its last bits between processors and BLAS kernels. Written at full precision,
those bits make a label file's bytes depend on the machine, and DVC then sees a change
that is only noise. The values are therefore rounded when written, to a precision far
below anything physical (docs/formats.md lists it):

- accelerations (m/s²): 1e-9, that is 0.1 µg, against label noise of a few µg;
- unit vectors, scale factors and other dimensionless values: 1e-10;
- angles: 1e-7 degree;
- times: 1e-9 s; clock drift 1e-6 ppm; sample rates 1e-9 Hz;
- condition numbers: 9 significant digits.

Values computed without BLAS (the simulator's products, see :mod:`ofbe_data.core.geometry`) are
the same on every machine already; rounding them too keeps one rule for every file.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

ACCEL_DECIMALS = 9
"""Decimal places of accelerations in m/s² (1e-9 m/s² ≈ 0.1 µg)."""
UNIT_DECIMALS = 10
"""Decimal places of dimensionless values (unit vectors, scale factors)."""
ANGLE_DECIMALS = 7
"""Decimal places of angles in degrees."""
TIME_DECIMALS = 9
"""Decimal places of times in seconds (1 ns)."""
PPM_DECIMALS = 6
"""Decimal places of clock drift in ppm."""
SIGNIFICANT_DIGITS = 9
"""Significant digits of values without a natural scale (condition numbers)."""


def round_decimals(x: float | None, decimals: int) -> float | None:
    """``x`` rounded to ``decimals`` places; None, NaN and ±inf pass unchanged."""
    if x is None:
        return None
    x = float(x)
    if not math.isfinite(x):
        return x
    return round(x, decimals) + 0.0  # + 0.0: no negative zero


def round_significant(x: float | None, digits: int = SIGNIFICANT_DIGITS) -> float | None:
    """``x`` rounded to ``digits`` significant digits; None, NaN, ±inf and 0 pass unchanged."""
    if x is None:
        return None
    x = float(x)
    if not math.isfinite(x) or x == 0.0:
        return x
    return float(f"{x:.{digits - 1}e}")


#: Rounding of each float column of a label file (products.md), by column name.
LABEL_COLUMN_DECIMALS: dict[str, int] = {
    "fs_hz": 9, "g_local": ACCEL_DECIMALS,
    **{f"{p}_{a}": ACCEL_DECIMALS for p in ("bias", "offset", "std") for a in "xyz"},
    **{f"gravity_{a}": UNIT_DECIMALS for a in "xyz"},
    "roll_deg": ANGLE_DECIMALS, "pitch_deg": ANGLE_DECIMALS,
    "sync_offset_s": TIME_DECIMALS, "sync_drift_ppm": PPM_DECIMALS,
    "sync_residual_s": 12, "segment_start_s": TIME_DECIMALS, "segment_end_s": TIME_DECIMALS,
    **{f"scale_{a}": UNIT_DECIMALS for a in "xyz"}, "temperature_c": 6,
    **{f"a_{r}{c}": UNIT_DECIMALS for r in "xyz" for c in "xyz"},
    **{f"imutk_s_{a}": UNIT_DECIMALS for a in "xyz"},
    **{f"imutk_mis_{n}": UNIT_DECIMALS for n in ("yz", "zy", "zx")},  # rad
    **{f"temp_slope_{a}": ACCEL_DECIMALS for a in "xyz"}, "temp_ref_c": 6,
    "fit_residual_rms": ACCEL_DECIMALS,
}
#: Label columns rounded to :data:`SIGNIFICANT_DIGITS` instead.
LABEL_SIGNIFICANT = frozenset({"fit_condition"})
SE_SIGNIFICANT_DIGITS = 6
"""Significant digits of a standard error (a label column ending in ``_se``): an uncertainty
is itself uncertain by far more, and its last digits come from finite differences and LAPACK."""


def round_label_value(column: str, value: Any) -> Any:
    """A label file's value as written: floats of known columns rounded, others unchanged."""
    if column in LABEL_SIGNIFICANT:
        return round_significant(value)
    if column.endswith("_se"):
        return round_significant(value, SE_SIGNIFICANT_DIGITS)
    decimals = LABEL_COLUMN_DECIMALS.get(column)
    if decimals is None or value is None:
        return value
    return round_decimals(value, decimals)


def round_floats(obj: Any, decimals: int, significant_keys: frozenset[str] = frozenset(),
                 ) -> Any:
    """A JSON-like structure with every float rounded to ``decimals`` places.

    Parameters
    ----------
    obj
        Nested dicts, lists and tuples of scalars (numpy scalars and arrays included).
    decimals
        Decimal places for floats.
    significant_keys
        Dict keys whose float values (or lists of floats) are rounded to
        :data:`SIGNIFICANT_DIGITS` significant digits instead (condition numbers).

    Returns
    -------
    The same structure with plain Python floats; ints, strings, bools and None unchanged.
    """
    return _round(obj, decimals, significant_keys, False)


def _round(obj: Any, decimals: int, keys: frozenset[str], significant: bool) -> Any:
    if isinstance(obj, Mapping):
        return {k: _round(v, decimals, keys, k in keys) for k, v in obj.items()}
    if isinstance(obj, np.ndarray):
        obj = obj.tolist()
    if isinstance(obj, list | tuple):
        return [_round(v, decimals, keys, significant) for v in obj]
    if isinstance(obj, bool | np.bool_) or obj is None or isinstance(obj, str):
        return obj.item() if isinstance(obj, np.bool_) else obj
    if isinstance(obj, int | np.integer):
        return int(obj)
    if isinstance(obj, float | np.floating):
        return round_significant(obj) if significant else round_decimals(obj, decimals)
    return obj
