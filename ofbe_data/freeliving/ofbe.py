"""``ofbe-autocal --mode ofbe``: one recording calibrated from its still epochs by ofbe's ladder.

The steps (docs/free-living.md):

1. idle epochs left out (:func:`~ofbe_data.freeliving.epochs.idle_sleep`: standard deviation 0,
   zero or repeated means) and counted;
2. still epochs: standard deviation below ``still_sd_g`` and |mean| below 2 g on every axis (GGIR's
   rule); none is "no still epochs", fewer than 10 (GGIR's count) "too few";
3. the error before (GGIR's ``cal.error``: mean | ‖mean‖ − 1 |) and the coverage rule
   (:mod:`~ofbe_data.freeliving.coverage`): a signed axis with no still epoch within 45° is
   "sphere not populated", the axes named;
4. the ladder (:func:`~ofbe_data.freeliving.ladder.choose_wear_model`): robust fits with
   cluster-robust standard errors, the model chosen by determination and Wald tests; a model
   the epochs do not determine at all is "sphere not populated" too, with the ladder's reason;
5. the error after; a fit that does not lower it (both rounded to 1e-5 g, as GGIR compares them)
   is not applied (identity coefficients), as in GGIR.

Coefficients, two conventions (:func:`coefficient_columns`)
    ofbe's own, as on the bench: raw = A·u + b + c·(T − τ₀) (u the unit gravity reaction, g),
    written ``ofbe_offset_*`` (b, g), ``a_xx`` … ``a_zz`` (A, upper triangular) and
    ``ofbe_temp_slope_*`` (c, g/°C); and GGIR's, calibrated = (raw + offset)·scale +
    (T − τ₀)·temp_offset, which a diagonal A allows: offset = −b, scale = 1/A_ii (imu_tk's s),
    temp_offset = −c·scale. A ``full`` model's non-orthogonality has no place in GGIR's
    convention, so its GGIR columns are left empty rather than written wrong.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ofbe_data.freeliving.coverage import COVERAGE_DEG, coverage_words, missing_faces
from ofbe_data.freeliving.epochs import EpochTable, idle_sleep
from ofbe_data.freeliving.ggir import (
    MAX_ABS_MEAN_G,
    MIN_STILL_EPOCHS,
    SettingsError,
    sphere_error,
    use_temperature,
)
from ofbe_data.freeliving.ladder import ALPHA, choose_wear_model
from ofbe_data.freeliving.robust import MAX_CONDITION, norm_residuals
from ofbe_data.labelling.conventions import derived_se
from ofbe_data.labelling.multiposition import MODELS, PoseFit, base_model, has_temperature, map_from_params

QC_OFBE_DONE = "recalibration done"
QC_OFBE_NOT_DECREASED = "recalibration not done because recalibration does not decrease error"
QC_OFBE_SPHERE = "recalibration not done because the sphere is not populated"
QC_OFBE_TOO_FEW = "recalibration not done because too few still epochs"
QC_OFBE_NO_STILL = "recalibration not done because no still epochs"
QC_OFBE_OUTCOMES = (QC_OFBE_DONE, QC_OFBE_NOT_DECREASED, QC_OFBE_SPHERE, QC_OFBE_TOO_FEW, QC_OFBE_NO_STILL)
"""How each ``qc`` line of ``--mode ofbe`` begins, one per outcome (GGIR's cases)."""

AXES = "xyz"
GGIR_COLUMNS = (*(f"offset_{a}" for a in AXES), *(f"scale_{a}" for a in AXES),
                *(f"temp_offset_{a}" for a in AXES))
"""GGIR's convention: offset (g), scale (1), temp_offset (g/°C)."""
OFBE_COLUMNS = (*(f"ofbe_offset_{a}" for a in AXES), *(f"a_{r}{c}" for r in AXES for c in AXES),
                *(f"ofbe_temp_slope_{a}" for a in AXES))
"""ofbe's convention: b (g), A (1), c (g/°C)."""


@dataclass(frozen=True)
class OfbeSettings:
    """The settings of ``--mode ofbe``.

    Attributes
    ----------
    still_sd_g
        An epoch is still when its standard deviation is below this on every axis, g.
    epoch_s
        Length of one epoch, s (for ``hours``).
    sphere_check
        False skips the coverage rule (the ladder's determination rules still apply).
    model
        ``auto`` (the ladder) or a model to force (``full+temperature`` …).
    coverage_deg
        The coverage rule's cone, degrees (above 0, at most 90).
    exclude_idle
        Leave idle epochs out (:func:`~ofbe_data.freeliving.epochs.idle_sleep`: standard
        deviation 0, zero or repeated means); False keeps them, as GGIR does.
    alpha
        Significance level of the ladder's Wald tests (0 < alpha < 1): a richer model is taken
        when p < alpha.
    max_condition
        Largest condition number of a model the ladder fits (at least 1).

    Raises
    ------
    SettingsError
        A setting out of its range (the message names it).
    """

    still_sd_g: float = 0.013
    epoch_s: float = 10.0
    sphere_check: bool = True
    model: str = "auto"
    coverage_deg: float = COVERAGE_DEG
    exclude_idle: bool = True
    alpha: float = ALPHA
    max_condition: float = MAX_CONDITION

    def __post_init__(self) -> None:
        for name in ("still_sd_g", "epoch_s", "coverage_deg", "max_condition"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise SettingsError("OfbeSettings", name, "a positive number", repr(value))
        if self.model != "auto" and self.model not in MODELS:
            raise SettingsError("OfbeSettings", "model", f"auto or one of {', '.join(MODELS)}",
                                repr(self.model))
        if not self.coverage_deg <= 90:
            raise SettingsError("OfbeSettings", "coverage_deg", "a number of degrees above 0 and at most 90",
                                repr(self.coverage_deg))
        if not (isinstance(self.alpha, int | float) and 0 < self.alpha < 1):
            raise SettingsError("OfbeSettings", "alpha", "a number between 0 and 1", repr(self.alpha))
        if not self.max_condition >= 1:
            raise SettingsError("OfbeSettings", "max_condition", "a number >= 1 (a condition number)",
                                repr(self.max_condition))


@dataclass(frozen=True, eq=False)
class OfbeResult:
    """One recording calibrated by ``--mode ofbe``.

    Attributes
    ----------
    model
        The model fitted (``full+temperature`` …); None when nothing was fitted.
    calibrated
        Whether the coefficients are applied (False: identity in GGIR's columns).
    qc
        One line beginning with one of :data:`QC_OFBE_OUTCOMES`.
    n_epochs, n_still, n_idle
        Epochs given; still epochs fitted; idle epochs left out.
    hours
        Hours of data: epochs less idle ones, times the epoch length.
    cal_error_start, cal_error_end
        GGIR's ``cal.error`` over the still epochs before and after, g; None where there is none.
    temp_mean_c
        τ₀, the still epochs' mean temperature, °C, when the model has a temperature slope.
    columns
        The coefficient columns of the summary (:func:`coefficient_columns`), each with its
        ``_se``; None where not fitted.
    idle, still
        Shape (n_epochs,): the idle epochs; the still epochs fitted.
    weights
        Shape (n_epochs,): each fitted epoch's robust weight (0 to 1), NaN elsewhere.
    missing
        The signed axes the coverage rule found without still epochs.
    reason
        The ladder's line ("" without a fit).
    fit
        The chosen fit, when one was made.
    """

    model: str | None
    calibrated: bool
    qc: str
    n_epochs: int
    n_still: int
    n_idle: int
    hours: float
    cal_error_start: float | None
    cal_error_end: float | None
    temp_mean_c: float | None
    columns: dict[str, float | None]
    idle: np.ndarray
    still: np.ndarray
    weights: np.ndarray
    missing: tuple[str, ...] = ()
    reason: str = ""
    fit: PoseFit | None = field(default=None)


def identity_columns() -> dict[str, float | None]:
    """The coefficient columns of a recording not calibrated: identity in GGIR's convention
    (scale 1, offsets 0, as GGIR writes), nothing else."""
    out: dict[str, float | None] = {n: None for n in (*GGIR_COLUMNS, *OFBE_COLUMNS)}
    out.update({f"{n}_se": None for n in (*GGIR_COLUMNS, *OFBE_COLUMNS)})
    for a in AXES:
        out[f"offset_{a}"], out[f"scale_{a}"], out[f"temp_offset_{a}"] = 0.0, 1.0, 0.0
    return out


def coefficient_columns(fit: PoseFit) -> dict[str, float | None]:
    """The summary's coefficient columns of a determined fit, each with its standard error.

    See the module notes for the two conventions. A value the model fixes (a scale of the
    ``offset`` model, A's zeros, no temperature slope) is written with an empty ``_se``; GGIR's
    columns are all empty for a ``full`` model.

    Parameters
    ----------
    fit
        A determined fit of the ladder (data in g).

    Returns
    -------
    dict
        Every name of :data:`GGIR_COLUMNS` and :data:`OFBE_COLUMNS` and its ``_se``.
    """
    model, x, cov = fit.model, fit.params, fit.covariance
    base, temp = base_model(model), has_temperature(model)
    out = {n: None for n in (*GGIR_COLUMNS, *OFBE_COLUMNS)} | {f"{n}_se": None for n in (*GGIR_COLUMNS,
                                                                                        *OFBE_COLUMNS)}
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))

    def put(names: list[str], func: Callable[[np.ndarray], np.ndarray], free: np.ndarray) -> None:
        values = np.asarray(func(x)).ravel()
        errors = derived_se(lambda p: np.asarray(func(p)).ravel(), x, cov)
        for k, name in enumerate(names):
            out[name] = float(values[k])
            out[f"{name}_se"] = float(errors[k]) if free[k] else None

    every = np.ones(9, dtype=bool)
    for k, a in enumerate(AXES):
        out[f"ofbe_offset_{a}"], out[f"ofbe_offset_{a}_se"] = float(x[k]), float(se[k])
    if base != "offset":
        free = np.eye(3, dtype=bool) if base == "scale-offset" else np.triu(np.ones((3, 3), dtype=bool))
        put([f"a_{r}{c}" for r in AXES for c in AXES], lambda p: map_from_params(p, model), free.ravel())
    for k, a in enumerate(AXES):
        if temp:
            out[f"ofbe_temp_slope_{a}"], out[f"ofbe_temp_slope_{a}_se"] = float(x[-3 + k]), float(se[-3 + k])
    if base == "full":
        return out

    def scale(p: np.ndarray) -> np.ndarray:
        return p[3:6] if base == "scale-offset" else np.ones(3)

    put([f"offset_{a}" for a in AXES], lambda p: -p[:3], every)
    put([f"scale_{a}" for a in AXES], scale, np.full(3, base == "scale-offset"))
    put([f"temp_offset_{a}" for a in AXES], lambda p: -p[-3:] * scale(p) if temp else np.zeros(3),
        np.full(3, temp))
    return out


