"""The model ladder for wear: the richest model a recording's still epochs support.

The bench's ladder (:func:`ofbe_data.labelling.multiposition.choose_fit`) in the same order, with the
same rules, on robust fits (:func:`~ofbe_data.freeliving.robust.fit_robust`):

1. ``offset``; when the still epochs have temperatures spanning at least 5 °C
   (:data:`~ofbe_data.labelling.multiposition.MIN_TEMPERATURE_SPAN_C`), ``offset+temperature``
   first (a slope of a mg per °C would otherwise pass for noise and hide the map), its
   ``+temperature`` kept up the ladder when significant;
2. ``scale-offset``, then ``full`` (scales plus the three non-orthogonality angles), each
   replacing the model chosen so far when it is *determined* (more postures than parameters,
   condition number ≤ 1000, as on the bench) and *significant*;
3. without a temperature slope yet, ``+temperature`` last, by the same rules.

Significance: the bench's F-test compares residual sums of squares, which presumes
independent errors of one variance; a wearable's still epochs are neither (epochs of one
posture share their error, some are not still at all). Here each richer model's extra
parameters are tested against the ideal sensor (scales 1, angles 0, slopes 0) by a Wald test
on their cluster-robust covariance (:func:`ofbe_data.labelling.multiposition.wald_test`): kept when
p < ``alpha`` (0.05). An ``offset`` model is kept only when an unseen scale error cannot move
it by more than the bench's 0.5 mg (:func:`ofbe_data.labelling.multiposition.scale_leak_mg`); beyond
that the ``scale-offset`` model is used when it is determined.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ofbe_data.freeliving.robust import MAX_CONDITION, RobustFit, fit_robust
from ofbe_data.io.gravity import G0
from ofbe_data.labelling.multiposition import (
    MAX_SCALE_LEAK_MG,
    MIN_TEMPERATURE_SPAN_C,
    MODELS,
    TEMPERATURE,
    base_model,
    has_temperature,
    parameter_names,
    scale_leak_mg,
    wald_test,
)

ALPHA = 0.05
"""Significance level of the Wald tests (the bench's)."""


@dataclass(frozen=True, eq=False)
class WearChoice:
    """The robust fit the ladder chose and why (:func:`choose_wear_model`).

    Attributes
    ----------
    fit
        The chosen model's robust fit (``fit.fit.determined`` False when even ``offset`` is not).
    reason
        One line: each step of the ladder and why it was taken or not.
    """

    fit: RobustFit
    reason: str


def ideal_params(model: str) -> np.ndarray:
    """Shape (P,): the parameters of an ideal sensor in ``model``'s order (offsets 0, imu_tk's
    scales 1, angles 0, temperature slopes 0)."""
    return np.array([1.0 if n.startswith("imutk_s_") else 0.0 for n in parameter_names(model)])


def departure_test(fit: RobustFit, names: list[str]) -> tuple[float, float]:
    """Wald statistic and p-value that the parameters ``names`` of ``fit`` are those of an ideal
    sensor (:func:`ideal_params`), on the fit's cluster-robust covariance."""
    pose = fit.fit
    return wald_test(replace(pose, params=pose.params - ideal_params(pose.model)), names)


def usable_span_c(temperatures_c: np.ndarray | None, n: int) -> float:
    """The span of the still epochs' temperatures, °C; NaN when there are none, or not ``n`` finite ones."""
    if temperatures_c is None:
        return float("nan")
    t = np.asarray(temperatures_c, dtype=np.float64)
    return float(np.ptp(t)) if t.shape == (n,) and n > 0 and np.all(np.isfinite(t)) else float("nan")


def _try_richer(means: np.ndarray, chosen: RobustFit, candidate: str, temperatures: np.ndarray | None,
                alpha: float, max_condition: float) -> tuple[str, RobustFit]:
    """Whether ``candidate`` replaces ``chosen``: (one-line verdict, the fit kept)."""
    rich = fit_robust(means, candidate, temperatures if has_temperature(candidate) else None, max_condition,
                      chosen.postures)
    if not rich.fit.determined:
        return f"{candidate} not fitted: {rich.fit.reason}", chosen
    extra = [n for n in parameter_names(candidate) if n not in parameter_names(chosen.fit.model)]
    stat, p_value = departure_test(rich, extra)
    if not p_value < alpha:
        return (f"{candidate} not used: its {len(extra)} more parameters are ideal within their errors "
                f"(W = {stat:.3g}, p = {p_value:.2g} ≥ {alpha:g})"), chosen
    return (f"{candidate} over {chosen.fit.model}: W = {stat:.3g}, p = {p_value:.2g} < {alpha:g}, "
            f"condition {rich.fit.condition:.3g}"), rich


def _leak_guard(means: np.ndarray, chosen: RobustFit, suffix: str, temperatures: np.ndarray | None,
                max_condition: float) -> tuple[str, RobustFit]:
    """An ``offset`` model whose offset an unseen scale error would move by more than 0.5 mg
    gives way to ``scale-offset`` (determined or not): ("" or a note, the fit kept)."""
    if base_model(chosen.fit.model) != "offset":
        return "", chosen
    leak = scale_leak_mg(chosen.fit, G0)
    if leak <= MAX_SCALE_LEAK_MG:
        return "", chosen
    richer = fit_robust(means, "scale-offset" + suffix, temperatures if suffix else None, max_condition,
                        chosen.postures)
    note = (f"an unseen scale error of 2 % would move the {chosen.fit.model} model's offset by "
            f"{leak:.2f} mg (at most {MAX_SCALE_LEAK_MG:g})")
    if richer.fit.determined:
        return f"scale-offset{suffix} used instead: {note}", richer
    return f"{note}, and scale-offset{suffix} is not fitted: {richer.fit.reason}", replace(
        chosen, fit=replace(chosen.fit, determined=False, reason=note))


def choose_wear_model(means_g: np.ndarray, temperatures_c: np.ndarray | None = None, model: str = "auto",
                      alpha: float = ALPHA, max_condition: float = MAX_CONDITION) -> WearChoice:
    """Fit the richest model of the ladder the still epochs support, or the one forced.

    Parameters
    ----------
    means_g
        Shape (n, 3): the still epochs' raw means, g, in time order.
    temperatures_c
        Shape (n,): their temperatures, °C, or None.
    model
        ``auto`` (the ladder, module notes) or a key of
        :data:`~ofbe_data.labelling.multiposition.MODELS` (only that model is fitted).
    alpha
        Significance level of the Wald tests.
    max_condition
        Largest condition number of a fitted model.

    Returns
    -------
    WearChoice

    Raises
    ------
    ValueError
        An unknown ``model``, or a ``+temperature`` model forced without temperatures.
    """
    m = np.asarray(means_g, dtype=np.float64)
    span = usable_span_c(temperatures_c, m.shape[0])
    temps = None if np.isnan(span) else np.asarray(temperatures_c, dtype=np.float64)
    if model != "auto":
        if model not in MODELS:
            raise ValueError(f"unknown model {model!r}; expected auto or one of: {', '.join(MODELS)}")
        if has_temperature(model) and temps is None:
            raise ValueError(f"the {model} model needs a finite temperature for every still epoch")
        fit = fit_robust(m, model, temps if has_temperature(model) else None, max_condition)
        return WearChoice(fit, f"{model}: forced" + ("" if fit.fit.determined else f"; {fit.fit.reason}"))
    chosen = fit_robust(m, "offset", None, max_condition)
    notes = [f"{m.shape[0]} still epochs in {chosen.n_postures} postures"]
    if not chosen.fit.determined:
        return WearChoice(chosen, f"offset: {'; '.join(notes)}; {chosen.fit.reason}")
    suffix = ""
    if span >= MIN_TEMPERATURE_SPAN_C:
        verdict, chosen = _try_richer(m, chosen, "offset" + TEMPERATURE, temps, alpha, max_condition)
        notes.append(f"{verdict} (temperature span {span:.1f} °C)")
        suffix = TEMPERATURE if has_temperature(chosen.fit.model) else ""
    for candidate in ("scale-offset", "full"):
        verdict, chosen = _try_richer(m, chosen, candidate + suffix, temps, alpha, max_condition)
        notes.append(verdict)
    if span >= MIN_TEMPERATURE_SPAN_C and not suffix:
        verdict, chosen = _try_richer(m, chosen, chosen.fit.model + TEMPERATURE, temps, alpha, max_condition)
        notes.append(verdict)
    elif np.isfinite(span) and span < MIN_TEMPERATURE_SPAN_C:
        notes.append(f"no temperature slope: the still epochs span {span:.1f} °C, "
                     f"{MIN_TEMPERATURE_SPAN_C:g} needed")
    note, chosen = _leak_guard(m, chosen, TEMPERATURE if has_temperature(chosen.fit.model) else "", temps,
                               max_condition)
    if note:
        notes.append(note)
    return WearChoice(chosen, f"{chosen.fit.model}: " + "; ".join(notes))
