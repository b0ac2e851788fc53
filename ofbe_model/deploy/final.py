"""Deployable models: one OFBENet and one gravity-prior per benchmark dataset, fitted on all its
windows, each with a model card whose accuracy figures are measured on the files it describes.

The cross-validation folds of ``ofbe-train`` measure accuracy; they are not what a user runs
on new recordings (five fold models, each blind to a fifth of the data). This module fits
the two estimators a user deploys on every window of each *benchmark dataset*, as the
benchmark evaluates it (:func:`ofbe_data.dataset.folds.benchmark_datasets`): the
gravity-aligned set pooled over its devices, each rotated device on its own. A model trained on
several rotated boards pooled cannot tell them apart (their tangential biases differ and are
invisible in a window), so it would be far worse than the per-device fold models it is quoted
with. A dataset evaluated per device gets one folder per device and a ``models.json`` index
(:data:`SET_NAME`) that ``ofbe-predict`` uses to pick each recording's model:

``<out>/<benchmark dataset>/final.keras`` (``<out>/rotated/sparkfun-1/final.keras``)
    OFBENet (``train:`` parameters, the first seed), in a fresh single-threaded worker so that
    its weights do not depend on the machine's thread count.
``<out>/<benchmark dataset>/gravity-prior.json``
    The ``gravity-prior`` with the direction model (the benchmark's
    ``gravity-prior-direction``), saved as JSON (no pickle).
``<out>/<benchmark dataset>/MODEL_CARD.md`` and ``model_card.json``
    What each model is for and what it cannot do, the training data (with the SHA-256 of the
    dataset's SHA256SUMS, which pins every file of it, and where it lies: ``path`` as given,
    ``relative_path`` from the card's folder; ``selected_devices`` when the model was trained
    on some devices of the dataset), the protocol-level RMSE that the benchmark measured for
    the same method on the same data, and per device two figures kept apart: the
    *in-sample* RMSE of the saved file itself (reloaded from disk) on its own training
    signals, and the *cross-validated* RMSE of the benchmark's fold models on that device's
    test signals (from ``errors.csv`` beside each ``benchmark.json``).

A deployed model that is far worse on its own training signals than the fold models were on
signals they never saw is broken (it cannot tell its devices apart, or its fit collapsed):
:func:`train_finals` raises :class:`DeployError` when any device's in-sample RMSE exceeds
``max_in_sample_ratio`` (1.5) times a cross-validated RMSE its card quotes for that device, and
removes the models it wrote.

:func:`card_dataset` finds a model's training data again from its card (``ofbe-export tflite``
without ``--dataset``).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ofbe_data import __version__
from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.errors import OfbeError
from ofbe_data.core.parallel import map_progress
from ofbe_data.dataset.folds import benchmark_datasets
from ofbe_data.dataset.reader import LoadedDataset, load_dataset
from ofbe_model.deploy.defaults import OFBENET_NAME, PRIOR_NAME
from ofbe_model.estimators.priors import GravityPrior
from ofbe_model.ofbenet.params import WORKER_ENV, OFBENetParams

CARD_FORMAT = "ofbe-model-card/1"
CARD_JSON = "model_card.json"
CARD_MD = "MODEL_CARD.md"
SET_NAME = "models.json"
SET_FORMAT = "ofbe-model-set/1"
ERRORS_NAME = "errors.csv"
MAX_IN_SAMPLE_RATIO = 1.5
"""Largest in-sample RMSE of a deployed model, per device, as a multiple of a cross-validated
RMSE its card quotes for that device."""
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
    name: str
    devices: tuple[str, ...] | None
    path: str
    params: OFBENetParams


def _rows(meta: Any, devices: tuple[str, ...] | None) -> np.ndarray:
    """Row positions of a benchmark dataset's windows (every row when ``devices`` is None)."""
    if devices is None:
        return np.arange(len(meta))
    return np.flatnonzero(meta["device"].isin(devices).to_numpy())


def _signals(meta: Any, rows: np.ndarray) -> np.ndarray:
    """The benchmark's signals among ``rows``: window 0 of each recording."""
    return rows[meta["window_index"].to_numpy()[rows] == 0]


def _sig6(value: float) -> float:
    """``value`` to 6 significant digits (the benchmark report's precision)."""
    return float(f"{value:.6g}")


