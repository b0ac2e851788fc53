"""The files that make a dataset folder a shareable package: Frictionless datapackage.json, the
dataset card, CITATION.cff, SHA256SUMS.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import yaml

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.dataset.store import (
    CITATION_NAME,
    DATAPACKAGE_NAME,
    FRAME,
    H5_NAME,
    PAPER_AUTHORS,
    PAPER_TITLE,
    PARQUET_NAME,
    README_NAME,
    RECORDING_KEY,
    SCHEMA_VERSION,
    SUMS_NAME,
    UNITS,
    DatasetInfo,
    _all_columns,
    _check_info_matches,
    _check_version,
    _Column,
    _json_bytes,
    _read_h5_header,
    _read_parquet_provenance,
    fold_column,
    sha256_file,
)

# ---------------------------------------------------------------------------------------------
# Package files: datapackage.json, README.md, CITATION.cff, SHA256SUMS


def fold_sizes(meta: pd.DataFrame) -> dict[str, dict[str, Any]]:
    """Test-set sizes of every protocol's folds.

    A recording here is one labelled series: a distinct (campaign, session, recording,
    device) (those of the key columns that ``meta`` has).

    Parameters
    ----------
    meta
        Window metadata with ``fold_<protocol>`` columns.

    Returns
    -------
    dict
        ``{protocol: {"folds": {fold: {"test_recordings": r, "test_windows": w}},
        "train_only": {"recordings": r, "windows": w}}}``, folds ascending, protocols in column
        order; ``train_only`` counts the rows with fold −1.
    """
    keys = [k for k in RECORDING_KEY if k in meta.columns]
    out: dict[str, dict[str, Any]] = {}
    for col in meta.columns:
        if not str(col).startswith("fold_"):
            continue
        folds = meta[col].to_numpy(dtype=np.int64)

        def count(mask: np.ndarray) -> tuple[int, int]:
            sub = meta.loc[mask, keys]
            return (int(len(sub.drop_duplicates())) if keys else int(mask.sum())), int(mask.sum())

        per_fold = {}
        for k in sorted(int(v) for v in np.unique(folds) if v >= 0):
            r, w = count(folds == k)
            per_fold[k] = {"test_recordings": r, "test_windows": w}
        r, w = count(folds < 0)
        out[str(col)[len("fold_"):]] = {"folds": per_fold, "train_only": {"recordings": r, "windows": w}}
    return out


def _device_counts(meta: pd.DataFrame) -> dict[str, dict[str, int]]:
    out = {}
    for device in sorted(meta["device"].unique()):
        sub = meta[meta["device"] == device]
        out[str(device)] = {"recordings": int(len(sub[list(RECORDING_KEY)].drop_duplicates())),
                            "windows": int(len(sub)), "power_cycles": int(sub["power_cycle"].nunique())}
    return out


_LICENCES = {
    "CC-BY-4.0": ("Creative Commons Attribution 4.0 International",
                  "https://creativecommons.org/licenses/by/4.0/"),
    "CC0-1.0": ("Creative Commons Zero v1.0 Universal", "https://creativecommons.org/publicdomain/zero/1.0/"),
    "CC-BY-SA-4.0": ("Creative Commons Attribution Share Alike 4.0 International",
                     "https://creativecommons.org/licenses/by-sa/4.0/"),
    "ODbL-1.0": ("Open Data Commons Open Database License v1.0", "https://opendatacommons.org/licenses/odbl/1-0/"),
    "MIT": ("MIT License", "https://opensource.org/licenses/MIT"),
}


def _licence_entry(licence: str) -> dict[str, str]:
    title, url = _LICENCES.get(licence, (licence, None))
    entry = {"name": licence, "title": title}
    if url is not None:
        entry["path"] = url
    return entry


def _package_name(name: str) -> str:
    return re.sub(r"[^a-z0-9._-]+", "-", name.lower()).strip("-") or "dataset"


def _field_entry(col: _Column) -> dict[str, Any]:
    entry: dict[str, Any] = {"name": col.name, "type": {"string": "string", "int": "integer",
                                                        "float": "number"}[col.kind],
                             "description": col.description,
                             "constraints": {"required": not col.nullable}}
    if col.unit is not None:
        entry["unit"] = col.unit
    return entry


def _datapackage(info: DatasetInfo, attrs: Mapping[str, Any], meta: pd.DataFrame,
                 files: Mapping[str, tuple[int, str]], sizes: Mapping[str, Any]) -> dict[str, Any]:
    h5_bytes, h5_hash = files[H5_NAME]
    pq_bytes, pq_hash = files[PARQUET_NAME]
    t = info.window_length
    protocols = {p: {**spec, "fold_column": fold_column(p), "fold_sizes": sizes.get(p)}
                 for p, spec in info.protocols.items()}
    return {
        "profile": "data-package",
        "name": _package_name(info.name),
        "title": info.title,
        "description": info.description,
        "version": info.version,
        "licenses": [_licence_entry(info.licence)],
        "contributors": [{"title": a, "role": "author"} for a in info.authors],
        "keywords": ["accelerometer", "bias estimation", "IMU", "stationary", "deep learning"],
        "sources": [{"title": f"Campaign {info.campaign} ({info.kind})"}],
        "resources": [
            {"name": "windows-h5", "path": H5_NAME, "profile": "data-resource", "format": "hdf5",
             "mediatype": "application/x-hdf5", "bytes": h5_bytes, "hash": f"sha256:{h5_hash}",
             "description": f"X float32 (N, {t}, 3) {UNITS}, sensor frame, one gzip+shuffle+fletcher32 chunk "
                            f"per window; y float64 (N, 3) {UNITS}; meta/ one dataset per column of "
                            f"{PARQUET_NAME}, same row order"},
            {"name": "windows", "path": PARQUET_NAME, "profile": "tabular-data-resource", "format": "parquet",
             "mediatype": "application/vnd.apache.parquet", "bytes": pq_bytes, "hash": f"sha256:{pq_hash}",
             "description": "one row per window, same order as windows.h5",
             "schema": {"fields": [_field_entry(c) for c in _all_columns(list(info.protocols))],
                        "primaryKey": "window_id"}},
        ],
        "ofbe": {
            "schema_version": SCHEMA_VERSION, "name": info.name, "campaign": info.campaign, "kind": info.kind,
            "units": UNITS, "frame": FRAME, "fs_hz": info.fs_hz, "window_length": t, "stride": info.stride,
            "n_windows": int(len(meta)),
            "n_recordings": int(len(meta[list(RECORDING_KEY)].drop_duplicates())),
            "devices": _device_counts(meta), "protocols": protocols,
            "toolkit_version": attrs.get("toolkit_version"), "dataset_info": info.to_dict(),
        },
    }


def _md_cell(value: Any) -> str:
    if isinstance(value, float):
        text = f"{value:.6g}"
    elif value is None:
        text = "–"
    elif isinstance(value, dict | list):
        text = json.dumps(value, ensure_ascii=False)
    else:
        text = str(value)
    return text.replace("|", "\\|").replace("\n", " ")


def _md_table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> list[str]:
    lines = ["| " + " | ".join(_md_cell(h) for h in header) + " |",
             "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(_md_cell(v) for v in row) + " |" for row in rows]
    return lines


def _fidelity_table(fidelity: Mapping[str, Any]) -> list[str]:
    """Label fidelity as Markdown: a row per quantity, per-axis values in columns x, y, z."""
    if fidelity and all(isinstance(v, Mapping) for v in fidelity.values()):
        cols: list[str] = []
        for v in fidelity.values():
            cols += [str(k) for k in v if str(k) not in cols]
        return _md_table(["", *cols], [[k, *(v.get(c) for c in cols)] for k, v in fidelity.items()])
    axes = [a for a in ("x", "y", "z") if any(isinstance(v, Mapping) and a in v for v in fidelity.values())]
    rows = [[k, *((v.get(a) for a in axes) if isinstance(v, Mapping) else [v, *[""] * (len(axes) - 1)])]
            for k, v in fidelity.items()]
    return _md_table(["quantity", *(axes or ["value"])], rows)


def _readme(info: DatasetInfo, attrs: Mapping[str, Any], meta: pd.DataFrame,
            files: Mapping[str, tuple[int, str]], sizes: Mapping[str, Any]) -> str:
    t, s, fs = info.window_length, info.stride, info.fs_hz
    n = len(meta)
    n_rec = len(meta[list(RECORDING_KEY)].drop_duplicates())
    devices = _device_counts(meta)
    protos = list(info.protocols)
    out = [f"# {info.title}", "",
           f"`{info.name}`: {n} windows of {t} samples (three-axis accelerometer, {UNITS}) from {n_rec} "
           f"recordings of {len(devices)} devices, campaign `{info.campaign}` ({info.kind}). Each window is "
           "labelled with the apparent bias of its recording.", "",
           f"Version {info.version} · licence {info.licence} · format `{SCHEMA_VERSION}` · built with ofbe "
           f"{attrs.get('toolkit_version')}.", "",
           "## What it is", "",
           "Stationary accelerometer data cut into fixed-length windows, for training and evaluating "
           "orientation-free bias estimators (Levin & Klein, *" + PAPER_TITLE + "*). The input is a window "
           "of raw specific force; the target is the apparent bias b_app = b + (A − I)·u·g_local of the "
           "recording it comes from, in the sensor frame.", "",
           "## How it was recorded", "", info.description.strip() or "Not described.", "",
           "## How the labels were made", "", info.labelling.strip() or "Not described.", "",
           "## Label fidelity", ""]
    out += (_fidelity_table(info.label_fidelity) if info.label_fidelity
            else ["Not quantified for this dataset."])
    out += ["", "## Units and frames", "",
            "The sensor frame is the chip's own logged axes. A resting ideal accelerometer reads the "
            "specific force, pointing up with magnitude g_local (chip flat, z up: [0, 0, +g]).", "",
            f"- `X`: specific force, {UNITS}, float32, axes (window, sample, x/y/z) of the device's sensor "
            "frame, as recorded (no calibration applied).",
            f"- `y` = `bias_x/y/z`: apparent-bias label, {UNITS}, float64, sensor frame.",
            f"- `offset_x/y/z`: zero-g offset, {UNITS}, sensor frame, null where the campaign fit does not "
            "determine it.",
            "- `gravity_x/y/z`: unit specific-force direction u in the sensor frame; `roll_deg`, "
            "`pitch_deg`: tilt implied by u, degrees; `g_local`: local gravity, " + UNITS + ".", "",
            "## Sampling and windowing", "",
            f"- Nominal sample rate {fs:g} Hz (the measured rate of each recording is in `fs_hz`).",
            f"- Window length T = {t} samples ({t / fs:.6g} s at the nominal rate), stride {s} samples.",
            "- Windows are cut from each recording's stationary segment only. `window_index` 0 is the "
            "first window of the segment (the test signal); `start_sample` counts from the segment's "
            "first sample.", "",
            "## Devices", ""]
    out += _md_table(["device", "recordings", "windows", "power cycles"],
                     [[d, c["recordings"], c["windows"], c["power_cycles"]] for d, c in devices.items()])
    out += ["", "## Protocols and folds", "",
            "A recording below is one labelled series (campaign, session, recording, device). All windows of "
            "a recording share its fold; −1 marks recordings used only for training.", ""]
    if not protos:
        out += ["No protocols.", ""]
    for p in protos:
        spec = dict(info.protocols[p])
        desc = spec.pop("description", "")
        out += [f"### {p}", ""]
        if desc:
            out += [str(desc), ""]
        props = ", ".join(f"{k} = {_md_cell(v)}" for k, v in spec.items())
        out += [f"Column `{fold_column(p)}`" + (f"; {props}." if props else "."), ""]
        fs_ = sizes.get(p, {"folds": {}, "train_only": {"recordings": 0, "windows": 0}})
        rows = [[k, v["test_recordings"], v["test_windows"]] for k, v in fs_["folds"].items()]
        rows.append(["−1 (training only)", fs_["train_only"]["recordings"], fs_["train_only"]["windows"]])
        out += _md_table(["fold", "test recordings", "test windows"], rows) + [""]
    out += ["## Files", ""]
    out += _md_table(["file", "bytes", "sha256", "content"],
                     [[H5_NAME, files[H5_NAME][0], f"`{files[H5_NAME][1]}`",
                       f"`X` (N, {t}, 3) float32, `y` (N, 3) float64, `meta/` columns"],
                      [PARQUET_NAME, files[PARQUET_NAME][0], f"`{files[PARQUET_NAME][1]}`",
                       "one row per window (same order)"],
                      [DATAPACKAGE_NAME, "", "", "Frictionless Data Package description"],
                      [README_NAME, "", "", "this card"],
                      [CITATION_NAME, "", "", "how to cite"],
                      [SUMS_NAME, "", "", "SHA-256 of every other file (`sha256sum -c SHA256SUMS`)"]])
    out += ["", "Columns of `windows.parquet` (and of `windows.h5:/meta`):", ""]
    out += _md_table(["column", "type", "unit", "meaning"],
                     [[c.name, {"string": "string", "int": "int64", "float": "float64"}[c.kind]
                       + (" (nullable)" if c.nullable else ""), c.unit or "", c.description]
                      for c in _all_columns(protos)])
    where = f"processed/datasets/{info.name}"
    out += ["", "## Loading", "", "```python", "from ofbe_data import load_dataset",
            "", f'ds = load_dataset("{where}")   # checks SHA256SUMS and the schema version',
            f"ds.X     # float32 (N, {t}, 3), {UNITS}", f"ds.y     # float64 (N, 3), {UNITS}",
            "ds.meta  # pandas DataFrame, one row per window",
            f'frame = load_dataset("{where}", as_="pandas")  # metadata and labels (bias_x/y/z), no X',
            f'tfds = load_dataset("{where}", as_="tf")       # tf.data.Dataset of (X, y), streamed',
            "```", "", "Without the toolkit: `h5py.File(\"windows.h5\")[\"X\"]` and "
            "`pyarrow.parquet.read_table(\"windows.parquet\")`.", ""]
    if info.extra:
        out += ["## Other properties", ""]
        out += _md_table(["property", "value"], [[k, v] for k, v in info.extra.items()]) + [""]
    out += ["## Licence", "", f"{_licence_entry(info.licence)['title']} (`{info.licence}`).", "",
            "## Citation", "", f"Cite the dataset ({CITATION_NAME}: {', '.join(info.authors)}, "
            f"*{info.title}*, version {info.version}) and the paper: {' & '.join(PAPER_AUTHORS)}, "
            f"*{PAPER_TITLE}*.", "",
            "## Schema version", "", f"`{SCHEMA_VERSION}`: in the root attributes of `{H5_NAME}`, the "
            f"`ofbe` metadata of `{PARQUET_NAME}` and `ofbe.schema_version` of `{DATAPACKAGE_NAME}`.", ""]
    return "\n".join(out)


def _citation(info: DatasetInfo) -> dict[str, Any]:
    return {
        "cff-version": "1.2.0",
        "message": "If you use this dataset, please cite it as below and cite the paper it serves.",
        "type": "dataset",
        "title": info.title,
        "version": info.version,
        "license": info.licence,
        "authors": [{"name": a} for a in info.authors],
        "abstract": info.description.strip() or info.title,
        "keywords": ["accelerometer", "bias estimation", "IMU"],
        "references": [{"type": "article", "title": PAPER_TITLE,
                        "authors": [{"family-names": a} for a in PAPER_AUTHORS]}],
    }


def _sums_text(folder: Path) -> str:
    names = sorted(p.name for p in folder.iterdir()
                   if p.is_file() and p.name != SUMS_NAME and not p.name.startswith("."))
    return "".join(f"{sha256_file(folder / n)}  {n}\n" for n in names)


def write_package_files(folder: str | Path, info: DatasetInfo) -> None:
    """Write ``datapackage.json``, ``README.md``, ``CITATION.cff`` and, last, ``SHA256SUMS``.

    Parameters
    ----------
    folder
        Folder that already holds ``windows.h5`` and ``windows.parquet``.
    info
        Dataset description; its structural fields (name, campaign, kind, windowing, protocols)
        must agree with ``windows.h5``'s attributes.

    Raises
    ------
    DatasetError
        When a data file is missing or unreadable, or disagrees with ``info``.
    """
    folder = Path(folder)
    h5_path, pq_path = folder / H5_NAME, folder / PARQUET_NAME
    attrs = _read_h5_header(h5_path)
    _check_info_matches(info, attrs, h5_path)
    _check_version(pq_path, _read_parquet_provenance(pq_path).get("schema_version"))
    meta = pq.read_table(pq_path).replace_schema_metadata(None).to_pandas()
    files = {n: ((folder / n).stat().st_size, sha256_file(folder / n)) for n in (H5_NAME, PARQUET_NAME)}
    sizes = fold_sizes(meta)
    write_bytes_atomic(folder / DATAPACKAGE_NAME, _json_bytes(_datapackage(info, attrs, meta, files, sizes)))
    write_bytes_atomic(folder / README_NAME, _readme(info, attrs, meta, files, sizes).encode())
    write_bytes_atomic(folder / CITATION_NAME,
                       yaml.safe_dump(_citation(info), sort_keys=False, allow_unicode=True).encode())
    write_bytes_atomic(folder / SUMS_NAME, _sums_text(folder).encode())
