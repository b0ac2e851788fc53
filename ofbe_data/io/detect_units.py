"""Column names, units and rates of a data file, for ``ofbe-session init``.

Column names are taken apart into a base and a stated unit (``'Accel X (g)'`` → ``accel_x``,
``g``) and matched to the manifest's column keys. The time unit and the sample rate come from
the time stamps' steps (and their magnitude, for epoch stamps); the acceleration unit, and for
raw counts the counts per g and the zero, come from the norm of the mean reading at rest. Pure
functions of arrays: :mod:`ofbe_data.io.detect` reads the file and calls them. Every decision
comes with its evidence (a short text a person can check), and a case that the numbers do not
settle raises :class:`DetectionError` naming the command-line flag that settles it, never a
guess.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.gravity import G0

RATE_RANGE_HZ = (0.5, 20_000.0)
"""Rates an accelerometer logs at (as :data:`ofbe_data.labelling.checks.RATE_RANGE_HZ`)."""
TYPICAL_RATE_HZ = (3.2, 3200.0)
"""A time step is read in the unit that puts its rate here (1000 wide, centred on 100 Hz)."""
TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
"""Seconds per time unit."""
EPOCH_FIRST = {"s": (1.0e9, 2.2e9), "ms": (1.0e12, 2.2e12), "us": (1.0e15, 2.2e15), "ns": (1.0e18, 2.2e18)}
"""First stamps that are Unix epoch times (2001–2039) in each unit."""
_EPOCH_WORD = {"s": "seconds", "ms": "milliseconds", "us": "microseconds", "ns": "nanoseconds"}
UNIT_TOLERANCE = 0.10
"""A norm at rest within 10 % of a unit's value of 1 g fits that unit."""
OFFSET_TOLERANCE = 0.05
"""Tighter for counts around an assumed zero (a weaker hypothesis)."""
TIE_MARGIN = 0.01
"""Two units whose fits differ by less than this (log ratio) are a tie: ask, do not guess."""
COUNTS_BITS = range(5, 17)
"""Counts per g that raw counts may have: 2^5 … 2^16."""
GAP_STEPS = 1.5
"""A step longer than this many median steps is a gap (as the readers count them)."""
COUNTS_FLAGS = "--unit counts --lsb-per-g N --zero-counts Z"


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


def unit_of_text(text: str) -> str | None:
    """The unit a column name's suffix or parenthesised part names, or None.

    ``s``, ``ms``, ``us``, ``ns`` for time; ``g``, ``mg``, ``m/s2``, ``counts`` for
    acceleration; ``C``, ``K``, ``F`` for temperature.
    """
    u = text.strip().lower().replace(" ", "").replace("°", "").replace("deg", "")
    table = {
        "s": "s", "sec": "s", "secs": "s", "second": "s", "seconds": "s",
        "ms": "ms", "msec": "ms", "millis": "ms", "milliseconds": "ms",
        "us": "us", "µs": "us", "μs": "us", "usec": "us", "micros": "us", "microseconds": "us",
        "ns": "ns", "nsec": "ns", "nanos": "ns", "nanoseconds": "ns",
        "g": "g", "mg": "mg", "counts": "counts", "count": "counts", "lsb": "counts", "raw": "counts",
        "adc": "counts", "digits": "counts",
        "c": "C", "k": "K", "f": "F",
    }
    if u in table:
        return table[u]
    if re.fullmatch(r"m/?s(\^?2|²|-2|\*\*2)|mps2|m_s2|m_s_2|ms2|ms\^-2|m\.s-2", u):
        return "m/s2"
    return None


# --------------------------------------------------------------------------- column names

TIME_NAMES = {"t", "time", "times", "timestamp", "time_stamp", "tstamp", "ts", "seconds", "secs", "sec",
               "elapsed", "elapsed_time", "millis", "micros", "nanos", "epoch", "epoch_time", "unix_time",
               "unixtime", "clock", "host_time", "sensor_time", "device_time", "timer", "utc", "rel_time",
               "time_since_start", "relative_time", "timestamp_s", "time_s"}