def device_rmse(y: np.ndarray, yhat: np.ndarray, devices: np.ndarray) -> dict[str, dict[str, Any]]:
    """RMSE per device, ``sqrt(mean_i ‖ŷ_i − y_i‖²)`` (the benchmark's RMSE), m/s².

    Parameters
    ----------
    y, yhat
        (N, 3) labels and estimates, m/s².
    devices
        (N,) device of each row.

    Returns
    -------
    dict
        device → ``{"rmse": float or None, "n_signals": int}``; None where an estimate is not
        finite (a broken model), never NaN.
    """
    out: dict[str, dict[str, Any]] = {}
    for d in sorted({str(v) for v in devices}):
        k = devices == d
        sq = np.sum((np.asarray(yhat, dtype=np.float64)[k] - np.asarray(y, dtype=np.float64)[k]) ** 2, axis=1)
        value = float(np.sqrt(np.mean(sq)))
        out[d] = {"rmse": _sig6(value) if np.isfinite(value) else None, "n_signals": int(k.sum())}
    return out


def _fit_ofbenet(task: _FinalTask) -> dict[str, Any]:
    from ofbe_model.ofbenet.network import OFBENet

    ds = load_dataset(task.dataset)
    meta = ds.meta.reset_index(drop=True)
    rows = _rows(meta, task.devices)
    every = rows.size == len(meta)
    X = ds.X if every else ds.X[rows]
    y = ds.y if every else ds.y[rows]
    fit_meta = meta if every else meta.iloc[rows].reset_index(drop=True)
    est = OFBENet.from_params(task.params).fit(X, y, fit_meta)
    est.save(task.path)
    # the card's in-sample figure is measured on the file as saved, read back from disk
    sig = _signals(meta, rows)
    saved = OFBENet.load(task.path)
    yhat = saved.predict(ds.X[sig], meta.iloc[sig].reset_index(drop=True))
    return {"epochs_run": len(est.history_["loss"]), "best_epoch": est.best_epoch_,
            "n_train": est.n_train_, "n_val": est.n_val_,
            "in_sample": device_rmse(ds.y[sig], yhat, meta["device"].to_numpy()[sig])}


class ModelCardError(OfbeError):
    """A model whose card does not lead to its training data (no card, no path, or no such folder)."""


class DeployError(OfbeError):
    """A deployed model far worse on its own training signals than its cross-validated figure."""


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


