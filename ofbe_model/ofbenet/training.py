"""``ofbe-train``: train OFBENet on every fold of a windowed dataset under one protocol.

Usage::

    ofbe-train processed/datasets/rotated --protocol grouped [--out models] [--folds 0 1]
               [--max-epochs N] [--seeds N] [--params params.yaml] [--quiet]

For every benchmark dataset (the pooled campaign, or one per device: see
:mod:`ofbe_data.dataset.folds`) and every fold of
:func:`~ofbe_data.dataset.folds.protocol_splits`, OFBENet is fitted on that fold's
training windows (never its test signals) and written to ``<out>/<dataset>/<protocol>/`` with ``/``
in the dataset name replaced by ``__``:

``fold-<k>.seed-<s>.keras``
    The model of fold k trained with seed s: raw (N, T, 3) m/s² windows → (N, 3) m/s²
    biases, scalings inside (:meth:`ofbe_model.ofbenet.network.OFBENet.load`).
``fold-<k>.seed-<s>.history.csv``
    Per epoch: ``epoch`` (1-based), ``loss``, ``val_loss``, ``learning_rate``.
``fold-<k>.training.png``
    The training curves of every seed of the fold: loss and validation loss against epoch,
    log scale.
``training.json``
    Per fold and seed: epochs run, best epoch and validation loss, seconds, windows trained
    on, validated on and held out for testing, and the parameters. Folds trained earlier and
    not named by ``--folds`` are kept.

OFBENet's result moves with its training seed (weight initialisation, validation split,
shuffling, dropout) by more than many differences between methods, so every fold is trained
with several seeds: ``train.seeds`` (or ``--seeds``) N trains seeds ``seed … seed + N − 1``
and the benchmark reports the mean ± sd over them.

Parameters come from the ``train:`` section of ``--params`` (keys: the fields of
:class:`~ofbe_model.ofbenet.network.OFBENetParams`, plus ``seeds``), then ``--max-epochs`` and
``--seeds``. Existing files of the folds trained are replaced; every file is written
atomically.

Exit status: 0 on success, 1 when the data are bad or training fails, 2 on a usage or
parameter error (unknown key, unknown protocol or fold, missing dataset folder). Every error
is one line.
"""

from __future__ import annotations

import dataclasses
import io
import json
import shutil
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from matplotlib import pyplot as plt
from matplotlib.ticker import MaxNLocator

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.errors import ConfigError
from ofbe_data.core.figures import new_figure, save_png
from ofbe_data.core.parallel import map_progress
from ofbe_data.dataset.folds import Split, protocol_splits
from ofbe_data.dataset.reader import load_dataset
from ofbe_data.io.typedconfig import from_plain, read_section
from ofbe_model.ofbenet.params import WORKER_ENV, OFBENetParams

PROG = "ofbe-train"
#: ``format`` of ``training.json``.
SUMMARY_FORMAT = "ofbe-training/1"
SUMMARY_NAME = "training.json"
PARAMS_SECTION = "train"
SEEDS_KEY = "seeds"
"""Key of ``train:`` giving how many training seeds each fold gets (not an OFBENet parameter)."""
DEFAULT_SEEDS = 1
"""Seeds per fold when neither ``train.seeds`` nor ``--seeds`` says."""


class TrainingUsageError(Exception):
    """A usage error: exit 2 with this message."""


def read_params(path: str | Path | None, max_epochs: int | None = None) -> OFBENetParams:
    """OFBENet parameters from the ``train:`` section of a YAML file, then ``max_epochs``.

    Parameters
    ----------
    path
        YAML file (e.g. params.yaml) or None for the defaults. A file without a ``train:``
        section gives the defaults. Its ``seeds`` key is read by :func:`read_seed_count`.
    max_epochs
        Overrides ``max_epochs`` when given.

    Raises
    ------
    ConfigError
        Unreadable YAML, an unknown key (the message lists the known ones), a value of the
        wrong type or out of range; the message names the file and the key.
    """
    source: str | Path = path if path is not None else "command line"
    data = dict(read_section(path, PARAMS_SECTION)) if path is not None else {}
    data.pop(SEEDS_KEY, None)
    if max_epochs is not None:
        data["max_epochs"] = max_epochs
    try:
        return from_plain(data, OFBENetParams, source, PARAMS_SECTION)
    except ConfigError as exc:
        if exc.source == "OFBENetParams":  # a range check of the dataclass: name the file and key
            key = "--max-epochs" if exc.key == "max_epochs" and max_epochs is not None else \
                f"{PARAMS_SECTION}.{exc.key}"
            raise ConfigError(source, key, exc.expected, exc.found) from None
        raise