INDEX_NAMES = {"n", "n_samples", "nsamples", "sample", "samples", "sample_index", "sample_no", "sample_nr",
                "sample_number", "sample_count", "sample_num", "index", "idx", "i", "count", "counter",
                "frame", "packet", "seq", "sequence", "record", "no", "nr", "num", "number"}
_UNIT_SUFFIX = re.compile(r"^(?P<base>.+?)_(?P<unit>s|sec|secs|ms|msec|us|usec|ns|nsec|g|mg|ms2|mps2|m_s2|"
                          r"raw|counts|lsb|c|degc|k|f)$")
_AXIS = re.compile(r"^(?:(?P<p>a|acc|accel|accl|acceleration|accelerometer|linear_acceleration|lin_acc|"
                   r"linacc|imu_acc|imu_accel)_?(?P<x>[xyz])|(?P<y>[xyz])(?:_?(?P<q>a|acc|accel|"
                   r"acceleration))?)$")
TEMP_NAMES = {"temp", "temperature", "die_temp", "chip_temp", "imu_temp", "sensor_temp", "board_temp"}


@dataclass(frozen=True)
class ColumnName:
    """A column name taken apart: ``'Accel X (g)'`` → base ``accel_x``, unit ``g``."""

    raw: str
    base: str
    unit: str | None


def parse_name(raw: str) -> ColumnName:
    """Lower-case base (blanks and punctuation as ``_``) and the unit it states, if any."""
    text, unit = raw, None
    m = re.match(r"^(.*?)\s*[(\[](.+?)[)\]]\s*$", text)
    if m:
        text, unit = m.group(1), unit_of_text(m.group(2))
    base = re.sub(r"[^a-z0-9]+", "_", text.lower()).strip("_")
    if unit is None:
        s = _UNIT_SUFFIX.match(base)
        if s and unit_of_text(s.group("unit").replace("degc", "c").replace("m_s2", "m/s2")) is not None:
            stem = s.group("base")
            if stem in TIME_NAMES | INDEX_NAMES or _AXIS.match(stem) or stem in TEMP_NAMES:
                base, unit = stem, unit_of_text(s.group("unit").replace("degc", "c").replace("m_s2", "m/s2"))
    if unit is None and base in ("millis", "micros", "nanos"):
        unit = unit_of_text(base)
    return ColumnName(raw, base, unit)


def axis_columns(path: Path, names: list[ColumnName]) -> tuple[dict[str, int], str | None]:
    """Columns of ax, ay, az by name (0-based), and the unit their names state (None: none or mixed).

    Raises
    ------
    DetectionError
        No complete x, y, z set of acceleration names, or more than one.
    """
    families: dict[str, dict[str, int]] = {}
    for i, n in enumerate(names):
        m = _AXIS.match(n.base)
        if not m:
            continue
        axis = m.group("x") or m.group("y")
        family = (m.group("p") or "") + "|" + (m.group("q") or "")
        families.setdefault(family, {}).setdefault("a" + axis, i)
    complete = {k: v for k, v in families.items() if len(v) == 3}
    prefixed = {k: v for k, v in complete.items() if k != "|"}
    chosen = prefixed or complete
    if len(chosen) != 1:
        found = "; ".join(",".join(names[i].raw for i in v.values()) for v in chosen.values()) or "none"
        raise DetectionError(path, f"acceleration columns by name: {len(chosen)} sets ({found})",
                             "--columns t=NAME,ax=NAME,ay=NAME,az=NAME")
    cols = next(iter(chosen.values()))
    units = {names[i].unit for i in cols.values()}
    return cols, (units.pop() if len(units) == 1 else None)


# --------------------------------------------------------------------------- time


