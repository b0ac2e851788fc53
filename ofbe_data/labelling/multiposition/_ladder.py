"""The model ladder's choice: the richest model the poses support (methods.md §8).

:func:`choose_fit` fits ``offset``, then each richer model of
``_fit`` that enough well-spread poses determine and that
improves the fit beyond noise (:func:`f_test`); where the norms cannot fit ``full`` from poses
on the six faces only, the six-face fit of ``_six_faces`` is used when
its non-orthogonality is significant (:func:`wald_test`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import chi2
from scipy.stats import f as f_distribution

from ofbe_data.io.gravity import G0
from ofbe_data.labelling.conventions import ANGLE_NAMES
from ofbe_data.labelling.multiposition._errors import (
    PoseNoise,
    missing_names,
    norm_fit_errors,
    prior_missing_covariance,
)
from ofbe_data.labelling.multiposition._fit import (
    MIN_TEMPERATURE_SPAN_C,
    TEMPERATURE,
    PoseFit,
    base_model,
    check_means,
    fit_poses,
    has_temperature,
    min_poses,
    nan_fit,
    parameter_names,
    temperature_problem,
)
from ofbe_data.labelling.multiposition._six_faces import face_tilt_deg, fit_six_faces, six_faces


def wald_test(fit: PoseFit, names: list[str]) -> tuple[float, float]:
    """Wald statistic and p-value that the parameters ``names`` of ``fit`` are all zero:
    W = θᵀ C⁻¹ θ, χ² with len(names) degrees of freedom (NaN when their covariance is not
    finite)."""
    order = parameter_names(fit.model)
    pick = [order.index(n) for n in names]
    theta = fit.params[pick]
    cov = fit.covariance[np.ix_(pick, pick)]
    if not (np.all(np.isfinite(theta)) and np.all(np.isfinite(cov))):
        return float("nan"), float("nan")
    stat = float(theta @ np.linalg.pinv(cov) @ theta)
    return stat, float(chi2.sf(stat, len(pick)))


def f_test(simple: PoseFit, rich: PoseFit) -> tuple[float, float]:
    """F statistic and p-value of ``rich`` against the nested ``simple`` fit of the same poses.

    F = ((RSS_simple − RSS_rich) / (P_rich − P_simple)) / (RSS_rich / (K − P_rich)); a small
    p-value says the richer model's extra parameters explain more than noise would.
    """
    extra = rich.params.size - simple.params.size
    if rich.dof < 1 or extra < 1:
        return float("nan"), float("nan")
    denominator = rich.rss / rich.dof
    if denominator <= 0:
        return float("inf"), 0.0
    stat = max(simple.rss - rich.rss, 0.0) / extra / denominator
    return float(stat), float(f_distribution.sf(stat, extra, rich.dof))


@dataclass(frozen=True)
class ModelChoice:
    """The fit the ladder chose and why (:func:`choose_fit`).

    Attributes
    ----------
    fit
        The chosen model's fit (``fit.determined`` False when even ``offset`` is not).
    reason
        One line: the model, what supported it, and why each richer model was not used.
    """

    fit: PoseFit
    reason: str


def choose_fit(means: np.ndarray, g: float, model: str = "auto", max_condition: float = 1000.0,
               alpha: float = 0.05, temperatures: np.ndarray | None = None,
               weights: np.ndarray | None = None, noise: PoseNoise | None = None) -> ModelChoice:
    """Fit the richest model of the ladder the poses support, or the one forced.

    ``auto`` starts from ``offset`` and moves to each richer model (``scale-offset``, then ``full``)
    that (1) has enough poses (:func:`min_poses`), (2) is well conditioned (``max_condition``) and
    (3) improves the fit beyond noise: its F-test against the model chosen so far has p < ``alpha``.
    When every pose has a temperature and they span ≥ 5 °C, a bias temperature slope is tried first
    on the offset model (a slope of mg per °C would otherwise pass for noise and hide the map) and
    kept up the ladder when significant, or tried last on top of the chosen model, by the same
    rules; otherwise the reason says why no slope was tried (:func:`temperature_problem`), and a
    forced ``+temperature`` model is refused for it. Where the norms do not determine ``full``
    (poses on the six faces only), :func:`fit_six_faces` is tried instead and used when its
    non-orthogonality angles differ from zero beyond its errors, placement included
    (:func:`wald_test`, p < ``alpha``); a forced ``full`` takes it whenever it is determined. Forced
    or chosen, an ``offset`` model is written only when an unseen scale error cannot move it by more
    than :data:`MAX_SCALE_LEAK_MG` (:func:`scale_leak_mg`). The chosen fit's covariance is that of
    ``_errors``, and its reason ends with the error model's terms.

    Parameters
    ----------
    means
        (K, 3) m/s², the poses' means.
    g
        m/s², local gravity magnitude.
    model
        ``auto`` or a key of :data:`MODELS` (then only that model is fitted).
    max_condition
        Largest condition number of a fitted model (:attr:`PoseFit.condition`).
    alpha
        Significance level of the F-tests.
    temperatures
        (K,) °C per pose, or None.
    weights
        (K,) samples per pose (the six-face fit uses each face's longest pose), or None.
    noise
        The poses' white noise and clusters (:func:`ofbe_data.labelling.multiposition.pose_noise`),
        or None: unknown, every pose alone.

    Returns
    -------
    ModelChoice
    """
    m = check_means(means)
    noise = PoseNoise.independent(m.shape[0]) if noise is None else noise
    if model != "auto":
        fit, reason = _forced(m, g, model, max_condition, temperatures, weights, noise)
        return _finish(m, g, fit, reason, max_condition, temperatures, weights, noise)
    chosen = fit_poses(m, g, "offset", max_condition)
    notes = [f"{m.shape[0]} poses"]
    if not chosen.determined:
        return ModelChoice(chosen, f"offset: {chosen.reason}")
    temps = None if temperatures is None else np.asarray(temperatures, dtype=np.float64)
    span = float(np.ptp(temps)) if temps is not None and temps.shape == (m.shape[0],) and np.all(
        np.isfinite(temps)) else float("nan")
    suffix = ""
    if span >= MIN_TEMPERATURE_SPAN_C:
        # a slope of a few mg/°C over the span would otherwise pass for noise and hide the map
        verdict, chosen = _try_richer(m, g, chosen, "offset" + TEMPERATURE, max_condition, alpha, temps)
        notes.append(f"{verdict} (temperature span {span:.1f} °C)")
        suffix = TEMPERATURE if has_temperature(chosen.model) else ""
    for candidate in ("scale-offset", "full"):
        verdict, richer = _try_richer(m, g, chosen, candidate + suffix, max_condition, alpha,
                                      temps if suffix else None)
        if richer is chosen and candidate + suffix == "full" and "not fitted" in verdict:
            verdict, richer = _try_six_faces(m, g, chosen, alpha, weights, verdict, noise)
        chosen = richer
        notes.append(verdict)
    if span >= MIN_TEMPERATURE_SPAN_C and not suffix:
        verdict, chosen = _try_richer(m, g, chosen, chosen.model + TEMPERATURE, max_condition, alpha, temps)
        notes.append(verdict)
    elif np.isfinite(span) and span < MIN_TEMPERATURE_SPAN_C:
        notes.append(f"no temperature slope: the poses span {span:.1f} °C, {MIN_TEMPERATURE_SPAN_C:g} needed")
    elif temps is not None and not np.isfinite(span) and (why := temperature_problem(temps, m.shape[0])):
        notes.append(f"no temperature slope: {why}")  # poses without a temperature: the rung goes, not they
    return _finish(m, g, chosen, f"{chosen.model}: " + "; ".join(notes), max_condition, temperatures, weights,
                   noise)


def _forced(m: np.ndarray, g: float, model: str, max_condition: float, temperatures: np.ndarray | None,
            weights: np.ndarray | None, noise: PoseNoise) -> tuple[PoseFit, str]:
    """The forced model's fit and reason (the six-face fit where the norms cannot fit ``full``); a
    ``+temperature`` model is refused where the poses' temperatures cannot give its slope
    (:func:`temperature_problem`: one missing, or a span under :data:`MIN_TEMPERATURE_SPAN_C`)."""
    problem = temperature_problem(temperatures, m.shape[0]) if has_temperature(model) else None
    if problem is not None and m.shape[0] >= min_poses(model):
        return nan_fit(model, m.shape[0], float("nan"), float("nan"), problem), f"{model}: {problem}"
    fit = fit_poses(m, g, model, max_condition, temperatures)
    why = "forced by label.fit_model" if fit.determined else fit.reason
    if not fit.determined and model == "full":
        faces = fit_six_faces(m, g, weights, noise)
        if faces.determined:
            words = _six_face_words(m, g, weights)
            return faces, f"full: forced by label.fit_model; {words} (the norms alone: {fit.reason})"
        why += f"; six-face fit: {faces.reason}"
    return fit, f"{model}: {why}"


def _finish(m: np.ndarray, g: float, chosen: PoseFit, reason: str, max_condition: float,
            temperatures: np.ndarray | None, weights: np.ndarray | None, noise: PoseNoise) -> ModelChoice:
    """The determination guard every written model passes, then the error model's covariance."""
    if not chosen.determined:
        return ModelChoice(chosen, reason)
    if base_model(chosen.model) == "offset":
        leak = scale_leak_mg(chosen, g)
        if leak > MAX_SCALE_LEAK_MG:
            why = (f"the poses do not determine it: a scale error of {SCALE_ERROR_PRIOR:.0%} per axis, "
                   f"which the offset model cannot see, would move it by up to {leak:.2f} mg (at most "
                   f"{MAX_SCALE_LEAK_MG:g} mg): the directions are unbalanced (a face without its "
                   f"opposite?); record the opposite faces, or {min_poses('scale-offset')} poses or more "
                   "for the scale-offset model")
            undetermined = nan_fit(chosen.model, m.shape[0], chosen.residual_rms, chosen.condition, why)
            return ModelChoice(undetermined, f"{reason}; {why}")
    words = ""
    if chosen.error_model is None:
        temps = temperatures if has_temperature(chosen.model) else None
        missing, words = _missing_covariance(m, g, chosen, max_condition, temps, weights, noise)
        covariance, terms = norm_fit_errors(chosen, m, g, noise, temps, missing)
        chosen = replace(chosen, covariance=covariance, error_model=terms)
    assert chosen.error_model is not None
    return ModelChoice(chosen, f"{reason}; {chosen.error_model.words()}{words}")


def _missing_covariance(m: np.ndarray, g: float, chosen: PoseFit, max_condition: float,
                        temperatures: np.ndarray | None, weights: np.ndarray | None,
                        noise: PoseNoise) -> tuple[np.ndarray | None, str]:
    """Covariance of the map parameters ``chosen`` leaves out (:func:`missing_names` order), from the
    richest fit that determines them (the norms' ``full`` or ``scale-offset``, or the six-face
    fit for the angles), else the sensor model's; and a clause saying which."""
    names = missing_names(chosen.model)
    if not names:
        return None, ""
    cov = prior_missing_covariance(names)
    suffix = TEMPERATURE if has_temperature(chosen.model) else ""
    found: list[str] = []
    for model in ("full", "scale-offset"):
        have = [n for n in names if n in parameter_names(model)]
        fit = fit_poses(m, g, model + suffix, max_condition, temperatures) if have else None
        if fit is not None and fit.determined:
            rich_cov, _ = norm_fit_errors(fit, m, g, noise, temperatures)
            _insert(cov, names, have, rich_cov, parameter_names(fit.model))
            found = have
            break
    angles = [n for n in names if n.startswith("imutk_mis_") and n not in found]
    if angles:
        faces = fit_six_faces(m, g, weights, noise)
        if faces.determined:
            _insert(cov, names, angles, faces.covariance, parameter_names("full"))
            found += angles
    assumed = [n for n in names if n not in found]
    what = ", ".join(sorted({"scales" if n.startswith("imutk_s_") else "angles" for n in names}))
    source = ("the sensor model's" if assumed and not found else "the richer fits'" if not assumed
              else "partly assumed")
    return cov, f", and the leak of the {what} it leaves out ({source} uncertainty)"


def _insert(cov: np.ndarray, names: list[str], have: list[str], source: np.ndarray, order: list[str]) -> None:
    """Put ``source``'s block of the parameters ``have`` (``order`` indexes ``source``) into ``cov``."""
    i = [names.index(n) for n in have]
    j = [order.index(n) for n in have]
    cov[np.ix_(i, i)] = source[np.ix_(j, j)]


SCALE_ERROR_PRIOR = 0.02
"""Per-axis scale error the ``offset`` model is assumed to leave unseen (an ADXL345's sensitivity
is specified to a few per cent)."""
MAX_SCALE_LEAK_MG = 0.5
"""Largest offset change, mg, such a scale error may cause for an ``offset`` fit to be written."""


def scale_leak_mg(fit: PoseFit, g: float) -> float:
    """How far an unseen scale error of :data:`SCALE_ERROR_PRIOR` per axis moves ``fit``'s offset, mg.

    Linearised: a scale error δs adds g·δs_i·u_k,i to pose k's axis i, which changes its norm
    residual by g·Σ_i u_k,i²·δs_i, so δb = g·(EᵀE)⁻¹Eᵀ·U²·δs with E the poses' unit directions
    and U² their squares. Opposite faces cancel (Σ u_k u_k,i² = 0): six faces, or any set
    balanced so, leave the offset untouched, while a face without its opposite leaks the
    scale error of its axis into the offset. Returns the worst axis with |δs_i| ≤ the prior.
    """
    e = fit.directions
    if not np.all(np.isfinite(e)):
        return float("inf")
    sens = g * np.linalg.pinv(e.T @ e) @ e.T @ (e * e)
    return float(np.max(np.sum(np.abs(sens), axis=1)) * SCALE_ERROR_PRIOR / (G0 / 1000.0))


def _six_face_words(means: np.ndarray, g: float, weights: np.ndarray | None) -> str:
    index, _ = six_faces(means, weights)
    assert index is not None
    tilt = face_tilt_deg(means[index], g)
    return (f"from six square faces (each offset from its axis' two faces, as Ferraris; faces {tilt:.2f}° "
            f"from opposite)")


def _try_six_faces(means: np.ndarray, g: float, chosen: PoseFit, alpha: float, weights: np.ndarray | None,
                   verdict: str, noise: PoseNoise) -> tuple[str, PoseFit]:
    """Whether the six-face ``full`` fit replaces ``chosen`` where the norms cannot fit it."""
    faces = fit_six_faces(means, g, weights, noise)
    if not faces.determined:
        return f"{verdict}; six-face fit not used: {faces.reason}", chosen
    stat, p_value = wald_test(faces, [f"imutk_mis_{n}" for n in ANGLE_NAMES])
    if not p_value < alpha:
        return (f"{verdict}; six-face fit not used: its angles are zero within noise "
                f"(W = {stat:.3g}, p = {p_value:.2g} ≥ {alpha:g})"), chosen
    return (f"full over {chosen.model} {_six_face_words(means, g, weights)}: non-orthogonality "
            f"W = {stat:.3g}, p = {p_value:.2g} < {alpha:g} ({verdict})"), faces


def _try_richer(means: np.ndarray, g: float, chosen: PoseFit, candidate: str, max_condition: float,
                alpha: float, temperatures: np.ndarray | None) -> tuple[str, PoseFit]:
    """Whether ``candidate`` replaces ``chosen``: (one-line verdict, the fit kept)."""
    needed = min_poses(candidate)
    if means.shape[0] < needed:
        return f"{candidate} not fitted: {needed} poses needed", chosen
    rich = fit_poses(means, g, candidate, max_condition, temperatures)
    if not rich.determined:
        return f"{candidate} not fitted: {rich.reason}", chosen
    stat, p_value = f_test(chosen, rich)
    if not p_value < alpha:
        return (f"{candidate} not used: no improvement beyond noise over {chosen.model} "
                f"(F = {stat:.3g}, p = {p_value:.2g} ≥ {alpha:g})"), chosen
    return (f"{candidate} over {chosen.model}: F = {stat:.3g}, p = {p_value:.2g} < {alpha:g}, "
            f"condition {rich.condition:.3g}"), rich
