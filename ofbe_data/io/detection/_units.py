"""Acceleration and angular-rate units of a data file, for ``ofbe-session init``, and what the
detection modules share: :class:`DetectionError` and :func:`fmt_num`.

The acceleration unit, and for raw counts the counts per g and the zero, come from the norm of
the mean reading at rest (≈ 9.8 → m/s², ≈ 1 → g, ≈ 1000 → mg, near a power of two → counts;
all axes near mid-scale of an unsigned converter → offset-binary counts); the angular-rate unit
from the names, else from values beyond any rad/s an IMU turns at (else it is left unmapped); the
temperature unit from the name, else from the values (a device's −40…125 °C as °C, kelvin or °F;
a column no unit settles is left unmapped, with a warning).
Pure functions of arrays: :mod:`ofbe_data.io.detection` reads the file and calls them (the column
names are taken apart by :mod:`ofbe_data.io.detection._names`, the time unit and rate found by
:mod:`ofbe_data.io.detection._time`). Every decision comes with its evidence (a short text a person
can check), and a case that the numbers do not settle raises :class:`DetectionError` naming the
command-line flag that settles it, never a guess.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.gravity import G0
from ofbe_data.io.recording import (
    TEMPERATURE_RANGE_C,
    TEMPERATURE_UNIT_WORDS,
    to_celsius,
    unit_hint,
    units_in_range,
)

UNIT_TOLERANCE = 0.10
"""A norm at rest within 10 % of a unit's value of 1 g fits that unit."""
OFFSET_TOLERANCE = 0.05
"""Tighter for counts around an assumed zero (a weaker hypothesis)."""
TIE_MARGIN = 0.01
"""Two units whose fits differ by less than this (log ratio) are a tie: ask, do not guess."""
COUNTS_BITS = range(5, 17)
"""Counts per g that raw counts may have: 2^5 … 2^16."""
COUNTS_FLAGS = "--unit counts --lsb-per-g N --zero-counts Z"
COUNTS_MIN = 2.0 ** (COUNTS_BITS.start - 1)
"""Integer readings this large at rest are raw counts (no g, m/s² or rad/s value is)."""


class DetectionError(RawFormatError):
    """A file whose layout or units the data do not settle; the message names the flag to give.

    Parameters
    ----------
    path
        The file.
    what
        What is ambiguous or missing, with the evidence.
    flags
        The command-line flags that settle it (e.g. ``--rate HZ``).
    """

    def __init__(self, path: str | Path, what: str, flags: str) -> None:
        self.path = Path(path)
        self.what = what
        self.flags = flags
        self.expected = flags
        self.found = what
        self.line = None
        Exception.__init__(self, f"{path}: {what}: give {flags}")


def fmt_num(x: float, digits: int = 4) -> str:
    """A number in ``digits`` significant digits, without a trailing ``.0`` for integers."""
    if x == int(x) and abs(x) < 1e15:
        return str(int(x))
    return f"{x:.{digits}g}"


# --------------------------------------------------------------------------- acceleration


def quiet_mean(acc: np.ndarray, window: int) -> tuple[np.ndarray, int, int]:
    """Mean reading over the quietest block of ``window`` samples (smallest variance).

    Returns
    -------
    mean, start, stop
        (3,) mean and the block's sample range [start, stop).
    """
    acc = np.asarray(acc, dtype=np.float64)
    n = acc.shape[0]
    w = int(min(max(window, 2), n))
    k = n // w
    blocks = acc[: k * w].reshape(k, w, acc.shape[1])
    var = blocks.var(axis=1).sum(axis=1)
    j = int(np.argmin(var))
    return blocks[j].mean(axis=0), j * w, (j + 1) * w