def card_selected_devices(model: str | Path) -> list[str] | None:
    """The devices of its dataset a deployed model was trained on, from the card beside it
    (``training_data.selected_devices``); None when it saw every device or has no such card."""
    try:
        card = json.loads((Path(model).parent / CARD_JSON).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    data = card.get("training_data") if isinstance(card, dict) else None
    chosen = data.get("selected_devices") if isinstance(data, dict) else None
    return [str(d) for d in chosen] if isinstance(chosen, list) and chosen else None


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


def cross_validated_rmse(reports: Sequence[str | Path], dataset: str) -> dict[str, dict[str, Any]]:
    """The benchmark's cross-validated RMSE of the deployed methods per device.

    Read from ``errors.csv`` beside each ``benchmark.json`` (one row per method, seed and test
    signal): per device and seed, ``sqrt(mean ‖ŷ − y‖²)`` over the device's test signals of
    every fold, then the mean over seeds (one model's accuracy, as the benchmark reports it).
    A report without ``errors.csv`` gives no per-device figure.

    Parameters
    ----------
    reports
        ``benchmark.json`` files (one per protocol).
    dataset
        The benchmark dataset's name (``gravity-aligned``, ``rotated/sparkfun-1``).

    Returns
    -------
    dict
        method → protocol → device → ``{"rmse": float, "n_signals": int, "seeds": int}`` (m/s²).
    """
    out: dict[str, dict[str, Any]] = {m: {} for m in BENCHMARK_METHODS}
    for path in reports:
        errors = Path(path).parent / ERRORS_NAME
        if not errors.is_file():
            continue
        report = json.loads(Path(path).read_text(encoding="utf-8"))
        protocol = str(report.get("protocol", Path(path).parent.name))
        table = pd.read_csv(errors, dtype={"device": str, "dataset": str, "method": str})
        table = table[table["dataset"] == dataset]
        for ours, theirs in BENCHMARK_METHODS.items():
            rows = table[table["method"] == theirs]
            if rows.empty:
                continue
            per: dict[str, Any] = {}
            for device, g in rows.groupby("device", sort=True):
                by_seed = g.groupby("seed")["err_norm"].apply(lambda e: float(np.sqrt(np.mean(np.square(e)))))
                per[str(device)] = {"rmse": _sig6(float(by_seed.mean())),
                                    "n_signals": int(len(g) // max(1, len(by_seed))),
                                    "seeds": int(len(by_seed))}
            out[ours][protocol] = per
    return out


def accuracy_problems(accuracy: Mapping[str, Any], max_ratio: float = MAX_IN_SAMPLE_RATIO) -> list[str]:
    """The devices on which a deployed model is far worse in-sample than cross-validated.

    Parameters
    ----------
    accuracy
        A card's ``accuracy``: model → ``{"in_sample": {device: {"rmse"}}, "cross_validated":
        {protocol: {device: {"rmse"}}}}``.
    max_ratio
        Largest allowed in-sample / cross-validated RMSE.

    Returns
    -------
    list of str
        One line per (model, device, protocol) over the limit, or with a non-finite in-sample
        RMSE; empty when every figure is within it.
    """
    problems = []
    for model, acc in accuracy.items():
        for device, ins in acc.get("in_sample", {}).items():
            if ins.get("rmse") is None:
                problems.append(f"{model}, device {device}: in-sample RMSE not finite (the model gives NaN "
                                "or inf on its own training signals)")
                continue
            for protocol, per in acc.get("cross_validated", {}).items():
                cv = per.get(device, {}).get("rmse")
                if cv is not None and cv > 0 and ins["rmse"] > max_ratio * cv:
                    problems.append(f"{model}, device {device}: in-sample RMSE {ins['rmse']:.4g} m/s² on its "
                                    f"own {ins['n_signals']} training signals, expected at most "
                                    f"{max_ratio:g}× the cross-validated {cv:.4g} m/s² ({protocol}), found "
                                    f"{ins['rmse'] / cv:.2f}×")
    return problems


def _card_markdown(card: Mapping[str, Any]) -> str:
    data = card["training_data"]
    selected = data.get("selected_devices")
    lines = [f"# Model card: {card['dataset']} (ofbe {card['ofbe_version']})", "",
             "Two deployable bias estimators, fitted on every window of the data below. Use them with "
             f"`ofbe-predict {card['files']['gravity-prior']} <session or file>` "
             f"(or `{card['files']['ofbenet']}`).",
             "", "## Intended use", "", card["intended_use"], "", "## Training data", "",
             f"- dataset `{data['path']}`, SHA-256 of its SHA256SUMS `{data['sha256sums_sha256']}`"
             + (f"; only the windows of {', '.join(selected)}" if selected else ""),
             f"- {data['n_windows']} windows of {data['window_length']} samples from "
             f"{len(data['devices'])} device(s): {', '.join(data['devices'])}",
             f"- sample rate {data['fs_hz'][0]:.4g}–{data['fs_hz'][1]:.4g} Hz; labels: {data['labels']}",
             "", "## Models", "",
             "| file | estimator | trained |", "|---|---|---|"]
    for key, m in card["models"].items():
        lines.append(f"| `{card['files'][key]}` | {m['estimator']} | {m['trained']} |")
    lines += ["", "## Accuracy per device", "",
              "In-sample: the file above, read back from disk, on its own training signals (window 0 of "
              "each recording). Cross-validated: the benchmark's fold models on the same device's test "
              "signals, which they never saw (RMSE over every fold's signals, mean over seeds). A "
              "deployed model is only as good as the cross-validated figure on new recordings; the "
              f"deploy stage refuses one whose in-sample RMSE exceeds {card['max_in_sample_ratio']:g}× it.",
              "", "| model | device | in-sample RMSE (m/s²) | signals | protocol | cross-validated RMSE "
              "(m/s²) | in-sample / cross-validated |", "|---|---|---|---|---|---|---|"]
    for key, acc in card["accuracy"].items():
        for device, ins in acc["in_sample"].items():
            cvs = [(protocol, per[device]["rmse"]) for protocol, per in acc["cross_validated"].items()
                   if device in per] or [("—", None)]
            for protocol, cv in cvs:
                ratio = "—" if cv is None or ins["rmse"] is None else f"{ins['rmse'] / cv:.2f}"
                ins_text = "not finite" if ins["rmse"] is None else f"{ins['rmse']:.4g}"
                cv_text = "—" if cv is None else f"{cv:.4g}"
                lines.append(f"| {key} | {device} | {ins_text} | {ins['n_signals']} | {protocol} | "
                             f"{cv_text} | {ratio} |")
    lines += ["", "## Accuracy per protocol (from the benchmark, cross-validated)", ""]
    rows = []
    for key, per_protocol in card["benchmark"].items():
        for protocol, per_ds in per_protocol.items():
            for name, r in per_ds.items():
                rows.append(f"| {key} | {protocol} | {name} | {r['rmse_mean']:.4g} ± {r['rmse_std']:.2g} | "
                            f"{r['max_error_mean']:.4g} | {r['n_folds']} |")
    if rows:
        lines += ["| model | protocol | benchmark dataset | RMSE (m/s², mean ± sd over folds) | "
                  "max error (m/s²) | folds |", "|---|---|---|---|---|---|", *rows, "",
                  "The benchmark's fold models were trained on 4/5 of these windows; the deployed models on "
                  "all of them."]
    else:
        lines.append("No benchmark report was given: run the benchmark on this dataset for the figures.")
    lines += ["", "## Limits", "", *[f"- {t}" for t in card["limits"]], ""]
    return "\n".join(lines)


def train_final(dataset: str | Path, out: str | Path, params: OFBENetParams,
                benchmark_reports: Sequence[str | Path] = (), progress: bool = True,
                max_in_sample_ratio: float = MAX_IN_SAMPLE_RATIO) -> list[Path]:
    """Fit the deployable OFBENet and gravity-prior of one dataset's benchmark datasets and write
    their cards: :func:`train_finals` of one dataset."""
    return train_finals([dataset], out, params, benchmark_reports, progress=progress,
                        max_in_sample_ratio=max_in_sample_ratio)


def train_finals(datasets: Sequence[str | Path], out: str | Path, params: OFBENetParams,
                 benchmark_reports: Sequence[str | Path] = (), progress: bool = True, jobs: int = 1,
                 scheduler: str = "processes",
                 max_in_sample_ratio: float = MAX_IN_SAMPLE_RATIO) -> list[Path]:
    """Fit the deployable OFBENet and gravity-prior of each benchmark dataset and write their cards.

    Parameters
    ----------
    datasets
        Dataset folders (``processed/datasets/<name>``). Each gives its benchmark datasets
        (:func:`~ofbe_data.dataset.folds.benchmark_datasets`): itself (pooled kinds) or
        one per device (``<name>/<device>``, with a :data:`SET_NAME` index in ``<out>/<name>/``).
    out
        Models folder; each benchmark dataset's files go to ``<out>/<benchmark dataset>/``.
    params
        OFBENet parameters (``params.seed`` is the seed).
    benchmark_reports
        ``benchmark.json`` files whose RMSE of ``ofbenet`` and ``gravity-prior-direction`` on
        each dataset go into its card; the ``errors.csv`` beside each gives the per-device
        cross-validated figures.
    progress
        A progress bar while the OFBENets train.
    jobs
        OFBENets trained at once, each in its own single-threaded worker process
        (:data:`WORKER_ENV`): the weights are the same whatever ``jobs``.
    scheduler
        ``processes``, ``dask`` or ``tcp://host:port``
        (:func:`ofbe_data.core.parallel.map_progress`).
    max_in_sample_ratio
        Largest in-sample RMSE of a deployed model, per device, as a multiple of each
        cross-validated RMSE its card quotes for the device.

    Returns
    -------
    list of Path
        ``<out>/<benchmark dataset>/`` of each benchmark dataset, in order.

    Raises
    ------
    DeployError
        A model over ``max_in_sample_ratio`` on some device (every line in the message); the
        models of this call are removed, nothing is left half-written.
    """
    tasks: list[_FinalTask] = []
    sets: dict[Path, dict[str, str]] = {}
    for dataset in datasets:
        meta = load_dataset(dataset, as_="pandas", verify=False)
        kind = str(meta.attrs["ofbe"]["kind"])
        for name, devices, _ in benchmark_datasets(meta, kind):
            folder = Path(out) / name
            per_device = name != Path(dataset).name
            if per_device:
                sets.setdefault(Path(out) / Path(dataset).name, {})[devices[0]] = Path(name).name
            tasks.append(_FinalTask(str(dataset), name, devices if per_device else None,
                                    str(folder / OFBENET_NAME), params))
    written = sorted({Path(out) / Path(t.name).parts[0] for t in tasks})
    for t in tasks:
        Path(t.path).parent.mkdir(parents=True, exist_ok=True)
    try:
        fits = map_progress(_fit_ofbenet, tasks, jobs=jobs, desc="final OFBENet", unit="fit",
                            progress=progress, worker_env=WORKER_ENV, scheduler=scheduler,
                            postfix=lambda r: f"{r['epochs_run']} epochs",
                            name=lambda t: f"final OFBENet of {t.name}")
        loaded = {d: load_dataset(d) for d in dict.fromkeys(t.dataset for t in tasks)}  # once per dataset
        cards = [_card(t, fit, loaded[t.dataset], benchmark_reports, max_in_sample_ratio)
                 for t, fit in zip(tasks, fits, strict=True)]
        problems = [f"{t.name}: {line}" for t, card in zip(tasks, cards, strict=True)
                    for line in accuracy_problems(card["accuracy"], max_in_sample_ratio)]
        if problems:
            raise DeployError("deployed models far worse on their own training signals than cross-validated "
                              "(no model written):\n  " + "\n  ".join(problems))
        for t, card in zip(tasks, cards, strict=True):
            _write_card(Path(t.path).parent, card)
        for folder, members in sets.items():
            index = {"format": SET_FORMAT, "dataset": folder.name, "per": "device", "devices": dict(sorted(
                members.items())), "files": {"ofbenet": OFBENET_NAME, "gravity-prior": PRIOR_NAME}}
            write_bytes_atomic(folder / SET_NAME, (json.dumps(index, indent=1) + "\n").encode())
    except BaseException:
        for folder in written:
            shutil.rmtree(folder, ignore_errors=True)
        raise
    return [Path(t.path).parent for t in tasks]


def _card(task: _FinalTask, fit: Mapping[str, Any], ds: LoadedDataset,
          benchmark_reports: Sequence[str | Path], max_ratio: float) -> dict[str, Any]:
    """Fit the gravity-prior of one benchmark dataset (of the loaded ``ds``) beside its OFBENet; the
    card of both."""
    dataset = Path(task.dataset)
    folder = Path(task.path).parent
    params = task.params
    meta = ds.meta.reset_index(drop=True)
    rows = _rows(meta, task.devices)
    sub = meta.iloc[rows].reset_index(drop=True)
    prior = GravityPrior(direction_model=True).fit(ds.X[rows], ds.y[rows], sub)
    prior.save(folder / PRIOR_NAME)
    sig = _signals(meta, rows)
    sig_meta = meta.iloc[sig].reset_index(drop=True)
    saved = GravityPrior.load(folder / PRIOR_NAME)
    prior_in_sample = device_rmse(ds.y[sig], saved.predict(ds.X[sig], sig_meta),
                                  sig_meta["device"].to_numpy())
    cross = cross_validated_rmse(benchmark_reports, task.name)
    fs = sub["fs_hz"].to_numpy(dtype=float)
    return {
        "format": CARD_FORMAT, "ofbe_version": __version__, "dataset": task.name,
        "files": {"ofbenet": OFBENET_NAME, "gravity-prior": PRIOR_NAME},
        "intended_use": ("Estimate the apparent bias of a cheap MEMS accelerometer (m/s², sensor frame) from "
                         "one stationary window of raw specific force, without levelling or rotating it, for "
                         "devices like those of the training data; the gravity-prior also gives a standard "
                         "deviation per axis."),
        "training_data": {"path": str(dataset), "relative_path": _relative_path(dataset, folder),
                          "sha256sums_sha256": dataset_hash(dataset),
                          "selected_devices": None if task.devices is None else list(task.devices),
                          "n_windows": int(rows.size), "window_length": int(ds.X.shape[1]),
                          "devices": sorted({str(d) for d in sub["device"]}),
                          "fs_hz": [round(float(fs.min()), 6), round(float(fs.max()), 6)],
                          "labels": "apparent bias b_app (bias_x/y/z), m/s²"},
        "models": {"ofbenet": {"estimator": "OFBENet", "trained": (
                       f"seed {params.seed}, {fit['epochs_run']} epochs (best {fit['best_epoch']}), "
                       f"{fit['n_train']} windows trained on, {fit['n_val']} validated on"),
                       "params": params.to_dict(),
                       **{k: v for k, v in fit.items() if k != "in_sample"}},
                   "gravity-prior": {"estimator": "gravity-prior with the direction model", "trained": (
                       f"{int(rows.size)} windows, closed form"),
                       "params": prior.get_params()}},
        "accuracy": {"ofbenet": {"in_sample": fit["in_sample"], "cross_validated": cross["ofbenet"]},
                     "gravity-prior": {"in_sample": prior_in_sample,
                                       "cross_validated": cross["gravity-prior"]}},
        "max_in_sample_ratio": max_ratio,
        "benchmark": benchmark_rmse(benchmark_reports, task.name),
        "limits": list(LIMITS),
    }


def _write_card(folder: Path, card: Mapping[str, Any]) -> None:
    write_bytes_atomic(folder / CARD_JSON, (json.dumps(card, indent=1, allow_nan=False) + "\n").encode())
    write_bytes_atomic(folder / CARD_MD, _card_markdown(card).encode())
