"""Static detection by moving variance, in the spirit of imu_tk's static detector.

imu_tk marks a sample static when the variance norm of the accelerometer over a window
centred on it is below ``k · σ²_init``, with σ²_init measured over a known-static start.
Here no part of a recording is known static in advance, so the noise floor is the median
of the moving variance over the candidate segment (robust: motion must fill more than half
of it to move the median), and an absolute ceiling catches a segment that moves throughout.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ofbe_data.io.recording import median

BLOCK = 1 << 16
"""Rows taken at a time by the running sums below when no (N, 3) buffer is given: the same
additions in the same order, with temporaries of a block, not of the recording (issue 36)."""


@dataclass(frozen=True)
class StaticParams:
    """Parameters of the static detector.

    Attributes
    ----------
    window_s
        Length of the moving window, s.
    variance_factor
        A window is moving when its variance norm exceeds this many times the segment's
        median variance norm (imu_tk's k).
    max_std_mps2
        A window is moving when the square root of its variance norm exceeds this, m/s²,
        whatever the median (about 30 mg: far above MEMS noise, far below handling).
    """

    window_s: float = 1.0
    variance_factor: float = 4.0
    max_std_mps2: float = 0.3


def _rows_of_three(x: np.ndarray) -> bool:
    """Whether ``x`` is a C-ordered float64 (N ≥ 1, 3) array, the layout whose reductions
    :func:`column_mean` and :func:`row_sum` reproduce."""
    return (x.ndim == 2 and x.shape[1] == 3 and x.shape[0] > 0 and x.dtype == np.float64
            and x.flags.c_contiguous)


def column_mean(x: np.ndarray, scratch: np.ndarray | None = None) -> np.ndarray:
    """``x.mean(axis=0)`` with the same bits, for an (N, 3) array, at a fraction of the cost.

    numpy sums the columns of such an array row by row: for each column a sequential sum
    that starts at 0, with the overhead of a ufunc loop per row. A cumulative sum makes the
    same additions in the same order (+ 0.0 turns the −0.0 of an all-(−0.0) column into the
    +0.0 that starting at 0 gives), and numpy divides the sum by N. Other shapes and layouts
    are left to numpy.

    Parameters
    ----------
    x
        (N, 3) array.
    scratch
        Optional (N, 3) float64 buffer for the cumulative sums (overwritten).
    """
    if not _rows_of_three(x):
        return x.mean(axis=0)
    if scratch is not None:
        return (running_sums(x, scratch)[-1] + 0.0) / x.shape[0]
    last = np.zeros(3)
    for a in range(0, x.shape[0], BLOCK):  # the running sum's last row, a block at a time
        y = x[a:a + BLOCK].copy()
        if a:  # out[i] = out[i − 1] + x[i] across the block's start, as in one pass
            y[0] += last
        last = running_sums(y)[-1]
    return (last + 0.0) / x.shape[0]


def running_sums(x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """``np.cumsum(x, axis=0, out=out)`` with the same bits, for an (N, 3) array in fewer passes.

    A cumulative sum is sequential per column: ``out[i] = out[i − 1] + x[i]``, from
    ``out[0] = x[0]``. Two columns viewed as one complex128 column run as one cumulative sum
    whose complex additions are those two real additions, side by side (complex addition adds
    the real parts and the imaginary parts, nothing else), so the loop makes one pass for the
    first two columns and one for the third. Other shapes and layouts are left to numpy.

    Parameters
    ----------
    x
        (N, 3) array.
    out
        Optional (N, 3) float64 buffer for the result (overwritten).

    Returns
    -------
    ndarray, shape (N, 3)
        ``out`` when given.
    """
    if not (_rows_of_three(x) and (out is None or (out.shape == x.shape and out.dtype == np.float64
                                                   and out.flags.c_contiguous
                                                   and not np.may_share_memory(x, out)))):
        return np.cumsum(x, axis=0, out=out)
    if out is None:
        out = np.empty(x.shape)
    np.cumsum(x[:, :2].view(np.complex128)[:, 0], out=out[:, :2].view(np.complex128)[:, 0])
    np.cumsum(x[:, 2], out=out[:, 2])
    return out


def row_sum(x: np.ndarray) -> np.ndarray:
    """``x.sum(axis=1)`` with the same bits for an (N, 3) array: numpy adds the three as
    ``((0 + x₀) + x₁) + x₂``; spelt out, the per-row loop overhead goes away."""
    if not _rows_of_three(x):
        return x.sum(axis=1)
    out = x[:, 0] + x[:, 1]
    out += x[:, 2]
    out += 0.0
    return out


def centred_sums(acc: np.ndarray, mean: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``acc``'s column mean (:func:`column_mean`, or ``mean`` when the caller has it) and the
    running sums of ``acc − mean`` with a leading row of zeros, (N + 1, 3): where
    :func:`moving_variance_norm` and the tap high-pass
    (:func:`ofbe_data.labelling.sync.highpass`) both start over a whole recording, so one
    computation serves both, with the same bits."""
    x = np.asarray(acc, dtype=np.float64)
    c = np.empty((x.shape[0] + 1,) + x.shape[1:])
    if mean is None:
        mean = column_mean(x, c[1:] if x.shape[0] else None)
    c[0] = 0.0
    for a in range(0, x.shape[0], BLOCK):  # x − mean a block at a time, the sums going on across blocks
        d = x[a:a + BLOCK] - mean
        if a:
            d[0] += c[a]
        running_sums(d, c[1 + a:1 + a + d.shape[0]])
    return mean, c


def moving_variance_norm(acc: np.ndarray, window: int, mean: np.ndarray | None = None,
                         sums: np.ndarray | None = None) -> np.ndarray:
    """Sum over axes of the variance of ``acc`` in a sliding window.

    Parameters
    ----------
    acc
        (N, 3) specific force, m/s².
    window
        Window length, samples (≥ 2, ≤ N).
    mean
        ``acc.mean(axis=0)`` when the caller has it (:func:`column_mean`), else computed here.
    sums
        With ``mean``, the running sums of ``acc − mean`` from :func:`centred_sums` (read only).

    Returns
    -------
    ndarray, shape (N − window + 1,)
        (m/s²)²; entry i covers samples i … i + window − 1.
    """
    x = np.asarray(acc, dtype=np.float64)
    n, k = x.shape
    # running sums of x − mean (centred: well conditioned) and of its square, with a leading row of
    # zeros, a block of windows at a time: each block's sums go on from the last one's (the
    # operations, and so the bits, are those of the textbook expressions in the comments)
    if mean is None:
        mean, sums = column_mean(x), None
    m = max(n - window + 1, 0)
    out = np.empty(m)
    carry = np.zeros((2, k))  # both running sums at the block's first window
    for a in range(0, m, BLOCK):
        b = min(m, a + BLOCK)
        d = x[a:b + window - 1] - mean
        c = np.empty((2, d.shape[0] + 1, k))
        c[:, 0] = carry
        sq = d * d
        if a:  # out[i] = out[i − 1] + x[i] across the block's start, as in one pass
            sq[0] += carry[1]
            d[0] += carry[0]
        running_sums(sq, c[1, 1:])
        c1 = sums[a:b + window] if sums is not None else c[0]
        if sums is None:
            running_sums(d, c[0, 1:])
        carry = np.stack((c1[b - a], c[1, b - a]))
        s1 = c1[window:] - c1[:b - a]
        s2 = c[1, window:] - c[1, :b - a]
        # var = (s2 − s1·s1 / window) / (window − 1)
        np.multiply(s1, s1, out=s1)
        s1 /= window
        s2 -= s1
        s2 /= window - 1
        np.maximum(s2, 0.0, out=s2)
        out[a:b] = row_sum(s2)
    return out


@dataclass(frozen=True)
class StaticCheck:
    """Outcome of the static detector on one segment.

    Attributes
    ----------
    static
        (N,) bool, True for samples covered by no moving window.
    noise_floor
        Median variance norm, (m/s²)².
    threshold
        Variance norm above which a window counts as moving, (m/s²)².
    peak
        Largest variance norm in the segment, (m/s²)².
    """

    static: np.ndarray
    noise_floor: float
    threshold: float
    peak: float

    @property
    def moving_samples(self) -> int:
        """Number of samples not marked static."""
        return int((~self.static).sum())


def _window(n: int, fs_hz: float, params: StaticParams) -> int:
    """The detector's window length, samples."""
    return int(np.clip(round(params.window_s * fs_hz), 2, max(n, 2)))


def check_static(acc: np.ndarray, fs_hz: float, params: StaticParams = StaticParams(),
                 mean: np.ndarray | None = None, sums: np.ndarray | None = None) -> StaticCheck:
    """Mark the samples of a segment that lie in no moving window.

    Parameters
    ----------
    acc
        (N, 3) specific force, m/s².
    fs_hz
        Sample rate, Hz (sets the window length in samples).
    params
        Detector parameters.
    mean, sums
        ``acc.mean(axis=0)`` when the caller has it (saves a pass), and with it the running sums
        of :func:`centred_sums`.

    Returns
    -------
    StaticCheck
    """
    n = int(acc.shape[0])
    window = _window(n, fs_hz, params)
    if n < window:
        return StaticCheck(np.zeros(n, dtype=bool), float("nan"), float("nan"), float("nan"))
    return _static_check(moving_variance_norm(acc, window, mean, sums), n, window, params)


def _static_check(v: np.ndarray, n: int, window: int, params: StaticParams) -> StaticCheck:
    """:func:`check_static` from the moving variance norm ``v`` of its ``n`` samples."""
    floor = median(v)
    threshold = min(params.variance_factor * floor, params.max_std_mps2**2)
    moving = v > threshold
    if not moving.any():  # a still segment: every sample is static
        return StaticCheck(np.ones(n, dtype=bool), floor, float(threshold), float(v.max()))
    # a sample is static when no window that covers it is moving
    cover = np.concatenate(([0], np.cumsum(moving)))
    # sample i is covered by windows lo … hi − 1, lo = clip(i − window + 1, 0, m) and
    # hi = clip(i + 1, 0, m), m = n − window + 1 windows: the gathers cover[hi] − cover[lo]
    # done by slices (lo is 0 for i < window − 1, hi is m for i ≥ m − 1)
    m = v.shape[0]
    hi_cover = np.empty(n, dtype=cover.dtype)
    hi_cover[:m] = cover[1:m + 1]
    hi_cover[m:] = cover[m]
    lo_cover = np.empty(n, dtype=cover.dtype)
    lo_cover[:window - 1] = cover[0]
    lo_cover[window - 1:] = cover[:n - window + 1]
    static = (hi_cover - lo_cover) == 0
    return StaticCheck(static, floor, float(threshold), float(v.max()))


def is_still(acc: np.ndarray, fs_hz: float, params: StaticParams = StaticParams(),
             mean: np.ndarray | None = None) -> bool:
    """``check_static(acc, fs_hz, params).moving_samples == 0``, mostly without its median.

    Nothing moves when the largest variance norm is within both the ceiling and
    ``variance_factor`` times the median. The median is at least a bound when fewer than
    half the values lie below it: one count instead of a partition. Otherwise (motion, or a
    peak too close to call) the detector itself decides.
    """
    n = int(acc.shape[0])
    window = _window(n, fs_hz, params)
    if n < window:
        return n == 0
    v = moving_variance_norm(acc, window, mean)
    if _peak_below_threshold(v, params):
        return True
    return _static_check(v, n, window, params).moving_samples == 0


def _peak_below_threshold(v: np.ndarray, params: StaticParams) -> bool:
    """True when no element of ``v`` can exceed :func:`check_static`'s threshold
    ``min(variance_factor · median(v), max_std_mps2²)``, shown by counting.

    With ``factor · bound ≥ peak`` in floating point and both middle elements of the sorted
    ``v`` at least ``bound`` (at most (n − 1) // 2 elements below it), the median, their mean,
    is at least ``bound`` and the threshold at least the peak: rounding is monotone. A NaN
    makes the peak NaN, and the test False.
    """
    factor = float(params.variance_factor)
    peak = float(v.max())
    if not (factor > 0 and peak <= params.max_std_mps2**2 and math.isfinite(peak)):
        return False
    bound = peak / factor
    while factor * bound < peak:
        bound = math.nextafter(bound, math.inf)
    return int(np.count_nonzero(v < bound)) <= (v.shape[0] - 1) // 2


def longest_run(mask: np.ndarray) -> tuple[int, int]:
    """The longest run of True in a boolean array.

    Parameters
    ----------
    mask
        (N,) bool.

    Returns
    -------
    start, stop
        Half-open sample range; (0, 0) when there is no True.
    """
    m = np.concatenate(([False], np.asarray(mask, dtype=bool), [False]))
    edges = np.flatnonzero(np.diff(m.astype(np.int8)))
    if edges.size == 0:
        return 0, 0
    starts, stops = edges[0::2], edges[1::2]
    k = int(np.argmax(stops - starts))
    return int(starts[k]), int(stops[k])
