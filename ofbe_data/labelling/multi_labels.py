"""Labels of a multi-position session: poses found inside the recordings, one fit per device.

methods.md §8. Every recording of a device may hold one pose or many; the poses are found
with a threshold chosen over all the device's recordings at once
(:func:`~ofbe_data.labelling.pose_search.find_session_poses`), each pose passes the same
checks as any stationary segment, and the norm-constrained fit over the device's poses gives
its zero-g offset (and, with ≥ ``scale_min_poses`` distinct directions under ``auto``, its
three scale factors). Each pose becomes one label row: ``pose`` numbers it within its
recording, ``segment_start_s``/``segment_end_s`` give its interval.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ofbe_data.io.manifest import DeviceSpec
from ofbe_data.io.recording import Recording
from ofbe_data.labelling.labels import (
    NO_SEGMENT,
    UNDETERMINED,
    LabelParams,
    Rejection,
    SessionLabels,
    _base_row,
    _file_problem,
    _finish_row,
    _quality,
    _Segment,
    _segment_mean,
)
from ofbe_data.labelling.multiposition import PoseFit, fit_poses, min_poses
from ofbe_data.labelling.pose_search import direction_groups, distinct_directions, find_session_poses
from ofbe_data.labelling.poses import NoPosesError

AUTO = "auto"
"""``label.multi_position_model`` that chooses by the number of distinct pose directions."""

RecordingSet = list[tuple[str, dict[str, Recording], dict[str, str]]]
"""Per recording of a session: its id, its files read (device → Recording) and their paths."""


def choose_model(means: np.ndarray, params: LabelParams) -> str:
    """The pose-fit model for a device's poses or faces, (K, 3) m/s² (methods.md §8).

    ``auto``: ``scale-offset`` with at least ``label.poses.scale_min_poses`` distinct
    directions (a face recorded twice counts once), ``offset`` otherwise; a fixed model is used
    as given.
    """
    if params.multi_position_model != AUTO:
        return params.multi_position_model
    return "scale-offset" if distinct_directions(means) >= params.poses.scale_min_poses else "offset"


def _device_rows(out: SessionLabels, dev: DeviceSpec, recordings: RecordingSet, params: LabelParams,
                 keep_segments: bool) -> list[dict[str, Any]]:
    """One row (without label) per accepted pose of one device's recordings."""
    m = out.manifest
    usable = []
    for rec_id, recs, rels in recordings:
        rec = recs.get(dev.id)
        if rec is None:
            continue
        bad = _file_problem(rec, params, m.g_local)
        if bad is not None:
            out.rejections.append(Rejection(rec_id, dev.id, *bad))
        else:
            usable.append((rec_id, rec, rels[dev.id]))
    if not usable:
        return []
    try:
        found = find_session_poses([(rec.t, rec.acc, rec.fs_hz) for _, rec, _ in usable], m.g_local,
                                   params.poses)
    except NoPosesError as exc:
        # still parts too few or too alike for the fit: undetermined; no still part: no segment
        reason = UNDETERMINED if exc.counts and max(exc.counts.values()) > 0 else NO_SEGMENT
        for rec_id, _, _ in usable:
            out.rejections.append(Rejection(rec_id, dev.id, reason, f"poses: {exc}"))
        return []
    rows = []
    for (rec_id, rec, rel), poses in zip(usable, found.poses, strict=True):
        if not poses:
            out.rejections.append(Rejection(rec_id, dev.id, NO_SEGMENT, (
                f"no static pose of {params.poses.min_pose_s:g} s or more at the session's threshold "
                f"(×{found.multiplier:g} the recording's noise floor)")))
            continue
        for p in poses:
            seg = _Segment(p.start, p.stop, static_checked=True)
            mean = _segment_mean(rec, seg)
            bad = _quality(rec, seg, params, m.g_local, min_samples=2, mean=mean)
            if bad is not None:
                out.rejections.append(Rejection(rec_id, dev.id, bad[0], f"pose {p.index} "
                                                f"({p.start_s:.3f}–{p.end_s:.3f} s): {bad[1]}"))
                continue
            row = _base_row(m, rec_id, dev, rec, seg, out.files, rel, params, keep_segments, mean)
            row["pose"] = p.index
            rows.append(row)
    if len(rows) > 1 or len(usable) > 1:
        out.warnings.append(f"{dev.id}: {len(rows)} poses in {len(usable)} recording(s), threshold "
                            f"×{found.multiplier:g} the noise floor (pose-fit residual "
                            f"{found.residuals[found.multiplier]:.3g} m/s²)")
    return rows


def pose_biases(means: np.ndarray, fit: PoseFit, g: float) -> tuple[np.ndarray, np.ndarray]:
    """Each pose's apparent bias and direction from a fit: u_k = A⁻¹(m_k − b) / |A⁻¹(m_k − b)|,
    b_app_k = m_k − g·u_k (means (K, 3) m/s²; returns (K, 3) m/s² and (K, 3) unit vectors)."""
    v = (means - fit.offset) / fit.scale
    u = v / np.sqrt(np.sum(v * v, axis=1, keepdims=True))
    return means - g * u, u


def _fit_device(out: SessionLabels, dev: DeviceSpec, rows: list[dict[str, Any]], params: LabelParams) -> None:
    """Norm-constrained fit over one device's poses; labels every pose or rejects them all.

    Poses in one direction (a face recorded twice, or the still seconds either side of a tap)
    are averaged into one before the fit, so that every direction weighs the same: otherwise a
    face held three times would pull an offset-only fit by its scale error.
    """
    g = out.manifest.g_local
    means = np.array([r["_mean"] for r in rows])
    groups = direction_groups(means)
    faces = np.array([means[grp].mean(axis=0) for grp in groups])
    model = choose_model(faces, params)
    fit = fit_poses(faces, g, model, params.multi_position_max_condition)
    if not fit.determined:
        need = min_poses("offset")
        why = (f"{len(rows)} poses in {len(groups)} distinct directions, {need} at least in directions "
               f"that span the sphere: {fit.reason}")
        for r in rows:
            out.rejections.append(Rejection(r["recording"], dev.id, UNDETERMINED,
                                            f"pose {r['pose']}: the session's poses do not determine the "
                                            f"offset ({why})"))
        return
    biases, directions = pose_biases(means, fit, g)
    for r, b, u in zip(rows, biases, directions, strict=True):
        _finish_row(r, b, u, "multi-position")
        r.update({"offset_x": float(fit.offset[0]), "offset_y": float(fit.offset[1]),
                  "offset_z": float(fit.offset[2]), "fit_condition": float(fit.condition),
                  "fit_model": fit.model, "scale_x": float(fit.scale[0]), "scale_y": float(fit.scale[1]),
                  "scale_z": float(fit.scale[2])})
        out.rows.append(r)


def label_multi_position(out: SessionLabels, recordings: RecordingSet, params: LabelParams,
                         keep_segments: bool = False) -> None:
    """Label a multi-position session: poses per device, then one fit per device.

    Parameters
    ----------
    out
        The session's labels; rows, rejections and warnings are appended.
    recordings
        Every recording of the session, read.
    params
        Labelling parameters (``poses``, ``multi_position_model``,
        ``multi_position_max_condition`` and the stationary-segment checks).
    keep_segments
        Keep each row's samples under ``"_segment"``.
    """
    for dev in out.manifest.duts:
        rows = _device_rows(out, dev, recordings, params, keep_segments)
        if rows:
            _fit_device(out, dev, rows, params)
