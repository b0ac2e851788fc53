"""What a fitted estimator was trained on, and whether new windows lie inside it.

A model learns a prior from its training windows: the devices (their bias spread), the
sample rate (the noise per sample and, for OFBENet, the time scale of its filters) and the
window length. ``ofbe-predict`` compares new recordings with this record: a device the model
never saw gets a warning (the gravity-prior then uses the mixture of its devices' priors,
OFBENet its pooled prior); a sample rate outside the trained range is refused unless the
user overrides it, since the model's noise model and filters no longer apply.

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
    """

    devices: tuple[str, ...]
    fs_hz: tuple[float, float] | None
    g_local: tuple[float, float]
    window_length: int
    n_windows: int

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready data."""
        return {"devices": list(self.devices), "fs_hz": None if self.fs_hz is None else list(self.fs_hz),
                "g_local": list(self.g_local), "window_length": self.window_length,
                "n_windows": self.n_windows}

    @classmethod
    def from_dict(cls, data: Any) -> TrainingDomain | None:
        """The record from :meth:`to_dict`'s output; None when ``data`` is not one."""
        try:
            fs = data["fs_hz"]
            return cls(tuple(str(d) for d in data["devices"]),
                       None if fs is None else (float(fs[0]), float(fs[1])),
                       (float(data["g_local"][0]), float(data["g_local"][1])),
                       int(data["window_length"]), int(data["n_windows"]))
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
                          int(np.shape(windows)[1]), int(np.shape(windows)[0]))


def domain_problems(domain: TrainingDomain | None, device: str, fs_hz: float | None
                    ) -> tuple[list[str], list[str]]:
    """How a recording falls outside a model's training domain.

    Parameters
    ----------
    domain
        The model's record (None: nothing to check).
    device
        The recording's device id.
    fs_hz
        Its measured sample rate, Hz.

    Returns
    -------
    refusals, warnings
        Sentences; a refusal means the estimate would rest on a model outside its domain
        (``ofbe-predict --allow-outside-domain`` overrides it).
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
        warns.append(f"device {device!r} is not among the {len(domain.devices)} devices the model was "
                     "trained on: its estimate rests on the other devices' prior, not its own")
    return refusals, warns
