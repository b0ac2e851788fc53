"""What to record next, and what the label would then state (methods.md §8, "Next pose").

``_next_pose`` chooses orientations among the cube's 26 directions by
the norms' linear expectation. This module says, with the label's own numbers, what
``ofbe-session check`` prints for a labelled device and what the rejection of a device whose
poses determine no model records:

- **now**: the model the label writes and its standard errors (the label's columns,
  :class:`LabelledFit`);
- **expected with the poses added**: the chosen poses are appended to the recorded ones as
  the means the model predicts for them at the linearisation point
  (:func:`_next_pose.predicted_means`), each with the white noise of a
  typical recorded pose (the median of their std²/n) and a pose-to-pose error of its own, and
  the ladder's fit of the planned model (:func:`~ofbe_data.labelling.multiposition.choose_fit`, the
  model forced) states their standard errors with the error model of
  :mod:`~ofbe_data.labelling.multiposition._errors` (white noise, pose-to-pose error, the leak of what
  the model leaves out). The figure is a prediction of what the label then writes, not the
  norms' σ·(JᵀJ)⁻¹ with σ the residual rms of a poorer model, which carries what that model
  leaves unexplained (scale errors of an offset fit: 38.4 mg predicted where the label then
  stated 0.065 mg, issue 36);
- **poses to add** where the label writes no model (too few poses, or too alike): the fewest
  distinct cube directions after which the label is expected to write one (:func:`poses_to_add`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ofbe_data.labelling.multiposition._error_model import DRIFT_PRIOR_MG
from ofbe_data.labelling.multiposition._errors import PoseNoise, pose_clusters
from ofbe_data.labelling.multiposition._fit import PoseFit, base_model, min_poses, n_unknowns, parameter_names
from ofbe_data.labelling.multiposition._ladder import ModelChoice, choose_fit
from ofbe_data.labelling.multiposition._next_pose import (
    MG,
    cube_directions,
    describe_direction,
    linearisation_point,
    next_poses,
    predicted_means,
    readable_se,
    se_in_mps2,
)

PLAN_MODEL = "full"
"""The model ``check``'s next poses are planned for (the richest of the ladder without temperature)."""

REFUSED_MODEL = "scale-offset"
"""The model the poses to add are planned for where the label fits none: the smallest model whose
offsets an unbalanced set of directions cannot bias (an ``offset`` fit needs each face's opposite,
:func:`~ofbe_data.labelling.multiposition.scale_leak_mg`)."""

DEFAULT_SIGMA = 1e-3
"""m/s², the residual noise assumed for planning when nothing better is known (missing, NaN or 0)."""

AXES_WORDS = "each sensor axis' angle above or below level; an axis pointing up reads +g"
"""How a direction's words are read (:func:`_next_pose.describe_direction`)."""


def noise_level(residual_rms: float | None) -> float:
    """σ from a fit's residual rms: :data:`DEFAULT_SIGMA` when missing, NaN or ≤ 0."""
    if residual_rms is None:
        return DEFAULT_SIGMA
    value = float(residual_rms)
    return value if math.isfinite(value) and value > 0 else DEFAULT_SIGMA


@dataclass(frozen=True)
class PlanningNoise:
    """What the label's error model knows of the recorded poses, for predicting its standard errors.

    Attributes
    ----------
    white
        (K, 3) (m/s²)², each recorded pose mean's white-noise variance per axis (std²/n), or None
        when unknown.
    n_samples
        (K,) samples per recorded pose, or None when unknown.
    recordings
        (K,) the recording of each pose, poses in time order per recording (the error model's
        clusters, :func:`~ofbe_data.labelling.multiposition.pose_clusters`).
    tau
        m/s², the pose-to-pose error per axis: the label's estimate, else the sensor model's
        in-run drift (:data:`_errors.DRIFT_PRIOR_MG`).
    """

    white: np.ndarray | None
    n_samples: np.ndarray | None
    recordings: tuple[str, ...]
    tau: float

    @classmethod
    def unknown(cls, k: int, sigma: float) -> PlanningNoise:
        """No sample statistics: ``k`` poses, each its own cluster, σ = ``sigma`` (m/s²) each."""
        return cls(None, None, tuple(f"pose {i}" for i in range(k)), float(sigma))

    @property
    def new_white(self) -> np.ndarray | None:
        """(3,) (m/s²)², a planned pose's white-noise variance: the recorded poses' median."""
        return None if self.white is None else np.median(self.white, axis=0)

    @property
    def sigma(self) -> float:
        """m/s², the noise of one planned pose's norm residual, √(mean white variance + τ²),
        which scales the planning's expectation (:func:`_next_pose.next_poses`)."""
        white = self.new_white
        value = math.sqrt((0.0 if white is None else float(np.mean(white))) + self.tau ** 2)
        return value if math.isfinite(value) and value > 0 else DEFAULT_SIGMA