@dataclass(frozen=True)
class AccDecision:
    """The unit of the acceleration columns.

    Attributes
    ----------
    unit
        ``m/s2``, ``g``, ``mg`` or ``counts``.
    lsb_per_g
        Counts per g (counts only).
    zero_counts
        Counts at zero specific force (counts only; 0 for signed counts).
    norm
        ‖mean at rest − zero‖ in the file's unit.
    direction
        (3,) unit vector of the mean at rest (sensor frame).
    evidence, lsb_evidence, zero_evidence
        Why.
    warnings
        Things a person should look at (a stated unit that the norm contradicts).
    """

    unit: str
    lsb_per_g: float | tuple[float, float, float] | None
    zero_counts: float | tuple[float, float, float]
    norm: float
    direction: np.ndarray
    evidence: str
    lsb_evidence: str = ""
    zero_evidence: str = ""
    warnings: tuple[str, ...] = ()


def _one_g(unit: str, lsb: float | None = None) -> float:
    return {"m/s2": G0, "g": 1.0, "mg": 1000.0}.get(unit, lsb or 1.0)


def _dist(norm: float, value: float) -> float:
    return abs(math.log(norm / value)) if norm > 0 else math.inf


def _contradiction(norm: float, stated: str) -> str | None:
    """The unit the norm at rest fits when it plainly does not fit ``stated`` (more than 30 %
    off 1 g in it, within :data:`UNIT_TOLERANCE` in the other), else None."""
    if stated not in ("m/s2", "g", "mg") or abs(norm / _one_g(stated) - 1.0) <= 0.3:
        return None
    fits = sorted((_dist(norm, _one_g(u)), u) for u in ("m/s2", "g", "mg") if u != stated)
    return fits[0][1] if fits[0][0] <= UNIT_TOLERANCE else None


def _power_of_two(norm: float, limit: float = math.inf, tol: float = UNIT_TOLERANCE) -> float | None:
    """The power of two 2^k (k in :data:`COUNTS_BITS`, ≤ ``limit``) within ``tol`` of ``norm``."""
    if not norm > 0:
        return None
    k = round(math.log2(norm))
    if k in COUNTS_BITS and 2.0**k <= limit and _dist(norm, 2.0**k) <= tol:
        return 2.0**k
    return None


def offset_binary_zero(acc: np.ndarray, mean: np.ndarray) -> int | None:
    """Mid-scale 2^(b−1) when the readings look like unsigned offset-binary counts, else None.

    Every value is a non-negative integer below 2^b (b ≥ 10, the bit length of the largest)
    and every axis' mean at rest sits near mid-scale (within 0.4–1.6 × 2^(b−1)): a signed
    sensor at rest has an axis near zero in nearly every orientation.
    """
    acc = np.asarray(acc, dtype=np.float64)
    if acc.size == 0 or acc.min() < 0 or not np.all(acc == np.round(acc)):
        return None
    bits = int(acc.max()).bit_length()
    if bits < 10:
        return None
    zero = 2 ** (bits - 1)
    if np.all((mean > 0.4 * zero) & (mean < 1.6 * zero)):
        return zero
    return None


def _per_axis_text(value: float | tuple[float, float, float]) -> str:
    if isinstance(value, tuple):
        return "[" + ", ".join(fmt_num(v) for v in value) + "]"
    return fmt_num(value)


def _counts(path: str | Path, acc: np.ndarray, mean: np.ndarray, where: str,
            lsb: float | tuple[float, float, float] | None,
            zero: float | tuple[float, float, float] | None, why: str,
            lsb_why: str = "given with --lsb-per-g") -> AccDecision:
    """Counts: the zero (given, offset-binary or 0) and the counts per g (given or a power of two)."""
    if zero is not None:
        z_ev = "given with --zero-counts"
    else:
        mid = offset_binary_zero(acc, mean)
        if mid is not None:
            zero, z_ev = float(mid), (f"unsigned offset-binary: every value is a non-negative integer "
                                      f"below 2^{mid.bit_length()} and every axis sits near mid-scale "
                                      f"{mid} (means {', '.join(f'{x:.0f}' for x in mean)})")
        else:
            zero, z_ev = 0.0, "signed counts (values on both sides of zero, or an axis near zero)"
    centred = mean - np.asarray(zero, dtype=np.float64)
    norm = float(np.linalg.norm(centred))
    if lsb is not None:
        l_ev = lsb_why
    else:
        p2 = _power_of_two(norm)
        if p2 is None:
            raise DetectionError(path, f"counts whose ‖mean − zero‖ at rest is {fmt_num(norm, 5)} ({where}, "
                                       f"zero {_per_axis_text(zero)}), not near a power of two", COUNTS_FLAGS)
        lsb = p2
        l_ev = f"‖mean − zero‖ = {fmt_num(norm, 5)} counts at rest ({where}) ≈ 2^{int(math.log2(p2))}"
    g = float(np.linalg.norm(centred / np.asarray(lsb, dtype=np.float64)))
    warn = ()
    if abs(g - 1.0) > 0.3:
        warn = (f"with lsb_per_g {_per_axis_text(lsb)} and zero_counts {_per_axis_text(zero)} the mean at "
                f"rest is {g:.3g} g, not about 1 g",)
    direction = centred / norm if norm > 0 else np.zeros(3)
    return AccDecision("counts", lsb, zero, norm, direction, why, l_ev, z_ev, warn)


