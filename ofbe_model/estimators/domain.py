"""What a fitted estimator was trained on, and whether new windows lie inside it.

A model learns a prior from its training windows: the devices (their bias spread), the
sample rate (the noise per sample and, for OFBENet, the time scale of its filters), the
orientations (the gravity directions it saw) and the window length. ``ofbe-predict`` compares
new recordings with this record and refuses, unless the user overrides it, a device the model
never saw (its estimate would rest on the other devices' bias, wrong by their spread: 0.4 m/s²
was measured), a sample rate outside the trained range (the noise model and filters no longer
apply) and a gravity direction farther than :data:`DIRECTION_TOLERANCE_DEG` from every
training window's (a model trained level knows nothing of a tilted board).

The record is saved with the model (the gravity-prior's JSON, OFBENet's sidecar) and is
``None`` for models saved before it existed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

RATE_TOLERANCE = 0.1
"""Relative margin around the trained sample-rate range inside which a rate is in domain."""
DIRECTION_TOLERANCE_DEG = 15.0
"""A window's gravity direction within this angle of a training window's is in domain."""
MAX_DIRECTIONS = 512
"""Most training directions kept in the record (an even, deterministic subsample)."""


@dataclass(frozen=True)
class TrainingDomain:
    """The training data of a fitted estimator, in brief.

    Attributes
    ----------
    devices
        Device ids of the training windows, sorted.
    fs_hz
        (lowest, highest) measured sample rate of the training windows, Hz; None when the
        training meta had no ``fs_hz``.
    g_local
        (lowest, highest) local gravity of the training windows, m/s².
    window_length
        Samples per training window.
    n_windows
        Training windows.
    directions
        (K, 3) unit gravity directions (window means, normalised, rounded to 1e-3, unique,
        at most :data:`MAX_DIRECTIONS`) of the training windows; None in records written
        before ofbe kept them.
    """

    devices: tuple[str, ...]
    fs_hz: tuple[float, float] | None
    g_local: tuple[float, float]
    window_length: int
    n_windows: int
    directions: tuple[tuple[float, float, float], ...] | None = None

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready data."""
        out: dict[str, Any] = {"devices": list(self.devices),
                               "fs_hz": None if self.fs_hz is None else list(self.fs_hz),
                               "g_local": list(self.g_local), "window_length": self.window_length,
                               "n_windows": self.n_windows}
        if self.directions is not None:
            out["directions"] = [list(d) for d in self.directions]
        return out

    @classmethod
    def from_dict(cls, data: Any) -> TrainingDomain | None:
        """The record from :meth:`to_dict`'s output; None when ``data`` is not one."""
        try:
            fs = data["fs_hz"]
            dirs = data.get("directions")
            return cls(tuple(str(d) for d in data["devices"]),
                       None if fs is None else (float(fs[0]), float(fs[1])),
                       (float(data["g_local"][0]), float(data["g_local"][1])),
                       int(data["window_length"]), int(data["n_windows"]),
                       None if dirs is None else tuple((float(a), float(b), float(c)) for a, b, c in dirs))
        except (TypeError, KeyError, IndexError, ValueError):
            return None

    def describe(self) -> str:
        """One line: what the model was trained on."""
        devices = ", ".join(self.devices[:6]) + (f" and {len(self.devices) - 6} more" if len(self.devices) > 6
                                                 else "")
        rate = "" if self.fs_hz is None else (
            f", {self.fs_hz[0]:.4g} Hz" if abs(self.fs_hz[1] - self.fs_hz[0]) < 0.01 * self.fs_hz[0]
            else f", {self.fs_hz[0]:.4g}–{self.fs_hz[1]:.4g} Hz")
        return f"{self.n_windows} windows of {self.window_length} samples from {devices}{rate}"


