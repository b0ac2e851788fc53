"""Label products: the campaign fit over labelled sessions, and the files of products.md.

``processed/labels/<campaign>/<session>.parquet`` (one row per labelled recording and DUT,
provenance in the Parquet metadata under ``ofbe``; not written when no row was labelled),
``<session>.rejected.json`` (rejections, warnings and notes) and ``campaign_fit.json`` (the fit
of every device, or why there is none). Every file is written to a temporary name and renamed.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from ofbe_data import __version__
from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.precision import ACCEL_DECIMALS, round_floats, round_label_value
from ofbe_data.labelling.campaign_fit import DeviceFit, fit_device
from ofbe_data.labelling.conventions import (
    IMUTK_COLUMNS,
    MATRIX_COLUMNS,
    TEMPERATURE_COLUMNS,
    empty_columns,
    imutk_columns,
    map_columns,
    scale_columns,
)
from ofbe_data.labelling.labels import REJECTIONS_FORMAT, LabelParams, SessionLabels, provenance

CAMPAIGN_FIT_FORMAT = "ofbe-campaign-fit/1"

#: Columns of a label file, in order, with their Arrow types (products.md plus extras).
LABEL_SCHEMA = pa.schema([
    ("campaign", pa.string()), ("session", pa.string()), ("recording", pa.string()),
    ("device", pa.string()), ("kind", pa.string()), ("power_cycle", pa.int64()),
    ("n_samples", pa.int64()), ("fs_hz", pa.float64()), ("g_local", pa.float64()),
    ("bias_x", pa.float64()), ("bias_y", pa.float64()), ("bias_z", pa.float64()),
    ("offset_x", pa.float64()), ("offset_y", pa.float64()), ("offset_z", pa.float64()),
    ("gravity_x", pa.float64()), ("gravity_y", pa.float64()), ("gravity_z", pa.float64()),
    ("roll_deg", pa.float64()), ("pitch_deg", pa.float64()),
    ("convergence_x", pa.int64()), ("convergence_y", pa.int64()), ("convergence_z", pa.int64()),
    ("label_method", pa.string()),
    ("sync_offset_s", pa.float64()), ("sync_drift_ppm", pa.float64()),
    ("sync_residual_s", pa.float64()), ("raw_sha256", pa.string()),
    # extras
    ("sync_method", pa.string()), ("raw_file", pa.string()),
    ("segment_start_s", pa.float64()), ("segment_end_s", pa.float64()),
    ("std_x", pa.float64()), ("std_y", pa.float64()), ("std_z", pa.float64()),
    ("skipped_lines", pa.int64()), ("missing_samples", pa.int64()), ("fit_condition", pa.float64()),
    ("pose", pa.int64()), ("temperature_c", pa.float64()),
    ("fit_model", pa.string()),
    ("scale_x", pa.float64()), ("scale_y", pa.float64()), ("scale_z", pa.float64()),
    # the calibration model (methods.md §8; docs/labelling.md "The calibration model"): how it was
    # chosen, the fitted map A and the conventions of imu_tk, every fitted value's standard error
    ("fit_model_reason", pa.string()), ("fit_residual_rms", pa.float64()), ("fit_dof", pa.int64()),
    ("fit_n_poses", pa.int64()),
    *((f"{name}_se", pa.float64()) for name in ("offset_x", "offset_y", "offset_z", "scale_x", "scale_y",
                                                 "scale_z")),
    *((name, pa.float64()) for name in MATRIX_COLUMNS),
    *((f"{name}_se", pa.float64()) for name in MATRIX_COLUMNS),
    *((name, pa.float64()) for name in IMUTK_COLUMNS),
    *((f"{name}_se", pa.float64()) for name in IMUTK_COLUMNS),
    *((name, pa.float64()) for name in TEMPERATURE_COLUMNS),
    *((f"{name}_se", pa.float64()) for name in TEMPERATURE_COLUMNS),
    ("temp_ref_c", pa.float64()),
])


def fit_campaign(sessions: Sequence[SessionLabels], params: LabelParams) -> dict[str, DeviceFit]:
    """Run the campaign fit per device over the rotated sessions given, and fill offsets.

    Rows of devices whose fit is determined get ``offset_*`` (their power cycle's offset),
    ``fit_condition``, and ``label_method = "campaign-fit"``; ``bias_*`` stays the direct
    apparent bias. Sessions of other kinds are left as they are.

    Parameters
    ----------
    sessions
        Labelled sessions of one campaign.
    params
        Labelling parameters (``campaign_fit``).

    Returns
    -------
    dict
        Fit per device id (rotated campaigns only).
    """
    rows = [r for s in sessions if s.manifest.kind == "rotated" for r in s.rows]
    if not rows or not params.campaign_fit.enabled:
        return {}
    fits = {}
    for device in sorted({r["device"] for r in rows}):
        mine = [r for r in rows if r["device"] == device]
        fit = fit_device(device, np.array([r["_u"] for r in mine]), np.array([r["_mean"] for r in mine]),
                         np.array([r["power_cycle"] for r in mine]),
                         float(np.mean([r["g_local"] for r in mine])), params.campaign_fit)
        fits[device] = fit
        if fit.determined:
            columns = campaign_map_columns(fit)
            for r in mine:
                r.update(columns)
                b, b_se = fit.offsets[r["power_cycle"]], fit.offset_se(r["power_cycle"])
                for i, a in enumerate("xyz"):
                    r[f"offset_{a}"], r[f"offset_{a}_se"] = float(b[i]), float(b_se[i])
                r["label_method"] = "campaign-fit"
    return fits


def campaign_map_columns(fit: DeviceFit) -> dict[str, Any]:
    """The label columns of a device's campaign fit: its full A (scale, cross-axis and the mount
    relative to the reference) with standard errors, and the scales and imu_tk's parameters of A's
    triangular part (:mod:`ofbe_data.labelling.conventions`)."""
    assert fit.A is not None
    cov = fit.matrix_covariance()
    columns: dict[str, Any] = empty_columns()
    columns.update(map_columns(fit.A, np.sqrt(np.maximum(np.diag(cov), 0.0)).reshape(3, 3)))
    for columns_of in (scale_columns, imutk_columns):
        columns.update(columns_of(lambda x: x.reshape(3, 3), fit.A.ravel(), cov))
    columns.update({"fit_model": "campaign", "fit_condition": fit.condition,
                    "fit_model_reason": f"campaign fit over {fit.n_recordings} recordings in "
                                        f"{fit.n_power_cycles} power cycles",
                    "fit_residual_rms": fit.residual_rms, "fit_dof": fit.dof,
                    "fit_n_poses": fit.n_recordings})
    return columns


def labels_table(labels: SessionLabels, params: LabelParams) -> pa.Table:
    """The session's rows as an Arrow table in :data:`LABEL_SCHEMA`, provenance attached."""
    names = LABEL_SCHEMA.names
    data = {n: [_missing_if_nan(round_label_value(n, r.get(n))) for r in labels.rows] for n in names}
    table = pa.Table.from_pydict(data, schema=LABEL_SCHEMA)
    meta = {b"ofbe": json.dumps(provenance(labels, params), sort_keys=True).encode()}
    return table.replace_schema_metadata(meta)


