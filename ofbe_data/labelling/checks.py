"""Plausibility checks that stop a silent wrong label (methods.md §9 and beyond).

Each is a small pure function of a recording's numbers; :mod:`ofbe_data.labelling.labels`
turns their findings into rejections or warnings:

- :func:`norm_problem`: ‖stationary mean‖ far from g_local, with the likely unit or scale
  mistake (``implausible-norm``);
- :func:`level_tilt_deg`: how far a "gravity-aligned" device really is from its nearest axis
  (``not-level`` above the small-angle threshold);
- :func:`rate_problem` and :func:`rate_step`: a sample rate no accelerometer logs at (a time
  unit mistake), one far from the header's nominal rate, or one that changes mid-file;
- :func:`clipped_samples`: a pile-up of identical extreme values (clipping at the logger's
  range) even where the file does not state its range; where the reader gives the recording's
  full scale (the generic csv: declared or inferred), only a pile-up at it counts;
- :func:`mount_error_deg`: the angle between a DUT's measured gravity direction and the one the
  declared mount predicts from the reference (``mount-mismatch``).
"""

from __future__ import annotations

import math

import numpy as np

from ofbe_data.core.geometry import dot3, mul3, norm3, unit
from ofbe_data.io.gravity import G0
from ofbe_data.io.recording import (
    SKIP_EMPTY,
    SKIP_FIELD_COUNT,
    SKIP_NON_INCREASING_TIME,
    SKIP_NON_NUMERIC,
    SKIP_OUT_OF_RANGE,
    ReadDiagnostics,
    median,
)
from ofbe_data.labelling.stationarity import row_sum

MAX_NORM_DEVIATION = 0.3
"""methods.md §9: a stationary mean more than 30 % away from g_local is implausible."""
LEVEL_TOLERANCE_MG = 50.0
"""Tangential gravity leak a level label may carry, mg (the paper's 50 mg contour)."""
MAX_LEVEL_TILT_DEG = math.degrees(math.asin(LEVEL_TOLERANCE_MG / 1000.0))
"""The small-angle threshold (2.866°): beyond it a level label leaks more than 50 mg."""
WARN_LEVEL_TILT_DEG = 2.0
"""An apparent tilt above this (≈ 35 mg) is worth a warning even when the label is kept. One
window cannot tell a tilt from a tangential bias (both turn the mean away from the axis), and
ADXL345 offsets of tens of mg are common, so smaller angles are not flagged."""
RATE_RANGE_HZ = (0.5, 20_000.0)
"""Sample rates outside this range are taken for a time-unit mistake (no MEMS logger is there)."""
MAX_RATE_DEVIATION = 0.5
"""A measured rate more than 50 % from the header's nominal one rejects the recording."""
WARN_RATE_DEVIATION = 0.05
"""More than 5 % from the nominal rate (crystal error is < 0.01 %) is worth a warning."""
CSV_WARN_RATE_DEVIATION = 0.02
"""raw-formats.md: a generic csv whose measured rate is more than 2 % from its
``sample_rate_hz`` gets a warning."""
UNEVEN_STEP_CV = 0.1
"""Sample steps whose standard deviation exceeds this fraction of the median step are
reported as uneven spacing (host-clock stamps); the data is not resampled."""
RATE_STEP_FACTOR = 1.3
"""Blocks of the file whose median sample step differs from the file's by this factor (either
way) show a rate change mid-file."""
MAX_MOUNT_ERROR_DEG = 10.0
"""Mount misalignment is a degree or two; ten means the declared reference_to_sensor is wrong."""

#: Ratios ‖mean‖ / g_local that name a unit or scale mistake, with what it would be.
_KNOWN_MISTAKES: tuple[tuple[float, str], ...] = (
    (1.0 / G0, "values in g declared as m/s2"),
    (G0, "values in m/s² declared as g"),
    (1000.0, "values in mg declared as g"),
    (1000.0 / G0, "values in mg declared as m/s2"),
    (1.0 / 1000.0, "values in g declared as mg"),
    (G0 / 1000.0, "values in m/s² declared as mg"),
)