def domain_of(windows: np.ndarray, meta: pd.DataFrame) -> TrainingDomain:
    """The training domain of windows (N, T, 3) with their meta (``device``, ``g_local`` and,
    when present, ``fs_hz``)."""
    fs = None
    if "fs_hz" in meta.columns and len(meta):
        rates = meta["fs_hz"].to_numpy(dtype=np.float64)
        fs = (round(float(np.min(rates)), 6), round(float(np.max(rates)), 6))
    g = meta["g_local"].to_numpy(dtype=np.float64)
    return TrainingDomain(tuple(sorted({str(d) for d in meta["device"]})), fs,
                          (round(float(g.min()), 9), round(float(g.max()), 9)) if g.size else (0.0, 0.0),
                          int(np.shape(windows)[1]), int(np.shape(windows)[0]), training_directions(windows))


def window_direction(window: np.ndarray) -> np.ndarray:
    """(3,) unit direction of a window's mean specific force ((T, 3) m/s²)."""
    m = np.asarray(window, dtype=np.float64).mean(axis=0)
    n = float(np.sqrt(m @ m))
    return m / n if n > 0 else np.array([0.0, 0.0, 1.0])


def training_directions(windows: np.ndarray) -> tuple[tuple[float, float, float], ...]:
    """The record's directions of (N, T, 3) windows: unique rounded unit means, an even subsample
    of at most :data:`MAX_DIRECTIONS` of them in sorted order."""
    w = np.asarray(windows, dtype=np.float64)
    if w.shape[0] == 0:
        return ()
    m = w.mean(axis=1)
    u = m / np.maximum(np.sqrt(np.sum(m * m, axis=1, keepdims=True)), np.finfo(float).tiny)
    unique = sorted({(round(float(a), 3), round(float(b), 3), round(float(c), 3)) for a, b, c in u})
    step = max(1, -(-len(unique) // MAX_DIRECTIONS))
    return tuple(unique[::step])


def domain_problems(domain: TrainingDomain | None, device: str, fs_hz: float | None,
                    direction: np.ndarray | None = None) -> tuple[list[str], list[str]]:
    """How a recording falls outside a model's training domain.

    Parameters
    ----------
    domain
        The model's record (None: nothing to check).
    device
        The recording's device id.
    fs_hz
        Its measured sample rate, Hz.
    direction
        (3,) unit gravity direction of its window (:func:`window_direction`), or None.

    Returns
    -------
    refusals, warnings
        Sentences; a refusal means the estimate would rest on a model outside its domain
        (``ofbe-predict --allow-outside-domain`` overrides it). ``warnings`` is kept for callers;
        every finding is now a refusal.
    """
    if domain is None:
        return [], []
    refusals, warns = [], []
    if domain.fs_hz is not None and fs_hz is not None and np.isfinite(fs_hz):
        lo, hi = domain.fs_hz
        if not lo / (1 + RATE_TOLERANCE) <= fs_hz <= hi * (1 + RATE_TOLERANCE):
            trained = f"{lo:.4g} Hz" if abs(hi - lo) < 0.01 * lo else f"{lo:.4g}–{hi:.4g} Hz"
            refusals.append(f"sample rate {fs_hz:.4g} Hz is outside what the model was trained on "
                            f"({trained}, ±{RATE_TOLERANCE:.0%})")
    if device not in domain.devices:
        refusals.append(f"device {device!r} is not among the {len(domain.devices)} devices the model was "
                        "trained on: its estimate would rest on the other devices' bias, not its own")
    if domain.directions and direction is not None and np.all(np.isfinite(direction)):
        trained = np.asarray(domain.directions, dtype=np.float64)
        cosine = float(np.max(trained @ np.asarray(direction, dtype=np.float64)))
        angle = float(np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0))))
        if angle > DIRECTION_TOLERANCE_DEG:
            shown = ", ".join(f"{v:.3f}" for v in direction)
            refusals.append(f"gravity direction ({shown}) is {angle:.1f}° from every training window's "
                            f"(at most {DIRECTION_TOLERANCE_DEG:g}°)")
    return refusals, warns
