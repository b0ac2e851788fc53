"""Typed recordings: what every raw-format reader returns."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from datetime import datetime
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from ofbe_data.core.errors import RawFormatError

#: Kinds of skipped lines, as counted in :attr:`ReadDiagnostics.skipped_by_kind`.
SKIP_FIELD_COUNT = "field-count"
SKIP_NON_NUMERIC = "non-numeric"
SKIP_EMPTY = "empty"
SKIP_OUT_OF_RANGE = "out-of-range"
SKIP_NON_INCREASING_TIME = "non-increasing-time"


TEMPERATURE = "temperature_c"
"""Key of a per-sample temperature (°C) in :attr:`Recording.extra`."""
GYRO = ("gyro_x_rad_s", "gyro_y_rad_s", "gyro_z_rad_s")
"""Keys of a per-sample angular rate (rad/s, sensor frame) in :attr:`Recording.extra`."""
GYRO_DEG_S = ("Gyro X (deg/s)", "Gyro Y (deg/s)", "Gyro Z (deg/s)")
"""Keys of a per-sample angular rate in deg/s (the Memsense readers keep their own column names)."""


@dataclass(frozen=True)
class SkippedLine:
    """A data line that was counted and skipped, never guessed.

    Attributes
    ----------
    line
        1-based line number in the file.
    kind
        One of the ``SKIP_*`` constants.
    detail
        Human-readable reason, e.g. ``"expected 4 fields, found 3"``.
    """

    line: int
    kind: str
    detail: str


@dataclass(frozen=True)
class Gap:
    """Samples missing between two consecutive kept samples.

    Attributes
    ----------
    line
        File line of the sample after the gap.
    t_s
        Time of the sample after the gap, s (device clock).
    duration_s
        Time between the two samples around the gap, s.
    missing_samples
        Estimated number of samples lost (round(duration / period) − 1).
    """

    line: int
    t_s: float
    duration_s: float
    missing_samples: int


@dataclass(frozen=True)
class ReadDiagnostics:
    """What a reader saw in one file.

    Attributes
    ----------
    path
        The file.
    preamble_lines
        Lines before the first data line (boot noise, header comments, column names).
    lines_read
        Data lines after the column header (kept plus skipped).
    samples
        Samples kept.
    skipped
        Lines skipped, with reasons.
    gaps
        Gaps in the time stamps (dropped samples).
    wraps
        Number of counter wrap-arounds undone (``micros()`` at 2³² µs).
    saturated_samples
        Kept samples with at least one axis at the converter's limit.
    boot_lines
        Lines before the format's header (boot noise), part of ``preamble_lines``.
    """

    path: Path
    preamble_lines: int
    lines_read: int
    samples: int
    skipped: tuple[SkippedLine, ...] = ()
    gaps: tuple[Gap, ...] = ()
    wraps: int = 0
    saturated_samples: int = 0
    boot_lines: int = 0

    @property
    def skipped_by_kind(self) -> dict[str, int]:
        """Count of skipped lines per kind."""
        return dict(Counter(s.kind for s in self.skipped))

    @property
    def missing_samples(self) -> int:
        """Total samples estimated lost in gaps."""
        return sum(g.missing_samples for g in self.gaps)

    def summary(self) -> str:
        """One line for logs: counts of everything noteworthy."""
        kinds = ", ".join(f"{k} {n}" for k, n in sorted(self.skipped_by_kind.items())) or "none"
        return (f"{self.path}: {self.samples} samples from {self.lines_read} data lines; "
                f"skipped: {kinds}; gaps {len(self.gaps)} ({self.missing_samples} samples); "
                f"wraps {self.wraps}; saturated {self.saturated_samples}")


FULL_SCALE_TOLERANCE = 0.05
"""A file's largest reading on an axis is near its inferred full scale when it is within this
fraction of the largest magnitude the file reads on any axis (a logger that calibrates each axis
before writing moves the clipped value by the axis' bias and scale: a few per cent)."""


@dataclass(frozen=True)
class FullScale:
    """Where a recording's readings can sit at its range, per axis: what a pile-up of identical
    extreme readings is judged against (:func:`~ofbe_data.labelling.checks.clipped_samples`).

    A pile-up at the high end of axis k counts as clipping only at ``high[k]`` or above, one at
    the low end only at ``low[k]`` or below (+inf and −inf: never).

    Attributes
    ----------
    low, high
        (3,) float64, in the recording's unit (m/s²).
    source
        ``declared``: the manifest's ``range_g`` (at or beyond the reader's saturation fraction
        of it); ``inferred``: the file's own extremes (:func:`full_scale`).
    """

    low: np.ndarray
    high: np.ndarray
    source: str


@dataclass(frozen=True)
class Recording:
    """One device's file of one recording, in SI units.

    Attributes
    ----------
    path
        Source file.
    format
        Raw format it was read as.
    t
        (N,) float64, s, on the device's own clock (monotonic; counter wraps undone).
    acc
        (N, 3) float64, m/s², specific force in the sensor frame.
    saturated
        (N,) bool, True where any axis sat at the converter's limit.
    line
        (N,) int64, the file line of each sample (for error messages).
    start_utc
        Header UTC stamp of the start, when the format has one.
    nominal_rate_hz
        Sample rate stated by the header, when known.
    header
        Header key/values as written.
    extra
        Further per-sample columns by name (e.g. gyro, temperature), (N,) float64.
    diagnostics
        What the reader saw.
    full_scale
        The range a pile-up of extreme readings is judged against (:class:`FullScale`); None:
        the format's own rule (the ofbe-logger's exact converter limits flag saturation, and a
        pile-up at any extreme of a segment counts as clipping).
    """

    path: Path
    format: str
    t: np.ndarray
    acc: np.ndarray
    saturated: np.ndarray
    line: np.ndarray
    start_utc: datetime | None
    nominal_rate_hz: float | None
    header: dict[str, str]
    diagnostics: ReadDiagnostics
    extra: dict[str, np.ndarray] = field(default_factory=dict)
    full_scale: FullScale | None = None

    def gyro(self) -> np.ndarray | None:
        """Angular rate, (N, 3) rad/s in the sensor frame, or None when the file has no gyroscope
        columns (read from :data:`GYRO`, or :data:`GYRO_DEG_S` converted)."""
        for keys, scale in ((GYRO, 1.0), (GYRO_DEG_S, np.pi / 180.0)):
            if all(k in self.extra for k in keys):
                return np.stack([np.asarray(self.extra[k], dtype=np.float64) for k in keys], axis=1) * scale
        return None

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.t.shape[0])

    def once(self, key: Hashable, compute: Callable[[], Any]) -> Any:
        """``compute()``, computed once per ``key`` for this recording (its arrays are not changed
        once read): a check of the whole file that each of its poses asks for costs one pass, not
        one per pose (a 20-hour file with thousands of still periods, issue 33)."""
        memo = self.__dict__.setdefault("_once", {})  # beside the frozen fields, as cached_property does
        if key not in memo:
            memo[key] = compute()
        return memo[key]

    @cached_property
    def median_step_s(self) -> float:
        """Median step between consecutive time stamps, ``np.median(np.diff(t))``, s (NaN with
        fewer than two samples); computed once, for the checks and the tap high-pass alike."""
        return median(np.diff(self.t)) if self.n >= 2 else float("nan")

    @property
    def fs_hz(self) -> float:
        """Measured sample rate, Hz: kept plus missing samples over the time span."""
        if self.n < 2:
            return float("nan")
        span = float(self.t[-1] - self.t[0])
        return (self.n - 1 + self.diagnostics.missing_samples) / span if span > 0 else float("nan")


