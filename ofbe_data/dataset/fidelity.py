"""Label fidelity: labels against the simulator's truth files (simulated campaigns only).

The simulator writes, beside each simulated campaign, ``_truth/<session>.json`` with the
apparent bias and zero-g offset of every (recording, device) (:mod:`ofbe_data.simulator`).
This module compares label rows with them; labelling itself never opens those files. The
result goes on dataset cards and into the pipeline's summary.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ofbe_data.core.errors import OfbeError

MG = 9.80665e-3
"""One milligravity, m/s²."""
AXES = ("x", "y", "z")


TRUTH_FOLDER = "_truth"
"""Name of the truth folder inside a simulated campaign folder."""


def truth_dir_of(raw_dir: str | Path) -> Path | None:
    """The truth folder of a raw campaign folder, or None when it has none (real data)."""
    path = Path(raw_dir) / TRUTH_FOLDER
    return path if path.is_dir() else None


class TruthError(OfbeError):
    """A truth file is missing or lacks a labelled recording."""


def _pose_truth(d: dict[str, Any], start_s: Any, end_s: Any) -> dict[str, Any]:
    """The truth of the pose a label row's interval lies in (continuous recordings list their
    poses, each with its own offset and direction), else the recording's own truth."""
    poses = d.get("poses")
    if not poses or start_s is None or end_s is None or not np.isfinite(start_s):
        return d
    overlaps = [min(end_s, p["t_device"][1]) - max(start_s, p["t_device"][0]) for p in poses]
    best = int(np.argmax(overlaps))
    return poses[best] if overlaps[best] > 0 else d


def _sensor_frame_bias(d: dict[str, Any], dev: dict[str, Any], g: float) -> list[float]:
    """The apparent bias with gravity's direction in the sensor's own axes, m/s² (3).

    The truth's ``apparent_bias`` takes the direction in the device's nominal axes (the
    mount as designed); a multi-position fit has no reference and sees the sensor's own axes
    (its triangular A fixes the rotation gravity cannot see), so its labels are compared with
    ``(A − I)·u_sensor·g + offset``: the mean reading less ``g·u_sensor``.
    """
    if "u_sensor" not in d or "A" not in dev or not np.isfinite(g):
        return [np.nan] * 3
    a = np.asarray(dev["A"], dtype=np.float64)
    return list((a - np.eye(3)) @ np.asarray(d["u_sensor"], dtype=np.float64) * g
                + np.asarray(d["offset"], dtype=np.float64))


def _reference_error(session: dict[str, Any], rec: dict[str, Any], d: dict[str, Any],
                     dev: dict[str, Any]) -> list[float]:
    """What the reference's own bias and scale put into a reference-based label, m/s² (3).

    The label takes gravity's direction from the reference's mean reading,
    ``normalize(A_ref·u·g + b_ref)``, where the truth has ``u``; through the nominal mount
    (``reference_to_sensor``) that direction error becomes ``g·(u_nominal − R·u_ref)`` in the
    label. NaN when the session has no reference or the truth lacks a term.
    """
    refs = [v for v in session.get("devices", {}).values()
            if isinstance(v, dict) and v.get("role") == "reference"]
    try:
        ref = refs[0]
        a_ref = np.asarray(ref["A"], dtype=np.float64)
        b_ref = np.asarray(ref["bias"], dtype=np.float64)
        u = np.asarray(rec["u_plate"], dtype=np.float64)
        r2s = np.asarray(dev["reference_to_sensor"], dtype=np.float64)
        u_nominal = np.asarray(d["u_nominal"], dtype=np.float64)
        g = float(session["g_local"])
    except (IndexError, KeyError, TypeError, ValueError):
        return [np.nan] * 3
    m = a_ref @ u * g + b_ref
    return list(g * (u_nominal - r2s @ (m / np.linalg.norm(m))))


def truth_table(truth_dir: str | Path, labels: pd.DataFrame) -> pd.DataFrame:
    """True apparent bias and offset of every label row, as a frame.

    A row of a continuous recording (many poses in one file) is compared with the truth of the
    pose its interval lies in, not with the recording's first pose.

    Parameters
    ----------
    truth_dir
        The campaign's ``_truth`` folder.
    labels
        Label rows (``session``, ``recording``, ``device``; ``segment_start_s``/``_end_s``).

    Returns
    -------
    pandas.DataFrame
        ``true_bias_x/y/z`` and ``true_offset_x/y/z`` (m/s²); ``true_sensor_bias_x/y/z``, the
        apparent bias with gravity's direction in the sensor's own axes (``u_sensor``: what a
        fit without a reference can know; NaN where the truth does not give it);
        ``reference_error_x/y/z``, the error the reference's own bias and scale put into a
        label through the gravity direction it gives (NaN without a reference); and
        ``true_A`` (the device's 3×3 map, for a campaign fit the one relative to the
        reference), index of ``labels``.

    Raises
    ------
    TruthError
        A session's truth file is missing, or it does not hold a labelled recording.
    """
    truth_dir = Path(truth_dir)
    cache: dict[str, dict[str, Any]] = {}
    out, maps = [], []
    for r in labels.itertuples():
        if r.session not in cache:
            path = truth_dir / f"{r.session}.json"
            try:
                cache[r.session] = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, json.JSONDecodeError) as exc:
                raise TruthError(f"{path}: expected the simulator's truth file for session {r.session}, "
                                 f"found {exc}") from None
        try:
            d = cache[r.session]["recordings"][r.recording]["devices"][r.device]
            dev = cache[r.session].get("devices", {}).get(r.device, {})
        except (KeyError, TypeError, AttributeError):
            raise TruthError(f"{truth_dir / (r.session + '.json')}: expected recording {r.recording}, device "
                             f"{r.device}, found no such entry") from None
        rec = cache[r.session]["recordings"][r.recording]
        d = _pose_truth(d, getattr(r, "segment_start_s", None), getattr(r, "segment_end_s", None))
        out.append([*d["apparent_bias"], *d["offset"],
                    *_sensor_frame_bias(d, dev, float(cache[r.session].get("g_local", np.nan))),
                    *_reference_error(cache[r.session], rec, d, dev)])
        key = "A_effective" if getattr(r, "label_method", "") == "campaign-fit" else "A"
        maps.append(np.asarray(dev.get(key, np.full((3, 3), np.nan)), dtype=np.float64))
    cols = ([f"true_bias_{a}" for a in AXES] + [f"true_offset_{a}" for a in AXES]
            + [f"true_sensor_bias_{a}" for a in AXES] + [f"reference_error_{a}" for a in AXES])
    frame = pd.DataFrame(np.array(out, dtype=np.float64).reshape(-1, 12), columns=cols, index=labels.index)
    frame["true_A"] = maps
    return frame