def _idle_words(n_idle: int) -> str:
    if not n_idle:
        return ""
    return (f"; {n_idle} idle-sleep epoch{'s' if n_idle != 1 else ''} left out (standard deviation 0, "
            "zero or repeated means)")


def ofbe_calibrate(epochs: EpochTable, settings: OfbeSettings | None = None) -> OfbeResult:
    """Calibrate one recording from its epochs by ofbe's ladder (module notes).

    Parameters
    ----------
    epochs
        The epochs of one recording, in time order (or GGIR's ``spheredata``, taken as it is).
    settings
        The settings (defaults when None).

    Returns
    -------
    OfbeResult
        Never raises on data: every outcome is a ``qc`` line.

    Raises
    ------
    ValueError
        ``settings.model`` is not a model of the ladder, or a ``+temperature`` model is forced
        on epochs without a usable temperature.
    """
    s = settings or OfbeSettings()
    n = epochs.n
    idle = idle_sleep(epochs) if s.exclude_idle else np.zeros(n, dtype=bool)
    n_idle = int(idle.sum())
    means, sds = epochs.mean_g, epochs.sd_g
    still = ~idle & np.all(sds < s.still_sd_g, axis=1) & np.all(np.abs(means) < MAX_ABS_MEAN_G, axis=1)
    hours = (n - n_idle) * s.epoch_s / 3600.0
    weights = np.full(n, np.nan)
    idle_note = _idle_words(n_idle)

    def outcome(qc: str, **kw: object) -> OfbeResult:
        base: dict[str, object] = dict(
            model=None, calibrated=False, qc=qc + idle_note, n_epochs=n, n_still=int(still.sum()),
            n_idle=n_idle, hours=hours, cal_error_start=None, cal_error_end=None, temp_mean_c=None,
            columns=identity_columns(), idle=idle, still=still, weights=weights)
        base.update(kw)
        return OfbeResult(**base)  # type: ignore[arg-type]

    n_still = int(still.sum())
    if n_still == 0:
        return outcome(f"{QC_OFBE_NO_STILL} (standard deviation below {s.still_sd_g * 1000:g} mg on every "
                       f"axis and |mean| below {MAX_ABS_MEAN_G:g} g)")
    if n_still < MIN_STILL_EPOCHS:
        return outcome(f"{QC_OFBE_TOO_FEW}: {n_still}, at least {MIN_STILL_EPOCHS} needed")
    x = means[still]
    temps = (epochs.temperature_c[still] if epochs.temperature_c is not None
             and use_temperature(epochs.temperature_c) else None)
    start = sphere_error(x)
    missing = missing_faces(x, s.coverage_deg)
    if s.sphere_check and missing:
        return outcome(f"{QC_OFBE_SPHERE}: {coverage_words(missing, s.coverage_deg)}", cal_error_start=start,
                       missing=missing)
    choice = choose_wear_model(x, temps, s.model, s.alpha, s.max_condition)
    fit = choice.fit.fit
    if not fit.determined:
        where = f"{coverage_words(missing, s.coverage_deg)}; " if missing else ""
        return outcome(f"{QC_OFBE_SPHERE}: {where}{choice.reason}", cal_error_start=start, missing=missing,
                       reason=choice.reason)
    dtemp = temps - fit.temp_ref_c if temps is not None and has_temperature(fit.model) else np.zeros(len(x))
    end = float(np.mean(np.abs(norm_residuals(fit.params, x, dtemp, fit.model))))
    weights[still] = choice.fit.weights
    temp_mean = fit.temp_ref_c if has_temperature(fit.model) else None
    common: dict[str, object] = dict(model=fit.model, cal_error_start=start, cal_error_end=end,
                                     missing=missing, reason=choice.reason, fit=fit, weights=weights)
    # compared at GGIR's resolution, 1e-5 g: a file already calibrated 'improves' by micrograms
    if not (math.isfinite(end) and round(end, 5) < round(start, 5)):
        return outcome(f"{QC_OFBE_NOT_DECREASED} ({fit.model}: {start * 1000:.3f} mg before, "
                       f"{end * 1000:.3f} mg after)", **common)
    return outcome(f"{QC_OFBE_DONE}: {fit.model} model, error {start * 1000:.3f} -> {end * 1000:.3f} mg "
                   f"({choice.reason})", calibrated=True, temp_mean_c=temp_mean,
                   columns=coefficient_columns(fit), **common)