def decide_acc_unit(path: str | Path, acc: np.ndarray, window: int, name_unit: str | None = None,
                    forced: str | None = None,
                    lsb: float | tuple[float, float, float] | None = None,
                    zero: float | tuple[float, float, float] | None = None,
                    stated_by: str = "the column names say") -> AccDecision:
    """The unit of the acceleration columns from the norm of the mean reading at rest.

    The mean at rest is the mean over the quietest block of ``window`` samples. ≈ 9.8 → m/s²,
    ≈ 1 → g, ≈ 1000 → mg, near a power of two (integers only) → counts with that many counts per
    g; all axes near mid-scale of an unsigned converter → offset-binary counts whose zero is
    mid-scale. A unit stated on the command line wins, then one stated by the column names.

    Parameters
    ----------
    path
        The file (for messages).
    acc
        (N, 3) readings as written in the file.
    window
        Samples per block when looking for the quietest part (about one second).
    name_unit
        Unit stated by the column names, or None.
    forced, lsb, zero
        ``--unit``, ``--lsb-per-g`` and ``--zero-counts``, or None.
    stated_by
        Who states ``name_unit``, for the evidence (``the unit row (line 2) says``).

    Raises
    ------
    DetectionError
        A norm that fits no unit, a tie between two units, or counts whose zero is unknown.
    """
    acc = np.asarray(acc, dtype=np.float64)
    mean, a, b = quiet_mean(acc, window)
    median = float(np.median(np.linalg.norm(acc, axis=1)))
    norm = float(np.linalg.norm(mean))
    where = f"the quietest {b - a} samples, rows {a + 1}–{b}"
    if forced is None and (lsb is not None or zero is not None):
        forced = "counts"
    if forced == "counts" or (forced is None and name_unit == "counts"):
        why = "given with --unit" if forced else f"{stated_by} raw counts"
        return _counts(path, acc, mean, where, lsb, zero, why)
    direction = mean / norm if norm > 0 else np.zeros(3)
    stated = forced or name_unit
    if stated is not None:
        g = norm / _one_g(stated)
        why = "given with --unit" if forced else f"{stated_by} so"
        other = None if forced else _contradiction(norm, stated)
        if other is not None:
            # the names say one unit and the values plainly are another (a header "ax (g)" over
            # m/s² values): neither is taken on trust, the user says which
            raise DetectionError(path, f"{stated_by} {stated}, but ‖mean‖ at rest ({where}) is "
                                       f"{fmt_num(norm, 5)} = {g:.3g} g in {stated}, and "
                                       f"{norm / _one_g(other):.4g} g in {other}",
                                 f"--unit {other} if the values are {other}, --unit {stated} if they are")
        warn = ()
        if abs(g - 1.0) > 0.3:
            warn = (f"‖mean‖ at rest is {fmt_num(norm, 5)} {stated} = {g:.3g} g, not about 1 g: is the "
                    f"unit {stated} right?",)
        return AccDecision(stated, None, 0.0, norm, direction,
                           f"{why}; ‖mean‖ = {fmt_num(norm, 5)} at rest = {g:.4g} g", warnings=warn)
    mid = offset_binary_zero(acc, mean)
    if mid is not None:
        centred = float(np.linalg.norm(mean - mid))
        if _power_of_two(centred, limit=mid, tol=OFFSET_TOLERANCE) is None:
            raise DetectionError(path, f"unsigned counts around mid-scale {mid} in every axis ({where}: "
                                       f"means {', '.join(f'{x:.0f}' for x in mean)}); "
                                       f"‖mean − {mid}‖ = {fmt_num(centred, 5)} is no power of two, so the "
                                       f"zero and the counts per g are unknown", COUNTS_FLAGS)
        return _counts(path, acc, mean, where, None, None,
                       f"‖mean − {mid}‖ = {fmt_num(centred, 5)} at rest ({where}) ≈ a power of two")
    integer = bool(np.all(acc == np.round(acc)))
    fits: list[tuple[float, str, float | None]] = [
        (_dist(norm, G0), "m/s2", None), (_dist(norm, 1.0), "g", None), (_dist(norm, 1000.0), "mg", None)]
    if integer:
        fits += [(_dist(norm, 2.0**k), "counts", 2.0**k) for k in COUNTS_BITS]
    fits.sort(key=lambda f: f[0])
    best, second = fits[0], fits[1]
    evidence = f"‖mean‖ = {fmt_num(norm, 5)} at rest ({where}; median ‖f‖ {fmt_num(median, 5)})"
    if best[0] > UNIT_TOLERANCE and integer and norm >= COUNTS_MIN:
        raise DetectionError(path, f"{evidence}: integers, so raw counts, but neither a power of two nor "
                                   "1000 (mg): the counts per g are unknown", "--lsb-per-g N")
    if best[0] > UNIT_TOLERANCE:
        raise DetectionError(path, f"{evidence} fits no unit (m/s2 ≈ 9.81, g ≈ 1, mg ≈ 1000, counts ≈ "
                                   "a power of two)", "--unit U (m/s2, g, mg; or " + COUNTS_FLAGS + ")")
    if second[0] <= UNIT_TOLERANCE and second[0] - best[0] < TIE_MARGIN:
        names = [f"{u}" + (f" with {fmt_num(v)} per g" if v else "") for _, u, v in (best, second)]
        flag_of = {f[1]: (f"--unit counts --lsb-per-g {fmt_num(f[2])}" if f[2] else f"--unit {f[1]}")
                   for f in (best, second)}
        raise DetectionError(path, f"{evidence} fits {names[0]} and {names[1]} alike",
                             " or ".join(flag_of.values()))
    if best[1] == "counts":
        return _counts(path, acc, mean, where, best[2], None, f"{evidence}: integers, ≈ a power of two",
                       f"the power of two nearest ‖mean‖ {fmt_num(norm, 5)}")
    return AccDecision(best[1], None, 0.0, norm, direction, evidence)


