"""The error model's record (:class:`ErrorModel`) and its constants: what a fit states of the
pose-to-pose error it assumed or estimated (``_errors`` estimates it; ``_fit`` carries it)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ofbe_data.io.gravity import G0

MG = G0 / 1000.0
"""m/s² per mg."""

DRIFT_PRIOR_MG = 0.3
"""Pose-to-pose error assumed, mg per axis, where the poses cannot tell it (docs/sensor-model.md:
the ADXL345's in-run drift, σ ≈ 0.3 mg over a recording)."""

MIN_TAU_DOF = 3.0
"""Fewest effective degrees of freedom of the residuals' estimate of τ² for it to be used alone."""


@dataclass(frozen=True)
class ErrorModel:
    """The error model's terms as estimated for one fit.

    Attributes
    ----------
    tau
        m/s², the pose-to-pose error per axis (τ).
    tau_dof
        Effective degrees of freedom of its estimate from the residuals.
    assumed
        τ is :data:`DRIFT_PRIOR_MG` (the residuals could not tell it).
    placement_rad
        σ_p, rad; NaN outside the six-face rung.
    """

    tau: float
    tau_dof: float
    assumed: bool
    placement_rad: float = float("nan")

    def words(self) -> str:
        """One clause for the label's ``fit_model_reason``."""
        if self.assumed:
            text = (f"standard errors with {self.tau / MG:.2g} mg of pose-to-pose error assumed (the poses "
                    f"cannot tell it: {self.tau_dof:.2g} degrees of freedom, {MIN_TAU_DOF:g} needed)")
        else:
            text = (f"standard errors with {self.tau / MG:.2g} mg of pose-to-pose error (from the residuals, "
                    f"{self.tau_dof:.2g} degrees of freedom)")
        if np.isfinite(self.placement_rad):
            text += f" and {np.degrees(self.placement_rad):.2g}° of face placement"
        return text