def _missing_if_nan(value: Any) -> Any:
    """A float NaN is written as a missing value (a parameter not fitted, products.md)."""
    return None if isinstance(value, float) and value != value else value


def _parquet_bytes(table: pa.Table) -> bytes:
    """The Parquet file of ``table`` (zstd), written into an Arrow buffer: the same bytes as into
    a Python file object, without a call back into Python for each of the writer's small writes."""
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, compression="zstd")
    return sink.getvalue().to_pybytes()


def _json_bytes(obj: Any) -> bytes:
    return (json.dumps(obj, indent=2, sort_keys=False, allow_nan=False) + "\n").encode()


def session_outputs(labels: SessionLabels, out_dir: str | Path) -> tuple[Path, Path]:
    """Paths of the label and rejection files of a session under ``out_dir``."""
    base = Path(out_dir) / labels.manifest.campaign
    return base / f"{labels.manifest.session}.parquet", base / f"{labels.manifest.session}.rejected.json"


def rejections_document(labels: SessionLabels) -> dict[str, Any]:
    """The content of ``<session>.rejected.json``: every rejection with its reason, the
    session's warnings (to check) and, where it has any, its notes (information, e.g. the poses
    found; the key is left out otherwise, so that the files of sessions without notes keep
    their bytes)."""
    m = labels.manifest
    doc = {"format": REJECTIONS_FORMAT, "toolkit_version": __version__, "campaign": m.campaign,
           "session": m.session, "labelled": len(labels.rows),
           "rejected": [r.to_dict() for r in labels.rejections], "warnings": labels.warnings}
    return {**doc, "notes": labels.notes} if labels.notes else doc