def planning_noise(std: np.ndarray, n_samples: np.ndarray, recordings: Sequence[str],
                   tau: float | None = None) -> PlanningNoise:
    """:class:`PlanningNoise` of recorded poses.

    Parameters
    ----------
    std
        (K, 3) m/s², each pose's per-axis sample standard deviation.
    n_samples
        (K,) samples per pose.
    recordings
        (K,) recording ids, poses in time order per recording.
    tau
        m/s², the label's pose-to-pose error; None (or not finite): :data:`DRIFT_PRIOR_MG`.
    """
    s = np.asarray(std, dtype=np.float64).reshape(-1, 3)
    n = np.asarray(n_samples, dtype=np.float64).reshape(-1)
    white = s * s / np.maximum(n, 1.0)[:, None]
    drift = DRIFT_PRIOR_MG * MG if tau is None or not math.isfinite(tau) else float(tau)
    return PlanningNoise(white if np.all(np.isfinite(white)) else None, n if np.all(np.isfinite(n)) else None,
                         tuple(str(r) for r in recordings), drift)


def noise_of_rows(rows: Sequence[dict[str, Any]]) -> PlanningNoise:
    """:class:`PlanningNoise` of one device's label rows (``std_*``, ``n_samples``, ``recording``,
    and the fit's error model under the private key ``_error_model`` when the label fitted one)."""
    error_model = rows[0].get("_error_model") if rows else None
    return planning_noise(np.array([[float(r[f"std_{a}"]) for a in "xyz"] for r in rows]).reshape(-1, 3),
                          np.array([float(r["n_samples"]) for r in rows]),
                          [str(r["recording"]) for r in rows],
                          None if error_model is None else float(error_model.tau))


def _checked_means(means: np.ndarray) -> np.ndarray:
    m = np.asarray(means, dtype=np.float64).reshape(-1, 3)
    if not np.all(np.isfinite(m)):
        raise ValueError("means must be finite")
    return m


def expected_fit(means: np.ndarray, g: float, noise: PlanningNoise, directions: np.ndarray, x: np.ndarray,
                 model: str = PLAN_MODEL, max_condition: float = 1000.0,
                 fit_as: str | None = None) -> ModelChoice:
    """The label's fit of ``model`` (forced; ``fit_as`` when given) over the recorded poses and
    planned ones.

    Parameters
    ----------
    means
        (K, 3) m/s², the recorded poses' means.
    g
        m/s², local gravity magnitude.
    noise
        The recorded poses' :class:`PlanningNoise`.
    directions
        (N, 3) unit specific-force directions of the planned poses, sensor frame.
    x
        The linearisation point (:func:`_next_pose.linearisation_point` of
        ``model``): the planned poses read its predicted means, without noise.
    model
        ``offset``, ``scale-offset`` or ``full``.
    max_condition
        The ladder's condition limit.
    fit_as
        The model fitted, when not ``model`` (e.g. ``offset`` over poses predicted by a richer one).

    Returns
    -------
    ModelChoice
        :func:`~ofbe_data.labelling.multiposition.choose_fit`'s, its covariance the error model's:
        each planned pose with the median white noise of the recorded ones and its own
        pose-to-pose error.
    """
    m = _checked_means(means)
    u = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    planned = predicted_means(u, g, x, model)
    every = np.vstack([m, planned])
    recordings = list(noise.recordings) + [f"planned pose {i + 1}" for i in range(u.shape[0])]
    new_white = noise.new_white
    white = (None if noise.white is None or new_white is None
             else np.vstack([noise.white, np.tile(new_white, (u.shape[0], 1))]))
    weights = (None if noise.n_samples is None
               else np.concatenate([noise.n_samples, np.full(u.shape[0], float(np.median(noise.n_samples)))]))
    pose_noise = PoseNoise(white, pose_clusters(recordings, every))
    return choose_fit(every, g, fit_as or model, max_condition, weights=weights, noise=pose_noise)