# --------------------------------------------------------------------------- angular rate

GYRO_RAD_S_MAX = 20.0
"""An angular rate beyond this many rad/s (1150 °/s) is no handled IMU's: such values are °/s."""


def decide_gyro_unit(omega: np.ndarray, name_unit: str | None, forced: str | None = None
                     ) -> tuple[str | None, str]:
    """The unit of the angular-rate columns (``rad/s``, ``deg/s``), or None when nothing settles it.

    Parameters
    ----------
    omega
        (N, 3) the three columns as written.
    name_unit
        The unit their names state (``(deg/s)``, ``_dps``), or None.
    forced
        ``--gyro-unit``, or None.

    Returns
    -------
    unit, evidence
        None when the names state no unit and the values fit both (at rest a gyroscope reads
        nearly zero in either unit): the columns are then left out of the manifest.
    """
    if forced is not None:
        return forced, "given with --gyro-unit"
    if name_unit in ("rad/s", "deg/s"):
        return name_unit, "the column names say so"
    omega = np.asarray(omega, dtype=np.float64)
    peak = float(np.max(np.abs(omega))) if omega.size else 0.0
    if name_unit is None and bool(np.all(omega == np.round(omega))) and peak >= COUNTS_MIN:
        return None, (f"integers up to {fmt_num(peak)}: raw gyroscope counts, which the manifest has no "
                      "scale for: not mapped")
    if name_unit is None and peak > GYRO_RAD_S_MAX:
        return "deg/s", (f"peak |ω| {fmt_num(peak)} is beyond {fmt_num(GYRO_RAD_S_MAX)} rad/s (1150 °/s), "
                         "which no handled IMU turns at: °/s")
    return None, (f"no unit in the names and the values (peak |ω| {fmt_num(peak)}) fit rad/s and °/s alike: "
                  "not mapped (give --gyro-unit rad/s or deg/s to map them)")