def read_seed_count(path: str | Path | None, seeds: int | None = None) -> int:
    """How many training seeds per fold: ``seeds`` when given, else ``train.seeds``, else 1.

    Raises
    ------
    ConfigError
        Not an integer ≥ 1 (naming the file and key, or ``--seeds``).
    """
    if seeds is not None:
        value: Any = seeds
        source, key = "command line", "--seeds"
    else:
        section = dict(read_section(path, PARAMS_SECTION)) if path is not None else {}
        value = section.get(SEEDS_KEY, DEFAULT_SEEDS)
        source, key = str(path), f"{PARAMS_SECTION}.{SEEDS_KEY}"
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise ConfigError(source, key, "an integer >= 1", repr(value))
    return int(value)


def dataset_dirname(name: str) -> str:
    """Folder name of a benchmark dataset: ``rotated/sparkfun-1`` → ``rotated__sparkfun-1``."""
    return name.replace("/", "__")


def history_csv(history: Mapping[str, Sequence[float]]) -> bytes:
    """The per-epoch history as CSV bytes: ``epoch`` (1-based) then ``loss``, ``val_loss``,
    ``learning_rate`` (those present, in that order, then any others)."""
    order = [k for k in ("loss", "val_loss", "learning_rate") if k in history]
    order += sorted(k for k in history if k not in order)
    n = len(history[order[0]]) if order else 0
    frame = pd.DataFrame({"epoch": np.arange(1, n + 1), **{k: list(history[k]) for k in order}})
    buf = io.StringIO()
    frame.to_csv(buf, index=False, float_format="%.9g", lineterminator="\n")
    return buf.getvalue().encode()


def loss_label(params: OFBENetParams) -> str:
    """What the loss values are, with units."""
    if params.target_scaling == "standardise":
        return "MSE of standardised targets (dimensionless)"
    return "MSE of biases, (m/s²)²"


def plot_history(histories: Mapping[int, Mapping[str, Sequence[float]]], path: Path, title: str,
                 ylabel: str, best_epochs: Mapping[int, int | None]) -> Path:
    """Training curves of one fold: loss and validation loss against epoch (log y), per seed.

    Parameters
    ----------
    histories
        Seed → ``loss`` and optionally ``val_loss``, one value per epoch.
    path
        Target PNG.
    title, ylabel
        Figure title and y-axis label.
    best_epochs
        Seed → 1-based epoch whose weights were kept (marked), or None.
    """
    fig, ax = new_figure()
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for i, (seed, history) in enumerate(sorted(histories.items())):
        colour = colours[i % len(colours)]
        tag = f"seed {seed}: " if len(histories) > 1 else ""
        for key, label, style in (("loss", "training loss", "-"), ("val_loss", "validation loss", "--")):
            values = np.asarray(history.get(key, []), dtype=np.float64)
            if values.size:
                ax.plot(np.arange(1, values.size + 1), values, style, color=colour, marker="o",
                        markersize=3, label=f"{tag}{label}")
        best = best_epochs.get(seed)
        if best is not None:
            ax.axvline(best, color=colour, linestyle=":", linewidth=1,
                       label=f"{tag}kept epoch {best}")
    ax.set_yscale("log")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("epoch")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.legend(frameon=False, fontsize="small", ncol=2 if len(histories) > 1 else 1)
    return save_png(fig, path)


def model_name(fold: int, seed: int) -> str:
    """File name of the model of one fold and training seed: ``fold-<k>.seed-<s>.keras``."""
    return f"fold-{fold}.seed-{seed}.keras"


def _read_summary(path: Path, dataset: str, protocol: str) -> dict[tuple[int, int], dict[str, Any]]:
    """(fold, seed) entries of an existing training.json of the same dataset and protocol ({} otherwise)."""
    try:
        old = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    if (not isinstance(old, dict) or old.get("format") != SUMMARY_FORMAT or old.get("dataset") != dataset
            or old.get("protocol") != protocol or not isinstance(old.get("folds"), list)):
        return {}
    return {(int(f["fold"]), int(f["seed"])): f for f in old["folds"]
            if isinstance(f, dict) and isinstance(f.get("fold"), int) and isinstance(f.get("seed"), int)}