@dataclass(frozen=True)
class StepStats:
    """Statistics of a time column's steps.

    Attributes
    ----------
    median
        Median step, in the column's units.
    jitter
        Standard deviation of the steps over the median (host clocks: percent; crystals: ~0).
    gaps
        Steps longer than :data:`GAP_STEPS` median steps.
    backwards
        Steps that do not advance (zero or negative).
    integer
        Whether every value is a whole number.
    """

    median: float
    jitter: float
    gaps: int
    backwards: int
    integer: bool


def step_stats(t: np.ndarray) -> StepStats:
    """Median step, jitter, gaps and backward steps of a time column (≥ 2 values)."""
    t = np.asarray(t, dtype=np.float64)
    steps = np.diff(t)
    fwd = steps[steps > 0]
    median = float(np.median(fwd)) if fwd.size else 0.0
    jitter = float(np.std(fwd) / median) if median > 0 else float("nan")
    gaps = int(np.count_nonzero(fwd > GAP_STEPS * median)) if median > 0 else 0
    integer = bool(np.all(np.isfinite(t)) and np.all(t == np.round(t)))
    return StepStats(median, jitter, gaps, int(steps.size - fwd.size), integer)


@dataclass(frozen=True)
class TimeDecision:
    """The unit of a time column and the sample rate it gives.

    Attributes
    ----------
    unit
        ``s``, ``ms``, ``us``, ``ns`` or ``samples``.
    rate_hz
        1 / median step, Hz (None for ``samples``: the index says nothing about the rate).
    stats
        The steps' statistics.
    evidence
        Why this unit.
    """

    unit: str
    rate_hz: float | None
    stats: StepStats
    evidence: str

    def rate_evidence(self) -> str:
        """The rate's evidence: median step, jitter and gaps."""
        s = self.stats
        step = f"{fmt_num(s.median)} {self.unit}" if self.unit != "samples" else fmt_num(s.median)
        jitter = "0" if not 100 * s.jitter >= 0.005 else f"{100 * s.jitter:.2g}"
        text = (f"median step {step}; jitter {jitter} % (std of steps / median); "
                f"{s.gaps} gap{'s' if s.gaps != 1 else ''} (steps > {GAP_STEPS:g} × median)")
        if s.backwards:
            text += f"; {s.backwards} steps that do not advance"
        return text


def _rate(median_step: float, unit: str) -> float:
    return 1.0 / (median_step * TIME_SCALE[unit]) if median_step > 0 else float("nan")


def _in(x: float, bounds: tuple[float, float]) -> bool:
    return bounds[0] <= x < bounds[1]