def label_fidelity(labels: pd.DataFrame, truth_dir: str | Path, maps: bool = True,
                   shares: bool = True) -> dict[str, Any]:
    """RMS and largest label errors against the truth, in mg (offsets) and ppm (the map A).

    ``maps=False`` leaves the map out (a dataset card reports the labels its windows carry);
    ``shares=False`` leaves out where the error comes from (the reference's share, the
    sensor-frame comparison; dataset cards state the plain errors).

    Returns
    -------
    dict
        ``n``; ``bias_rms_mg`` and ``bias_max_mg`` per axis (apparent bias, the paper's
        label); for reference-based labels ``reference_rms_mg`` (the error the reference's
        own bias and scale put in them, :func:`_reference_error`) and ``bias_own_rms_mg``
        (the rest: the labeller's own error); where the truth gives gravity in the sensor's
        own axes, ``bias_sensor_frame_rms_mg`` (multi-position labels against
        :func:`_sensor_frame_bias`); ``offset_rms_mg`` / ``offset_max_mg`` per axis and
        ``n_offsets`` when some rows carry a zero-g offset; ``A_rms_ppm`` / ``A_max_ppm``
        (entries of the fitted A against the truth's, over each fitted device and power cycle
        once) and ``n_maps`` when some rows carry a fitted A.
    """
    truth = truth_table(truth_dir, labels)
    out: dict[str, Any] = {"n": len(labels)}
    for name in ("bias", "offset"):
        est = labels[[f"{name}_{a}" for a in AXES]].to_numpy(dtype=np.float64)
        tru = truth[[f"true_{name}_{a}" for a in AXES]].to_numpy()
        ok = np.all(np.isfinite(est), axis=1)
        if not ok.any():
            continue
        err = (est[ok] - tru[ok]) / MG
        if name == "offset":
            out["n_offsets"] = int(ok.sum())
        rms = np.sqrt(np.mean(err**2, axis=0))
        big = np.max(np.abs(err), axis=0)
        out[f"{name}_rms_mg"] = {a: round(float(rms[i]), 4) for i, a in enumerate(AXES)}
        out[f"{name}_max_mg"] = {a: round(float(big[i]), 4) for i, a in enumerate(AXES)}
    est = labels[[f"bias_{a}" for a in AXES]].to_numpy(dtype=np.float64)
    tru = truth[[f"true_bias_{a}" for a in AXES]].to_numpy()
    sensor = truth[[f"true_sensor_bias_{a}" for a in AXES]].to_numpy()
    reference = truth[[f"reference_error_{a}" for a in AXES]].to_numpy()
    fitted = (labels["label_method"] == "multi-position").to_numpy() if "label_method" in labels else False
    finite = np.all(np.isfinite(est), axis=1)
    ok = finite & fitted & np.all(np.isfinite(sensor), axis=1)  # labels in the sensor's own axes
    parts = {"bias_sensor_frame_rms_mg": est[ok] - sensor[ok]} if ok.any() and shares else {}
    ok = finite & np.all(np.isfinite(reference), axis=1)  # labels through the reference's direction
    if ok.any() and shares:
        parts.update(reference_rms_mg=reference[ok], bias_own_rms_mg=est[ok] - tru[ok] - reference[ok])
    for name, err in parts.items():
        rms = np.sqrt(np.mean((err / MG) ** 2, axis=0))
        out[name] = {a: round(float(rms[i]), 4) for i, a in enumerate(AXES)}
    names = [f"a_{r}{c}" for r in AXES for c in AXES]
    if maps and set(names) <= set(labels.columns):
        fitted = labels[names].to_numpy(dtype=np.float64)
        ok = np.all(np.isfinite(fitted), axis=1)
        keys = labels[["session", "device"]].astype(str).agg("/".join, axis=1).to_numpy()
        first = {k: i for i, k in reversed(list(enumerate(keys))) if ok[i]}
        if first:
            idx = sorted(first.values())
            err = np.array([fitted[i] - truth["true_A"].iloc[i].ravel() for i in idx]) * 1e6
            out["n_maps"] = len(idx)
            out["A_rms_ppm"] = round(float(np.sqrt(np.mean(err**2))), 2)
            out["A_max_ppm"] = round(float(np.max(np.abs(err))), 2)
    return out
