"""Multi-position calibration: static poses found inside recordings, the model ladder fitted to
them with standard errors, and what to record next (methods.md §8).

One power cycle's poses fix the zero-g offset b and, when they are many and spread, the scales,
the axes' non-orthogonality and a bias temperature slope: the norm-constrained fit
``|A⁻¹ (m_k − b)| = g`` as imu_tk and imucal do it. The public names below are what the rest of
ofbe uses (one label row per pose of a session is :mod:`ofbe_data.labelling.multi_labels`); the
modules behind them are private:

- ``_poses``: static poses within one recording (:func:`detect_static`, :class:`PoseParams`);
- ``_search``: the threshold chosen over all of a device's recordings (:func:`find_poses`);
- ``_fit``: the ladder's models fitted to the poses (:func:`fit_poses`, :class:`PoseFit`,
  :data:`MODELS`);
- ``_six_faces``: imucal's Ferraris fit of ``full`` from the six square faces;
- ``_errors`` and ``_error_model``: the poses' correlated errors (drift clusters, τ², the standard errors);
- ``_ladder``: the choice among the fits (determination, the scale-leak guard, Wald tests);
- ``_next_pose`` and ``_advice``: the poses to add and the standard errors the label would then
  state (``ofbe-session check``, too-few-poses rejections).

:mod:`ofbe_data.freeliving` fits the same ladder to a wearer's still epochs through these names.
The package may import :mod:`ofbe_data.core`, :mod:`ofbe_data.io` and
:mod:`ofbe_data.labelling.conventions`; nothing that labels sessions (that is its caller).
"""

from ofbe_data.labelling.multiposition._advice import (
    labelled_fit,
    noise_of_rows,
    planning_noise,
    refusal_advice,
    report_lines,
)
from ofbe_data.labelling.multiposition._errors import (
    column_space_basis,
    estimate_tau2,
    pose_clusters,
    pose_noise,
)
from ofbe_data.labelling.multiposition._fit import (
    MIN_TEMPERATURE_SPAN_C,
    MODELS,
    TEMPERATURE,
    PoseFit,
    base_model,
    fit_poses,
    has_temperature,
    jacobian_condition,
    map_from_params,
    min_poses,
    n_unknowns,
    parameter_names,
    residual_jacobian,
    span_condition,
)
from ofbe_data.labelling.multiposition._ladder import (
    MAX_SCALE_LEAK_MG,
    ModelChoice,
    choose_fit,
    scale_leak_mg,
    wald_test,
)
from ofbe_data.labelling.multiposition._poses import NoPosesError, Pose, PoseParams, detect_static
from ofbe_data.labelling.multiposition._search import direction_groups, find_poses, find_session_poses
from ofbe_data.labelling.multiposition._six_faces import FACE_ORDER

__all__ = [
    "FACE_ORDER",
    "MAX_SCALE_LEAK_MG",
    "MIN_TEMPERATURE_SPAN_C",
    "MODELS",
    "TEMPERATURE",
    "ModelChoice",
    "NoPosesError",
    "Pose",
    "PoseFit",
    "PoseParams",
    "base_model",
    "choose_fit",
    "column_space_basis",
    "detect_static",
    "direction_groups",
    "estimate_tau2",
    "find_poses",
    "find_session_poses",
    "fit_poses",
    "has_temperature",
    "jacobian_condition",
    "labelled_fit",
    "map_from_params",
    "min_poses",
    "n_unknowns",
    "noise_of_rows",
    "parameter_names",
    "planning_noise",
    "pose_clusters",
    "pose_noise",
    "refusal_advice",
    "report_lines",
    "residual_jacobian",
    "scale_leak_mg",
    "span_condition",
    "wald_test",
]
