"""The paper's convergence criterion for the running mean of one axis.

Running mean m_k of the first k samples; d_k = |m_k − m_{k−1}|; the signal has converged
at the first k where the mean of the last ``window`` values of d is below ``threshold``.
"""

from __future__ import annotations

import numpy as np

PAPER_WINDOW = 40
"""Number of running-mean steps averaged (paper)."""
PAPER_THRESHOLD = 5e-6
"""Threshold on the averaged step, m/s² (paper)."""


def running_mean(x: np.ndarray) -> np.ndarray:
    """Running mean m_k = mean(x[:k]) for k = 1..N.

    Parameters
    ----------
    x
        (N,) samples (any unit).

    Returns
    -------
    ndarray, shape (N,)
    """
    x = np.asarray(x, dtype=np.float64)
    return np.cumsum(x) / np.arange(1, x.shape[0] + 1)


def convergence_index(x: np.ndarray, window: int = PAPER_WINDOW,
                      threshold: float = PAPER_THRESHOLD) -> int:
    """Number of samples after which the running mean of ``x`` has converged.

    Parameters
    ----------
    x
        (N,) one axis, m/s² (the threshold's unit).
    window
        Number of consecutive running-mean steps averaged.
    threshold
        Convergence threshold on the averaged step, same unit as ``x``.

    Returns
    -------
    int
        The first k (number of samples, 1-based) at which the mean of d_{k−window+1..k}
        is below ``threshold``; −1 when the signal never converges.
    """
    m = running_mean(x)
    if m.shape[0] <= window:
        return -1
    d = np.abs(np.diff(m))  # d[j] = d_{j+2}: step from m_{j+1} to m_{j+2}
    c = np.concatenate(([0.0], np.cumsum(d)))
    avg = (c[window:] - c[:-window]) / window  # avg[i] = mean(d[i:i+window]), ends at k=i+window+1
    hits = np.flatnonzero(avg < threshold)
    return int(hits[0] + window + 1) if hits.size else -1