def largest_stated_se(fit: PoseFit, g: float) -> float:
    """The largest standard error a fit states, m/s² (offsets as they are, imu_tk's scales and
    angles times g: the specific-force error each causes at 1 g); ``inf`` when not determined."""
    if not fit.determined:
        return float("inf")
    base = base_model(fit.model)
    se = np.sqrt(np.maximum(np.diag(fit.covariance)[:n_unknowns(base)], 0.0))
    worst = float(np.max(se_in_mps2(se, g, base)))
    return worst if math.isfinite(worst) else float("inf")


@dataclass(frozen=True)
class Advice:
    """Poses to record and what the label is expected to state with them (:func:`advise`).

    Attributes
    ----------
    model
        The model planned for.
    directions
        (N, 3) the poses' unit specific-force directions (the up direction), sensor frame, in order.
    after
        (N,) m/s², the largest standard error of ``model`` the label is expected to state once
        the first 1, 2, … N of them are added (:func:`largest_stated_se`); ``inf`` while not determined.
    """

    model: str
    directions: np.ndarray
    after: np.ndarray

    @property
    def determined(self) -> bool:
        """Whether the label is expected to determine ``model`` with every pose added."""
        return bool(self.after.size and math.isfinite(float(self.after[-1])))

    def listed(self) -> str:
        """``1. +x+y (x up 45°, y up 45°, z level); 2. …``."""
        return "; ".join(f"{k + 1}. {describe_direction(u)}" for k, u in enumerate(self.directions))


def _after_each(m: np.ndarray, g: float, noise: PlanningNoise, directions: np.ndarray, x: np.ndarray,
                model: str, max_condition: float, fit_as: str) -> np.ndarray:
    """(N,) :func:`largest_stated_se` of the label's fit once the first 1, 2, … N planned poses are added."""
    fits = [expected_fit(m, g, noise, directions[:k], x, model, max_condition, fit_as).fit
            for k in range(1, directions.shape[0] + 1)]
    return np.array([largest_stated_se(fit, g) for fit in fits])


def advise(means: np.ndarray, g: float, noise: PlanningNoise, max_condition: float = 1000.0,
           model: str = PLAN_MODEL, n: int = 3) -> Advice:
    """The next ``n`` distinct poses for ``model`` (:func:`_next_pose.next_poses`)
    and the label's expected largest standard error of ``model`` after each (:func:`expected_fit`)."""
    m = _checked_means(means)
    x, _ = linearisation_point(m, g, max_condition, model)
    directions = np.array([u for u, _ in next_poses(m, g, x, noise.sigma, n, model)]).reshape(-1, 3)
    return Advice(model, directions, _after_each(m, g, noise, directions, x, model, max_condition, model))


MIN_RICHER_DOF = 3
"""Fewest residual degrees of freedom of a planned ``scale-offset`` fit for the advice to count on
it: the ladder takes it only when its F-test against ``offset`` passes, and with one or two
degrees of freedom that test misses scale errors of per cent (F(3, 1) must exceed 216 at 5 %;
F(3, 3), 9.3)."""


