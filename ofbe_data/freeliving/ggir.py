"""GGIR's free-living auto-calibration (``g.calibrate``), reproduced on epoch data.

Reference: wadpac/GGIR, R/g.calibrate.R (Apache-2.0; van Hees et al. 2014, J Appl Physiol
117:738, and the fitting code by Zhou Fang in it), as stored at commit ad173355402e (GGIR 3.x).
The fitting loop is the same at 02485a861345 (2019) and reproduces GGIR's own 2016 result in
tests/data/ggir-calibrate/ to 1e-14. The steps below are written anew from the algorithm; each
says which part of ``g.calibrate`` (or of ``g.part1``, which applies the result) it follows.

Model (GGIR's sign and units)::

    calibrated = (raw + offset) * scale + (T - T_mean) * temp_offset

with raw and calibrated in g, T in °C, per axis. The fit moves the still epochs' means onto the
unit sphere by iteratively re-weighted least squares.

What differs from GGIR, and why
-------------------------------
- GGIR reads raw data in blocks of about 12 h, re-fits on everything read so far after each
  block and stops reading at the first fit it accepts (more than ``minloadcrit`` = 72 h read,
  error below 10 mg and reduced). Given epochs, this fits all of them once: the same as GGIR
  when GGIR reads the whole file (a recording of up to about 3 days, or one GGIR cannot
  calibrate), or when the epochs are GGIR's own ``spheredata``.
- GGIR ignores the temperature when the mean of the first 10 *raw samples* of a block is above
  120 °C or their standard deviation in a block is below 0.01 °C; here the same thresholds
  apply to the epoch temperatures (the first 10 epochs; all epochs).
- GGIR removes all-zero raw samples (a device's idle periods) before making epochs; here an
  epoch whose three means are exactly 0 is removed.
- For ActiGraph and Movisens data only, GGIR drops epochs whose nearest sphere point is
  undefined during the fit; with all-zero epochs removed no such epoch remains here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ofbe_data.freeliving.epochs import EpochTable

QC_DONE = "recalibration done, no problems detected"
QC_DONE_NO_TEMPERATURE = "recalibration done, but temperature values not used"
QC_NOT_GOOD_ENOUGH = ("recalibration attempted with all available data, but possibly not good enough: "
                      "Check calibration error variable to varify this")
"""GGIR's words, its spelling ("varify") kept so that its users can search for them."""
QC_NOT_DECREASED = "recalibration not done because recalibration does not decrease error"
QC_SPHERE_NOT_POPULATED = "recalibration not done because not enough points on all sides of the sphere"
QC_NO_STILL = "recalibration not done because no non-movement data available"
QC_TOO_SHORT = "recalibration not done because not enough data in the file or because file is corrupt"
QC_MESSAGES = (QC_DONE, QC_DONE_NO_TEMPERATURE, QC_NOT_GOOD_ENOUGH, QC_NOT_DECREASED,
               QC_SPHERE_NOT_POPULATED, QC_NO_STILL, QC_TOO_SHORT)
"""Every ``QCmessage`` that ``g.calibrate`` gives, verbatim."""

MAX_ABS_MEAN_G = 2.0
"""A still epoch's mean is below this on every axis, g (GGIR: "to reduce chance of including
clipping periods")."""
MIN_STILL_EPOCHS = 10
"""Fewer still epochs than this is "no non-movement data" (GGIR 3.x)."""
MAX_ITERATIONS = 1000
"""GGIR's ``maxiter``."""
TOLERANCE = 1e-10
"""GGIR's ``tol``: the fit stops when its weighted mean squared residual changes by less."""
MAX_WEIGHT = 100.0
"""GGIR's cap on an epoch's weight, ``1/0.01``: residuals below 10 mg weigh alike."""
MAX_ERROR_G = 0.01
"""A fit is accepted only with ``cal.error.end`` below this, g."""
TEMPERATURE_MAX_C = 120.0
"""Temperature is ignored when the first 10 values average above this, °C (GGIR 3.x; 40 °C
in GGIR 1.x)."""
TEMPERATURE_MIN_SD_C = 0.01
"""Temperature is ignored when its standard deviation is below this, °C."""
ERROR_DECIMALS = 5
"""GGIR 3.x rounds ``cal.error.start`` and ``cal.error.end`` to 5 decimals (1e-5 g) and decides
on the rounded values."""
_LOAD_ROWS_MARGIN = 21
"""GGIR needs more than ``minloadcrit - 21`` epochs (51 by default) before it looks for still
ones: hours less a margin, compared with a count of epochs, as GGIR does."""


