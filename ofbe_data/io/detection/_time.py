"""The time unit and the sample rate of a data file, for ``ofbe-session init``.

They come from the time stamps' steps (and their magnitude, for epoch stamps; a unit a name
states is checked against the rate it gives); a column of integers that increase by 1 is a
sample index, whose rate must be given or stated in the preamble (``Fs,100``,
``# sampling rate: 100 Hz``). Pure functions of arrays and lines: :mod:`ofbe_data.io.detection`
reads the file and calls them. Every decision comes with its evidence (a short text a person
can check), and a case that the numbers do not settle raises
:class:`~ofbe_data.io.detection.DetectionError` naming the command-line flag that settles
it, never a guess.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from ofbe_data.io.detection._layout import Layout, split_fields
from ofbe_data.io.detection._units import DetectionError, fmt_num

RATE_RANGE_HZ = (0.5, 20_000.0)
"""Rates an accelerometer logs at (as :data:`ofbe_data.labelling.checks.RATE_RANGE_HZ`)."""
TYPICAL_RATE_HZ = (3.2, 3200.0)
"""A time step is read in the unit that puts its rate here (1000 wide, centred on 100 Hz)."""
TIME_SCALE = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9}
"""Seconds per time unit."""
EPOCH_FIRST = {"s": (1.0e9, 2.2e9), "ms": (1.0e12, 2.2e12), "us": (1.0e15, 2.2e15), "ns": (1.0e18, 2.2e18)}
"""First stamps that are Unix epoch times (2001–2039) in each unit."""
_EPOCH_WORD = {"s": "seconds", "ms": "milliseconds", "us": "microseconds", "ns": "nanoseconds"}
GAP_STEPS = 1.5
"""A step longer than this many median steps is a gap (as the readers count them)."""


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
    warning
        What a person should look at (a unit in the name that the steps contradict), or None.
    """

    unit: str
    rate_hz: float | None
    stats: StepStats
    evidence: str
    warning: str | None = None

    def rate_evidence(self) -> str:
        """The rate's evidence: median step (and the rate it gives), jitter and gaps."""
        s = self.stats
        step = f"{fmt_num(s.median)} {self.unit}" if self.unit != "samples" else fmt_num(s.median)
        if self.rate_hz is not None:
            step += f" → {fmt_num(self.rate_hz, 5)} Hz"
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
                     forced: str | None = None, first: float | None = None,
                     stamps: list[tuple[int, str]] | None = None) -> TimeDecision:
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
    stamps
        (file line, text) of the column on sampled lines (:func:`stamp_texts`): a column that
        never advances because its stamps were written in scientific notation says so.

    Raises
    ------
    DetectionError
        No unit gives a rate an accelerometer logs at.
    """
    s = step_stats(t)
    if not s.median > 0:
        raise DetectionError(path, f"{name} does not advance (no positive step){_same_stamps(stamps or [])}",
                             "--time-column NAME, or --rate HZ when the file has no time column")
    ones = float(np.mean(np.diff(t) == 1.0)) if s.integer else 0.0
    if forced is not None:
        rate = None if forced == "samples" else _rate(s.median, forced)
        return TimeDecision(forced, rate, s, "given with --time-unit")
    if name_unit is not None:
        rate = _rate(s.median, name_unit)
        if _in(rate, RATE_RANGE_HZ):
            return TimeDecision(name_unit, rate, s, f"the column name {name} says so; median step "
                                                    f"{fmt_num(s.median)} → {fmt_num(rate)} Hz")
        return _against_the_name(path, s, name, name_unit, rate)
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


def _against_the_name(path: str | Path, s: StepStats, name: str, name_unit: str, rate: float) -> TimeDecision:
    """The unit of a time column whose name states a unit that gives no accelerometer rate
    (``t_ms`` holding seconds: 100 kHz): the one unit that gives a typical rate, with a warning.

    Raises
    ------
    DetectionError
        No unit, or more than one, gives a typical rate.
    """
    lo, hi = RATE_RANGE_HZ
    said = (f"the column name {name} says {name_unit}, but its median step {fmt_num(s.median)} would "
            f"give {rate:.4g} Hz, outside the {fmt_num(lo)}–{fmt_num(hi)} Hz an accelerometer logs at")
    typical = [u for u in TIME_SCALE if u != name_unit and _in(_rate(s.median, u), TYPICAL_RATE_HZ)]
    if len(typical) != 1:
        raise DetectionError(path, said, "--time-unit U (s, ms, us or ns)")
    unit = typical[0]
    better = _rate(s.median, unit)
    why = f"{said}; in {unit} it gives {fmt_num(better)} Hz"
    return TimeDecision(unit, better, s, why, f"{why}: read in {unit} (give --time-unit {name_unit} if "
                                              "the name is right)")


PRECISION_LINES = 1000
"""Data lines whose time text :func:`stamp_texts` samples for the precision it keeps."""
MAX_QUANTUM = 0.01
"""A time column written in scientific notation (a float export) or beyond float64's digits may
step by this fraction of the sample period at the finest before its lost precision is named."""
COARSER = 1.01
"""Any time column whose finest step exceeds the sample period by this factor is named (stamps
with exactly the period's resolution, ``%.2f`` s at 100 Hz, are not)."""
_NUMBER = re.compile(r"[+-]?(?P<int>\d*)(?:\.(?P<frac>\d*))?(?:[eE](?P<exp>[+-]?\d+))?")


@dataclass(frozen=True)
class LostPrecision:
    """Time stamps written with fewer digits than the sample period needs.

    Attributes
    ----------
    line, text
        The file line whose stamp shows it, and the stamp as written.
    digits
        Significant digits the stamps keep (as written, or as float64 keeps them).
    quantum
        Finest step the stamps can show, in the column's unit.
    period
        The sample period, in the column's unit: the rows' span over their count, or the median
        step when that is shorter (gaps).
    stuck, steps
        Steps that do not advance, of all steps.
    """

    line: int
    text: str
    digits: int
    quantum: float
    period: float
    stuck: int
    steps: int

    def note(self, unit: str) -> str:
        """A short clause for the evidence of the time unit and of the rate."""
        return (f"lost precision: the time stamps keep only {self.digits} significant digits (line "
                f"{self.line}: {self.text!r}): {self._steps(unit)}")

    def warning(self, name: str, unit: str, rate_hz: float | None) -> str:
        """The warning ``init`` prints, naming the line, the digits kept and what to do."""
        if self.quantum > COARSER * self.period:
            what = (f"{self.stuck} of {self.steps} steps do not advance, so the rate measured from the steps"
                    + (f" ({fmt_num(rate_hz, 5)} Hz)" if rate_hz else "") + " is wrong")
        else:
            what = "each step is off by up to that much"
        return (f"line {self.line}: {name} keeps only {self.digits} significant digits ({self.text!r}): "
                f"{self._steps(unit)}: {what} (scientific notation or float64 keep too few digits); export "
                "the time as integers (e.g. epoch nanoseconds written in full, not in scientific notation)")

    def _steps(self, unit: str) -> str:
        scale = TIME_SCALE.get(unit, 1.0)
        ratio = self.quantum / self.period
        share = f"{fmt_num(ratio, 3)} times" if ratio >= 1.0 else f"{fmt_num(100 * ratio, 2)} % of"
        return (f"they step by {self.quantum:.3g} {unit} ({self.quantum * scale:.3g} s) at the finest, "
                f"{share} the sample period of about {self.period:.4g} {unit} (the rows' span gives "
                f"{fmt_num(1.0 / (self.period * scale), 5)} Hz)")


def stamp_texts(lines: list[str], lay: Layout, column: int, limit: int = PRECISION_LINES
                ) -> list[tuple[int, str]]:
    """(file line, text) of a column on the first ``limit`` data lines (the lines
    :func:`~ofbe_data.io.detection._layout.read_numbers` reads)."""
    out: list[tuple[int, str]] = []
    for i in range(lay.data_start, len(lines)):
        line = lines[i]
        if not line.strip() or (lay.comment and line.startswith(lay.comment)):
            continue
        f = split_fields(line.replace(",", ".") if lay.decimal_comma else line, lay.delimiter)
        if len(f) == lay.width:
            out.append((i + 1, f[column]))
            if len(out) >= limit:
                break
    return out


def text_quantum(text: str) -> tuple[float, bool] | None:
    """The finest step a number's text can show (``'1.7000000001e+18'``: 1e8; ``'12.345'``: 0.001)
    and whether it is in scientific notation; None for text that is not a plain number."""
    m = _NUMBER.fullmatch(text.strip())
    if m is None or not (m.group("int") or m.group("frac")):
        return None
    return 10.0 ** (int(m.group("exp") or 0) - len(m.group("frac") or "")), m.group("exp") is not None


def _same_stamps(stamps: list[tuple[int, str]]) -> str:
    """Why a column in scientific notation does not advance (its digits), or ``""``."""
    sci = [(line, text.strip()) for line, text in stamps if (q := text_quantum(text)) is not None and q[1]]
    if not sci:
        return ""
    line, text = sci[0]
    digits = len(re.sub(r"[^0-9]", "", re.split(r"[eE]", text)[0]).lstrip("0")) or 1
    return (f": every stamp reads {text!r} from line {line}, {digits} significant digits in scientific "
            "notation (lost precision: export the time as integers, e.g. epoch nanoseconds written in full)")


def lost_precision(stamps: list[tuple[int, str]], t: np.ndarray, exact: bool) -> LostPrecision | None:
    """Whether time stamps were written with too few digits for their sample period, or None.

    Parameters
    ----------
    stamps
        (file line, text) of the column on sampled data lines (:func:`stamp_texts`).
    t
        The column's values (≥ 2), in file order.
    exact
        The values were read as integers (relative to the first, :func:`read_numbers`), not
        through float64.

    Returns
    -------
    LostPrecision or None
        When the finest step the stamps can show (the text's last digit, or float64's spacing at
        their magnitude) is coarser than the sample period (:data:`COARSER`), or more than
        :data:`MAX_QUANTUM` of it for stamps in scientific notation or beyond float64's digits.
    """
    t = np.asarray(t, dtype=np.float64)
    quanta = [(q[0], q[1], line, text) for line, text in stamps if (q := text_quantum(text)) is not None]
    if t.size < 2 or not quanta:
        return None
    q_text, _, line, text = min(quanta, key=lambda x: x[0])
    sci = any(x[1] for x in quanta)
    magnitude = max(abs(float(v)) for v in (t[0], t[-1]))
    q_float = 0.0 if exact else float(np.spacing(magnitude))
    quantum = max(q_text, q_float)
    s = step_stats(t)
    span = (float(t.max()) - float(t.min())) / (t.size - 1)
    period = min(x for x in (span, s.median) if x > 0) if max(span, s.median) > 0 else 0.0
    if not period > 0:
        return None
    if not (quantum > COARSER * period or ((sci or q_float > q_text) and quantum > MAX_QUANTUM * period)):
        return None
    value = abs(float(text)) or magnitude  # a plain number's text (text_quantum matched it)
    digits = math.floor(math.log10(value)) - math.floor(math.log10(quantum)) + 1 if value > 0 else 1
    return LostPrecision(line, text.strip(), max(1, digits), quantum, period, s.backwards, int(t.size - 1))


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