def poses_to_add(means: np.ndarray, g: float, noise: PlanningNoise, max_condition: float = 1000.0,
                 fit_model: str = "auto") -> Advice | None:
    """The fewest distinct poses after which the label is expected to write a model, where the
    recorded poses determine none.

    The poses are chosen for :data:`REFUSED_MODEL` (``full`` when ``label.fit_model`` forces it),
    one more at a time, until the label's own fit of that model over the recorded and planned
    poses (:func:`expected_fit`) is determined, with :data:`MIN_RICHER_DOF` residual degrees of
    freedom for ``scale-offset``. The ``offset`` model is not planned for: the ladder writes it only
    where the directions balance each other (:func:`~ofbe_data.labelling.multiposition.scale_leak_mg`),
    and hand-placed faces 2° off their axes already miss that (0.8 mg of leak against 0.5 allowed,
    on a simulated six-face set), while ``scale-offset`` needs no balance.

    Returns
    -------
    Advice or None
        No pose (an empty advice) when the recorded poses already do it: the label refused for
        another reason (a forced temperature model without a temperature span); None when no set
        of the 26 cube directions does it.
    """
    m = _checked_means(means)
    plan = PLAN_MODEL if fit_model != "auto" and base_model(fit_model) == PLAN_MODEL else REFUSED_MODEL
    x, _ = linearisation_point(m, g, max_condition, plan)
    fewest = min_poses(plan) - 1 + (MIN_RICHER_DOF if plan == REFUSED_MODEL else 1)
    none = np.zeros((0, 3))
    if m.shape[0] >= fewest and expected_fit(m, g, noise, none, x, plan, max_condition).fit.determined:
        return Advice(plan, none, np.zeros(0))
    for count in range(max(1, fewest - m.shape[0]), cube_directions().shape[0] + 1):
        directions = np.array([u for u, _ in next_poses(m, g, x, noise.sigma, count, plan)]).reshape(-1, 3)
        if expected_fit(m, g, noise, directions, x, plan, max_condition).fit.determined:
            after = _after_each(m, g, noise, directions, x, plan, max_condition, plan)
            return Advice(plan, directions, after)
    return None


def refusal_advice(means: np.ndarray, g: float, noise: PlanningNoise, max_condition: float = 1000.0,
                   fit_model: str = "auto") -> str:
    """What the rejection of a device whose poses determine no model says to record
    (:func:`poses_to_add`), and the largest standard error the label is then expected to state;
    empty when the poses are not what is missing."""
    a = poses_to_add(means, g, noise, max_condition, fit_model)
    if a is None:
        return (f"no set of the {cube_directions().shape[0]} cube directions added to these poses lets the "
                "label fit a model")
    count = a.directions.shape[0]
    if not count:
        return ""
    groups = "offsets, scales × g" + (", angles × g" if a.model == PLAN_MODEL else "")
    return (f"record {count} more pose{'s' if count != 1 else ''} ({AXES_WORDS}): {a.listed()}; with them "
            f"the label is expected to fit the {a.model} model, largest standard error "
            f"{_mg(float(a.after[-1]))} ({groups})")


@dataclass(frozen=True)
class LabelledFit:
    """What the label writes for a device's poses (the ladder's choice, :func:`labelled_fit`).

    Attributes
    ----------
    model
        ``fit_model`` (``offset``, ``scale-offset``, ``full``, …; empty when not labelled).
    reason
        ``fit_model_reason``: what the poses determine and why.
    se
        (9,) standard errors of ``offset_*`` (m/s²), ``imutk_s_*`` and ``imutk_mis_*`` (rad);
        NaN where the model does not fit the parameter.
    """

    model: str
    reason: str
    se: np.ndarray

    def largest(self, g: float) -> float:
        """The largest of the fitted standard errors as :func:`largest_stated_se` counts them, m/s²
        (``inf`` when none is finite)."""
        se = se_in_mps2(self.se, g)
        finite = se[np.isfinite(se)]
        return float(np.max(finite)) if finite.size else float("inf")


def labelled_fit(row: dict[str, object]) -> LabelledFit:
    """:class:`LabelledFit` from one label row of a multi-position session."""
    se = []
    for name in parameter_names("full"):
        value = row.get(name + "_se")
        se.append(float(value) if isinstance(value, int | float) else float("nan"))
    return LabelledFit(str(row.get("fit_model") or ""), str(row.get("fit_model_reason") or ""), np.array(se))