def likely_mistake(ratio: float, counts: bool = False) -> str:
    """The unit or scale mistake that best explains ``‖mean‖ / g_local = ratio``.

    A known unit confusion within 10 %, else a power-of-two factor (raw counts read with the
    wrong ``lsb_per_g``), else a generic description. ``counts``: the file holds raw counts
    scaled by a stated ``lsb_per_g`` (no unit to confuse), so the scale is what is off
    (a factor of 10 would otherwise read as m/s² declared as g, 9.81).
    """
    if not ratio > 0 or not math.isfinite(ratio):
        return "no signal (all readings zero or not finite)"
    if counts:
        k = round(math.log2(ratio))
        exact = f"2^{k} = {2.0 ** k:g}" if k != 0 and abs(math.log2(ratio) - k) < 0.1 else f"{ratio:.3g}"
        return (f"counts scaled with the wrong lsb_per_g (the readings come out {exact} times too "
                f"{'large' if ratio > 1 else 'small'}: lsb_per_g looks {ratio:.3g} times too "
                f"{'small' if ratio > 1 else 'large'}; check the range and resolution of the logger)")
    for factor, what in _KNOWN_MISTAKES:
        if abs(math.log(ratio / factor)) < math.log(1.1):
            return what
    for scale, declared in ((G0, "m/s2"), (1.0, "g")):
        k = round(math.log2(ratio * scale))
        if k >= 6 and abs(math.log2(ratio * scale) - k) < 0.1:
            return (f"raw counts declared as {declared} (about {2 ** k} counts per g: declare counts and "
                    "lsb_per_g)")
    k = round(math.log2(ratio))
    if k != 0 and abs(math.log2(ratio) - k) < 0.1:
        return (f"counts scaled with the wrong lsb_per_g (off by 2^{k} = {2.0 ** k:g}: check the "
                "range and resolution of the logger)")
    return "a unit or scale mistake, or a sensor that is not at rest"


def norm_problem(mean: np.ndarray, g: float, max_deviation: float = MAX_NORM_DEVIATION,
                 counts: bool = False) -> str | None:
    """Why a stationary mean cannot be a resting accelerometer's reading, or None.

    Parameters
    ----------
    mean
        (3,) mean specific force over the stationary segment, m/s².
    g
        Local gravity, m/s².
    max_deviation
        Largest accepted ``|‖mean‖ / g − 1|``.
    counts
        The readings are raw counts scaled by a stated ``lsb_per_g`` (see :func:`likely_mistake`).
    """
    norm = float(norm3(np.asarray(mean, dtype=np.float64)))
    ratio = norm / g
    if abs(ratio - 1.0) <= max_deviation:
        return None
    return (f"‖mean‖ = {norm:.4g} m/s² is {ratio:.3g} × g_local ({g:.4f} m/s²), more than "
            f"{max_deviation:.0%} away: likely {likely_mistake(ratio, counts)}")


def typical_reading(acc: np.ndarray) -> np.ndarray:
    """A reading whose norm is the recording's median norm (robust to taps and motion)."""
    norms = np.sqrt(np.sum(acc * acc, axis=1))
    return np.array([median(norms), 0.0, 0.0]) if norms.size else np.zeros(3)