def decide_time_unit(path: str | Path, t: np.ndarray, name: str, name_unit: str | None, kind: str,
                     forced: str | None = None, first: float | None = None) -> TimeDecision:
    """The unit of a time column, from its name, its steps and its magnitude.

    Parameters
    ----------
    path
        The file (for messages).
    t
        The column's values in file order (≥ 2).
    name
        How to name the column in evidence (``'Time (s)'``, ``column 0``).
    name_unit
        The unit its name states (``(ms)``, ``_us``…), or None; a stated unit wins.
    kind
        ``time`` (a time-like name), ``index`` (an index-like name) or ``values`` (found by
        its values: no header, or a name that says nothing).
    forced
        The unit given on the command line (``--time-unit``), or None.
    first
        The column's first value when ``t`` holds values relative to it (stamps too long for
        float64, such as epoch nanoseconds, are read as integers less the first), else None.

    Raises
    ------
    DetectionError
        No unit gives a rate an accelerometer logs at.
    """
    s = step_stats(t)
    if not s.median > 0:
        raise DetectionError(path, f"{name} does not advance (no positive step)",
                             "--time-column NAME, or --rate HZ when the file has no time column")
    ones = float(np.mean(np.diff(t) == 1.0)) if s.integer else 0.0
    if forced is not None:
        rate = None if forced == "samples" else _rate(s.median, forced)
        return TimeDecision(forced, rate, s, "given with --time-unit")
    if name_unit is not None:
        rate = _rate(s.median, name_unit)
        return TimeDecision(name_unit, rate, s, f"the column name {name} says so; median step "
                                                f"{fmt_num(s.median)} → {fmt_num(rate)} Hz")
    if s.integer and s.median == 1.0 and ones >= 0.99 and kind in ("index", "values"):
        return TimeDecision("samples", None, s, f"{name} holds integers that increase by 1 "
                                                f"({100 * ones:.4g} % of steps): a sample index")
    first = float(t[0]) if first is None else first
    for unit, bounds in EPOCH_FIRST.items():
        rate = _rate(s.median, unit)
        if _in(first, bounds) and _in(rate, RATE_RANGE_HZ):
            when = datetime.fromtimestamp(first * TIME_SCALE[unit], UTC).strftime("%Y-%m-%d %H:%M:%S UTC")
            return TimeDecision(unit, rate, s, f"epoch {_EPOCH_WORD[unit]}: first stamp {first:.4g} = "
                                               f"{when}; median step {fmt_num(s.median)} → "
                                               f"{fmt_num(rate)} Hz")
    typical = [u for u in TIME_SCALE if _in(_rate(s.median, u), TYPICAL_RATE_HZ)]
    plausible = [u for u in TIME_SCALE if _in(_rate(s.median, u), RATE_RANGE_HZ)]
    chosen = typical or (plausible if len(plausible) == 1 else [])
    if not chosen:
        raise DetectionError(path, f"the median step of {name}, {fmt_num(s.median)}, gives no "
                                   f"accelerometer rate in s, ms, us or ns", "--time-unit U (s, ms, us, ns "
                                   "or samples with --rate HZ)")
    unit = chosen[0]
    rate = _rate(s.median, unit)
    others = ", ".join(f"{_rate(s.median, u):.3g} Hz in {u}" for u in TIME_SCALE if u != unit)
    why = (f"median step {fmt_num(s.median)} → {fmt_num(rate)} Hz in {unit}, the only unit giving "
           f"{fmt_num(TYPICAL_RATE_HZ[0])}–{fmt_num(TYPICAL_RATE_HZ[1])} Hz ({others})")
    if s.integer and s.median == 1.0:
        why += "; an integer step of 1: if it is a sample index give --time-unit samples --rate HZ"
    return TimeDecision(unit, rate, s, why)


_RATE_LINE = re.compile(
    r"""^\s*(?:\#|%|//)?\s*["']?
    (?:fs|f_s|sample[\s_-]?rate|sampling[\s_-]?rate|sampling[\s_-]?frequency|sample[\s_-]?frequency|
       samplerate|rate|odr|output[\s_-]?data[\s_-]?rate|data[\s_-]?rate|frequency)
    \s*(?:\(hz\)|\[hz\]|_hz|hz)?["']?\s*[,;:=\t ]\s*["']?
    (?P<value>\d+(?:\.\d*)?)["']?\s*(?:hz)?\s*[,;]*\s*$""",
    re.IGNORECASE | re.VERBOSE)


def preamble_rate(lines: list[str], first_line: int = 1) -> tuple[float, str] | None:
    """A sample rate stated in the lines before the data (``Fs,100``, ``fs=100``,
    ``Sample Rate (Hz),100``, ``# sampling rate: 100 Hz``), as (Hz, evidence), or None.

    Parameters
    ----------
    lines
        The preamble lines.
    first_line
        File line number of ``lines[0]`` (for the evidence).
    """
    for i, line in enumerate(lines):
        m = _RATE_LINE.match(line)
        if m:
            rate = float(m.group("value"))
            if rate > 0:
                return rate, f"line {first_line + i}: {line.strip()!r}"
    return None


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
                    zero: float | tuple[float, float, float] | None = None) -> AccDecision:
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
        why = "given with --unit" if forced else "the column names say raw counts"
        return _counts(path, acc, mean, where, lsb, zero, why)
    direction = mean / norm if norm > 0 else np.zeros(3)
    stated = forced or name_unit
    if stated is not None:
        g = norm / _one_g(stated)
        why = "given with --unit" if forced else "the column names say so"
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