def ladder_fit(means: np.ndarray, g: float, max_condition: float = 1000.0) -> LabelledFit:
    """:class:`LabelledFit` of the ladder's ``auto`` choice for poses without a label (no sample
    statistics: every pose alone)."""
    choice = choose_fit(_checked_means(means), g, "auto", max_condition)
    se = np.full(9, np.nan)
    if choice.fit.determined:
        order = parameter_names("full")
        for name, value in zip(parameter_names(choice.fit.model), np.sqrt(np.diag(choice.fit.covariance)),
                               strict=False):
            if name in order:
                se[order.index(name)] = value
    return LabelledFit(choice.fit.model if choice.fit.determined else "", choice.reason, se)


def fitted_se_text(se: np.ndarray) -> str:
    """Standard errors as :func:`_next_pose.readable_se` writes them, a group
    the model does not fit as ``… not fitted``."""
    se = np.asarray(se, dtype=np.float64)
    groups = readable_se(np.where(np.isnan(se), 0.0, se))
    names = ("offsets", "scales", "angles")
    return "; ".join(text if not np.all(np.isnan(se[3 * i:3 * i + 3])) else f"{names[i]} not fitted"
                     for i, text in enumerate(groups))


def _now_words(fit: LabelledFit, g: float) -> str:
    """The label's largest standard error now, and of which model."""
    if not fit.model:
        return "the label fits no model now"
    now = _mg(fit.largest(g))
    if base_model(fit.model) == PLAN_MODEL:
        return f"the label states {now} now"
    missing = "scales and angles" if base_model(fit.model) == "offset" else "angles"
    return f"the label now fits {fit.model} ({missing} not fitted), largest standard error {now}"


def report_lines(device: str, means: np.ndarray, g: float, residual_rms: float | None,
                 max_condition: float = 1000.0, n: int = 3, fitted: LabelledFit | None = None,
                 noise: PlanningNoise | None = None) -> list[str]:
    """What ``ofbe-session check`` prints for one device of a multi-position session.

    The determination and the standard errors, now and expected with the next poses, are the
    label's (``fitted``, or the ladder's ``auto`` choice when None; :func:`advise`), so that
    ``check`` and ``ofbe-label`` say the same thing about the same poses.

    Parameters
    ----------
    device
        The device id (each line starts with it).
    means
        (K, 3) m/s², the device's pose means.
    g
        m/s², local gravity magnitude.
    residual_rms
        m/s², the device's pose-fit residual rms: σ of every pose when ``noise`` is None
        (:func:`noise_level`).
    max_condition
        Largest condition of a fit (the ladder's and the linearisation point's).
    n
        How many next poses to suggest.
    fitted
        The label's fit (:func:`labelled_fit`), or None.
    noise
        The poses' :class:`PlanningNoise` (:func:`noise_of_rows`), or None.

    Returns
    -------
    list of str
        The label's model with its standard errors, the ladder's reason, and the next-poses line.
    """
    m = _checked_means(means)
    fit = ladder_fit(m, g, max_condition) if fitted is None else fitted
    if noise is None:
        noise = PlanningNoise.unknown(m.shape[0], noise_level(residual_rms))
    if fit.model:
        out = [f"{device}: the label fits {fit.model} from {m.shape[0]} poses, standard errors "
               f"{fitted_se_text(fit.se)}"]
    else:
        out = [f"{device}: the label fits no model from {m.shape[0]} poses"]
    out.append(f"{device}: why: {fit.reason}")
    a = advise(m, g, noise, max_condition, PLAN_MODEL, n)
    if a.determined:
        each = f" ({', '.join(_mg(float(w)) for w in a.after)} after each)" if a.after.size > 1 else ""
        expected = (f"with them the label's {PLAN_MODEL} model is expected to state a largest standard error "
                    f"(offsets, scales × g, angles × g) of {_mg(float(a.after[-1]))}{each}")
    else:
        expected = (f"with them the label is still not expected to determine the {PLAN_MODEL} model "
                    f"({min_poses(PLAN_MODEL)} poses at least, in directions that span the sphere)")
    out.append(f"{device}: next poses to record ({AXES_WORDS}): {a.listed()}; {expected}; "
               f"{_now_words(fit, g)}")
    return out


def _mg(value_mps2: float) -> str:
    return f"{value_mps2 / MG:.3g} mg" if math.isfinite(value_mps2) else "undetermined"