def typical_norm_problem(acc: np.ndarray, g: float, max_deviation: float = MAX_NORM_DEVIATION,
                         counts: bool = False) -> str | None:
    """``norm_problem(typical_reading(acc), g, max_deviation)``, mostly without the median.

    The accepted norms are one interval (the test is monotone in the norm): when both ends
    of a slightly narrower interval pass and at most (n − 1) // 2 readings lie below it and
    at most as many above it, both middle elements of the sorted norms, and so the median,
    lie inside. That takes a few counts over the squared norms (bounds chosen so that the
    rounded square root keeps the side), where the median takes a partition. Anything else
    (NaN, a band too narrow to call) computes the median.
    """
    acc = np.asarray(acc, dtype=np.float64)
    if acc.ndim == 2 and acc.shape[0] and _median_norm_accepted(acc, g, max_deviation):
        return None
    return norm_problem(typical_reading(acc), g, max_deviation, counts)


def _median_norm_accepted(acc: np.ndarray, g: float, max_deviation: float) -> bool:
    """True when the median row norm of ``acc`` certainly passes :func:`norm_problem`."""
    lo, hi = g * (1.0 - max_deviation) * (1.0 + 1e-9), g * (1.0 + max_deviation) * (1.0 - 1e-9)
    if not (0.0 <= lo <= hi) or any(norm_problem(np.array([b, 0.0, 0.0]), g, max_deviation) is not None
                                    for b in (lo, hi)):
        return False
    lo2, hi2 = lo * lo, hi * hi  # sqrt(s) >= lo whenever s >= lo2; sqrt(s) <= hi whenever s <= hi2
    while math.sqrt(lo2) < lo:
        lo2 = math.nextafter(lo2, math.inf)
    while math.sqrt(hi2) > hi:
        hi2 = math.nextafter(hi2, -math.inf)
    s = row_sum(acc * acc)  # the squared norms with the bits np.sum(axis=1) gives them
    if math.isnan(float(s.max())):
        return False
    half = (s.shape[0] - 1) // 2
    return int(np.count_nonzero(s < lo2)) <= half and int(np.count_nonzero(s > hi2)) <= half


def level_tilt_deg(mean: np.ndarray, axis: np.ndarray) -> float:
    """Angle between the measured gravity direction and the nearest signed axis, degrees."""
    c = float(np.clip(abs(dot3(unit(mean), np.asarray(axis, dtype=np.float64))), -1.0, 1.0))
    return math.degrees(math.acos(c))


def rate_problem(fs_hz: float, nominal_hz: float | None, warn_deviation: float = WARN_RATE_DEVIATION
                 ) -> tuple[str, bool] | None:
    """A measured sample rate that is wrong, as (description, reject?), or None.

    Rejected: outside :data:`RATE_RANGE_HZ` (a time-unit mistake), or more than
    :data:`MAX_RATE_DEVIATION` from the header's nominal rate. Warned: more than
    ``warn_deviation`` from it (default :data:`WARN_RATE_DEVIATION`; the generic csv format
    warns at :data:`CSV_WARN_RATE_DEVIATION`).
    """
    lo, hi = RATE_RANGE_HZ
    if not lo <= fs_hz <= hi:
        hint = "time in s declared as ms or µs?" if fs_hz > hi else "time in ms or µs declared as s?"
        return (f"measured sample rate {fs_hz:.4g} Hz is outside {lo:g}–{hi:g} Hz ({hint})", True)
    if nominal_hz:
        dev = fs_hz / nominal_hz - 1.0
        text = f"measured sample rate {fs_hz:.4g} Hz is {dev:+.1%} from the nominal {nominal_hz:g} Hz"
        if abs(dev) > MAX_RATE_DEVIATION:
            return text + " (wrong time unit, or the wrong device's file?)", True
        if abs(dev) > warn_deviation:
            return text, False
    return None


