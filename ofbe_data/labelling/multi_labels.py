"""Labels of a multi-position session: poses found inside the recordings, one fit per device.

methods.md §8. Every recording of a device may hold one pose or many; the poses are found
with a threshold chosen over all the device's recordings at once
(:func:`~ofbe_data.labelling.multiposition.find_session_poses`), each pose passes the same
checks as any stationary segment, and the norm-constrained fit over the device's poses gives
its zero-g offset, and as far as the poses support it (``label.fit_model``, the ladder of
:func:`~ofbe_data.labelling.multiposition.choose_fit`) its scales, non-orthogonality and bias
temperature slope, every parameter with its standard error. Each pose becomes one label row:
``pose`` numbers it within its recording, ``segment_start_s``/``segment_end_s`` give its
interval; the device's fit is repeated on each of its rows.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ofbe_data.io.manifest import DeviceSpec
from ofbe_data.io.recording import Recording
from ofbe_data.labelling.conventions import derived_se, empty_columns, map_columns, scale_columns
from ofbe_data.labelling.label_rows import (
    NO_SEGMENT,
    UNDETERMINED,
    LabelParams,
    Rejection,
    Segment,
    SessionLabels,
    base_row,
    file_problem,
    finish_row,
    quality,
    segment_mean,
)
from ofbe_data.labelling.multiposition import (
    ModelChoice,
    NoPosesError,
    Pose,
    PoseFit,
    base_model,
    choose_fit,
    direction_groups,
    find_session_poses,
    has_temperature,
    map_from_params,
    min_poses,
    noise_of_rows,
    parameter_names,
    planning_noise,
    pose_noise,
    refusal_advice,
)

RecordingSet = list[tuple[str, dict[str, Recording], dict[str, str]]]
"""Per recording of a session: its id, its files read (device → Recording) and their paths."""


def _fixed_entries(model: str) -> np.ndarray:
    """(3, 3) bool: the entries of A that ``model`` fixes rather than fits (their SE is missing)."""
    base = base_model(model)
    if base == "scale-offset":
        return ~np.eye(3, dtype=bool)
    return np.tril(np.ones((3, 3), dtype=bool), -1)


def pose_fit_columns(choice: ModelChoice) -> dict[str, Any]:
    """The label columns of a session's pose fit: every fitted parameter with its standard
    error (imu_tk's s and angles are the fit's own unknowns), A and the scales derived from
    them, and the model's record.

    Parameters of the ladder that the chosen model does not fit stay missing (None); A and the
    scales are missing for the ``offset`` model, which fits no map.
    """
    fit = choice.fit
    cols: dict[str, Any] = empty_columns()
    se = np.sqrt(np.maximum(np.diag(fit.covariance), 0.0))
    for name, value, error in zip(parameter_names(fit.model), fit.params, se, strict=True):
        cols[name], cols[name + "_se"] = float(value), float(error)
    model = fit.model

    def to_matrix(x: np.ndarray) -> np.ndarray:
        return map_from_params(x, model)

    if base_model(model) != "offset":
        if fit.matrix_se is not None:  # the six-face fit: a general A, each entry fitted
            matrix_se = fit.matrix_se
        else:
            matrix_se = derived_se(lambda x: to_matrix(x).ravel(), fit.params, fit.covariance).reshape(3, 3)
            matrix_se = np.where(_fixed_entries(model), np.nan, matrix_se)
        cols.update(map_columns(fit.matrix, matrix_se))
        cols.update(scale_columns(to_matrix, fit.params, fit.covariance))
    if has_temperature(model):
        cols["temp_ref_c"] = fit.temp_ref_c
    cols.update({"fit_model": model, "fit_model_reason": choice.reason, "fit_condition": float(fit.condition),
                 "fit_residual_rms": fit.residual_rms, "fit_dof": fit.dof, "fit_n_poses": fit.n_poses})
    return cols


def _device_rows(out: SessionLabels, dev: DeviceSpec, recordings: RecordingSet, params: LabelParams,
                 keep_segments: bool) -> list[dict[str, Any]]:
    """One row (without label) per accepted pose of one device's recordings."""
    m = out.manifest
    usable = []
    for rec_id, recs, rels in recordings:
        rec = recs.get(dev.id)
        if rec is None:
            continue
        bad = file_problem(rec, params, m.g_local)
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
        # still parts too few or too alike for the fit: undetermined, with the poses to add; no
        # still part: no segment
        found_any = bool(exc.counts) and max(exc.counts.values()) > 0
        reason = UNDETERMINED if found_any else NO_SEGMENT
        advice = _poses_to_add(usable, exc.poses, m.g_local, params) if found_any and exc.poses else ""
        for rec_id, _, _ in usable:
            out.rejections.append(Rejection(rec_id, dev.id, reason, f"poses: {exc}{advice}"))
        return []
    rows = []
    for (rec_id, rec, rel), poses in zip(usable, found.poses, strict=True):
        if not poses:
            out.rejections.append(Rejection(rec_id, dev.id, NO_SEGMENT, (
                f"no static pose of {params.poses.min_pose_s:g} s or more at the session's threshold "
                f"(×{found.multiplier:g} the recording's noise floor)")))
            continue
        for p in poses:
            seg = Segment(p.start, p.stop, static_checked=True)
            mean = segment_mean(rec, seg)
            bad = quality(rec, seg, params, m.g_local, min_samples=2, mean=mean)
            if bad is not None:
                out.rejections.append(Rejection(rec_id, dev.id, bad[0], f"pose {p.index} "
                                                f"({p.start_s:.3f}–{p.end_s:.3f} s): {bad[1]}"))
                continue
            row = base_row(m, rec_id, dev, rec, seg, out.files, rel, params, keep_segments, mean)
            row["pose"] = p.index
            rows.append(row)
    if len(rows) > 1 or len(usable) > 1:  # information on a good session: a note, not a warning
        out.notes.append(f"{dev.id}: {len(rows)} poses in {len(usable)} recording(s), threshold "
                            f"×{found.multiplier:g} the noise floor (pose-fit residual "
                            f"{found.residuals[found.multiplier]:.3g} m/s²)")
    return rows