def median(x: np.ndarray) -> float:
    """``float(np.median(x))`` with the same bits, for a 1-D float64 array, from one selection.

    ``np.median`` partitions at the middle rank or ranks (and at the last, for NaN) and takes
    ``np.mean`` of the middle element or elements. A partition at the upper middle rank n // 2
    alone puts every smaller element before it, and the largest of those is the element of the
    lower middle rank (n even): the values numpy averages, in its order. Equal floats are the
    same bits except for zeros (−0.0 == 0.0), so the result is numpy's whenever there is no NaN
    (the maximum is not NaN) and no zero among them; otherwise numpy itself decides.
    """
    n = x.shape[0] if x.ndim == 1 else 0
    if n < 2 or x.dtype != np.float64 or math.isnan(float(x.max())):
        return float(np.median(x))
    k = n // 2
    part = np.partition(x, k)
    middle = part[k:k + 1] if n % 2 else np.array([part[:k].max(), part[k]])
    if not middle.all():  # a zero: which one is numpy's to say
        return float(np.median(x))
    return float(np.mean(middle))


def output_steps(acc: np.ndarray) -> np.ndarray:
    """Per axis, the step of the value grid the readings sit on, in the readings' unit.

    A logger writes quantised values: raw counts, or g printed with a fixed number of decimals.
    No two distinct readings of an axis then differ by less than one step, so the smallest
    difference between distinct values is the step (a reading between two grid values, such as
    an average of two readings, only makes it smaller). Readings that are not quantised (floats
    with many digits) give a spacing far below any noise. Only finite values count.

    Parameters
    ----------
    acc
        (N, 3) readings.

    Returns
    -------
    np.ndarray
        (3,) float64, the step per axis; 0 for an axis with fewer than two distinct finite values.
    """
    x = np.asarray(acc, dtype=np.float64)
    out = np.zeros(x.shape[1] if x.ndim == 2 else 0)
    for k in range(out.shape[0]):
        values = np.unique(x[:, k][np.isfinite(x[:, k])])
        if values.size >= 2:
            out[k] = float(np.diff(values).min())
    return out