def rate_step(t: np.ndarray, block: int = 500, median_step: float | None = None,
              ) -> tuple[int, float, float] | None:
    """A change of sample rate inside a recording, as (first sample of the changed block, rate
    before, rate after) in Hz, or None.

    The file is cut into blocks of ``block`` samples; unless every block's median step is
    within :data:`RATE_STEP_FACTOR` of the whole file's, the first block whose median differs
    from the first block's by that factor marks the change (gaps from lost samples are single
    long steps and do not move a block's median).
    ``median_step`` is ``np.median(np.diff(t))`` when the caller has it
    (:attr:`~ofbe_data.io.recording.Recording.median_step_s`).
    """
    t = np.asarray(t, dtype=np.float64)
    if t.size < 2 * block:
        return None
    steps = np.diff(t)
    overall = median(steps) if median_step is None else median_step
    if not overall > 0:
        return None
    n = steps.size // block
    blocks = steps[: n * block].reshape(n, block)
    if _medians_within(blocks, overall):
        return None
    medians = np.median(blocks, axis=1)
    # against the file's first block: the whole file's median is the later rate when the
    # later part is longer, and would put the change at the first block, backwards
    ratio = medians / (medians[0] if medians[0] > 0 else overall)
    off = np.flatnonzero((ratio > RATE_STEP_FACTOR) | (ratio < 1.0 / RATE_STEP_FACTOR))
    if off.size == 0:
        return None
    k = int(off[0])
    before = float(np.median(medians[:k])) if k else overall
    return k * block, 1.0 / before, 1.0 / float(medians[k])


def _medians_within(blocks: np.ndarray, overall: float) -> bool:
    """True when every row's median is certainly within :data:`RATE_STEP_FACTOR` of
    ``overall`` (so :func:`rate_step` finds no change), by counting instead of sorting.

    A row's median takes its sorted elements at (b − 1) // 2 and b // 2: when fewer than
    ⌈b/2⌉ elements lie above a bound, both are at most it (likewise below). The bounds sit a
    relative 1e-12 inside the factor, so that no rounding of ``median / overall`` can cross
    it; a row near the limit makes this False, and the medians are then computed.
    """
    b = blocks.shape[1]
    need = b - b // 2
    hi = overall * RATE_STEP_FACTOR * (1.0 - 1e-12)
    lo = overall * (1.0 / RATE_STEP_FACTOR) * (1.0 + 1e-12)
    for beyond in (blocks > hi, blocks < lo):
        # the whole count bounds every row's (gaps are a few long steps in the whole file)
        if np.count_nonzero(beyond) >= need and np.any(np.count_nonzero(beyond, axis=1) >= need):
            return False
    return True


MIN_CLIP_LEVELS = 5
"""Distinct values an axis needs before a pile-up at its extreme is taken for clipping: with
fewer (a coarse sensor, a quiet one), which level holds more samples is set by where the
quantisation thresholds fall, not by a range."""
MOSTLY_CLIPPED = 0.9
"""Share of an axis' samples at its extreme from which an axis of few levels counts as clipped
while the other axes vary (an unclipped quiet axis piles up there only with σ ≲ 0.15 LSB)."""
MIN_CLIP_RATIO = 2.0
"""A clipped extreme holds at least this many times the samples of the value next to it (a
clip 3σ out of a noise spanning many levels gives about 3, nearer the mean far more)."""


def without_repeats(x: np.ndarray) -> np.ndarray:
    """(M, 3) ``x`` without the samples equal to the one before (an oversampling logger writes
    each reading several times, which would multiply every count)."""
    x = np.asarray(x, dtype=np.float64)
    if x.shape[0] < 2:
        return x
    keep = _repeats_dropped(np.ascontiguousarray(x.T))
    return x if keep is None else x[keep]


def _repeats_dropped(columns: np.ndarray) -> np.ndarray | None:
    """The samples to keep of ``x`` given as its contiguous columns (``x.T``, (k, M), M ≥ 2):
    the mask ``keep[0] = True``, ``keep[1:] = np.any(x[1:] != x[:-1], axis=1)``, or None when it
    keeps every sample. One comparison per column over contiguous values, the columns' results
    or-ed together: the same booleans as the row-wise ``any`` (False for no column)."""
    keep = np.ones(columns.shape[1], dtype=bool)
    changed = keep[1:]
    if columns.shape[0] == 0:
        changed[:] = False
        return keep
    np.not_equal(columns[0, 1:], columns[0, :-1], out=changed)
    for col in columns[1:]:
        changed |= col[1:] != col[:-1]
    return None if changed.all() else keep