def _poses_to_add(usable: list[tuple[str, Recording, str]], found: tuple[tuple[Pose, ...], ...], g: float,
                  params: LabelParams) -> str:
    """``; record N more poses …``: the poses that let the label fit a model
    (:func:`~ofbe_data.labelling.multiposition.refusal_advice`), from the still poses found (per
    recording of ``usable``) with their own noise; empty when there is none."""
    poses = [(rec_id, rec, p) for (rec_id, rec, _), mine in zip(usable, found, strict=False) for p in mine]
    if not poses:
        return ""
    means = np.array([p.mean for _, _, p in poses], dtype=np.float64).reshape(-1, 3)
    std = np.array([rec.acc[p.start:p.stop].std(axis=0) for _, rec, p in poses], dtype=np.float64)
    noise = planning_noise(std, np.array([p.stop - p.start for _, _, p in poses]), [r for r, _, _ in poses])
    advice = refusal_advice(means, g, noise, params.multi_position_max_condition, params.fit_model)
    return f"; {advice}" if advice else ""


def pose_biases(means: np.ndarray, fit: PoseFit, g: float,
                temperatures: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each pose's apparent bias and direction from a fit: u_k = A⁻¹(m_k − b(τ_k)) normalised,
    b_app_k = m_k − g·u_k (means (K, 3) m/s²; returns (K, 3) m/s² and (K, 3) unit vectors)."""
    offsets = np.broadcast_to(fit.offset, means.shape)
    if has_temperature(fit.model):
        offsets = offsets + (np.asarray(temperatures) - fit.temp_ref_c)[:, None] * fit.temp_slope
    v = np.linalg.solve(fit.matrix, (means - offsets).T).T
    u = v / np.sqrt(np.sum(v * v, axis=1, keepdims=True))
    return means - g * u, u


def _temperatures(rows: list[dict[str, Any]]) -> np.ndarray | None:
    """(K,) °C of the rows, NaN where a row has no temperature; None when none has one."""
    temps = np.array([np.nan if r.get("temperature_c") is None else r["temperature_c"] for r in rows],
                     dtype=np.float64)
    return temps if np.any(np.isfinite(temps)) else None


def _fit_device(out: SessionLabels, dev: DeviceSpec, rows: list[dict[str, Any]], params: LabelParams) -> None:
    """The ladder's fit over one device's poses; labels every pose or rejects them all.

    Every pose enters the fit as it is, as in imu_tk: averaging the means of poses in nearly
    one direction would put a point inside the ellipsoid (two directions 2° apart average to
    a norm 1.5e-4 short, 0.15 mg), and a face held twice is two measurements of one direction,
    which the residual's degrees of freedom then count. The standard errors know each pose's
    white noise (its samples' variance over their number) and which poses share one placement
    (consecutive in a recording, one direction), :func:`~ofbe_data.labelling.multiposition.pose_noise`.
    """
    g = out.manifest.g_local
    means = np.array([r["_mean"] for r in rows])
    temps = _temperatures(rows)
    groups = direction_groups(means)
    n_samples = np.array([r["n_samples"] for r in rows], dtype=np.float64)
    noise = pose_noise(np.array([[r[f"std_{a}"] for a in "xyz"] for r in rows], dtype=np.float64), n_samples,
                       [str(r["recording"]) for r in rows], means)
    choice = choose_fit(means, g, params.fit_model, params.multi_position_max_condition, params.fit_alpha,
                        temps, n_samples, noise)
    fit = choice.fit
    if not fit.determined:
        need = min_poses("offset" if params.fit_model == "auto" else params.fit_model)
        advice = refusal_advice(means, g, noise_of_rows(rows), params.multi_position_max_condition,
                                params.fit_model)
        why = (f"{len(rows)} poses in {len(groups)} distinct directions, {need} at least in directions "
               f"that span the sphere: {choice.reason}" + (f"; {advice}" if advice else ""))
        for r in rows:
            out.rejections.append(Rejection(r["recording"], dev.id, UNDETERMINED,
                                            f"pose {r['pose']}: the session's poses do not determine the "
                                            f"{fit.model} model ({why})"))
        return
    biases, directions = pose_biases(means, fit, g, temps)
    columns = pose_fit_columns(choice)
    for r, b, u in zip(rows, biases, directions, strict=True):
        finish_row(r, b, u, "multi-position")
        r.update(columns)
        r["_error_model"] = fit.error_model  # private (not written): check's planning of the next poses
        out.rows.append(r)


def label_multi_position(out: SessionLabels, recordings: RecordingSet, params: LabelParams,
                         keep_segments: bool = False) -> None:
    """Label a multi-position session: poses per device, then one fit per device.

    Parameters
    ----------
    out
        The session's labels; rows, rejections, warnings and notes are appended.
    recordings
        Every recording of the session, read.
    params
        Labelling parameters (``poses``, ``fit_model``, ``fit_alpha``,
        ``multi_position_max_condition`` and the stationary-segment checks).
    keep_segments
        Keep each row's samples under ``"_segment"``.
    """
    for dev in out.manifest.duts:
        rows = _device_rows(out, dev, recordings, params, keep_segments)
        if rows:
            _fit_device(out, dev, rows, params)
