"""What every kind of label shares: the labelling parameters, the session's labels and
rejections, the reasons for a rejection, the stationary segment and the label row built from
it (:mod:`ofbe_data.labelling.labels` labels rotated and gravity-aligned sessions with them,
:mod:`ofbe_data.labelling.multi_labels` multi-position ones)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ofbe_data.core.errors import ConfigError
from ofbe_data.io.manifest import DeviceSpec, SessionManifest
from ofbe_data.io.recording import TEMPERATURE, Recording, mean_temperature
from ofbe_data.io.typedconfig import from_plain, read_section
from ofbe_data.labelling.campaign_fit import CampaignFitParams
from ofbe_data.labelling.checks import (
    MAX_LEVEL_TILT_DEG,
    MAX_MOUNT_ERROR_DEG,
    MAX_NORM_DEVIATION,
    MIN_CLIP_RATIO,
    WARN_LEVEL_TILT_DEG,
    clipped_samples,
    norm_problem,
    rate_problem,
    skipped_lines_problem,
    typical_norm_problem,
)
from ofbe_data.labelling.convergence import PAPER_THRESHOLD, PAPER_WINDOW, convergence_index
from ofbe_data.labelling.multiposition import MODELS, PoseParams
from ofbe_data.labelling.orientation import roll_pitch
from ofbe_data.labelling.stationarity import (
    StaticParams,
    check_static,
    column_mean,
    is_still,
)
from ofbe_data.labelling.sync import SyncParams

LABELS_FORMAT = "ofbe-labels/1"
REJECTIONS_FORMAT = "ofbe-rejections/1"

#: Rejection reasons (``reason`` in the rejection file).
GARBLED = "garbled"
SATURATED = "saturated"
MOTION = "motion"
TOO_SHORT = "too-short"
NO_SEGMENT = "no-stationary-segment"
SYNC_FAILED = "sync-failed"
UNDETERMINED = "multi-position-undetermined"
IMPLAUSIBLE_NORM = "implausible-norm"
IMPLAUSIBLE_RATE = "implausible-rate"
NOT_LEVEL = "not-level"
MOUNT_MISMATCH = "mount-mismatch"
REFERENCE_PREFIX = "reference-"


@dataclass(frozen=True)
class LabelParams:
    """Parameters of labelling (``label:`` in params.yaml).

    Attributes
    ----------
    min_samples
        Fewest stationary samples a label may rest on (the convergence analysis' result).
    margin_s
        Time left out after the first and before the last tap, s.
    max_skipped_fraction
        Largest fraction of a file's data lines that may be garbled and skipped.
    convergence_window, convergence_threshold
        The paper's convergence criterion (steps, m/s²).
    fit_model
        The model of methods.md §8's ladder fitted to a multi-position session's poses:
        ``auto`` (the richest the poses support, :func:`ofbe_data.labelling.multiposition.choose_fit`)
        or one forced: ``offset``, ``scale-offset``, ``full``, or any of them with
        ``+temperature``. (``multi_position_model`` is read as a former name of this key.)
    fit_alpha
        Significance level of the F-test by which ``auto`` moves to a richer model.
    multi_position_max_condition
        Largest condition number of a session's pose fit (its column-scaled Jacobian: good
        pose sets give 1–10, nearly coplanar ones thousands).
    static
        Static detector.
    sync
        Tap synchronisation.
    campaign_fit
        Campaign-level refinement.
    max_norm_deviation
        Largest ``|‖mean‖ / g_local − 1|`` of a stationary mean (methods.md §9: 0.3); beyond
        it the recording is rejected as ``implausible-norm`` with the likely unit mistake.
    max_level_tilt_deg
        Largest tilt of a gravity-aligned device from its nearest axis (default: the
        small-angle threshold 2.866°, where a level label leaks 50 mg); beyond it ``not-level``.
    warn_level_tilt_deg
        A smaller tilt above this is kept with a warning.
    max_mount_error_deg
        Largest angle between a DUT's measured gravity direction and the one its declared
        ``reference_to_sensor`` predicts (rotated sessions); beyond it ``mount-mismatch``.
    poses
        The pose detector of multi-position sessions (:mod:`ofbe_data.labelling.multiposition._poses`).
    """

    min_samples: int = 4500
    margin_s: float = 1.0
    max_skipped_fraction: float = 0.01
    convergence_window: int = PAPER_WINDOW
    convergence_threshold: float = PAPER_THRESHOLD
    fit_model: str = "auto"
    fit_alpha: float = 0.05
    multi_position_max_condition: float = 1000.0
    static: StaticParams = field(default_factory=StaticParams)
    sync: SyncParams = field(default_factory=SyncParams)
    campaign_fit: CampaignFitParams = field(default_factory=CampaignFitParams)
    max_norm_deviation: float = MAX_NORM_DEVIATION
    max_level_tilt_deg: float = MAX_LEVEL_TILT_DEG
    warn_level_tilt_deg: float = WARN_LEVEL_TILT_DEG
    max_mount_error_deg: float = MAX_MOUNT_ERROR_DEG
    poses: PoseParams = field(default_factory=PoseParams)


def label_params_from(data: dict[str, Any] | None, source: str | Path = "<parameters>") -> LabelParams:
    """Build :class:`LabelParams` from a plain mapping, checking keys and types.

    Raises
    ------
    ConfigError
        Unknown key, wrong type, or a value out of range.
    """
    data = dict(data or {})
    if "multi_position_model" in data:  # the key's former name
        if "fit_model" in data:
            raise ConfigError(source, "label.multi_position_model", "only label.fit_model (its new name)",
                              "both keys")
        data["fit_model"] = data.pop("multi_position_model")
    params: LabelParams = from_plain(data, LabelParams, source, "label")
    if params.min_samples < 2:
        raise ConfigError(source, "label.min_samples", "an integer ≥ 2", str(params.min_samples))
    if params.margin_s < 0:
        raise ConfigError(source, "label.margin_s", "a number ≥ 0", str(params.margin_s))
    for key in ("max_norm_deviation", "max_level_tilt_deg", "warn_level_tilt_deg", "max_mount_error_deg"):
        if not getattr(params, key) > 0:
            raise ConfigError(source, f"label.{key}", "a number > 0", str(getattr(params, key)))
    if params.fit_model not in ("auto", *MODELS):
        raise ConfigError(source, "label.fit_model", "auto or one of " + ", ".join(MODELS),
                          repr(params.fit_model))
    if not params.multi_position_max_condition >= 1:  # a condition number is never below 1
        raise ConfigError(source, "label.multi_position_max_condition", "a number ≥ 1 (a condition number)",
                          str(params.multi_position_max_condition))
    if not 0 < params.fit_alpha < 1:
        raise ConfigError(source, "label.fit_alpha", "a number between 0 and 1", str(params.fit_alpha))
    return params


def read_label_section(path: str | Path) -> dict[str, Any]:
    """The plain ``label:`` section of a YAML file (params.yaml), or the whole document when
    it has none."""
    return read_section(path, "label", whole_if_missing=True)


def load_label_params(path: str | Path) -> LabelParams:
    """Labelling parameters from a YAML file (see :func:`read_label_section`)."""
    return label_params_from(read_label_section(path), path)


@dataclass(frozen=True)
class Rejection:
    """A recording of one device that was not labelled, and why."""

    recording: str
    device: str
    reason: str
    detail: str

    def to_dict(self) -> dict[str, str]:
        return {"recording": self.recording, "device": self.device, "reason": self.reason,
                "detail": self.detail}


@dataclass
class SessionLabels:
    """Everything labelling found in one session.

    Attributes
    ----------
    manifest
        The session's manifest.
    rows
        One dict per labelled (recording, device), keyed by column name.
    rejections
        Recordings not labelled.
    warnings
        Things a person should check (e.g. taps missing, header-stamp alignment).
    notes
        Information on a good session, no warning (e.g. the poses found and the threshold).
    files
        SHA-256 of every file read, by path relative to the session folder (manifest too).

    Rows also carry two private entries for the campaign fit, not written out: ``_mean``
    (3,) mean reading and ``_u`` (3,) gravity direction, sensor frame.
    """

    manifest: SessionManifest
    rows: list[dict[str, Any]] = field(default_factory=list)
    rejections: list[Rejection] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    files: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Segment:
    """Samples [start, stop) of a recording chosen as stationary, or why none."""

    start: int
    stop: int
    problem: str = ""
    static_checked: bool = False  # chosen by the static detector itself: no second check


def _in_counts(rec: Recording) -> bool:
    """Whether the file holds raw counts scaled by a stated lsb_per_g (no unit to confuse)."""
    return rec.format == "ofbe-logger" or rec.header.get("acc_unit") == "counts"


def file_problem(rec: Recording, params: LabelParams, g: float) -> tuple[str, str] | None:
    """What forbids any label from a whole file, as (reason, detail): too many garbled lines,
    an implausible sample rate, or readings whose typical norm is no resting norm (checked
    before the static detector, whose absolute ceiling misfires on readings in the wrong
    unit)."""
    garbled = skipped_lines_problem(rec.diagnostics, params.max_skipped_fraction, rec.header)
    if garbled is not None:
        return GARBLED, garbled
    rate = rate_problem(rec.fs_hz, rec.nominal_rate_hz)
    if rate is not None and rate[1]:
        return IMPLAUSIBLE_RATE, rate[0]
    norm = typical_norm_problem(rec.acc, g, params.max_norm_deviation, _in_counts(rec))
    if norm is not None:
        return IMPLAUSIBLE_NORM, norm
    return None


def segment_mean(rec: Recording, seg: Segment) -> np.ndarray | None:
    """``acc.mean(axis=0)`` over the segment (None when it is empty), computed once for the
    static check, the plausibility of the mean and the row."""
    return column_mean(rec.acc[seg.start:seg.stop]) if seg.stop > seg.start else None


def quality(rec: Recording, seg: Segment, params: LabelParams, g: float, min_samples: int | None = None,
             mean: np.ndarray | None = None) -> tuple[str, str] | None:
    """First problem that forbids a label on this segment, as (reason, detail).

    ``g`` is the local gravity (for the plausibility of the mean); ``min_samples`` defaults
    to ``params.min_samples`` (the DUT's rule; a reference only needs enough samples for a
    mean); ``mean`` is :func:`segment_mean` when the caller has it."""
    need = params.min_samples if min_samples is None else min_samples
    if mean is None:
        mean = segment_mean(rec, seg)
    bad = rec.once(("file_problem", params, g), lambda: file_problem(rec, params, g))  # once per file
    if bad is not None:
        return bad
    if seg.problem:
        return NO_SEGMENT, seg.problem
    sat = int(rec.saturated[seg.start:seg.stop].sum())
    if sat:
        first = int(rec.line[seg.start + int(np.argmax(rec.saturated[seg.start:seg.stop]))])
        return SATURATED, f"{sat} saturated samples in the stationary segment (first at line {first})"
    n = seg.stop - seg.start
    if n >= 2 and not seg.static_checked and not is_still(rec.acc[seg.start:seg.stop], rec.fs_hz,
                                                           params.static, mean):
        check = check_static(rec.acc[seg.start:seg.stop], rec.fs_hz, params.static, mean)
        if check.moving_samples:
            first = int(rec.line[seg.start + int(np.argmin(check.static))])
            return MOTION, (f"{check.moving_samples} of {n} samples in the stationary segment are "
                            f"moving (from line {first}; moving-std peak "
                            f"{np.sqrt(check.peak):.3g} m/s² against a threshold of "
                            f"{np.sqrt(check.threshold):.3g} m/s²)")
    if n < need:
        return TOO_SHORT, f"{n} stationary samples, at least {need} needed"
    x = rec.acc[seg.start:seg.stop]
    scale = rec.full_scale
    clipped = clipped_samples(x, bounds=None if scale is None else (scale.low, scale.high))
    if clipped is not None:
        count, k, value, whole = clipped
        if whole:
            return SATURATED, (f"the {'xyz'[k]} axis reads {value:.5g} m/s² on every sample of the "
                               "stationary segment while the others vary: clipped at the logger's range, "
                               "or stuck "
                               "(record with a wider range)")
        return SATURATED, (f"{count} of {n} samples of the stationary segment sit at the same extreme "
                           f"{'xyz'[k]} value {value:.5g} m/s², more than {MIN_CLIP_RATIO:g} times the value "
                           "next to it: clipping at the logger's range? (record with a wider range)")
    norm = norm_problem(mean, g, params.max_norm_deviation, _in_counts(rec))
    if norm is not None:
        return IMPLAUSIBLE_NORM, norm
    return None


def _temperature(rec: Recording, seg: Segment) -> float | None:
    """Mean temperature over the segment's samples that have one, °C; None without any."""
    temp = rec.extra.get(TEMPERATURE)
    value = float("nan") if temp is None else mean_temperature(temp[seg.start:seg.stop])
    return value if math.isfinite(value) else None


