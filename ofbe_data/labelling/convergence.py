"""The paper's convergence criterion for the running mean of one axis.

Running mean m_k of the first k samples; d_k = |m_k − m_{k−1}|; the signal has converged
at the first k where the mean of the last ``window`` values of d is below ``threshold``.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ofbe_data.core.errors import OfbeError

PAPER_WINDOW = 40
"""Number of running-mean steps averaged (paper)."""
PAPER_THRESHOLD = 5e-6
"""Threshold on the averaged step, m/s² (paper)."""
REPORT_FORMAT = "ofbe-convergence/1"
"""Format of ``reports/convergence/convergence.json`` (written by ``ofbe-convergence``)."""


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
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    if n <= window:
        return -1
    # every quantity below at index i depends on x[:i + 1] only (running sums), so a prefix
    # gives the same values as the whole; most signals converge early, and the whole is
    # only read when the prefix holds no hit
    length = _FIRST_PREFIX
    while True:
        hit = _first_hit(x[:length], window, threshold)
        if hit >= 0 or length >= n:
            return hit
        length *= 4


_FIRST_PREFIX = 8192
"""Samples :func:`convergence_index` examines first (the paper's convergence is ≈ 4500)."""


def _first_hit(x: np.ndarray, window: int, threshold: float) -> int:
    """:func:`convergence_index` of ``x`` itself (−1 when it holds no hit), written into
    buffers in place: the operations (and so the bits) of the expressions in the comments."""
    n = x.shape[0]
    if n <= window:
        return -1
    m = np.cumsum(x)
    m /= np.arange(1, n + 1)  # running_mean(x)
    c = np.empty(n)  # c = [0, cumsum(d)], d = |diff(m)|: d[j] = d_{j+2}, from m_{j+1} to m_{j+2}
    c[0] = 0.0
    d = np.diff(m)
    np.abs(d, out=d)
    np.cumsum(d, out=c[1:])
    avg = c[window:] - c[:-window]
    avg /= window  # avg[i] = mean(d[i:i+window]), ends at k=i+window+1
    below = avg < threshold
    i = int(np.argmax(below))
    return i + window + 1 if below[i] else -1


def step_average(x: np.ndarray, window: int = PAPER_WINDOW) -> np.ndarray:
    """The criterion's statistic: mean of the last ``window`` running-mean steps.

    Parameters
    ----------
    x
        (N,) one axis, m/s².
    window
        Number of steps averaged.

    Returns
    -------
    ndarray, shape (N,)
        Element k−1 is the value at k samples (NaN until ``window`` steps exist); the signal
        has converged at the first k where it is below the threshold.
    """
    m = running_mean(x)
    out = np.full(m.shape[0], np.nan)
    if m.shape[0] <= window:
        return out
    c = np.concatenate(([0.0], np.cumsum(np.abs(np.diff(m)))))
    out[window:] = (c[window:] - c[:-window]) / window
    return out


@dataclass(frozen=True)
class AxisConvergence:
    """Convergence indices of one axis over many recordings (samples).

    Attributes
    ----------
    n
        Recordings analysed.
    n_not_converged
        Recordings whose running mean never met the criterion (left out of the statistics).
    mean, std, median, p05, p95, min, max
        Of the converged recordings' indices; NaN when none converged. ``std`` is the
        sample standard deviation (ddof = 1).
    """

    n: int
    n_not_converged: int
    mean: float
    std: float
    median: float
    p05: float
    p95: float
    min: float
    max: float

    def to_dict(self) -> dict[str, float | int]:
        return dataclasses.asdict(self)


def axis_statistics(indices: np.ndarray) -> AxisConvergence:
    """Summary of convergence indices, (N,) int, −1 meaning never converged."""
    idx = np.asarray(indices, dtype=np.int64)
    ok = idx[idx >= 0].astype(np.float64)
    if ok.size == 0:
        nan = float("nan")
        return AxisConvergence(int(idx.size), int(idx.size), nan, nan, nan, nan, nan, nan, nan)
    p05, med, p95 = np.percentile(ok, [5, 50, 95])
    return AxisConvergence(
        n=int(idx.size), n_not_converged=int(idx.size - ok.size), mean=float(ok.mean()),
        std=float(ok.std(ddof=1)) if ok.size > 1 else 0.0, median=float(med), p05=float(p05),
        p95=float(p95), min=float(ok.min()), max=float(ok.max()))


STATISTICS = ("mean", "mean+std", "median", "p95")
"""Statistics a recommendation may be based on."""
AXES = ("x", "y", "z")
"""Axes a recommendation may be based on (the convergence report's, :mod:`ofbe_data.reports.convergence`)."""


def recommend_min_samples(stats: AxisConvergence, statistic: str = "mean", round_to: int = 100) -> int:
    """The recommended fewest samples per label from one axis' convergence statistics.

    The paper takes the mean convergence index of x (≈4500 samples); ``statistic`` allows a
    more conservative choice. The value is rounded up to a multiple of ``round_to``.

    Raises
    ------
    ValueError
        Unknown statistic, or no recording converged.
    """
    value = {"mean": stats.mean, "mean+std": stats.mean + stats.std, "median": stats.median,
             "p95": stats.p95}.get(statistic)
    if value is None:
        raise ValueError(f"statistic: expected one of {', '.join(STATISTICS)}, found {statistic!r}")
    if not np.isfinite(value):
        raise ValueError(f"no recording converged ({stats.n} analysed): nothing to recommend")
    return int(np.ceil(value / round_to) * round_to)


def read_recommendation(path: str | Path) -> int:
    """The recommended fewest samples per label from a ``convergence.json``.

    Raises
    ------
    OfbeError
        Missing or unreadable file, or no recommendation in it.
    """
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise OfbeError(f"{path}: expected a convergence report (run ofbe-convergence), found no such file"
                        ) from None
    except (OSError, json.JSONDecodeError) as exc:
        raise OfbeError(f"{path}: expected a convergence report in JSON, found {exc}") from None
    if not isinstance(doc, dict):
        doc = {}
    value = doc.get("recommended_label_start")
    if doc.get("format") != REPORT_FORMAT or not isinstance(value, int) or value < 2:
        raise OfbeError(f"{path}: expected format {REPORT_FORMAT} with an integer recommended_label_start "
                        f"≥ 2, found format {doc.get('format')!r}, recommended_label_start {value!r}")
    return value
