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
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ofbe_data import __version__
from ofbe_data.core.checksums import file_sha256 as sha256_file  # noqa: F401 (re-exported)
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.formats.filebytes import file_digests
from ofbe_data.io.manifest import SessionManifest, load_manifest
from ofbe_data.io.recording import Recording, temperature_notes
from ofbe_data.labelling.checks import (
    CSV_WARN_RATE_DEVIATION,
    UNEVEN_STEP_CV,
    WARN_RATE_DEVIATION,
    level_tilt_deg,
    mount_error_deg,
    rate_problem,
    rate_step,
)
from ofbe_data.labelling.label_rows import (  # noqa: F401 (the labels' records, re-exported)
    GARBLED,
    IMPLAUSIBLE_NORM,
    IMPLAUSIBLE_RATE,
    LABELS_FORMAT,
    MOTION,
    MOUNT_MISMATCH,
    NO_SEGMENT,
    NOT_LEVEL,
    REFERENCE_PREFIX,
    REJECTIONS_FORMAT,
    SATURATED,
    SYNC_FAILED,
    TOO_SHORT,
    UNDETERMINED,
    LabelParams,
    Rejection,
    Segment,
    SessionLabels,
    base_row,
    file_problem,
    finish_row,
    label_params_from,
    load_label_params,
    quality,
    read_label_section,
    segment_mean,
)
from ofbe_data.labelling.multi_labels import label_multi_position
from ofbe_data.labelling.orientation import apparent_bias, nearest_axis, rodrigues_label, roll_pitch
from ofbe_data.labelling.stationarity import (
    centred_sums,
    check_static,
    longest_run,
)
from ofbe_data.labelling.sync import SyncError, synchronise, tap_signals


def _own_segment(rec: Recording, taps: np.ndarray, params: LabelParams,
                 centred: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[Segment, bool]:
    """Stationary segment of a recording from its own signal: between its first and last tap
    (``taps``, s, its clock), else the longest static run (``centred``: the recording's
    :func:`centred_sums` when the caller has them). Returns the segment and whether taps
    bounded it."""
    if taps.size >= 2:
        a = int(np.searchsorted(rec.t, taps[0] + params.margin_s, side="left"))
        b = int(np.searchsorted(rec.t, taps[-1] - params.margin_s, side="right"))
        return Segment(a, max(a, b)), True
    static = check_static(rec.acc, rec.fs_hz, params.static, *(centred or (None, None)))
    a, b = longest_run(static.static)
    if b <= a:
        return Segment(0, 0, "the static detector found no still part"), False
    margin = int(round(params.margin_s * rec.fs_hz))
    if a > 0:
        a += margin
    if b < rec.n:
        b -= margin
    if b <= a:
        return Segment(0, 0, "the static detector found no still part longer than the margins"), False
    return Segment(a, b, static_checked=True), False


def _rate_warnings(out: SessionLabels, rec_id: str, dev_id: str, rec: Recording) -> None:
    """Warnings for a sample rate off its nominal value or changing, and the reader's temperature notes."""
    out.warnings.extend(f"{rec_id}/{dev_id}: {rec.path.name}: {note}" for note in temperature_notes(rec))
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


def _reference_window(ref: Recording, taps: np.ndarray, params: LabelParams,
                      ) -> tuple[float, float, Segment]:
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
    return s0, s1, Segment(r0, max(r0, r1), problem)


def _label_rotated(out: SessionLabels, rec_id: str, recs: dict[str, Recording],
                   rels: dict[str, str], params: LabelParams, keep_segments: bool) -> None:
    m = out.manifest
    ref_spec = m.reference
    assert ref_spec is not None
    ref = recs[ref_spec.id]
    # the reference's signals, window and checks do not depend on the DUT: once per recording
    ref_sig = tap_signals(ref, params.sync)
    s0, s1, ref_seg = _reference_window(ref, ref_sig.taps, params)
    ref_mean = segment_mean(ref, ref_seg)
    ref_bad = quality(ref, ref_seg, params, m.g_local, min_samples=2, mean=ref_mean)
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
        seg = Segment(a, max(a, b))
        mean = segment_mean(rec, seg)
        bad = quality(rec, seg, params, m.g_local, mean=mean)
        if bad is not None:
            out.rejections.append(Rejection(rec_id, dev.id, *bad))
            continue
        row = base_row(m, rec_id, dev, rec, seg, out.files, rels[dev.id], params, keep_segments, mean)
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
        finish_row(row, bias, u, "reference-rodrigues")
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
        mean = segment_mean(rec, seg)
        bad = quality(rec, seg, params, m.g_local, mean=mean)
        if bad is not None:
            out.rejections.append(Rejection(rec_id, dev.id, *bad))
            continue
        if not tapped and (seg.start > 0 or seg.stop < rec.n):
            out.warnings.append(f"{rec_id}/{dev.id}: no taps; stationary part found by the static "
                                f"detector at lines {int(rec.line[seg.start])}–"
                                f"{int(rec.line[seg.stop - 1])}")
        rows.append(base_row(m, rec_id, dev, rec, seg, out.files, rels[dev.id], params, keep_segments, mean))
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
    finish_row(row, apparent_bias(mean, u, row["g_local"]), u, "level")
    row["roll_deg"], row["pitch_deg"] = roll, pitch  # what was measured, not the axis's 0°
    out.rows.append(row)


DEFAULT_PARAMS = LabelParams()
"""The labelling parameters when none are given (methods.md's defaults)."""


def label_session(folder: str | Path, params: LabelParams = DEFAULT_PARAMS, *,
                  keep_segments: bool = False, manifest: SessionManifest | None = None,
                  read: Mapping[tuple[str, str], tuple[Recording, str]] | None = None) -> SessionLabels:
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
    read
        Files the caller has read already (``ofbe-session check``, which reports on each):
        ``(recording id, device) → (recording, hex SHA-256 of the bytes its reader parsed)``;
        those are not read again.

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
            if read is not None and (rec_spec.id, dev_id) in read:
                recs[dev_id], out.files[rel] = read[(rec_spec.id, dev_id)]
            else:
                recs[dev_id], out.files[rel] = read_hashed(path, m.devices[dev_id])
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
        label_multi_position(out, read_all, params, keep_segments)
    return out


def read_hashed(path: str | Path, spec: Any) -> tuple[Recording, str]:
    """A device file read (:func:`~ofbe_data.io.formats.read_device_file` with its manifest
    ``spec``) and the hex SHA-256 of the bytes its reader parsed (of the file, where the reader
    does not say)."""
    with file_digests() as digests:
        rec = read_device_file(path, spec)
    return rec, digests.get(Path(path)) or sha256_file(path)


def provenance(labels: SessionLabels, params: LabelParams) -> dict[str, Any]:
    """What a label file was made from: toolkit version, parameters, file hashes."""
    return {"format": LABELS_FORMAT, "toolkit": "ofbe", "toolkit_version": __version__,
            "campaign": labels.manifest.campaign, "session": labels.manifest.session,
            "parameters": dataclasses.asdict(params), "files_sha256": dict(sorted(labels.files.items()))}