def clipped_samples(x: np.ndarray, min_count: int = 5, min_fraction: float = 0.01,
                    bounds: tuple[np.ndarray, np.ndarray] | None = None,
                    ) -> tuple[int, int, float, bool] | None:
    """Samples piled up at an axis' extreme value (clipping), as (count, axis, value, whole), or None.

    A clipped axis reads its limit again and again: the extreme value then occurs more often
    (:data:`MIN_CLIP_RATIO` times) than the value next to it. Noise instead thins out towards
    its extremes, so its largest value is rarer than the next one. Repeated samples
    (:func:`without_repeats`) are counted once. An axis with fewer than :data:`MIN_CLIP_LEVELS`
    distinct values (a coarse or quiet sensor) is judged clipped only when its extreme holds
    :data:`MOSTLY_CLIPPED` of its samples while every other axis varies over that many values; one that
    holds a single value for the whole segment while the others vary so is clipped (or stuck)
    as a whole: ``whole`` True.

    Parameters
    ----------
    x
        (N, 3) readings of the stationary segment.
    min_count, min_fraction
        The extreme must occur at least this often (and in this fraction of the samples).
    bounds
        Where a reading can be at the range (:class:`~ofbe_data.io.recording.FullScale`'s
        ``(low, high)``, (3,) each): a pile-up at an axis' high end counts only at ``high[k]`` or
        above, one at its low end only at ``low[k]`` or below; an axis with neither end there is
        not examined. None: every extreme counts (the segment alone is judged).
    """
    x = np.asarray(x, dtype=np.float64)
    columns = np.ascontiguousarray(x.T)  # contiguous columns: the counts and extremes are exact either way
    if x.shape[0] >= 2:  # without_repeats(x), on the columns
        keep = _repeats_dropped(columns)
        if keep is not None:
            columns = columns[:, keep]
    n = columns.shape[1]
    need = max(min_count, min_fraction * n)
    for k in range(columns.shape[0]):
        col = columns[k]
        if col.size == 0:
            continue
        hi, lo = col.max(), col.min()
        ends = (True, True) if bounds is None else (bool(hi >= bounds[1][k]), bool(lo <= bounds[0][k]))
        if not any(ends):
            continue
        if hi == lo and np.isfinite(hi) and n >= need:
            if _others_vary(columns, k):
                return n, k, float(hi), True
            continue
        if not (np.isfinite(hi) and np.isfinite(lo)) or hi == 0.0 or lo == 0.0:
            # NaN, infinities or a signed zero at an end: np.unique's own grouping decides
            found = _clipped_by_unique(col, need, ends)
        else:
            found = _clipped_at_ends(col, hi, lo, need, ends)
        if found is None:
            continue
        mostly = found[0] >= MOSTLY_CLIPPED * n and _others_vary(columns, k)
        if mostly or np.unique(col).size >= MIN_CLIP_LEVELS:
            return found[0], k, found[1], False
    return None


def _others_vary(columns: np.ndarray, k: int) -> bool:
    """Whether every axis but ``k`` takes :data:`MIN_CLIP_LEVELS` distinct values or more: the
    sensor's noise spans many levels, so an axis held at (mostly) one value is clipped."""
    return all(np.unique(columns[j]).size >= MIN_CLIP_LEVELS for j in range(columns.shape[0]) if j != k)