def write_session(labels: SessionLabels, params: LabelParams,
                  out_dir: str | Path) -> tuple[Path | None, Path]:
    """Write ``<session>.parquet`` and ``<session>.rejected.json`` atomically.

    A session with no labelled row writes no Parquet file (a label file of no label is no
    product): its rejection file says why, and a label file an earlier run wrote for the
    session is removed, so that no stale label stays readable as current.

    Returns
    -------
    The label file's path (None when not written) and the rejection file's.
    """
    parquet_path, rejected_path = session_outputs(labels, out_dir)
    parquet_path.parent.mkdir(parents=True, exist_ok=True)
    if labels.rows:
        write_bytes_atomic(parquet_path, _parquet_bytes(labels_table(labels, params)))
    else:
        parquet_path.unlink(missing_ok=True)
    write_bytes_atomic(rejected_path, _json_bytes(rejections_document(labels)))
    return (parquet_path if labels.rows else None), rejected_path


def write_campaign_fit(campaign: str, fits: dict[str, DeviceFit], sessions: Sequence[SessionLabels],
                       params: LabelParams, out_dir: str | Path) -> Path:
    """Write ``<campaign>/campaign_fit.json``: every device's fit or why there is none."""
    path = Path(out_dir) / campaign / "campaign_fit.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    kinds = sorted({s.manifest.kind for s in sessions})
    note = "" if fits else ("no rotated sessions: offsets come from the multi-position fit"
                            if kinds == ["multi-position"] else
                            "no reference: the orientations of gravity-aligned sessions do not "
                            "determine the map A, so zero-g offsets stay unknown"
                            if "rotated" not in kinds else "campaign fit disabled")
    doc = {"format": CAMPAIGN_FIT_FORMAT, "toolkit_version": __version__, "campaign": campaign,
           "model": "m_k = g_local * A @ u_k + b_(power cycle of k)",
           "sessions": sorted(s.manifest.session for s in sessions), "note": note,
           "parameters": dataclasses.asdict(params.campaign_fit),
           "devices": {d: f.to_dict() for d, f in sorted(fits.items())}}
    write_bytes_atomic(path, _json_bytes(round_floats(doc, ACCEL_DECIMALS, frozenset({"condition"}))))
    return path


def read_labels(path: str | Path) -> pd.DataFrame:
    """Read label files (one file, or every ``*.parquet`` in a folder) into one frame.

    Parameters
    ----------
    path
        A ``<session>.parquet`` file or a campaign folder of them.

    Returns
    -------
    pandas.DataFrame
        Rows in file-name order; nullable offsets as NaN.
    """
    p = Path(path)
    files = sorted(p.glob("*.parquet")) if p.is_dir() else [p]
    tables = [pq.read_table(f) for f in files]
    if not tables:
        return LABEL_SCHEMA.empty_table().to_pandas()
    return pa.concat_tables([t.replace_schema_metadata(None) for t in tables]).to_pandas()


def read_provenance(path: str | Path) -> dict[str, Any]:
    """The provenance stored in a label file's Parquet metadata."""
    meta = pq.read_schema(path).metadata or {}
    return json.loads(meta[b"ofbe"])