# --------------------------------------------------------------------------- temperature

HOT_AT_REST_C = 45.0
"""A temperature column whose values read as °C have a median above this, and read as °F lie
within 0…45 °C, is flagged: a device at rest is seldom that hot, and °F of a room look so."""


@dataclass(frozen=True)
class TemperatureDecision:
    """The unit of a temperature column (:func:`decide_temperature_unit`).

    Attributes
    ----------
    unit
        ``C``, ``K`` or ``F``; None: the column is left out of the manifest.
    evidence
        Why, in a few words a person can check.
    warning
        What a person should look at (a unit the values contradict, °F that read as hot °C), or None.
    """

    unit: str | None
    evidence: str
    warning: str | None = None


def decide_temperature_unit(values: np.ndarray, name_unit: str | None, column: str) -> TemperatureDecision:
    """The unit of a temperature column from its name, else from its values.

    A device temperature lies within :data:`~ofbe_data.io.recording.TEMPERATURE_RANGE_C`: values
    beyond it as °C that fit it as kelvin alone, or as °F alone, are in that unit (the manifest
    says so, and the evidence why); values that fit no unit, or both K and °F, or contradict the unit
    the name states, leave the column unmapped, with a warning. °C values that read as hot and as
    °F would be a room's (:data:`HOT_AT_REST_C`) are kept as °C with a warning.

    Parameters
    ----------
    values
        (N,) the column as written (NaN where not a number).
    name_unit
        The unit the column name states (``C``, ``K``, ``F``), or None.
    column
        The column's name, for the texts.

    Returns
    -------
    TemperatureDecision
    """
    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return TemperatureDecision(None, "no number in the column: not mapped")
    low, high = TEMPERATURE_RANGE_C
    span = f"values {fmt_num(float(x.min()))} to {fmt_num(float(x.max()))}"
    fits = units_in_range(x)
    unmapped = f"temperature column {column!r} not mapped: "
    if name_unit in TEMPERATURE_UNIT_WORDS and name_unit not in fits:
        why = f"the name says {name_unit}, but {unit_hint(x, name_unit)}"
        return TemperatureDecision(None, f"{why}: not mapped", unmapped + why)
    if name_unit in TEMPERATURE_UNIT_WORDS:
        unit, evidence = name_unit, "the column name says so"
    elif "C" in fits:
        unit, evidence = "C", f"{span}: °C, within a device's {low:g} to {high:g} °C"
    elif len(fits) == 1:
        unit = fits[0]
        c = to_celsius(np.array([x.min(), x.max()]), unit)
        evidence = (f"{span} are beyond a device's {low:g} to {high:g} °C as °C; as "
                    f"{TEMPERATURE_UNIT_WORDS[unit]} they are {c[0]:.1f} to {c[1]:.1f} °C")
    else:
        why = unit_hint(x, "C")
        return TemperatureDecision(None, f"{why}: not mapped", unmapped + why)
    middle = float(np.median(x))
    as_f = float(to_celsius(np.array(middle), "F"))
    warning = None
    if unit == "C" and middle > HOT_AT_REST_C and 0.0 <= as_f <= HOT_AT_REST_C:
        warning = (f"temperature column {column!r} reads {fmt_num(middle)} °C (median), hot for a device at "
                   f"rest; as degrees Fahrenheit it is {as_f:.1f} °C: if so, set temperature_unit: F")
    return TemperatureDecision(unit, evidence, warning)