def full_scale(acc: np.ndarray, declared: float | None = None, limit_fraction: float = 1.0) -> FullScale:
    """The range a recording's pile-ups of extreme readings are judged against.

    A sensor clips every axis at its range, so a clipped reading is the largest magnitude the
    file holds anywhere, and no reading of its axis goes beyond it. With a declared range R
    (± R), only readings at or beyond ``limit_fraction`` · R can be clipped. Without, the range is
    inferred from the file: the high end of an axis can be clipped only at the axis' largest
    reading, and only when that reading is within :data:`FULL_SCALE_TOLERANCE` of the largest
    magnitude on any axis (likewise the low end). A pile-up well inside
    the range (a short pose whose quantised noise happens to hit its lowest value a few times)
    is never clipping. An axis that reads one value over the whole file is stuck: that value
    counts at both ends, whatever the range.

    Parameters
    ----------
    acc
        (N, 3) readings of the whole recording.
    declared
        The declared range, same unit (None: not stated).
    limit_fraction
        Fraction of the declared range from which a reading is at its limit.

    Returns
    -------
    FullScale
    """
    x = np.asarray(acc, dtype=np.float64).reshape(-1, 3)
    finite = np.isfinite(x)
    seen = finite.any(axis=0)  # an axis with no finite reading has no range to be at
    every = bool(finite.all())  # then no masked copies of the readings (bounded memory)
    high = (x if every else np.where(finite, x, -np.inf)).max(axis=0, initial=-np.inf)
    low = (x if every else np.where(finite, x, np.inf)).min(axis=0, initial=np.inf)
    if declared is not None:
        lim = limit_fraction * float(declared)
        hi_bound, lo_bound, source = np.full(3, lim), np.full(3, -lim), "declared"
    else:
        scale = float(np.max(np.maximum(np.abs(high), np.abs(low))[seen], initial=0.0))
        near = (1.0 - FULL_SCALE_TOLERANCE) * scale
        hi_bound = np.where(seen & (high >= near), high, np.inf)
        lo_bound = np.where(seen & (-low >= near), low, -np.inf)
        source = "inferred"
    stuck = seen & (high == low)
    hi_bound = np.where(stuck, high, hi_bound)
    lo_bound = np.where(stuck, low, lo_bound)
    return FullScale(lo_bound, hi_bound, source)