def train_fold(x: np.ndarray, y: np.ndarray, meta: pd.DataFrame, split: Split, params: OFBENetParams,
               folder: Path, on_epoch: Callable[[int, dict[str, float]], None] | None = None,
               ) -> tuple[dict[str, Any], dict[str, list[float]]]:
    """Fit one fold with one seed (``params.seed``); write its model and history CSV.

    Parameters
    ----------
    x, y, meta
        The whole dataset: (N, T, 3) m/s², (N, 3) m/s², N rows.
    split
        The fold (its ``train`` rows are fitted; its ``test`` rows are only counted).
    params
        OFBENet parameters, the training seed included.
    folder
        ``<out>/<dataset>/<protocol>``.
    on_epoch
        Called after every epoch with the 1-based epoch and its logs (progress display).

    Returns
    -------
    entry
        The (fold, seed) entry of ``training.json``.
    history
        The per-epoch history (for the training-curve figure).
    """
    # imported here, in the fit's worker: the process that schedules the fits (ofbe-train, the
    # deploy stage) never loads TensorFlow (its imports: 2.2 s of CPU and 158 MB, not 7.6 s and 658 MB)
    from ofbe_model.ofbenet.network import OFBENet

    name = model_name(split.fold, params.seed)
    stem = name.removesuffix(".keras")
    t0 = time.perf_counter()
    est = OFBENet.from_params(params).fit(x[split.train], y[split.train],
                                          meta.iloc[split.train].reset_index(drop=True), on_epoch=on_epoch)
    seconds = time.perf_counter() - t0
    est.save(folder / name)
    write_bytes_atomic(folder / f"{stem}.history.csv", history_csv(est.history_))
    val = est.history_.get("val_loss")
    lr = est.history_.get("learning_rate")
    entry = {"fold": split.fold, "seed": params.seed, "model": name, "history": f"{stem}.history.csv",
             "curve": f"fold-{split.fold}.training.png", "epochs_run": len(est.history_["loss"]),
             "best_epoch": est.best_epoch_, "best_val_loss": min(val) if val else None,
             "best_loss": est.history_["loss"][est.best_epoch_ - 1],
             "final_learning_rate": lr[-1] if lr else None, "seconds": round(seconds, 3),
             "n_train": est.n_train_, "n_val": est.n_val_, "n_test": int(split.test.size),
             "params": params.to_dict()}
    return entry, {k: list(v) for k, v in est.history_.items()}


def _history_from_csv(path: Path) -> dict[str, list[float]]:
    """A history CSV written by :func:`history_csv` back as columns ({} when unreadable)."""
    try:
        frame = pd.read_csv(path)
    except (OSError, ValueError):
        return {}
    return {c: frame[c].tolist() for c in frame.columns if c != "epoch"}


_CACHE: dict[str, Any] = {"datasets": {}, "splits": {}}
"""A worker's loaded datasets (by path) and protocol splits (by path and protocol)."""


@dataclass(frozen=True)
class FitTask:
    """One fit: a benchmark dataset's fold of a protocol, with one seed (a worker's task)."""

    dataset: str
    protocol: str
    name: str
    fold: int
    params: OFBENetParams
    folder: str


def _fit_task(task: FitTask) -> tuple[dict[str, Any], dict[str, list[float]]]:
    """Run one :class:`FitTask` (in a worker; each dataset is loaded once per worker, and a
    worker may get fits of several datasets and protocols)."""
    datasets, all_splits = _CACHE["datasets"], _CACHE["splits"]
    if task.dataset not in datasets:
        datasets[task.dataset] = load_dataset(task.dataset)
    ds = datasets[task.dataset]
    key = (task.dataset, task.protocol)
    if key not in all_splits:
        all_splits[key] = list(protocol_splits(ds.meta, str(ds.info["kind"]), task.protocol))
    split = next(s for s in all_splits[key] if s.dataset == task.name and s.fold == task.fold)
    return train_fold(ds.X, ds.y, ds.meta, split, task.params, Path(task.folder))


