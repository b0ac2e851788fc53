"""Typed recordings: what every raw-format reader returns."""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from datetime import datetime
from functools import cached_property
from pathlib import Path

import numpy as np

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