# --------------------------------------------------------------------------- temperature


TEMPERATURE_RANGE_C = (-40.0, 125.0)
"""Range of a device temperature, °C: the widest operating range of MEMS accelerometers'
datasheets (ADXL345 −40…+85 °C, automotive parts to +125 °C). A value outside it is no reading
of a working sensor: another unit than the one declared, a scaled value, or no temperature."""
TEMPERATURE_UNIT_WORDS = {"C": "degrees Celsius", "K": "kelvin", "F": "degrees Fahrenheit"}
"""The units of ``temperature_unit`` (raw-formats.md, "Generic csv"), in words."""
MISSING_CELLS = frozenset({"", "nan", "-nan", "+nan", "na", "n/a", "#n/a", "<na>", "null", "none", "-"})
"""Temperature cells (trimmed, lower-cased) that hold no value: a sample without temperature, not a
garbled line (the markers pandas and spreadsheets write for a missing number)."""
TEMPERATURE_NOTE = "temperature_note"
"""Header key of what a reader says about a temperature column it read with holes, or without
any value (:func:`temperature_notes`)."""


class ImplausibleTemperatureError(RawFormatError):
    """A temperature column holds values no sensor reads in the unit the manifest declares."""


def to_celsius(x: np.ndarray, unit: str) -> np.ndarray:
    """Temperatures in ``unit`` (``C``, ``K``, ``F``) as °C, same shape."""
    if unit == "K":
        return x - 273.15
    if unit == "F":
        return (x - 32.0) * (5.0 / 9.0)
    return x


def units_in_range(values: np.ndarray) -> list[str]:
    """The units (of ``C``, ``K``, ``F``, in that order) in which every finite value of ``values``
    is a device temperature (:data:`TEMPERATURE_RANGE_C`); [] when none is, or no value is finite."""
    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return []
    lo, hi = float(x.min()), float(x.max())
    low, high = TEMPERATURE_RANGE_C
    return [u for u in TEMPERATURE_UNIT_WORDS
            if low <= float(to_celsius(np.array(lo), u)) and float(to_celsius(np.array(hi), u)) <= high]


def _span(values: np.ndarray, unit: str | None = None) -> str:
    """``285.2 to 291.1`` (as written; with ``unit``: as °C, ``12.0 to 18.0 °C``); one value alone
    when they are all equal."""
    ends = [float(np.min(values)), float(np.max(values))]
    if unit is not None:
        ends = [float(to_celsius(np.array(e), unit)) for e in ends]
    text = [f"{e:.1f}" if unit is not None else f"{e:.6g}" for e in ends]
    both = text[0] if text[0] == text[1] else f"{text[0]} to {text[1]}"
    return both + (" °C" if unit is not None else "")


def unit_hint(values: np.ndarray, declared: str, settable: bool = True) -> str:
    """What the finite ``values`` (written in ``declared``, which some do not fit) look like.

    ``the values, 285.2 to 291.1, look like kelvin (12.0 to 18.0 °C): set temperature_unit: K``;
    with no unit in which they are all a device temperature, what else they may be: a few values
    beyond the range among many within, or a scaled or raw value. ``settable`` False: a format
    whose unit is fixed (no manifest key changes it), so the advice is about the file instead.
    """
    x = np.asarray(values, dtype=np.float64)
    x = x[np.isfinite(x)]
    fits = [u for u in units_in_range(x) if u != declared]
    fixed = (f"this format writes {TEMPERATURE_UNIT_WORDS[declared]}: is the file damaged, or of another "
             "format?")
    if fits:
        words = " or ".join(f"{TEMPERATURE_UNIT_WORDS[u]} ({_span(x, u)})" for u in fits)
        advice = f"set temperature_unit: {' or '.join(fits)}" if settable else fixed
        return f"the values, {_span(x)}, look like {words}: {advice}"
    low, high = TEMPERATURE_RANGE_C
    c = to_celsius(x, declared)
    inside = (c >= low) & (c <= high)
    without = "leave columns.temperature out to read the file without temperature" if settable else fixed
    if np.any(inside):
        n = int((~inside).sum())
        return (f"{n} of {x.size} values {'is' if n == 1 else 'are'} outside the range, the others "
                f"{_span(x[inside])}: {without}")
    return (f"the values, {_span(x)}, are no device temperature in C, K or F (a scaled or raw value?): "
            f"{without}")