def plan_runs(datasets: Mapping[str, Any], protocols: Sequence[str]) -> list[tuple[str, str]]:
    """(dataset, protocol) runs: each dataset under each of ``protocols`` it has (a
    ``fold_<protocol>`` column), in the order given.

    Parameters
    ----------
    datasets
        Dataset folder → its loaded dataset (:func:`~ofbe_data.dataset.reader.load_dataset`).
    protocols
        Protocol names.

    Raises
    ------
    TrainingUsageError
        A protocol that none of the datasets has, or a dataset that has none of them.
    """
    runs: list[tuple[str, str]] = []
    used: set[str] = set()
    for dataset, ds in datasets.items():
        have = [c.removeprefix("fold_") for c in ds.meta.columns if c.startswith("fold_")]
        mine = [p for p in protocols if p in have]
        if not mine:
            raise TrainingUsageError(f"--protocol: expected one of the protocols of {dataset} "
                         f"({', '.join(sorted(have))}), found {', '.join(repr(p) for p in protocols)}")
        runs += [(dataset, p) for p in mine]
        used.update(mine)
    missing = [p for p in protocols if p not in used]
    if missing:
        raise TrainingUsageError(f"--protocol: expected protocols of the datasets given, found "
                     f"{', '.join(map(repr, missing))} in none of them")
    return runs


def train(dataset: str | Path, protocol: str, out: str | Path, params: OFBENetParams,
          folds: Sequence[int] | None = None, progress: bool = True, seeds: int = DEFAULT_SEEDS,
          jobs: int = 1, scheduler: str = "processes") -> list[Path]:
    """Train every (selected) fold of every benchmark dataset of one windowed dataset under one
    protocol: :func:`train_many` of one dataset and one protocol."""
    return train_many([dataset], [protocol], out, params, folds, progress, seeds, jobs, scheduler)


def _run_splits(ds: Any, protocol: str, folds: Sequence[int] | None) -> list[Split]:
    """The selected folds of one protocol of a loaded dataset that has it (raises
    :class:`TrainingUsageError` for an unknown fold)."""
    splits = list(protocol_splits(ds.meta, str(ds.info["kind"]), protocol))
    available = sorted({s.fold for s in splits})
    if folds is not None:
        unknown = sorted(set(folds) - set(available))
        if unknown:
            known = ", ".join(map(str, available))
            raise TrainingUsageError(f"--folds: expected folds of {protocol} ({known}), "
                                     f"found {', '.join(map(str, unknown))}")
        splits = [s for s in splits if s.fold in set(folds)]
    return splits


def train_many(datasets: Sequence[str | Path], protocols: Sequence[str], out: str | Path,
               params: OFBENetParams, folds: Sequence[int] | None = None, progress: bool = True,
               seeds: int = DEFAULT_SEEDS, jobs: int = 1, scheduler: str = "processes") -> list[Path]:
    """Train every (selected) fold of every benchmark dataset of each dataset under each of
    ``protocols`` it has (:func:`plan_runs`), all fits in one pool.

    The fits of every (dataset, protocol) run are one list of tasks, the largest training sets
    first, so that ``jobs`` workers stay busy to the end instead of waiting at the end of each
    run (longest first is the classic greedy bound for scheduling independent jobs). A fit's
    model does not depend on which worker trains it or when: the outputs are those of
    training each run alone.

    Parameters
    ----------
    datasets
        Dataset folders (``processed/datasets/<name>``), each loaded once here.
    protocols
        Protocols (``fold_<protocol>`` columns); each dataset is trained under those it has.
    out
        Models folder.
    params
        OFBENet parameters; ``params.seed`` is the first training seed.
    folds
        Fold indices to train in every run (all when None).
    progress
        A progress bar on stderr over the fits (folds × seeds), naming the last one finished
        and its epochs; the per-epoch history goes to the history CSVs and ``training.json``.
    seeds
        Training seeds per fold: ``params.seed`` … ``params.seed + seeds − 1``.
    jobs
        Fits trained at once, each in its own single-threaded worker process
        (:data:`WORKER_ENV`); the models are the same whatever ``jobs``.
    scheduler
        Where the fits run: ``processes``, ``dask`` or ``tcp://host:port``
        (:func:`ofbe_data.core.parallel.map_progress`; the Dask workers get :data:`WORKER_ENV`
        before they start), the models the same whatever it is.

    Returns
    -------
    list of Path
        The ``training.json`` files written, one per benchmark dataset and run.

    Raises
    ------
    TrainingUsageError
        A protocol none of the datasets has, a dataset with none of them, or an unknown fold.
    OfbeError
        A bad dataset (:class:`~ofbe_data.dataset.store.DatasetError`), a failed fit
        (:class:`~ofbe_model.estimators.base.EstimatorError`), or a fit whose worker process
        died (:class:`~ofbe_data.core.parallel.TaskError`); the other fits are finished first.
    """
    out = Path(out)
    loaded = {str(dataset): load_dataset(dataset) for dataset in datasets}
    runs = [(dataset, protocol, _run_splits(loaded[dataset], protocol, folds))
            for dataset, protocol in plan_runs(loaded, protocols)]
    sized: list[tuple[int, FitTask]] = []
    created: list[Path] = []  # the topmost folders this run makes, removed again if it fails
    for dataset, protocol, splits in runs:
        for split in splits:
            folder = out / dataset_dirname(split.dataset) / protocol
            missing = [p for p in (folder, *folder.parents) if not p.exists()]
            if missing:  # its topmost missing folder: once made, later folders under it are not missing
                created.append(missing[-1])
            folder.mkdir(parents=True, exist_ok=True)
            sized += [(int(split.train.size), FitTask(dataset, protocol, split.dataset, split.fold,
                                                      dataclasses.replace(params, seed=params.seed + i),
                                                      str(folder)))
                      for i in range(seeds)]
    try:
        return _fit_and_summarise(sized, runs, loaded, out, params, jobs, progress, scheduler)
    except BaseException:
        for folder in created:  # nothing half-made stays behind (empty model folders, partial summaries)
            shutil.rmtree(folder, ignore_errors=True)
        raise