class SettingsError(ValueError):
    """A setting of :class:`GgirSettings` or :class:`~ofbe_data.freeliving.ofbe.OfbeSettings`
    out of its range; ``name`` is the field, so that a parameter file can name its key.

    Parameters
    ----------
    record
        The settings' class name (``GgirSettings``).
    name
        The field.
    expected, found
        What the field takes and what was given.
    """

    def __init__(self, record: str, name: str, expected: str, found: str) -> None:
        self.name, self.expected, self.found = name, expected, found
        super().__init__(f"{record}.{name}: expected {expected}, found {found}")


@dataclass(frozen=True)
class GgirSettings:
    """The settings of ``g.calibrate`` that a user may change (GGIR's defaults).

    Attributes
    ----------
    still_sd_g
        GGIR's ``sdcriter``: an epoch is still when its standard deviation is below this on
        every axis, g (0.013; GGIR uses ``rmc.noise * 1.2`` for its ad-hoc csv format).
    sphere_crit_g
        GGIR's ``spherecrit``: every axis needs still epochs below ``-sphere_crit_g`` and
        above ``+sphere_crit_g``, g.
    min_load_hours
        GGIR's ``minloadcrit``: a fit is accepted only from more than this many hours of data.
    epoch_s
        Length of one epoch, s (GGIR's ``calibEpochSize``, fixed at 10); converts epochs to
        hours.
    sphere_check
        False skips the sphere-coverage rule (``--no-sphere-check``; GGIR has no such switch).
    """

    still_sd_g: float = 0.013
    sphere_crit_g: float = 0.3
    min_load_hours: float = 72.0
    epoch_s: float = 10.0
    sphere_check: bool = True

    def __post_init__(self) -> None:
        for name in ("still_sd_g", "sphere_crit_g", "min_load_hours", "epoch_s"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise SettingsError("GgirSettings", name, "a positive number", repr(value))


@dataclass(frozen=True, eq=False)
class GgirResult:
    """What ``g.calibrate`` returns for one recording, with the coefficients GGIR applies.

    Attributes
    ----------
    scale
        Shape (3,): scale per axis (dimensionless); ones when not calibrated.
    offset
        Shape (3,): offset per axis, g, GGIR's sign (added to the raw value before scaling);
        zeros when not calibrated.
    temp_offset
        Shape (3,): temperature coefficient per axis, g/°C; zeros when not calibrated or the
        temperature is not used.
    temp_mean_c
        Mean temperature of the still epochs, °C (GGIR's ``meantempcal``); None without
        temperature or still epochs.
    cal_error_start, cal_error_end
        Mean | ‖mean‖ − 1 | over the still epochs before and after calibration, g, not rounded
        (GGIR 3.x prints them rounded to 1e-5 g); None where GGIR has none (no still epochs;
        no fit).
    qc
        GGIR's ``QCmessage``, verbatim (one of :data:`QC_MESSAGES`).
    calibrated
        Whether GGIR applies the coefficients (``g.part1``: not when either error is missing
        or the error grew).
    use_temp
        Whether the temperature was used (GGIR's ``use.temp``).
    n_epochs
        Epochs given.
    n_still
        Still epochs fitted (GGIR's ``npoints``); 0 when there were too few.
    hours
        Hours of data behind the decision (GGIR's ``nhoursused``).
    iterations
        Iterations of the fit; 0 without a fit.
    still
        Shape (n_epochs,): which of the given epochs were the still epochs used.
    """

    scale: np.ndarray
    offset: np.ndarray
    temp_offset: np.ndarray
    temp_mean_c: float | None
    cal_error_start: float | None
    cal_error_end: float | None
    qc: str
    calibrated: bool
    use_temp: bool
    n_epochs: int
    n_still: int
    hours: float
    iterations: int = 0
    still: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    @property
    def model(self) -> str:
        """``ggir scale-offset+temperature`` or ``ggir scale-offset``."""
        return "ggir scale-offset+temperature" if self.use_temp else "ggir scale-offset"


@dataclass(frozen=True)
class _Fit:
    scale: np.ndarray
    offset: np.ndarray
    temp_offset: np.ndarray
    iterations: int


def sphere_error(means_g: np.ndarray) -> float:
    """Mean | ‖v‖ − 1 | over rows of ``means_g`` (shape (n, 3), g): GGIR's ``cal.error``."""
    return float(np.mean(np.abs(np.sqrt(np.sum(means_g**2, axis=1)) - 1.0)))


def use_temperature(temperature_c: np.ndarray | None) -> bool:
    """GGIR's temperature checks (g.calibrate, after reading a block: ``use.temp`` becomes FALSE
    when ``mean(data[1:10, "temperature"]) > 120`` or ``sd(data[, "temperature"]) < 0.01``),
    applied to the epoch temperatures."""
    if temperature_c is None or len(temperature_c) == 0:
        return False
    if np.mean(temperature_c[:10]) > TEMPERATURE_MAX_C:
        return False
    return not (len(temperature_c) > 1 and np.std(temperature_c, ddof=1) < TEMPERATURE_MIN_SD_C)


def _without_duplicates(means: np.ndarray, sds: np.ndarray) -> np.ndarray:
    """Mask of the epochs GGIR keeps after its duplicate removal (g.calibrate, "remove
    duplicates, e.g. caused by periods of nonwear": an epoch goes when exactly three of its six
    values ``meanx … sdz`` equal those of the next epoch, ``rowSums(… == …) == 3`` as written)."""
    keep = np.ones(len(means), dtype=bool)
    if len(means) > 1:
        values = np.column_stack([means, sds])
        same = np.sum(values[:-1] == values[1:], axis=1)
        keep[:-1] = same != 3
    return keep


def fit_sphere(means_g: np.ndarray, temperature_c: np.ndarray | None) -> tuple[np.ndarray, np.ndarray,
                                                                                np.ndarray, int]:
    """GGIR's iteratively re-weighted fit of still epochs to the unit sphere.

    Follows g.calibrate's "Zhou Fang's code" block step by step:

    1. temperature centred on its mean over the still epochs (``inputtemp - meantemp``), or
       zero without temperature; offset 0, scale 1, temperature offset 0, weights 1;
    2. each iteration: the current calibrated means (``curr``), their nearest points on the
       unit sphere (``closestpoint = curr / ‖curr‖``), and per axis a weighted least-squares
       fit of the nearest point on (1, current value, centred temperature) (``lm.wfit``);
    3. the fitted intercept a, slope b and temperature slope c update the coefficients as
       ``offset += a / (scale * b)``, ``temp_offset = temp_offset * b + c``,
       ``scale *= b``; the fitted values become the current means;
    4. ``res`` = 3 · mean(w · (curr − closest)²) / Σw; new weights
       w = min(1 / ‖curr − closest‖, 100);
    5. stop when ``res`` changes by less than 1e-10, or after 1000 iterations.

    Parameters
    ----------
    means_g
        Shape (n, 3): means of the still epochs, g.
    temperature_c
        Shape (n,): their temperatures, °C; None to fit scale and offset only.

    Returns
    -------
    scale, offset, temp_offset, iterations
        Shapes (3,), (3,) g, (3,) g/°C, and the number of iterations run.
    """
    x = np.asarray(means_g, dtype=np.float64)
    n = len(x)
    use_temp = temperature_c is not None
    t = (np.asarray(temperature_c, dtype=np.float64) - np.mean(temperature_c)) if use_temp else np.zeros(n)
    offset, scale, temp_offset = np.zeros(3), np.ones(3), np.zeros(3)
    weights = np.ones(n)
    previous = math.inf
    ones = np.ones(n)
    iterations = 0
    for _ in range(MAX_ITERATIONS):
        iterations += 1
        curr = (x + offset) * scale + t[:, None] * temp_offset
        closest = curr / np.sqrt(np.sum(curr**2, axis=1))[:, None]
        a, b, c = np.zeros(3), np.ones(3), np.zeros(3)
        root_w = np.sqrt(weights)
        for k in range(3):
            design = np.column_stack([ones, curr[:, k], t] if use_temp else [ones, curr[:, k]])
            coef = np.linalg.lstsq(design * root_w[:, None], closest[:, k] * root_w, rcond=None)[0]
            a[k], b[k] = coef[0], coef[1]
            if use_temp:
                c[k] = coef[2]
            curr[:, k] = design @ coef
        offset = offset + a / (scale * b)
        if use_temp:
            temp_offset = temp_offset * b + c
        scale = scale * b
        residual = curr - closest
        res = 3.0 * float(np.mean(weights[:, None] * residual**2 / np.sum(weights)))
        with np.errstate(divide="ignore"):
            weights = np.minimum(1.0 / np.sqrt(np.sum(residual**2, axis=1)), MAX_WEIGHT)
        if abs(res - previous) < TOLERANCE:
            break
        previous = res
    return scale, offset, temp_offset, iterations


def apply_ggir(means_g: np.ndarray, temperature_c: np.ndarray | None, scale: np.ndarray, offset: np.ndarray,
               temp_offset: np.ndarray, temp_mean_c: float | None) -> np.ndarray:
    """GGIR's calibration of epoch means: ``(raw + offset) * scale + (T - T_mean) * temp_offset``.

    Parameters
    ----------
    means_g
        Shape (n, 3): raw means, g.
    temperature_c
        Shape (n,): temperatures, °C; None (or ``temp_mean_c`` None) for no temperature term.
    scale, offset, temp_offset
        Shapes (3,): GGIR's coefficients (dimensionless, g, g/°C).
    temp_mean_c
        GGIR's ``meantempcal``, °C.

    Returns
    -------
    np.ndarray
        Shape (n, 3): calibrated means, g.
    """
    out = (np.asarray(means_g, dtype=np.float64) + offset) * scale
    if temperature_c is not None and temp_mean_c is not None:
        out = out + (np.asarray(temperature_c, dtype=np.float64) - temp_mean_c)[:, None] * temp_offset
    return out


def _not_calibrated(epochs: EpochTable, qc: str, use_temp: bool, hours: float, still: np.ndarray,
                    start: float | None = None, temp_mean_c: float | None = None) -> GgirResult:
    """A result with identity coefficients (g.part1 resets them when GGIR has no error after)."""
    return GgirResult(scale=np.ones(3), offset=np.zeros(3), temp_offset=np.zeros(3), temp_mean_c=temp_mean_c,
                      cal_error_start=start, cal_error_end=None, qc=qc, calibrated=False, use_temp=use_temp,
                      n_epochs=epochs.n, n_still=int(still.sum()), hours=hours, still=still)


def _sphere_populated(means_g: np.ndarray, crit_g: float) -> bool:
    """GGIR's coverage rule (g.calibrate, "check whether sphere is well populated"): on each
    axis the smallest still mean is below ``-crit_g`` and the largest above ``+crit_g``."""
    return bool(np.all((means_g.min(axis=0) < -crit_g) & (means_g.max(axis=0) > crit_g)))


def ggir_calibrate(epochs: EpochTable, settings: GgirSettings | None = None, *,
                   hours: float | None = None) -> GgirResult:
    """Calibrate one recording from its epochs as GGIR's ``g.calibrate`` does.

    The steps, in GGIR's order (g.calibrate unless said otherwise):

    1. temperature used when the epochs have it and it passes GGIR's checks
       (``use.temp = temp.available``, then the 120 °C and 0.01 °C checks);
    2. epochs with all three means exactly 0 removed (GGIR removes all-zero raw samples), and
       GGIR's duplicate removal (see :func:`_without_duplicates`);
    3. more than ``minloadcrit - 21`` epochs needed, else "not enough data"; the hours used
       (``nhoursused``) are the epochs kept times 10 s;
    4. the recording's first epoch dropped (``features_temp[-1, ]``);
    5. still epochs: standard deviation below ``still_sd_g`` and |mean| below 2 g on every
       axis (``nomovement``); fewer than 10 is "no non-movement data";
    6. ``cal.error.start`` over the still epochs; the sphere-coverage rule;
    7. the fit (:func:`fit_sphere`), ``cal.error.end``;
    8. QC: accepted ("recalibration done, …") when the error after is below the error before
       and below 10 mg and more than ``minloadcrit`` hours were used; "does not decrease
       error" when it grew; otherwise "attempted … possibly not good enough";
    9. g.part1 applies the coefficients unless an error is missing or the error grew; then
       identity (scale 1, offsets 0).

    For GGIR's own ``spheredata`` (``epochs.ggir_spheredata``) steps 2–4 were done by GGIR
    already and are skipped; the still criteria of step 5 hold for every epoch of it.

    Parameters
    ----------
    epochs
        The epochs of one recording (GGIR's 10-s epochs unless ``settings.epoch_s`` says
        otherwise).
    settings
        GGIR's settings (its defaults when None).
    hours
        Hours of recording the epochs stand for (GGIR's ``nhoursused``), when they are more than
        the epochs show: GGIR's ``spheredata`` holds the still epochs only. Default: the number
        of epochs kept times ``epoch_s``.

    Returns
    -------
    GgirResult
        Never raises on data: every outcome GGIR reports as a ``QCmessage`` is a result.
    """
    s = settings or GgirSettings()
    temp_available = epochs.temperature_c is not None
    use_temp = use_temperature(epochs.temperature_c)
    means, sds = epochs.mean_g, epochs.sd_g
    considered = np.ones(epochs.n, dtype=bool)
    if not epochs.ggir_spheredata:
        considered &= ~np.all(means == 0.0, axis=1)
        kept = np.flatnonzero(considered)
        considered[kept[~_without_duplicates(means[kept], sds[kept])]] = False
    n_kept = int(considered.sum())
    used_hours = (n_kept * s.epoch_s / 3600.0) if hours is None else float(hours)
    none = np.zeros(epochs.n, dtype=bool)
    if not epochs.ggir_spheredata:
        if n_kept <= s.min_load_hours - _LOAD_ROWS_MARGIN:
            return _not_calibrated(epochs, QC_TOO_SHORT, use_temp, 0.0 if hours is None else used_hours, none)
        considered[np.flatnonzero(considered)[0]] = False
    still = considered & np.all(sds < s.still_sd_g, axis=1) & np.all(np.abs(means) < MAX_ABS_MEAN_G, axis=1)
    if still.sum() < MIN_STILL_EPOCHS:
        return _not_calibrated(epochs, QC_NO_STILL, use_temp, used_hours, none)
    x = means[still]
    temps = epochs.temperature_c[still] if use_temp and epochs.temperature_c is not None else None
    temp_mean = float(np.mean(temps)) if temps is not None else None
    start = sphere_error(x)
    if s.sphere_check and not _sphere_populated(x, s.sphere_crit_g):
        return _not_calibrated(epochs, QC_SPHERE_NOT_POPULATED, use_temp, used_hours, still, start, temp_mean)
    scale, offset, temp_offset, iterations = fit_sphere(x, temps)
    end = sphere_error(apply_ggir(x, temps, scale, offset, temp_offset, temp_mean))
    if not all(map(math.isfinite, (end, *scale, *offset, *temp_offset))):
        # GGIR stops with an R error here (lm.wfit refuses NaN); ofbe reports "not decreased"
        return _not_calibrated(epochs, QC_NOT_DECREASED, use_temp, used_hours, still, start, temp_mean)
    start_r, end_r = round(start, ERROR_DECIMALS), round(end, ERROR_DECIMALS)
    if end_r < start_r and end_r < MAX_ERROR_G and used_hours > s.min_load_hours:
        qc = QC_DONE if use_temp == temp_available else QC_DONE_NO_TEMPERATURE
    else:
        qc = QC_NOT_GOOD_ENOUGH
    if end_r > start_r:
        qc = QC_NOT_DECREASED
    if start_r < end_r:  # g.part1: "cal.error.start < cal.error.end" → identity coefficients
        result = _not_calibrated(epochs, qc, use_temp, used_hours, still, start, temp_mean)
        return replace(result, cal_error_end=end, iterations=iterations)
    return GgirResult(scale=scale, offset=offset, temp_offset=temp_offset, temp_mean_c=temp_mean,
                      cal_error_start=start, cal_error_end=end, qc=qc, calibrated=True, use_temp=use_temp,
                      n_epochs=epochs.n, n_still=int(still.sum()), hours=used_hours, iterations=iterations,
                      still=still)
