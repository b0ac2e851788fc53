"""Campaign-level refinement: each device's 3×3 map and one zero-g offset per power cycle.

For recording k of a device, in power cycle j(k), with ``u_k`` the reference's gravity
direction in the device's nominal axes and ``m_k`` the device's mean over the stationary
segment (both sensor frame)::

    m_k = g · A · u_k + b_j(k)

A holds scale, cross-axis and the mount misalignment relative to the reference. The model
is linear in the 9 entries of A and the 3·J offsets, so it is solved by linear least squares.
The condition number of the column-normalised design matrix says whether the orientations
determine A; when they do not (every cycle seen in one orientation only, or too few
recordings) the offsets stay unknown and the reason is given.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class CampaignFitParams:
    """When to trust the campaign fit.

    Attributes
    ----------
    enabled
        Run the fit at all.
    min_recordings
        Fewest labelled recordings of a device (the 9 + 3·J unknowns need 3·K equations).
    max_condition
        Largest condition number of the column-normalised design matrix.
    """

    enabled: bool = True
    min_recordings: int = 12
    max_condition: float = 1000.0


@dataclass(frozen=True)
class DeviceFit:
    """The campaign fit of one device.

    Attributes
    ----------
    device
        Device id.
    n_recordings, n_power_cycles
        What the fit used.
    determined
        True when A and the offsets are determined.
    reason
        Why not, when not.
    A
        (3, 3) fitted map, or None.
    offsets
        Zero-g offset per power cycle, (3,) m/s² each.
    condition
        Condition number of the column-normalised design matrix (inf when rank-deficient).
    residual_rms
        rms of m_k − (g·A·u_k + b_j) over recordings and axes, m/s².
    covariance
        (9 + 3J, 9 + 3J) covariance of ``[A.ravel(), b_0, …]`` (power cycles in sorted
        order), σ̂²·(XᵀX)⁻¹ with σ̂² the residual variance per degree of freedom; or None.
    dof
        3K − (9 + 3J), the residual's degrees of freedom.
    """

    device: str
    n_recordings: int
    n_power_cycles: int
    determined: bool
    reason: str = ""
    A: np.ndarray | None = None
    offsets: dict[int, np.ndarray] = field(default_factory=dict)
    condition: float = float("inf")
    residual_rms: float = float("nan")
    covariance: np.ndarray | None = None
    dof: int = 0

    def matrix_covariance(self) -> np.ndarray:
        """(9, 9) covariance of A's entries, row-major."""
        if self.covariance is None:
            raise ValueError(f"{self.device}: the campaign fit is not determined")
        return self.covariance[:9, :9]

    def offset_se(self, power_cycle: int) -> np.ndarray:
        """(3,) m/s², standard errors of the offset of ``power_cycle``."""
        if self.covariance is None:
            raise ValueError(f"{self.device}: the campaign fit is not determined")
        i = 9 + 3 * sorted(self.offsets).index(power_cycle)
        return np.sqrt(np.maximum(np.diag(self.covariance)[i:i + 3], 0.0))

    def to_dict(self) -> dict[str, object]:
        """Plain JSON-ready form."""
        return {
            "device": self.device, "n_recordings": self.n_recordings,
            "n_power_cycles": self.n_power_cycles, "determined": self.determined,
            "reason": self.reason,
            "A": None if self.A is None else self.A.tolist(),
            "offsets": {str(k): v.tolist() for k, v in sorted(self.offsets.items())},
            "condition": self.condition if np.isfinite(self.condition) else None,
            "residual_rms_mps2": self.residual_rms if np.isfinite(self.residual_rms) else None,
        }


def design_matrix(u: np.ndarray, cycle_index: np.ndarray, n_cycles: int, g: float) -> np.ndarray:
    """Design matrix of ``m_k = g·A·u_k + b_j(k)``, unknowns ``[A.ravel(), b_0, …, b_{J−1}]``.

    Parameters
    ----------
    u
        (K, 3) unit directions, sensor frame.
    cycle_index
        (K,) int, 0 … J − 1.
    n_cycles
        J.
    g
        m/s².

    Returns
    -------
    ndarray, shape (3K, 9 + 3J)
        Row 3k + i is axis i of recording k.
    """
    k = u.shape[0]
    X = np.zeros((3 * k, 9 + 3 * n_cycles))
    for i in range(3):
        rows = 3 * np.arange(k) + i
        X[rows, 3 * i:3 * i + 3] = g * u
        X[rows, 9 + 3 * cycle_index + i] = 1.0
    return X


def fit_device(device: str, u: np.ndarray, mean: np.ndarray, power_cycle: np.ndarray, g: float,
               params: CampaignFitParams = CampaignFitParams()) -> DeviceFit:
    """Fit one device's map A and its per-power-cycle offsets.

    Parameters
    ----------
    device
        Device id (for the record).
    u
        (K, 3) gravity directions in the device's nominal axes (unit).
    mean
        (K, 3) mean readings over the stationary segments, m/s².
    power_cycle
        (K,) int power-cycle id of each recording.
    g
        Local gravity, m/s² (one site per campaign).
    params
        Acceptance thresholds.

    Returns
    -------
    DeviceFit
    """
    cycles, idx = np.unique(np.asarray(power_cycle), return_inverse=True)
    k, j = u.shape[0], cycles.size
    if k < params.min_recordings:
        return DeviceFit(device, k, j, False, f"{k} labelled recordings, the fit needs at least "
                         f"{params.min_recordings} (label the whole campaign together)")
    X = design_matrix(u, idx, j, g)
    norms = np.linalg.norm(X, axis=0)
    sv = np.linalg.svd(X / norms, compute_uv=False)
    full_rank = sv.size == X.shape[1] and sv[-1] > 1e-12 * sv[0]
    condition = float(sv[0] / sv[-1]) if full_rank else float("inf")
    if not condition <= params.max_condition:
        return DeviceFit(device, k, j, False,
                         f"the orientations do not determine A: condition number {condition:.3g} > "
                         f"{params.max_condition:g} (each power cycle needs several distinct "
                         "orientations, and together they must span three dimensions)",
                         condition=condition)
    theta, *_ = np.linalg.lstsq(X, np.asarray(mean, dtype=np.float64).ravel(), rcond=None)
    r = X @ theta - mean.ravel()
    residual = float(np.sqrt(np.mean(r ** 2)))
    dof = X.shape[0] - X.shape[1]
    scaled = X / norms
    covariance = (float(np.sum(r * r)) / dof if dof > 0 else float("nan")) \
        * np.linalg.inv(scaled.T @ scaled) / np.outer(norms, norms)
    A = theta[:9].reshape(3, 3)
    offsets = {int(c): theta[9 + 3 * i:12 + 3 * i].copy() for i, c in enumerate(cycles)}
    return DeviceFit(device, k, j, True, "", A, offsets, condition, residual, covariance, dof)