def _fit_and_summarise(sized: list[tuple[int, FitTask]], runs: list[tuple[str, str, list[Split]]],
                       loaded: Mapping[str, Any], out: Path, params: OFBENetParams, jobs: int, progress: bool,
                       scheduler: str) -> list[Path]:
    """Run every fit (largest first) and write the summaries; :func:`train_many`'s body."""
    tasks = [task for _, task in sorted(sized, key=lambda pair: -pair[0])]  # stable: ties keep their order
    desc = f"{PROG} {runs[0][1]}" if len(runs) == 1 else f"{PROG} {len(runs)} runs"
    results = map_progress(_fit_task, tasks, jobs=jobs, desc=desc, unit="fit", progress=progress,
                           worker_env=WORKER_ENV, scheduler=scheduler,
                           postfix=lambda r: (f"fold {r[0]['fold']} seed {r[0]['seed']}: "
                                              f"{r[0]['epochs_run']} epochs"),
                           name=lambda t: f"{t.name} {t.protocol} fold {t.fold} seed {t.params.seed}")
    done: dict[tuple[str, str], dict[tuple[str, int, int], Any]] = {}
    for t, r in zip(tasks, results, strict=True):
        done.setdefault((t.dataset, t.protocol), {})[t.name, t.fold, t.params.seed] = r
    written: list[Path] = []
    for dataset, protocol, splits in runs:
        written += _write_summaries(dataset, protocol, loaded[dataset], splits,
                                    done.get((dataset, protocol), {}), out, params)
    return written


def _write_summaries(dataset: str, protocol: str, ds: Any, splits: Sequence[Split],
                     done: Mapping[tuple[str, int, int], tuple[dict[str, Any], dict[str, list[float]]]],
                     out: Path, params: OFBENetParams) -> list[Path]:
    """``training.json`` and the training curves of one run's benchmark datasets."""
    written: list[Path] = []
    by_dataset: dict[str, list[Split]] = {}
    for s in splits:
        by_dataset.setdefault(s.dataset, []).append(s)
    for name, group in by_dataset.items():
        folder = out / dataset_dirname(name) / protocol
        summary_path = folder / SUMMARY_NAME
        entries = _read_summary(summary_path, name, protocol)
        entries.update({(f, seed): r[0] for (n, f, seed), r in done.items() if n == name})
        summary = {"format": SUMMARY_FORMAT, "dataset": name, "dataset_path": dataset,
                   "protocol": protocol, "kind": str(ds.info["kind"]), "devices": list(group[0].devices),
                   "window_length": int(ds.X.shape[1]), "loss": loss_label(params),
                   "folds": [entries[k] for k in sorted(entries)]}
        write_bytes_atomic(summary_path, (json.dumps(summary, indent=2, allow_nan=False) + "\n").encode())
        for split in group:
            # the figure shows every seed of the fold on record, those trained earlier included
            on_record = {seed: e for (fold, seed), e in entries.items() if fold == split.fold}
            histories = {seed: (done[(name, split.fold, seed)][1] if (name, split.fold, seed) in done
                                else _history_from_csv(folder / e["history"]))
                         for seed, e in on_record.items()}
            plot_history(histories, folder / f"fold-{split.fold}.training.png",
                         f"OFBENet, {split.dataset}, {protocol}, fold {split.fold}", loss_label(params),
                         {seed: e["best_epoch"] for seed, e in on_record.items()})
        written.append(summary_path)
    return written