def base_row(m: SessionManifest, rec_id: str, dev: DeviceSpec, rec: Recording, seg: Segment,
              files: dict[str, str], rel: str, params: LabelParams, keep_segment: bool = False,
              mean: np.ndarray | None = None) -> dict[str, Any]:
    x = rec.acc[seg.start:seg.stop]
    conv = [convergence_index(x[:, i], params.convergence_window, params.convergence_threshold)
            for i in range(3)]
    return {
        "campaign": m.campaign, "session": m.session, "recording": rec_id, "device": dev.id,
        "kind": m.kind, "power_cycle": m.power_cycle, "n_samples": int(x.shape[0]),
        "fs_hz": float(rec.fs_hz), "g_local": float(m.g_local),
        "convergence_x": conv[0], "convergence_y": conv[1], "convergence_z": conv[2],
        "sync_offset_s": None, "sync_drift_ppm": None, "sync_residual_s": None,
        "sync_method": None, "raw_sha256": files[rel], "raw_file": rel,
        "segment_start_s": float(rec.t[seg.start]), "segment_end_s": float(rec.t[seg.stop - 1]),
        "std_x": float(x[:, 0].std()), "std_y": float(x[:, 1].std()), "std_z": float(x[:, 2].std()),
        "skipped_lines": len(rec.diagnostics.skipped),
        "missing_samples": rec.diagnostics.missing_samples,
        "offset_x": None, "offset_y": None, "offset_z": None, "fit_condition": None,
        "pose": 0, "temperature_c": _temperature(rec, seg),
        "_mean": column_mean(x) if mean is None else mean,
        **({"_segment": x} if keep_segment else {}),
    }


def finish_row(row: dict[str, Any], bias: np.ndarray, u: np.ndarray, method: str) -> None:
    roll, pitch = roll_pitch(u)
    row.update({"bias_x": float(bias[0]), "bias_y": float(bias[1]), "bias_z": float(bias[2]),
                "gravity_x": float(u[0]), "gravity_y": float(u[1]), "gravity_z": float(u[2]),
                "roll_deg": roll, "pitch_deg": pitch, "label_method": method, "_u": u})
