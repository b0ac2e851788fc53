"""Labelling one session: stationary segments, orientation and the apparent-bias label.

methods.md §Labelling, steps 1–6 and 8, for one session folder. The campaign fit (step 7)
needs every session of a campaign and lives in :mod:`ofbe_data.labelling.campaign_fit`; writing the
products is :mod:`ofbe_data.labelling.store`.

Per recording and DUT device:

1. Stationary segment. Rotated sessions: between the reference's first and last tap, less
   ``margin_s`` on each side, mapped onto the DUT clock by the tap synchronisation.
   Sessions without a reference: between the device's own first and last tap when it has
   two, else the longest run the static detector accepts (less the margin where it borders
   motion).
2. Checks, in this order, each a recorded rejection: too many skipped lines (``garbled``),
   a saturated sample in the segment (``saturated``), motion in the segment (``motion``),
   fewer than ``min_samples`` samples (``too-short``); the reference's own problems reject
   every DUT of that recording (``reference-…``).
3. Label: the mean over the segment minus g·u, u from the reference (rotated, Rodrigues),
   the nearest axis (gravity-aligned), or the session's norm-constrained fit
   (multi-position).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ofbe_data import __version__
from ofbe_data.core.checksums import file_sha256 as sha256_file  # noqa: F401 (re-exported)
from ofbe_data.core.errors import ConfigError
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.formats.filebytes import file_digests
from ofbe_data.io.manifest import DeviceSpec, SessionManifest, load_manifest
from ofbe_data.io.recording import TEMPERATURE, Recording
from ofbe_data.io.typedconfig import from_plain, read_section
from ofbe_data.labelling.campaign_fit import CampaignFitParams
from ofbe_data.labelling.checks import (
    CSV_WARN_RATE_DEVIATION,
    MAX_LEVEL_TILT_DEG,
    MAX_MOUNT_ERROR_DEG,
    MAX_NORM_DEVIATION,
    MIN_CLIP_RATIO,
    UNEVEN_STEP_CV,
    WARN_LEVEL_TILT_DEG,
    WARN_RATE_DEVIATION,
    clipped_samples,
    level_tilt_deg,
    mount_error_deg,
    norm_problem,
    rate_problem,
    rate_step,
    skipped_lines_problem,
    typical_norm_problem,
)
from ofbe_data.labelling.convergence import PAPER_THRESHOLD, PAPER_WINDOW, convergence_index
from ofbe_data.labelling.multiposition import MODELS
from ofbe_data.labelling.orientation import apparent_bias, nearest_axis, rodrigues_label, roll_pitch
from ofbe_data.labelling.poses import PoseParams
from ofbe_data.labelling.stationarity import (
    StaticParams,
    centred_sums,
    check_static,
    column_mean,
    is_still,
    longest_run,
)
from ofbe_data.labelling.sync import SyncError, SyncParams, synchronise, tap_signals

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
        ``auto`` (the richest the poses support, :func:`ofbe_data.labelling.ladder.choose_fit`)
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
        The pose detector of multi-position sessions (:mod:`ofbe_data.labelling.poses`).
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
        Things a person should know (e.g. taps missing, header-stamp alignment).
    files
        SHA-256 of every file read, by path relative to the session folder (manifest too).

    Rows also carry two private entries for the campaign fit, not written out: ``_mean``
    (3,) mean reading and ``_u`` (3,) gravity direction, sensor frame.
    """

    manifest: SessionManifest
    rows: list[dict[str, Any]] = field(default_factory=list)
    rejections: list[Rejection] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    files: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class _Segment:
    """Samples [start, stop) of a recording chosen as stationary, or why none."""

    start: int
    stop: int
    problem: str = ""
    static_checked: bool = False  # chosen by the static detector itself: no second check


