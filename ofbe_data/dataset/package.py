"""The files that make a dataset folder a shareable package: Frictionless datapackage.json, the
Croissant croissant.json, the dataset card (with its Hugging Face front matter), CITATION.cff,
SHA256SUMS. A sharded dataset gets one resource, one card row and one checksum per shard file
(HDF5 and signal Parquet).

``datapackage.json`` is valid for frictionless-py's own validator: the HDF5 and signal Parquet
files are plain file resources (``"type": "file"``, checked by size and SHA-256), and
``windows.parquet`` is a tabular resource with its schema (checked row by row) and no ``bytes``:
frictionless reads Parquet through pyarrow, counts no bytes, and would report any declared
``bytes`` as a byte-count error. Its SHA-256 stays in ``hash`` and in ``SHA256SUMS``.
"""

from __future__ import annotations

import json
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import yaml

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.dataset.croissant import croissant_document
from ofbe_data.dataset.store import (
    CITATION_NAME,
    CROISSANT_NAME,
    DATAPACKAGE_NAME,
    FRAME,
    H5_NAME,
    PAPER_AUTHORS,
    PAPER_TITLE,
    PARQUET_NAME,
    README_NAME,
    RECORDING_KEY,
    SCHEMA_VERSION,
    SHARD_COLUMNS,
    SIGNAL_COLUMN,
    SUMS_NAME,
    UNITS,
    ColumnSpec,
    DatasetError,
    DatasetInfo,
    all_columns,
    check_info_matches,
    check_version,
    fold_column,
    json_bytes,
    read_h5_header,
    read_parquet_provenance,
    same_signal_schema,
    sha256_file,
    shard_layout,
    signal_names,
    signal_schema,
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
    keys = list(dict.fromkeys([*RECORDING_KEY, "device"]))
    by = meta.groupby("device", sort=False)
    windows, cycles = by.size(), by["power_cycle"].nunique()
    recordings = meta.drop_duplicates(keys).groupby("device", sort=False).size()
    return {str(d): {"recordings": int(recordings[d]), "windows": int(windows[d]),
                     "power_cycles": int(cycles[d])} for d in sorted(meta["device"].unique())}


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


def _field_entry(col: ColumnSpec) -> dict[str, Any]:
    entry: dict[str, Any] = {"name": col.name, "type": {"string": "string", "int": "integer",
                                                        "float": "number"}[col.kind],
                             "description": col.description,
                             "constraints": {"required": not col.nullable}}
    if col.unit is not None:
        entry["unit"] = col.unit
    return entry


def _h5_resources(info: DatasetInfo, files: Mapping[str, tuple[int, str]],
                  layout: list[tuple[str, int]] | None) -> list[dict[str, Any]]:
    """The Frictionless resources of ``windows.h5``, or one per shard file."""
    t = info.window_length
    if layout is None:
        h5_bytes, h5_hash = files[H5_NAME]
        return [{"name": "windows-h5", "path": H5_NAME, "profile": "data-resource", "type": "file",
                 "format": "hdf5",
                 "mediatype": "application/x-hdf5", "bytes": h5_bytes, "hash": f"sha256:{h5_hash}",
                 "description": f"X float32 (N, {t}, 3) {UNITS}, sensor frame, one gzip+shuffle+fletcher32 "
                                f"chunk per window; y float64 (N, 3) {UNITS}; meta/ one dataset per column "
                                f"of {PARQUET_NAME}, same row order"}]
    out, first = [], 0
    for i, (name, n) in enumerate(layout):
        size, digest = files[name]
        out.append({"name": name.replace(".", "-"), "path": name, "profile": "data-resource", "type": "file",
                    "format": "hdf5",
                    "mediatype": "application/x-hdf5", "bytes": size, "hash": f"sha256:{digest}",
                    "description": f"shard {i} of {len(layout)}: windows {first}..{first + n - 1} "
                                   f"(window_id); X float32 ({n}, {t}, 3) {UNITS}, sensor frame, one "
                                   f"gzip+shuffle+fletcher32 chunk per window; y float64 ({n}, 3) {UNITS}; "
                                   f"meta/ the rows of {PARQUET_NAME} with shard = {i}, same order"})
        first += n
    return out


def _signal_resources(info: DatasetInfo, files: Mapping[str, tuple[int, str]], signals: Sequence[str] | None,
                      layout: list[tuple[str, int]] | None) -> list[dict[str, Any]]:
    """The Frictionless resources of the signal Parquet files: plain files (size and SHA-256), since a
    (T, 3) array per cell is no tabular type."""
    t = info.window_length
    out = []
    for i, name in enumerate(signals or ()):
        size, digest = files[name]
        rows = "the rows of windows.parquet" if layout is None else (
            f"the rows of windows.parquet with shard = {i} (windows of {layout[i][0]})")
        out.append({"name": name.replace(".", "-"), "path": name, "profile": "data-resource", "type": "file",
                    "format": "parquet", "mediatype": "application/vnd.apache.parquet", "bytes": size,
                    "hash": f"sha256:{digest}",
                    "description": f"{rows}, same columns and order, plus {SIGNAL_COLUMN}: the window, "
                                   f"fixed-size list of {t} fixed-size lists of 3 float32, {UNITS}, sensor "
                                   "frame, equal to the HDF5 X; what the card's Hugging Face configs and "
                                   "croissant.json's record set 'signals' read"})
    return out


def _datapackage(info: DatasetInfo, attrs: Mapping[str, Any], meta: pd.DataFrame,
                 files: Mapping[str, tuple[int, str]], sizes: Mapping[str, Any],
                 layout: list[tuple[str, int]] | None = None,
                 signals: Sequence[str] | None = None) -> dict[str, Any]:
    _, pq_hash = files[PARQUET_NAME]
    t = info.window_length
    protocols = {p: {**spec, "fold_column": fold_column(p), "fold_sizes": sizes.get(p)}
                 for p, spec in info.protocols.items()}
    sharded = layout is not None
    doc = {
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
            *_h5_resources(info, files, layout),
            {"name": "windows", "path": PARQUET_NAME, "profile": "tabular-data-resource", "format": "parquet",
             "mediatype": "application/vnd.apache.parquet", "hash": f"sha256:{pq_hash}",
             "description": ("one row per window, same order as windows.h5" if not sharded else
                             "the index: one row per window, in window_id order, with its shard file and "
                             "row there (shard, shard_row)"),
             "schema": {"fields": [_field_entry(c) for c in all_columns(list(info.protocols), sharded)],
                        "primaryKey": "window_id"}},
            *_signal_resources(info, files, signals, layout),
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
    if layout is not None:  # single-file datasets keep their bytes
        doc["ofbe"]["shards"] = {"n_shards": len(layout), "windows_per_shard": int(attrs["shard_windows"]),
                                 "files": [{"path": name, "n_windows": n} for name, n in layout]}
    return doc


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


#: SPDX id → the Hugging Face Hub's licence id (hf.co/docs/hub/repositories-licenses); others are
#: written as ``license: other`` with ``license_name``.
HF_LICENCES = {"CC-BY-4.0": "cc-by-4.0", "CC-BY-SA-4.0": "cc-by-sa-4.0", "CC-BY-NC-4.0": "cc-by-nc-4.0",
               "CC0-1.0": "cc0-1.0", "MIT": "mit", "Apache-2.0": "apache-2.0", "ODbL-1.0": "odbl",
               "PDDL-1.0": "pddl", "BSD-3-Clause": "bsd-3-clause", "GPL-3.0-only": "gpl-3.0"}
HF_SIZE_CATEGORIES = ((1_000, "n<1K"), (10_000, "1K<n<10K"), (100_000, "10K<n<100K"),
                      (1_000_000, "100K<n<1M"), (10_000_000, "1M<n<10M"))


_HF_DTYPES = {"string": "string", "int": "int64", "float": "float64"}


def hf_configs(info: DatasetInfo, signals: Sequence[str]) -> list[dict[str, Any]]:
    """The Hugging Face ``configs`` of the card: one per protocol, named after it.

    Each reads every signal file (one ``train`` split: every window; the folds are a column, not
    splits, because a fold's training set is every other fold plus the −1 rows) and keeps the
    columns of ``windows.parquet`` less the index columns ``shard``/``shard_row`` and the other
    protocols' fold columns, plus ``X``. ``features`` spell out every type, ``X`` as an
    ``Array2D`` of shape (T, 3), float32, so ``datasets`` gives each window back as a (T, 3) array
    (numpy format) without inferring anything. The first protocol's config is the default; a
    dataset without protocols gets one ``default`` config with every column.

    Parameters
    ----------
    info
        The dataset description (window length, protocols in order).
    signals
        The signal Parquet files, in window order.

    Returns
    -------
    list of dict
        The ``configs`` entries, ready for YAML.
    """
    protocols = list(info.protocols)
    columns = [c for c in all_columns(protocols) if c.name not in SHARD_COLUMNS]
    out: list[dict[str, Any]] = []
    for proto in protocols or [None]:  # fresh objects for each config: YAML would alias shared ones
        signal = {"name": SIGNAL_COLUMN,
                  "dtype": {"array2_d": {"shape": [info.window_length, 3], "dtype": "float32"}}}
        keep = [c for c in columns if not c.name.startswith("fold_") or proto is None
                or c.name == fold_column(proto)]
        config: dict[str, Any] = {
            "config_name": proto or "default",
            "data_files": [{"split": "train", "path": list(signals)}],
            "columns": [*(c.name for c in keep), SIGNAL_COLUMN],
            "features": [*({"name": c.name, "dtype": _HF_DTYPES[c.kind]} for c in keep), signal],
        }
        if not out:
            config["default"] = True
        out.append(config)
    return out


def hf_front_matter(info: DatasetInfo, n_windows: int, signals: Sequence[str] | None = None) -> str:
    """The card's YAML front matter in the Hugging Face dataset-card convention: licence, task,
    size category, pretty name and, when the folder has signal Parquet files, the ``configs``
    that read them (:func:`hf_configs`: one per protocol, windows with their samples).

    A folder without signal files gets no ``configs``: the only Parquet file there,
    ``windows.parquet``, holds no samples, and a config on it would load windows without their
    signals.
    """
    hf = HF_LICENCES.get(info.licence)
    meta: dict[str, Any] = {"license": hf or "other"}
    if hf is None:
        meta["license_name"] = info.licence
    meta.update({
        "pretty_name": info.title,
        "task_categories": ["tabular-regression"],
        "tags": ["accelerometer", "imu", "sensor-calibration", "bias-estimation", "time-series"],
        "size_categories": [next((c for limit, c in HF_SIZE_CATEGORIES if n_windows < limit), "n>10M")],
    })
    if signals:
        meta["configs"] = hf_configs(info, signals)
    return "---\n" + yaml.safe_dump(meta, sort_keys=False, allow_unicode=True, width=1000) + "---\n\n"


def _readme(info: DatasetInfo, attrs: Mapping[str, Any], meta: pd.DataFrame,
            files: Mapping[str, tuple[int, str]], sizes: Mapping[str, Any],
            layout: list[tuple[str, int]] | None = None, signals: Sequence[str] | None = None) -> str:
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
    if layout is None:
        h5_rows = [[H5_NAME, files[H5_NAME][0], f"`{files[H5_NAME][1]}`",
                    f"`X` (N, {t}, 3) float32, `y` (N, 3) float64, `meta/` columns"]]
    else:
        out += [f"Sharded: {len(layout)} HDF5 files of at most {int(attrs['shard_windows'])} windows, each "
                f"laid out like a single `{H5_NAME}` for its rows; `{PARQUET_NAME}` is the index of all of "
                "them (columns `shard`, `shard_row`).", ""]
        h5_rows, first = [], 0
        for name, k in layout:
            h5_rows.append([name, files[name][0], f"`{files[name][1]}`",
                            f"windows {first}–{first + k - 1}: `X` ({k}, {t}, 3), `y`, `meta/`"])
            first += k
    signal_rows, first = [], 0
    for i, name in enumerate(signals or ()):
        k = len(meta) if layout is None else layout[i][1]
        where_rows = "every row" if layout is None else f"windows {first}–{first + k - 1}"
        signal_rows.append([name, files[name][0], f"`{files[name][1]}`",
                            f"{where_rows} of `{PARQUET_NAME}` plus `{SIGNAL_COLUMN}`: the window, "
                            f"({t}, 3) float32 (Hugging Face, Croissant, any Parquet reader)"])
        first += k
    out += _md_table(["file", "bytes", "sha256", "content"],
                     [*h5_rows,
                      [PARQUET_NAME, files[PARQUET_NAME][0], f"`{files[PARQUET_NAME][1]}`",
                       "one row per window (same order)" if layout is None else
                       "the index: one row per window, with its `shard` and `shard_row`"],
                      *signal_rows,
                      [DATAPACKAGE_NAME, "", "", "Frictionless Data Package description"],
                      [CROISSANT_NAME, "", "", "MLCommons Croissant 1.1 description"],
                      [README_NAME, "", "", "this card"],
                      [CITATION_NAME, "", "", "how to cite"],
                      [SUMS_NAME, "", "", "SHA-256 of every other file (`sha256sum -c SHA256SUMS`)"]])
    out += ["", "Columns of `windows.parquet` (and of `windows.h5:/meta`):" if layout is None else
            "Columns of `windows.parquet` (and of every shard's `meta/`, for its rows):", ""]
    out += _md_table(["column", "type", "unit", "meaning"],
                     [[c.name, {"string": "string", "int": "int64", "float": "float64"}[c.kind]
                       + (" (nullable)" if c.nullable else ""), c.unit or "", c.description]
                      for c in all_columns(protos, layout is not None)])
    where = f"processed/datasets/{info.name}"
    out += ["", "## Loading", "", "```python", "from ofbe_data import load_dataset",
            "", f'ds = load_dataset("{where}")   # checks SHA256SUMS and the schema version',
            f"ds.X     # float32 (N, {t}, 3), {UNITS}", f"ds.y     # float64 (N, 3), {UNITS}",
            "ds.meta  # pandas DataFrame, one row per window",
            f'frame = load_dataset("{where}", as_="pandas")  # metadata and labels (bias_x/y/z), no X',
            f'tfds = load_dataset("{where}", as_="tf")       # tf.data.Dataset of (X, y), streamed',
            "```", ""]
    if layout is None:
        out += ["Without the toolkit: `h5py.File(\"windows.h5\")[\"X\"]` and "
                "`pyarrow.parquet.read_table(\"windows.parquet\")`.", ""]
    else:
        out += ["`ds.X` reads every shard on first use; `for X, y, meta in ds.iter_shards():` holds one "
                "shard at a time. Without the toolkit: `h5py.File(\"windows-00000.h5\")[\"X\"]`, … and "
                "`pyarrow.parquet.read_table(\"windows.parquet\")` (columns `shard`, `shard_row`).", ""]
    if signals:
        first_proto = next(iter(info.protocols), "default")
        out += ["With Hugging Face `datasets` (offline, from this folder): one config per protocol "
                f"({', '.join(f'`{p}`' for p in info.protocols) or '`default`'}; `{first_proto}` is the "
                "default), one `train` split holding every window with its samples, its label, its "
                "metadata and the fold column of that protocol:", "",
                "```python", "import datasets", "",
                f'ds = datasets.load_dataset("{where}", "{first_proto}", split="train").with_format("numpy")',
                f'ds[0]["{SIGNAL_COLUMN}"]   # float32 ({t}, 3), {UNITS}',
                *([f'folds = ds["{fold_column(first_proto)}"]   # fold k: tests on its window-0s, trains on '
                   "fold != k"] if info.protocols else []),
                "```", "",
                f"With MLCommons Croissant: `mlcroissant.Dataset(jsonld=\"{CROISSANT_NAME}\")`, record sets "
                f"`windows` (labels, metadata, folds) and `signals` (the same plus `{SIGNAL_COLUMN}`).", ""]
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


def _present_signals(folder: Path, layout: list[tuple[str, int]] | None,
                     info: DatasetInfo) -> list[str] | None:
    """The folder's signal Parquet files (all of them, schemas checked), or ``None`` when it has none."""
    names = signal_names(layout)
    present = [n for n in names if (folder / n).is_file()]
    if not present:
        return None
    if len(present) != len(names):
        missing = next(n for n in names if n not in present)
        raise DatasetError(folder / missing, f"a signal file like the others ({', '.join(present)})",
                           "no such file")
    expected = signal_schema(list(info.protocols), info.window_length, layout is not None)
    for name in names:
        try:
            schema = pq.read_schema(folder / name)
        except (OSError, pa.ArrowException) as exc:
            raise DatasetError(folder / name, "a Parquet file", f"an unreadable one ({exc})") from exc
        if not same_signal_schema(schema, expected, info.window_length):
            raise DatasetError(folder / name, f"the columns {[f'{f.name}:{f.type}' for f in expected]}",
                               f"{[f'{f.name}:{f.type}' for f in schema]}")
    return names


def write_package_files(folder: str | Path, info: DatasetInfo) -> None:
    """Write ``datapackage.json``, ``croissant.json``, ``README.md``, ``CITATION.cff`` and, last,
    ``SHA256SUMS``.

    Parameters
    ----------
    folder
        Folder that already holds ``windows.h5`` (or the shard files), ``windows.parquet`` and,
        normally, the signal Parquet file(s) (:func:`~ofbe_data.dataset.signals.write_signal_files`).
        Without signal files the card has no Hugging Face ``configs`` and ``croissant.json`` no
        ``signals`` record set.
    info
        Dataset description; its structural fields (name, campaign, kind, windowing, protocols)
        must agree with ``windows.h5``'s attributes.

    Raises
    ------
    DatasetError
        When a data file is missing or unreadable, or disagrees with ``info``; or when only some of
        the signal files are there, or one has other columns than ``windows.parquet`` plus ``X``.
    """
    folder = Path(folder)
    pq_path = folder / PARQUET_NAME
    layout = shard_layout(folder)
    h5_names = [H5_NAME] if layout is None else [name for name, _ in layout]
    h5_path = folder / h5_names[0]
    attrs = read_h5_header(h5_path)
    check_info_matches(info, attrs, h5_path)
    check_version(pq_path, read_parquet_provenance(pq_path).get("schema_version"))
    meta = pq.read_table(pq_path).replace_schema_metadata(None).to_pandas()
    signals = _present_signals(folder, layout, info)
    files = {n: ((folder / n).stat().st_size, sha256_file(folder / n))
             for n in (*h5_names, PARQUET_NAME, *(signals or ()))}
    sizes = fold_sizes(meta)
    write_bytes_atomic(folder / DATAPACKAGE_NAME,
                       json_bytes(_datapackage(info, attrs, meta, files, sizes, layout, signals)))
    urls = {k: url for k, (_, url) in _LICENCES.items()}
    write_bytes_atomic(folder / CROISSANT_NAME,
                       json_bytes(croissant_document(info, files, layout, signals, urls)))
    card = (hf_front_matter(info, len(meta), signals)
            + _readme(info, attrs, meta, files, sizes, layout, signals))
    write_bytes_atomic(folder / README_NAME, card.encode())
    write_bytes_atomic(folder / CITATION_NAME,
                       yaml.safe_dump(_citation(info), sort_keys=False, allow_unicode=True).encode())
    write_bytes_atomic(folder / SUMS_NAME, _sums_text(folder).encode())