def checked_temperature(path: str | Path, values: np.ndarray, lines: np.ndarray, unit: str,
                        column: str | int, settable: bool = True) -> np.ndarray:
    """A temperature column as °C, refused when a value is no device temperature.

    Parameters
    ----------
    path
        The file (for the message).
    values
        (N,) the column as written, in ``unit``; NaN where a sample has no temperature.
    lines
        (N,) int, the file line of each value.
    unit
        ``C``, ``K`` or ``F``: what the manifest declares (``temperature_unit``).
    column
        The column's name or index, for the message.
    settable
        Whether a manifest key sets the unit (generic csv); False for formats that fix it.

    Returns
    -------
    np.ndarray
        (N,) °C, NaN kept.

    Raises
    ------
    ImplausibleTemperatureError
        A finite value outside :data:`TEMPERATURE_RANGE_C` once converted, naming the line of the
        first, its value, and the unit the column's values look like.
    """
    x = np.asarray(values, dtype=np.float64)
    celsius = to_celsius(x, unit)
    low, high = TEMPERATURE_RANGE_C
    outside = np.isfinite(celsius) & ((celsius < low) | (celsius > high))
    if np.any(outside):
        i = int(np.argmax(outside))
        name = repr(column) if isinstance(column, str) else f"{column} (0-based)"
        raise ImplausibleTemperatureError(
            path, f"a device temperature from {low:g} to {high:g} °C in column {name} "
                  + (f"(temperature_unit: {unit}, {TEMPERATURE_UNIT_WORDS[unit]})" if settable
                     else f"({TEMPERATURE_UNIT_WORDS[unit]})"),
            f"{float(x[i]):.6g} ({unit_hint(x, unit, settable)})", int(lines[i]))
    return celsius


def mean_temperature(values: np.ndarray) -> float:
    """Mean over the samples that have a temperature, °C; NaN when none has one."""
    x = np.asarray(values, dtype=np.float64)
    have = np.isfinite(x)
    return float(np.mean(x[have])) if np.any(have) else float("nan")


def missing_temperature_note(column: str | int, missing: np.ndarray, lines: np.ndarray) -> str | None:
    """What a reader says of a temperature column with samples that have no temperature, or None.

    Parameters
    ----------
    column
        The column's name or index.
    missing
        (N,) bool, the samples without a temperature.
    lines
        (N,) int, their file lines.
    """
    n = int(missing.sum())
    if n == 0:
        return None
    name = repr(column) if isinstance(column, str) else f"column {column}"
    if n == missing.shape[0]:
        return (f"the temperature column {name} holds no value (every cell empty or NaN): read without "
                "temperature")
    first = int(lines[int(np.argmax(missing))])
    return (f"{n} of {missing.shape[0]} samples have no temperature in column {name} (empty or NaN "
            f"cells, the first at line {first}): an interval's temperature is the mean over its samples "
            "that have one")


def temperature_notes(rec: Recording) -> list[str]:
    """What the reader said about ``rec``'s temperature column (:data:`TEMPERATURE_NOTE`), if anything."""
    note = rec.header.get(TEMPERATURE_NOTE)
    return [note] if note else []