def _own_segment(rec: Recording, taps: np.ndarray, params: LabelParams,
                 centred: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[_Segment, bool]:
    """Stationary segment of a recording from its own signal: between its first and last tap
    (``taps``, s, its clock), else the longest static run (``centred``: the recording's
    :func:`centred_sums` when the caller has them). Returns the segment and whether taps
    bounded it."""
    if taps.size >= 2:
        a = int(np.searchsorted(rec.t, taps[0] + params.margin_s, side="left"))
        b = int(np.searchsorted(rec.t, taps[-1] - params.margin_s, side="right"))
        return _Segment(a, max(a, b)), True
    static = check_static(rec.acc, rec.fs_hz, params.static, *(centred or (None, None)))
    a, b = longest_run(static.static)
    if b <= a:
        return _Segment(0, 0, "the static detector found no still part"), False
    margin = int(round(params.margin_s * rec.fs_hz))
    if a > 0:
        a += margin
    if b < rec.n:
        b -= margin
    if b <= a:
        return _Segment(0, 0, "the static detector found no still part longer than the margins"), False
    return _Segment(a, b, static_checked=True), False


def _in_counts(rec: Recording) -> bool:
    """Whether the file holds raw counts scaled by a stated lsb_per_g (no unit to confuse)."""
    return rec.format == "ofbe-logger" or rec.header.get("acc_unit") == "counts"


def _file_problem(rec: Recording, params: LabelParams, g: float) -> tuple[str, str] | None:
    """What forbids any label from a whole file, as (reason, detail): too many garbled lines,
    an implausible sample rate, or readings whose typical norm is no resting norm (checked
    before the static detector, whose absolute ceiling misfires on readings in the wrong
    unit)."""
    garbled = skipped_lines_problem(rec.diagnostics, params.max_skipped_fraction)
    if garbled is not None:
        return GARBLED, garbled
    rate = rate_problem(rec.fs_hz, rec.nominal_rate_hz)
    if rate is not None and rate[1]:
        return IMPLAUSIBLE_RATE, rate[0]
    norm = typical_norm_problem(rec.acc, g, params.max_norm_deviation, _in_counts(rec))
    if norm is not None:
        return IMPLAUSIBLE_NORM, norm
    return None


def _segment_mean(rec: Recording, seg: _Segment) -> np.ndarray | None:
    """``acc.mean(axis=0)`` over the segment (None when it is empty), computed once for the
    static check, the plausibility of the mean and the row."""
    return column_mean(rec.acc[seg.start:seg.stop]) if seg.stop > seg.start else None


def _quality(rec: Recording, seg: _Segment, params: LabelParams, g: float, min_samples: int | None = None,
             mean: np.ndarray | None = None) -> tuple[str, str] | None:
    """First problem that forbids a label on this segment, as (reason, detail).

    ``g`` is the local gravity (for the plausibility of the mean); ``min_samples`` defaults
    to ``params.min_samples`` (the DUT's rule; a reference only needs enough samples for a
    mean); ``mean`` is :func:`_segment_mean` when the caller has it."""
    need = params.min_samples if min_samples is None else min_samples
    if mean is None:
        mean = _segment_mean(rec, seg)
    bad = _file_problem(rec, params, g)
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


def _rate_warnings(out: SessionLabels, rec_id: str, dev_id: str, rec: Recording) -> None:
    """Warnings for a sample rate off its nominal value, or changing inside the file."""
    warn = CSV_WARN_RATE_DEVIATION if rec.format == "csv" else WARN_RATE_DEVIATION
    rate = rate_problem(rec.fs_hz, rec.nominal_rate_hz, warn)
    if rate is not None and not rate[1]:
        out.warnings.append(f"{rec_id}/{dev_id}: {rec.path.name}: {rate[0]}")
    cv = float(rec.header.get("step_cv", "nan"))
    if cv > UNEVEN_STEP_CV:
        out.warnings.append(f"{rec_id}/{dev_id}: {rec.path.name}: uneven sample spacing (step sd "
                            f"{cv:.0%} of the median step {rec.header.get('step_median_s')} s, longest "
                            f"{rec.header.get('step_max_s')} s, {len(rec.diagnostics.gaps)} gaps); "
                            "used as logged, not resampled")
    step = rate_step(rec.t, median_step=rec.median_step_s)
    if step is not None:
        i, before, after = step
        line = int(rec.line[min(i, rec.n - 1)])
        out.warnings.append(f"{rec_id}/{dev_id}: {rec.path.name}: the sample rate changes from "
                            f"{before:.4g} Hz to {after:.4g} Hz around line {line}; fs_hz "
                            f"({rec.fs_hz:.4g} Hz) is an average")


def _temperature(rec: Recording, seg: _Segment) -> float | None:
    """Mean temperature over the segment, °C, when the file has a temperature column."""
    temp = rec.extra.get(TEMPERATURE)
    if temp is None or seg.stop <= seg.start:
        return None
    value = float(np.mean(temp[seg.start:seg.stop]))
    return value if math.isfinite(value) else None


def _base_row(m: SessionManifest, rec_id: str, dev: DeviceSpec, rec: Recording, seg: _Segment,
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


def _finish_row(row: dict[str, Any], bias: np.ndarray, u: np.ndarray, method: str) -> None:
    roll, pitch = roll_pitch(u)
    row.update({"bias_x": float(bias[0]), "bias_y": float(bias[1]), "bias_z": float(bias[2]),
                "gravity_x": float(u[0]), "gravity_y": float(u[1]), "gravity_z": float(u[2]),
                "roll_deg": roll, "pitch_deg": pitch, "label_method": method, "_u": u})


def _reference_window(ref: Recording, taps: np.ndarray, params: LabelParams,
                      ) -> tuple[float, float, _Segment]:
    """The stationary window on the reference clock, (start, end) s, and its samples.

    Between the reference's first and last tap less the margins; without two taps, the
    reference's own longest static run."""
    if taps.size >= 2:
        s0, s1, problem = taps[0] + params.margin_s, taps[-1] - params.margin_s, ""
    else:
        seg, _ = _own_segment(ref, taps, params)
        s0, s1, problem = ((0.0, 0.0, seg.problem) if seg.problem else
                           (float(ref.t[seg.start]), float(ref.t[seg.stop - 1]), ""))
    r0 = int(np.searchsorted(ref.t, s0, side="left"))
    r1 = int(np.searchsorted(ref.t, s1, side="right"))
    return s0, s1, _Segment(r0, max(r0, r1), problem)


def _label_rotated(out: SessionLabels, rec_id: str, recs: dict[str, Recording],
                   rels: dict[str, str], params: LabelParams, keep_segments: bool) -> None:
    m = out.manifest
    ref_spec = m.reference
    assert ref_spec is not None
    ref = recs[ref_spec.id]
    # the reference's signals, window and checks do not depend on the DUT: once per recording
    ref_sig = tap_signals(ref, params.sync)
    s0, s1, ref_seg = _reference_window(ref, ref_sig.taps, params)
    ref_mean = _segment_mean(ref, ref_seg)
    ref_bad = _quality(ref, ref_seg, params, m.g_local, min_samples=2, mean=ref_mean)
    for dev in m.duts:
        rec = recs[dev.id]
        try:
            sync = synchronise(rec, ref, dev.reference_to_sensor, params.sync, ref_sig)
        except SyncError as exc:
            out.rejections.append(Rejection(rec_id, dev.id, SYNC_FAILED, str(exc)))
            continue
        if sync.warning:
            out.warnings.append(f"{rec_id}/{dev.id}: {sync.warning}")
        if ref_bad is not None:
            out.rejections.append(Rejection(rec_id, dev.id, REFERENCE_PREFIX + ref_bad[0],
                                            f"{rels[ref_spec.id]}: {ref_bad[1]}"))
            continue
        t_ref = sync.to_reference(rec.t)
        a = int(np.searchsorted(t_ref, s0, side="left"))
        b = int(np.searchsorted(t_ref, s1, side="right"))
        seg = _Segment(a, max(a, b))
        mean = _segment_mean(rec, seg)
        bad = _quality(rec, seg, params, m.g_local, mean=mean)
        if bad is not None:
            out.rejections.append(Rejection(rec_id, dev.id, *bad))
            continue
        row = _base_row(m, rec_id, dev, rec, seg, out.files, rels[dev.id], params, keep_segments, mean)
        N = np.eye(3) if dev.reference_to_sensor is None else dev.reference_to_sensor
        error = mount_error_deg(row["_mean"], ref_mean, N)
        if error > params.max_mount_error_deg:
            taps = " (the taps' signed signals disagreed with it too)" if sync.warning else ""
            out.rejections.append(Rejection(rec_id, dev.id, MOUNT_MISMATCH, (
                f"the DUT's measured gravity direction is {error:.1f}° from the one its declared "
                f"reference_to_sensor predicts from the reference (at most {params.max_mount_error_deg:g}° "
                f"expected){taps}: check reference_to_sensor for {dev.id} in the manifest")))
            continue
        bias, u = rodrigues_label(row["_mean"], ref_mean, N, m.g_local)
        _finish_row(row, bias, u, "reference-rodrigues")
        row.update({"sync_offset_s": sync.offset_s, "sync_drift_ppm": sync.drift_ppm,
                    "sync_residual_s": None if np.isnan(sync.residual_s) else sync.residual_s,
                    "sync_method": sync.method})
        out.rows.append(row)


def _label_alone(out: SessionLabels, rec_id: str, recs: dict[str, Recording],
                 rels: dict[str, str], params: LabelParams, keep_segments: bool) -> list[dict[str, Any]]:
    """Rows (without label) of the DUTs of a recording with no reference."""
    m = out.manifest
    rows = []
    for dev in m.duts:
        rec = recs[dev.id]
        centred = centred_sums(rec.acc)  # shared by the high-pass and the static detector
        seg, tapped = _own_segment(rec, tap_signals(rec, params.sync, centred).taps, params, centred)
        mean = _segment_mean(rec, seg)
        bad = _quality(rec, seg, params, m.g_local, mean=mean)
        if bad is not None:
            out.rejections.append(Rejection(rec_id, dev.id, *bad))
            continue
        if not tapped and (seg.start > 0 or seg.stop < rec.n):
            out.warnings.append(f"{rec_id}/{dev.id}: no taps; stationary part found by the static "
                                f"detector at lines {int(rec.line[seg.start])}–"
                                f"{int(rec.line[seg.stop - 1])}")
        rows.append(_base_row(m, rec_id, dev, rec, seg, out.files, rels[dev.id], params, keep_segments, mean))
    return rows


def _label_level(out: SessionLabels, row: dict[str, Any], params: LabelParams) -> None:
    """A gravity-aligned row: the level label, unless the device is visibly tilted."""
    mean = row["_mean"]
    u = nearest_axis(mean)
    tilt = level_tilt_deg(mean, u)
    roll, pitch = roll_pitch(mean)
    axis = f"{'+' if u.sum() > 0 else '-'}{'xyz'[int(np.argmax(np.abs(u)))]}"
    what = (f"the measured gravity direction is {tilt:.2f}° from the nearest axis {axis} "
            f"(roll {roll:.2f}°, pitch {pitch:.2f}°)")
    if tilt > params.max_level_tilt_deg:
        leak = 1000.0 * math.sin(math.radians(tilt))
        out.rejections.append(Rejection(row["recording"], row["device"], NOT_LEVEL, (
            f"{what}, above label.max_level_tilt_deg = {params.max_level_tilt_deg:.3g}°: a level label "
            f"would carry about {leak:.0f} mg of gravity in its tangential axes. One window cannot tell a "
            f"tilt of {tilt:.2f}° from a tangential bias of about {leak:.0f} mg: if the board is known to "
            f"be level (a verified level mount), set label.max_level_tilt_deg above {tilt:.2f} (in a "
            "params YAML given to ofbe-label --params) and the offset is labelled as bias; otherwise level "
            "the device, or label the session as rotated (with a reference) or multi-position")))
        return
    if tilt > params.warn_level_tilt_deg:
        leak = 1000.0 * math.sin(math.radians(tilt))
        out.warnings.append(f"{row['recording']}/{row['device']}: {what}: a tilt, or a tangential bias "
                            f"of about {leak:.0f} mg (one window cannot tell which); if it is a tilt, the "
                            "level label carries that much gravity in its tangential axes")
    _finish_row(row, apparent_bias(mean, u, row["g_local"]), u, "level")
    row["roll_deg"], row["pitch_deg"] = roll, pitch  # what was measured, not the axis's 0°
    out.rows.append(row)


def label_session(folder: str | Path, params: LabelParams = LabelParams(), *,
                  keep_segments: bool = False, manifest: SessionManifest | None = None) -> SessionLabels:
    """Label every (recording, DUT) of one session folder.

    Parameters
    ----------
    folder
        Session folder (with ``session.yaml``) or the manifest itself.
    params
        Labelling parameters.
    keep_segments
        Also keep each row's stationary samples, (n, 3) m/s², under the private key
        ``"_segment"`` (for analyses such as the convergence report; the label writer
        ignores it).
    manifest
        The session's manifest when already loaded from ``folder`` (else it is read here).

    Returns
    -------
    SessionLabels
        Rows for the labelled recordings, rejections with reasons, warnings and file hashes.
        Offsets from the campaign fit are filled later (:mod:`ofbe_data.labelling.store`).

    Raises
    ------
    ManifestError
        The manifest is invalid.
    RawFormatError
        A file cannot be read (missing, empty, no data line, wrong header…).
    """
    m = load_manifest(folder) if manifest is None else manifest
    out = SessionLabels(m)
    out.files["session.yaml"] = sha256_file(m.path)
    read_all = []
    for rec_spec in m.recordings:
        recs: dict[str, Recording] = {}
        rels: dict[str, str] = {}
        for dev_id, rel in rec_spec.files.items():
            path = m.file_path(rec_spec, dev_id)
            with file_digests() as digests:  # hashed from the bytes the reader parsed
                recs[dev_id] = read_device_file(path, m.devices[dev_id])
            out.files[rel] = digests.get(Path(path)) or sha256_file(path)
            rels[dev_id] = rel
            _rate_warnings(out, rec_spec.id, dev_id, recs[dev_id])
        if m.kind == "rotated":
            _label_rotated(out, rec_spec.id, recs, rels, params, keep_segments)
        elif m.kind == "gravity-aligned":
            for row in _label_alone(out, rec_spec.id, recs, rels, params, keep_segments):
                _label_level(out, row, params)
        else:
            read_all.append((rec_spec.id, recs, rels))  # poses are found over all recordings
    if m.kind == "multi-position":
        from ofbe_data.labelling.multi_labels import label_multi_position

        label_multi_position(out, read_all, params, keep_segments)
    return out


def provenance(labels: SessionLabels, params: LabelParams) -> dict[str, Any]:
    """What a label file was made from: toolkit version, parameters, file hashes."""
    return {"format": LABELS_FORMAT, "toolkit": "ofbe", "toolkit_version": __version__,
            "campaign": labels.manifest.campaign, "session": labels.manifest.session,
            "parameters": dataclasses.asdict(params), "files_sha256": dict(sorted(labels.files.items()))}
