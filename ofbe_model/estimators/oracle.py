"""The oracle: the posterior mean under the simulator's true device distributions (simulated data
only; the one estimator that reads truth files).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from ofbe_model.estimators.base import LAST, Estimator, EstimatorError, check_inputs, register
from ofbe_model.estimators.common import (
    TRUTH_FORMAT,
    check_fitted,
    device_column,
    g_local_column,
    nearest_axes,
    unit_rows,
    window_means,
)
from ofbe_model.estimators.priors import condition_on_norm

# ----------------------------------------------------------------------------- oracle


@dataclass(frozen=True)
class TruthDevice:
    """A DUT's campaign-level parameters from the simulator's truth files.

    Attributes
    ----------
    A
        (3, 3) effective map ``A_effective`` (sensor map × mount misalignment).
    offset
        (3,) fixed factory offset ``offset_device``, m/s².
    delta_cov
        (3, 3) prior covariance of the per-recording offset change (turn-on + drift),
        diag(turn_on_sigma² + drift_sigma²), (m/s²)².
    noise_var
        (3,) white-noise variance per sample, noise_rms², (m/s²)².
    drift_var
        drift_sigma², (m/s²)²: the in-run drift's variance over a recording.
    """

    A: np.ndarray
    offset: np.ndarray
    delta_cov: np.ndarray
    noise_var: np.ndarray
    drift_var: float


def _truth_device(entry: dict[str, Any], where: str) -> TruthDevice:
    """One ``devices[dev]`` entry of a truth file as a :class:`TruthDevice`."""
    try:
        A = np.asarray(entry["A_effective"], dtype=np.float64)
        offset = np.asarray(entry["offset_device"], dtype=np.float64)
        turn_on = np.asarray(entry["turn_on_sigma"], dtype=np.float64)
        drift = float(entry["drift_sigma"])
        noise = np.asarray(entry["noise_rms"], dtype=np.float64)
    except (KeyError, TypeError, ValueError) as exc:
        raise EstimatorError(f"{where}: expected A_effective, offset_device, turn_on_sigma, drift_sigma, "
                             f"noise_rms, found a problem with {exc}") from None
    if A.shape != (3, 3) or offset.shape != (3,) or turn_on.shape != (3,) or noise.shape != (3,):
        raise EstimatorError(f"{where}: expected A_effective 3×3 and 3-vectors, found shapes {A.shape}, "
                             f"{offset.shape}, {turn_on.shape}, {noise.shape}")
    if abs(np.linalg.det(A)) < 1e-6:
        raise EstimatorError(f"{where}: expected an invertible A_effective, found det {np.linalg.det(A):.3g}")
    return TruthDevice(A, offset, np.diag(turn_on**2 + drift**2), noise**2, drift**2)


def read_truth_devices(truth_dir: str | Path) -> tuple[str, dict[str, TruthDevice]]:
    """The campaign kind and every DUT's device-level parameters from ``<truth_dir>/*.json``.

    Only device-level fields are read (``kind``, ``devices[dev]``): never a recording's
    offset, apparent bias or direction.

    Parameters
    ----------
    truth_dir
        The simulator's truth folder of one campaign (``ofbe-truth/1`` files).

    Returns
    -------
    kind
        The campaign's session kind (``rotated``, ``gravity-aligned``...).
    devices
        ``{device: TruthDevice}`` for every device with an ``A_effective`` (the DUTs).

    Raises
    ------
    EstimatorError
        No such folder, no truth file, a file that is not ``ofbe-truth/1`` JSON, mixed
        kinds, or a device whose parameters differ between files.
    """
    folder = Path(truth_dir)
    if not folder.is_dir():
        raise EstimatorError(f"oracle: expected the simulator's truth folder, found no folder {folder}")
    files = sorted(folder.glob("*.json"))
    if not files:
        raise EstimatorError(f"{folder}: expected {TRUTH_FORMAT} truth files (*.json), found none")
    kind: str | None = None
    devices: dict[str, TruthDevice] = {}
    for path in files:
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise EstimatorError(f"{path}: expected a {TRUTH_FORMAT} JSON truth file, found {exc}") from None
        if not isinstance(data, dict) or data.get("format") != TRUTH_FORMAT:
            found = data.get("format") if isinstance(data, dict) else type(data).__name__
            raise EstimatorError(f"{path}: format: expected {TRUTH_FORMAT!r}, found {found!r}")
        k = data.get("kind")
        if not isinstance(k, str):
            raise EstimatorError(f"{path}: kind: expected a session kind, found {k!r}")
        if kind is not None and k != kind:
            raise EstimatorError(f"{path}: kind: expected {kind!r} like the other truth files, found {k!r}")
        kind = k
        entries = data.get("devices")
        if not isinstance(entries, dict):
            raise EstimatorError(f"{path}: devices: expected an object, found {type(entries).__name__}")
        for d, entry in entries.items():
            if not isinstance(entry, dict) or "A_effective" not in entry:
                continue  # the reference IMU: no A_effective, not a DUT
            dev = _truth_device(entry, f"{path}: devices.{d}")
            old = devices.get(d)
            if old is not None and not (np.allclose(old.A, dev.A, rtol=0, atol=1e-12)
                                        and np.allclose(old.offset, dev.offset, rtol=0, atol=1e-12)):
                raise EstimatorError(f"{path}: devices.{d}: expected the same A_effective and offset_device "
                                     f"as the other truth files (one campaign), found different values")
            devices[d] = dev
    if not devices:
        raise EstimatorError(f"{folder}: expected DUT devices (with A_effective) in the truth files, "
                             f"found none")
    assert kind is not None
    return kind, devices


@register
class Oracle(Estimator):
    """``oracle``: the posterior mean under the simulator's true device distributions.

    Simulated data only: :meth:`fit` reads the campaign's truth folder (``ofbe-truth/1``,
    :func:`read_truth_devices`), keeping per device only the campaign-level parameters: the
    effective map A, the factory offset o, the turn-on and drift spread and the noise. A
    recording's own offset or apparent bias is never read. The simulator's model is
    m = A·u·g + o + δ + n̄ with u the nominal direction and δ ~ N(0, diag(σ_on² + σ_drift²));
    the label is b_app = m − g·u. Per window of mean m of device d:

    - ``gravity-aligned`` campaigns: u is a point mass on the signed axes, so u = the nearest
      signed axis of m and b̂ = m − g·u: the oracle equals ``level-mean`` there (up to the
      noise of the window mean, which nothing can remove).
    - otherwise (orientations spread over the sphere): v = A⁻¹(m − o) = g·u + A⁻¹δ + noise;
      with e = A⁻¹δ ~ N(0, A⁻¹Σ_δA⁻ᵀ) the constraint ‖v − e‖ = g is conditioned on exactly
      as in :func:`condition_on_norm` (at e = 0 its first pass is δ̂ = Σh(‖v‖ − g)/(hᵀΣh + σ²)
      with h = A⁻ᵀv/‖v‖ in δ terms), with σ² = ĥᵀA⁻¹ diag(noise_rms²/T) A⁻ᵀĥ; then
      û = (v − ê)/‖v − ê‖ and b̂ = m − g·û.

    :meth:`predict_std`: sqrt of diag(Σ_post(e) + diag(noise_rms²)/T) (the posterior spread
    of the offset change, approximately mapped, plus the noise of the window mean);
    sqrt(noise_rms²/T + drift_sigma²) on gravity-aligned campaigns (the window's mean bias
    differs from the recording's by the in-run drift, bounded by its spread).

    Parameters
    ----------
    truth_dir
        The simulator's truth folder of the campaign (``raw/<campaign>/_truth``).

    Attributes
    ----------
    kind_
        The campaign's kind.
    devices_
        ``{device: TruthDevice}``.
    """

    name: ClassVar[str] = "oracle"
    order: ClassVar[int] = LAST
    needs_fit: ClassVar[bool] = True

    def __init__(self, truth_dir: str | None = None) -> None:
        self.truth_dir = truth_dir

    def fit(self, windows: np.ndarray, labels: np.ndarray, meta: pd.DataFrame) -> Oracle:
        """Read the truth folder (the windows and labels are not used)."""
        check_inputs(windows, meta, labels)
        if self.truth_dir is None:
            raise EstimatorError("oracle: expected truth_dir (the simulator's truth folder), found None; "
                                 "the oracle exists on simulated data only")
        self.kind_, self.devices_ = read_truth_devices(self.truth_dir)
        self._known(device_column(meta))
        return self

    def _known(self, dev: np.ndarray) -> None:
        missing = sorted(set(dev) - set(self.devices_))
        if missing:
            have = ", ".join(sorted(self.devices_))
            raise EstimatorError(f"oracle: expected devices of the truth folder ({have}), "
                                 f"found {', '.join(missing)}")

    def _posterior(self, windows: np.ndarray, meta: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
        """Estimates (N, 3) m/s² and their standard deviations (N, 3) m/s²."""
        check_inputs(windows, meta)
        check_fitted(self, "devices_")
        dev = device_column(meta)
        self._known(dev)
        n_samples = np.asarray(windows).shape[1]
        m = window_means(windows)
        g = g_local_column(meta)
        est = np.empty_like(m)
        std = np.empty_like(m)
        for d in sorted(set(dev)):
            rows = dev == d
            td = self.devices_[d]
            noise_var = td.noise_var / n_samples
            if self.kind_ == "gravity-aligned":
                est[rows] = m[rows] - g[rows, None] * nearest_axes(m[rows])
                std[rows] = np.sqrt(noise_var + td.drift_var)
                continue
            a_inv = np.linalg.inv(td.A)
            v = (m[rows] - td.offset) @ a_inv.T
            cov_e = a_inv @ td.delta_cov @ a_inv.T
            noise_e = a_inv @ np.diag(noise_var) @ a_inv.T
            hv, _ = unit_rows(v)
            obs_var = np.einsum("ni,ij,nj->n", hv, noise_e, hv)
            e_hat, e_cov, _ = condition_on_norm(v, g[rows], np.zeros(3), cov_e, obs_var)
            u, _ = unit_rows(v - e_hat)
            est[rows] = m[rows] - g[rows, None] * u
            std[rows] = np.sqrt(np.clip(np.einsum("nii->ni", e_cov), 0.0, None) + noise_var)
        return est, std

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Posterior-mean apparent bias per window, (N, 3) m/s²."""
        return self._posterior(windows, meta)[0]

    def predict_std(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Approximate posterior standard deviation per window and axis, (N, 3) m/s²."""
        return self._posterior(windows, meta)[1]