def _clipped_by_unique(col: np.ndarray, need: float, ends: tuple[bool, bool] = (True, True),
                       ) -> tuple[int, float] | None:
    """A pile-up at the high end (when ``ends[0]``), else at the low end (``ends[1]``), of one
    axis' values, as (count, value), by :func:`np.unique`'s grouping."""
    values, counts = np.unique(col, return_counts=True)
    if values.size < 2:
        return None
    for end, neighbour in ((e, nb) for (e, nb), on in zip(((-1, -2), (0, 1)), ends, strict=True) if on):
        c = int(counts[end])
        if c >= need and c > MIN_CLIP_RATIO * counts[neighbour]:
            return c, float(values[end])
    return None


def _clipped_at_ends(col: np.ndarray, hi: float, lo: float, need: float,
                     ends: tuple[bool, bool] = (True, True)) -> tuple[int, float] | None:
    """:func:`_clipped_by_unique` for finite values without a zero at either end: the counts
    of the extremes and of the values next to them, without sorting."""
    if hi == lo:
        return None
    for value, beyond in ((v, b) for (v, b), on in zip(((hi, col < hi), (lo, col > lo)), ends, strict=True)
                          if on):
        c = int(np.count_nonzero(col == value))
        if c < need:
            continue
        rest = col[beyond]
        nxt = rest.max() if value == hi else rest.min()
        if c > MIN_CLIP_RATIO * int(np.count_nonzero(col == nxt)):
            return c, float(value)
    return None


def mount_error_deg(dut_mean: np.ndarray, ref_mean: np.ndarray, reference_to_sensor: np.ndarray) -> float:
    """Angle between a DUT's measured gravity direction and ``N·û_ref``, degrees."""
    predicted = mul3(np.asarray(reference_to_sensor, dtype=np.float64), unit(ref_mean))
    c = float(np.clip(dot3(unit(dut_mean), unit(predicted)), -1.0, 1.0))
    return math.degrees(math.acos(c))


_SKIP_WORDS = {
    SKIP_FIELD_COUNT: "with the wrong number of fields",
    SKIP_NON_NUMERIC: "not numeric",
    SKIP_EMPTY: "empty",
    SKIP_OUT_OF_RANGE: "out of range",
    SKIP_NON_INCREASING_TIME: ("with a time stamp that repeats or runs backwards (duplicated lines, or rows "
                               "not in time order: a file sorted by another column is read in time order "
                               "with sort_by_time: true; the file itself is never changed)"),
}
"""How a garbled-file rejection names each kind of skipped line."""
_SORTED_TIME_WORDS = ("with a time stamp that repeats an earlier one (sort_by_time: true is set, so the rows "
                      "are read in time order and none runs backwards: duplicated lines, or a clock coarser "
                      "than the sample period; remove the duplicated lines, or log the time with more "
                      "digits; the file itself is never changed)")
"""Their words for a file already read in time order (sorting again would change nothing)."""


def skipped_lines_problem(diagnostics: ReadDiagnostics, max_fraction: float,
                          header: dict[str, str] | None = None) -> str | None:
    """Why a file skipped too many of its data lines (``garbled``), naming each kind, or None.

    Parameters
    ----------
    diagnostics
        The reader's account of the file.
    max_fraction
        Largest fraction of the data lines that may be skipped.
    header
        The recording's header: ``sort_by_time: "true"`` (a generic csv read in time order)
        words the dropped time stamps as repeats, without advising ``sort_by_time``.
    """
    d = diagnostics
    skipped = len(d.skipped)
    if not (d.lines_read and skipped / d.lines_read > max_fraction):
        return None
    words = _SKIP_WORDS
    if (header or {}).get("sort_by_time") == "true":
        words = {**_SKIP_WORDS, SKIP_NON_INCREASING_TIME: _SORTED_TIME_WORDS}
    what = "; ".join(f"{n} {words.get(kind, kind)}"
                     for kind, n in sorted(d.skipped_by_kind.items(), key=lambda kv: (-kv[1], kv[0])))
    share = skipped / d.lines_read
    return f"{skipped} of {d.lines_read} data lines skipped ({share:.2%} > {max_fraction:.2%}): {what}"
