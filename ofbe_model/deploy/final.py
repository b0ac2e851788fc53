"""Deployable models: one OFBENet and one gravity-prior per dataset, fitted on all its windows,
each with a model card.

The cross-validation folds of ``ofbe-train`` measure accuracy; they are not what a user runs
on new recordings (five fold models, each blind to a fifth of the data). This module fits
the two estimators a user deploys on every window of a dataset:

``<out>/<dataset>/final.keras``
    OFBENet (``train:`` parameters, the first seed), in a fresh single-threaded worker so that
    its weights do not depend on the machine's thread count.
``<out>/<dataset>/gravity-prior.json``
    The ``gravity-prior`` with the direction model (the benchmark's
    ``gravity-prior-direction``), saved as JSON (no pickle).
``<out>/<dataset>/MODEL_CARD.md`` and ``model_card.json``
    What each model is for and what it cannot do, the training data (with the SHA-256 of the
    dataset's SHA256SUMS, which pins every file of it, and where it lies: ``path`` as given,
    ``relative_path`` from the card's folder), and the protocol-level RMSE that the benchmark
    measured for the same method on the same data.

:func:`card_dataset` finds a model's training data again from its card (``ofbe-export tflite``
without ``--dataset``).
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ofbe_data import __version__
from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.errors import OfbeError
from ofbe_data.core.parallel import map_progress
from ofbe_data.dataset.reader import load_dataset
from ofbe_model.estimators.priors import GravityPrior
from ofbe_model.ofbenet.params import WORKER_ENV, OFBENetParams

CARD_FORMAT = "ofbe-model-card/1"
OFBENET_NAME = "final.keras"
PRIOR_NAME = "gravity-prior.json"
CARD_JSON = "model_card.json"
CARD_MD = "MODEL_CARD.md"
#: Benchmark method names of the two deployed estimators.
BENCHMARK_METHODS = {"ofbenet": "ofbenet", "gravity-prior": "gravity-prior-direction"}

LIMITS = (
    "One stationary window fixes only the bias component along gravity (‖mean‖ − g); the two "
    "tangential components are invisible in it, so what the model returns for them is the prior it "
    "learned from its training devices, not a measurement.",
    "The estimate is an apparent bias b + (A − I)·u·g at the window's orientation, not the zero-g offset; "
    "a multi-position calibration separates the two.",
    "Trained on the devices, sample rates and window length in 'training data'; ofbe-predict warns for "
    "another device and refuses another sample rate unless --allow-outside-domain.",
    "The accuracy figures are cross-validated on the same kind of data (simulated campaigns in this "
    "repository's pipeline); on another rig or another sensor model they are not a guarantee.",
)


@dataclass(frozen=True)
class _FinalTask:
    dataset: str
    path: str
    params: OFBENetParams


def _fit_ofbenet(task: _FinalTask) -> dict[str, Any]:
    from ofbe_model.ofbenet.network import OFBENet

    ds = load_dataset(task.dataset)
    est = OFBENet.from_params(task.params).fit(ds.X, ds.y, ds.meta.reset_index(drop=True))
    est.save(task.path)
    return {"epochs_run": len(est.history_["loss"]), "best_epoch": est.best_epoch_,
            "n_train": est.n_train_, "n_val": est.n_val_}


class ModelCardError(OfbeError):
    """A model whose card does not lead to its training data (no card, no path, or no such folder)."""


def _relative_path(dataset: Path, folder: Path) -> str | None:
    """``dataset`` relative to ``folder``, POSIX separators (None: no relative path, another drive)."""
    try:
        return Path(os.path.relpath(os.path.abspath(dataset), os.path.abspath(folder))).as_posix()
    except ValueError:
        return None


def card_dataset(model: str | Path, cwd: str | Path | None = None) -> tuple[Path, str | None]:
    """The dataset a deployed model was trained on, from the ``model_card.json`` beside it.

    The card's ``training_data`` is looked up, first found wins: ``relative_path`` from the
    card's folder; ``path`` as written when absolute, else relative to ``cwd`` (the working
    directory) and to the repository root above the card (the nearest folder with
    ``dvc.yaml``: the pipeline writes paths relative to it).

    Parameters
    ----------
    model
        The model file (``final.keras``) the card describes.
    cwd
        Working directory (default: the process's).

    Returns
    -------
    path
        The dataset folder.
    warning
        A one-line warning when its SHA256SUMS is not the one the card recorded (the dataset
        was rebuilt since the model was trained), else None.

    Raises
    ------
    ModelCardError
        No card beside the model, a card that is not JSON or describes another file, a card
        without a path (cards written before ``relative_path`` keep ``path``), or a dataset
        found nowhere (the message names the card and where it looked).
    """
    model = Path(model)
    card_file = model.parent / CARD_JSON
    if not card_file.is_file():
        raise ModelCardError(f"{model}: expected a {CARD_JSON} beside it naming the training data, "
                             "found none")
    try:
        card = json.loads(card_file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelCardError(f"{card_file}: expected a JSON model card ({CARD_FORMAT}), found an unreadable "
                             f"file ({exc})") from None
    card = card if isinstance(card, dict) else {}
    files = card.get("files") if isinstance(card.get("files"), dict) else {}
    data = card.get("training_data")
    described = files.get("ofbenet")
    if described != model.name:
        raise ModelCardError(f"{card_file}: expected a card describing {model.name}, found one describing "
                             f"{described!r}")
    data = data if isinstance(data, dict) else {}
    given = [v for v in (data.get("relative_path"), data.get("path")) if isinstance(v, str) and v]
    if not given:
        raise ModelCardError(f"{card_file}: training_data: expected the dataset's path or relative_path, "
                             "found neither")
    here = Path.cwd() if cwd is None else Path(cwd)
    root = next((p for p in card_file.resolve().parents if (p / "dvc.yaml").is_file()), None)
    candidates: list[Path] = []
    if isinstance(data.get("relative_path"), str) and data["relative_path"]:
        candidates.append(Path(os.path.normpath(card_file.parent / data["relative_path"])))
    if isinstance(data.get("path"), str) and data["path"]:
        path = Path(data["path"])
        candidates += [path] if path.is_absolute() else [here / path] + ([root / path] if root else [])
    found = next((c for c in candidates if c.is_dir()), None)
    if found is None:
        looked = ", ".join(dict.fromkeys(str(c) for c in candidates))
        raise ModelCardError(f"{card_file}: expected the training data {given[-1]!r} on disk, found no such "
                             f"folder (looked in {looked})")
    warning = None
    recorded = data.get("sha256sums_sha256")
    try:
        current = dataset_hash(found)
    except OSError:
        current = None
    if recorded and current != recorded:
        warning = (f"{found}: its SHA256SUMS is not the one {card_file} recorded (the dataset changed since "
                   "the model was trained)")
    return found, warning


def dataset_hash(folder: str | Path) -> str:
    """SHA-256 of a dataset's SHA256SUMS file (which lists every file's own hash)."""
    return hashlib.sha256((Path(folder) / "SHA256SUMS").read_bytes()).hexdigest()


def benchmark_rmse(reports: Sequence[str | Path], dataset: str) -> dict[str, dict[str, Any]]:
    """The benchmark's RMSE of the deployed methods on a dataset, per protocol.

    Parameters
    ----------
    reports
        ``benchmark.json`` files (one per protocol).
    dataset
        The dataset's name; per-device benchmark datasets (``rotated/sparkfun-1``) count too.

    Returns
    -------
    dict
        method → protocol → benchmark dataset → {rmse_mean, rmse_std, max_error_mean, n_folds}
        (m/s²).
    """
    out: dict[str, dict[str, Any]] = {m: {} for m in BENCHMARK_METHODS}
    for path in reports:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
        protocol = str(data.get("protocol", Path(path).parent.name))
        for name, entry in sorted(data.get("datasets", {}).items()):
            if name != dataset and not name.startswith(f"{dataset}/"):
                continue
            for ours, theirs in BENCHMARK_METHODS.items():
                m = entry.get("methods", {}).get(theirs)
                if m is None:
                    continue
                out[ours].setdefault(protocol, {})[name] = {
                    "rmse_mean": m.get("rmse_mean"), "rmse_std": m.get("rmse_std"),
                    "max_error_mean": m.get("max_error_mean"), "n_folds": entry.get("n_folds")}
    return out


def _card_markdown(card: Mapping[str, Any]) -> str:
    data = card["training_data"]
    lines = [f"# Model card: {card['dataset']} (ofbe {card['ofbe_version']})", "",
             "Two deployable bias estimators, fitted on every window of the dataset below. Use them with "
             f"`ofbe-predict {card['files']['gravity-prior']} <session or file>` "
             f"(or `{card['files']['ofbenet']}`).",
             "", "## Intended use", "", card["intended_use"], "", "## Training data", "",
             f"- dataset `{data['path']}`, SHA-256 of its SHA256SUMS `{data['sha256sums_sha256']}`",
             f"- {data['n_windows']} windows of {data['window_length']} samples from "
             f"{len(data['devices'])} device(s): {', '.join(data['devices'])}",
             f"- sample rate {data['fs_hz'][0]:.4g}–{data['fs_hz'][1]:.4g} Hz; labels: {data['labels']}",
             "", "## Models", "",
             "| file | estimator | trained |", "|---|---|---|"]
    for key, m in card["models"].items():
        lines.append(f"| `{card['files'][key]}` | {m['estimator']} | {m['trained']} |")
    lines += ["", "## Accuracy (from the benchmark, cross-validated)", ""]
    rows = []
    for key, per_protocol in card["benchmark"].items():
        for protocol, per_ds in per_protocol.items():
            for name, r in per_ds.items():
                rows.append(f"| {key} | {protocol} | {name} | {r['rmse_mean']:.4g} ± {r['rmse_std']:.2g} | "
                            f"{r['max_error_mean']:.4g} | {r['n_folds']} |")
    if rows:
        lines += ["| model | protocol | benchmark dataset | RMSE (m/s², mean ± sd over folds) | "
                  "max error (m/s²) | folds |", "|---|---|---|---|---|---|", *rows, "",
                  "The benchmark's fold models were trained on 4/5 of these windows (per device where the "
                  "benchmark dataset names one); the deployed models on all of them."]
    else:
        lines.append("No benchmark report was given: run the benchmark on this dataset for the figures.")
    lines += ["", "## Limits", "", *[f"- {t}" for t in card["limits"]], ""]
    return "\n".join(lines)


def train_final(dataset: str | Path, out: str | Path, params: OFBENetParams,
                benchmark_reports: Sequence[str | Path] = (), progress: bool = True) -> Path:
    """Fit the deployable OFBENet and gravity-prior of one dataset and write their card:
    :func:`train_finals` of one dataset."""
    return train_finals([dataset], out, params, benchmark_reports, progress=progress)[0]


def train_finals(datasets: Sequence[str | Path], out: str | Path, params: OFBENetParams,
                 benchmark_reports: Sequence[str | Path] = (), progress: bool = True, jobs: int = 1,
                 scheduler: str = "processes") -> list[Path]:
    """Fit the deployable OFBENet and gravity-prior of each dataset and write their cards.

    Parameters
    ----------
    datasets
        Dataset folders (``processed/datasets/<name>``).
    out
        Models folder; each dataset's files go to ``<out>/<name>/``.
    params
        OFBENet parameters (``params.seed`` is the seed).
    benchmark_reports
        ``benchmark.json`` files whose RMSE of ``ofbenet`` and ``gravity-prior-direction`` on
        each dataset go into its card.
    progress
        A progress bar while the OFBENets train.
    jobs
        OFBENets trained at once, each in its own single-threaded worker process
        (:data:`WORKER_ENV`): the weights are the same whatever ``jobs``.
    scheduler
        ``processes``, ``dask`` or ``tcp://host:port``
        (:func:`ofbe_data.core.parallel.map_progress`).

    Returns
    -------
    list of Path
        ``<out>/<name>/`` of each dataset, in order.
    """
    folders = [Path(out) / Path(d).name for d in datasets]
    tasks = []
    for dataset, folder in zip(datasets, folders, strict=True):
        folder.mkdir(parents=True, exist_ok=True)
        tasks.append(_FinalTask(str(dataset), str(folder / OFBENET_NAME), params))
    fits = map_progress(_fit_ofbenet, tasks, jobs=jobs, desc="final OFBENet", unit="fit", progress=progress,
                        worker_env=WORKER_ENV, scheduler=scheduler,
                        postfix=lambda r: f"{r['epochs_run']} epochs",
                        name=lambda t: f"final OFBENet of {t.dataset}")
    for dataset, folder, fit in zip(datasets, folders, fits, strict=True):
        _write_final(Path(dataset), folder, params, fit, benchmark_reports)
    return folders


def _write_final(dataset: Path, folder: Path, params: OFBENetParams, fit: Mapping[str, Any],
                 benchmark_reports: Sequence[str | Path]) -> None:
    """Fit the gravity-prior of one dataset and write it and the model card beside its OFBENet."""
    ds = load_dataset(dataset)
    name = dataset.name
    prior = GravityPrior(direction_model=True).fit(ds.X, ds.y, ds.meta)
    prior.save(folder / PRIOR_NAME)
    fs = ds.meta["fs_hz"].to_numpy(dtype=float)
    card = {
        "format": CARD_FORMAT, "ofbe_version": __version__, "dataset": name,
        "files": {"ofbenet": OFBENET_NAME, "gravity-prior": PRIOR_NAME},
        "intended_use": ("Estimate the apparent bias of a cheap MEMS accelerometer (m/s², sensor frame) from "
                         "one stationary window of raw specific force, without levelling or rotating it, for "
                         "devices like those of the training data; the gravity-prior also gives a standard "
                         "deviation per axis."),
        "training_data": {"path": str(dataset), "relative_path": _relative_path(dataset, folder),
                          "sha256sums_sha256": dataset_hash(dataset),
                          "n_windows": int(ds.X.shape[0]), "window_length": int(ds.X.shape[1]),
                          "devices": sorted({str(d) for d in ds.meta["device"]}),
                          "fs_hz": [round(float(fs.min()), 6), round(float(fs.max()), 6)],
                          "labels": "apparent bias b_app (bias_x/y/z), m/s²"},
        "models": {"ofbenet": {"estimator": "OFBENet", "trained": (
                       f"seed {params.seed}, {fit['epochs_run']} epochs (best {fit['best_epoch']}), "
                       f"{fit['n_train']} windows trained on, {fit['n_val']} validated on"),
                       "params": params.to_dict(), **fit},
                   "gravity-prior": {"estimator": "gravity-prior with the direction model", "trained": (
                       f"{int(ds.X.shape[0])} windows, closed form"),
                       "params": prior.get_params()}},
        "benchmark": benchmark_rmse(benchmark_reports, name),
        "limits": list(LIMITS),
    }
    write_bytes_atomic(folder / CARD_JSON, (json.dumps(card, indent=1, allow_nan=False) + "\n").encode())
    write_bytes_atomic(folder / CARD_MD, _card_markdown(card).encode())
