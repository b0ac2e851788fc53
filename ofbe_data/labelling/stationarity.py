"""Static detection by moving variance, in the spirit of imu_tk's static detector.

imu_tk marks a sample static when the variance norm of the accelerometer over a window
centred on it is below ``k · σ²_init``, with σ²_init measured over a known-static start.
Here no part of a recording is known static in advance, so the noise floor is the median
of the moving variance over the candidate segment (robust: motion must fill more than half
of it to move the median), and an absolute ceiling catches a segment that moves throughout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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


def moving_variance_norm(acc: np.ndarray, window: int) -> np.ndarray:
    """Sum over axes of the variance of ``acc`` in a sliding window.

    Parameters
    ----------
    acc
        (N, 3) specific force, m/s².
    window
        Window length, samples (≥ 2, ≤ N).

    Returns
    -------
    ndarray, shape (N − window + 1,)
        (m/s²)²; entry i covers samples i … i + window − 1.
    """
    x = np.asarray(acc, dtype=np.float64)
    x = x - x.mean(axis=0)  # keeps the cumulative sums well conditioned
    zero = np.zeros((1, x.shape[1]))
    c1 = np.concatenate((zero, np.cumsum(x, axis=0)))
    c2 = np.concatenate((zero, np.cumsum(x * x, axis=0)))
    s1 = c1[window:] - c1[:-window]
    s2 = c2[window:] - c2[:-window]
    var = (s2 - s1 * s1 / window) / (window - 1)
    return np.maximum(var, 0.0).sum(axis=1)


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


def check_static(acc: np.ndarray, fs_hz: float, params: StaticParams = StaticParams()) -> StaticCheck:
    """Mark the samples of a segment that lie in no moving window.

    Parameters
    ----------
    acc
        (N, 3) specific force, m/s².
    fs_hz
        Sample rate, Hz (sets the window length in samples).
    params
        Detector parameters.

    Returns
    -------
    StaticCheck
    """
    n = int(acc.shape[0])
    window = int(np.clip(round(params.window_s * fs_hz), 2, max(n, 2)))
    if n < window:
        return StaticCheck(np.zeros(n, dtype=bool), float("nan"), float("nan"), float("nan"))
    v = moving_variance_norm(acc, window)
    floor = float(np.median(v))
    threshold = min(params.variance_factor * floor, params.max_std_mps2**2)
    moving = v > threshold
    # a sample is static when no window that covers it is moving
    cover = np.concatenate(([0], np.cumsum(moving)))
    lo = np.clip(np.arange(n) - window + 1, 0, v.shape[0])
    hi = np.clip(np.arange(n) + 1, 0, v.shape[0])
    static = (cover[hi] - cover[lo]) == 0
    return StaticCheck(static, floor, float(threshold), float(v.max()))


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
