"""``ofbe-benchmark``: every estimator on every fold of a protocol, and the report.

For each benchmark dataset (the gravity-aligned set pooled, each rotated device on its own;
:mod:`ofbe_data.dataset.folds`) and each fold of the protocol, every estimator is fitted on
the fold's training windows and predicts the fold's test signals (window 0 of each test
recording). The predictions table (one row per method and test signal) feeds
:mod:`ofbe_model.benchmark.report`: ``benchmark.json``, the paper's Table 3 as
``benchmark.md``, per-signal errors, paired t-tests, the oracle ratio and the figures.

OFBENet is either loaded per fold from ``ofbe-train``'s models (``--models``: every training
seed on record, one predictions row per seed and signal, the report averages over seeds), or
trained here (one seed). The oracle reads the simulator's truth files (``--truth``) and nothing else does.
"""

from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from tqdm import tqdm

from ofbe_data.core.errors import ConfigError
from ofbe_data.dataset.folds import Split, protocol_splits
from ofbe_data.dataset.reader import load_dataset
from ofbe_data.io.typedconfig import from_plain
from ofbe_model.estimators.base import Estimator, EstimatorError, make_estimator, registered_names

#: Meta columns an estimator never sees at prediction time (they are the labels).
LABEL_COLUMNS = ("bias_x", "bias_y", "bias_z", "offset_x", "offset_y", "offset_z", "gravity_x", "gravity_y",
                 "gravity_z", "roll_deg", "pitch_deg")

DEFAULT_VARIANTS: dict[str, dict[str, Any]] = {
    "ls-trf-as-written": {"estimator": "ls-trf", "variant": "as-written"},
    "ls-trf-bounded": {"estimator": "ls-trf", "variant": "bounded"},
    "gravity-prior-direction": {"estimator": "gravity-prior", "direction_model": True},
}
"""Variants the default benchmark runs besides the registered defaults."""


def default_methods() -> tuple[str, ...]:
    """The methods a benchmark runs when its parameters name none: every registered estimator, in
    registration order (:func:`ofbe_model.estimators.registered_names`), each followed by its
    variants in :data:`DEFAULT_VARIANTS`. (The pipeline names its own in params.yaml.)"""
    out: list[str] = []
    for name in registered_names():
        out += [name, *(v for v, p in DEFAULT_VARIANTS.items() if p.get("estimator") == name)]
    return tuple(out)


@dataclass(frozen=True)
class BenchmarkParams:
    """``benchmark:`` in params.yaml.

    Attributes
    ----------
    methods
        Methods run: registry names, or labels of variants defined in ``estimator_params``.
    baselines
        Methods every other method is compared with (improvement %, t-tests).
    estimator_params
        Per method, keyword arguments of its constructor; the key ``estimator`` names the
        registered estimator of a variant (e.g. ``ls-trf-as-written: {estimator: ls-trf,
        variant: as-written}``).
    """

    methods: tuple[str, ...] = field(default_factory=default_methods)
    baselines: tuple[str, ...] = ("ls-trf", "won2009")
    estimator_params: dict[str, dict[str, Any]] = field(default_factory=lambda: dict(DEFAULT_VARIANTS))


def benchmark_params_from(data: dict[str, Any] | None, source: str) -> BenchmarkParams:
    """:class:`BenchmarkParams` from a plain mapping (``estimator_params`` values are kept as given)."""
    plain = dict(data or {})
    est = plain.pop("estimator_params", None) or {}
    if not isinstance(est, dict) or not all(isinstance(v, dict) for v in est.values()):
        raise ConfigError(source, "benchmark.estimator_params", "a mapping of method → mapping of parameters",
                          repr(est))
    params: BenchmarkParams = from_plain(plain, BenchmarkParams, source, "benchmark")
    merged = {**DEFAULT_VARIANTS, **{str(k): dict(v) for k, v in est.items()}}
    return BenchmarkParams(params.methods, params.baselines, merged)


def model_folder(models_dir: Path, dataset: str, protocol: str) -> Path:
    """Where ``ofbe-train`` saves the OFBENets of one benchmark dataset and protocol."""
    return models_dir / dataset.replace("/", "__") / protocol


def model_path(models_dir: Path, dataset: str, protocol: str, fold: int, seed: int) -> Path:
    """Where ``ofbe-train`` saves the OFBENet of one benchmark dataset, protocol, fold and seed."""
    return model_folder(models_dir, dataset, protocol) / f"fold-{fold}.seed-{seed}.keras"


def trained_seeds(models_dir: Path, dataset: str, protocol: str, fold: int) -> list[int]:
    """The training seeds on record for one fold (``training.json`` of ``ofbe-train``).

    Raises
    ------
    EstimatorError
        No readable ``training.json``, or no model of this fold in it.
    """
    path = model_folder(models_dir, dataset, protocol) / "training.json"
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        seeds = sorted({int(f["seed"]) for f in doc["folds"] if int(f["fold"]) == fold})
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise EstimatorError(f"{path}: expected ofbe-train's summary with a seed per fold, "
                             f"found {type(exc).__name__}: {exc} (run ofbe-train)") from None
    if not seeds:
        raise EstimatorError(f"{path}: expected a model of fold {fold}, found none (run ofbe-train)")
    return seeds


def _estimators(method: str, split: Split, protocol: str, params: BenchmarkParams, models_dir: Path | None,
                truth_dir: Path | None) -> list[tuple[int, Estimator, bool]]:
    """(seed, estimator, already fitted) of one method for one fold: one per training seed for
    OFBENet loaded from ``ofbe-train``'s models, a single one (seed 0) otherwise."""
    kwargs = dict(params.estimator_params.get(method, {}))
    name = str(kwargs.pop("estimator", method))
    if name == "oracle":
        if truth_dir is None:
            raise EstimatorError("oracle: expected --truth (the simulator's truth folder), found none")
        kwargs["truth_dir"] = str(truth_dir)
    if name == "ofbenet" and models_dir is not None:
        from ofbe_model.ofbenet.network import OFBENet

        return [(seed, OFBENet.load(model_path(models_dir, split.dataset, protocol, split.fold, seed)), True)
                for seed in trained_seeds(models_dir, split.dataset, protocol, split.fold)]
    return [(0, make_estimator(name, **kwargs), False)]


class _Rows:
    """Rows ``rows`` of an array, indexed lazily: ``_Rows(X, rows)[k]`` is ``X[rows[k]]``."""

    def __init__(self, x: Any, rows: np.ndarray) -> None:
        self._x, self._rows = x, rows

    def __getitem__(self, k: np.ndarray) -> np.ndarray:
        return np.asarray(self._x[self._rows[k]])


def _per_window(est: Estimator, fitted: bool) -> bool:
    """Whether an estimator's predictions need no fold: no training, and each window's
    estimate from that window and its meta row alone (the class says so with
    ``per_window = True``, as the physics estimators do)."""
    return not fitted and not est.needs_fit and bool(getattr(est, "per_window", False))


class WindowCache:
    """Estimates of the per-window estimators, kept across protocols (and datasets) of one run.

    A per-window estimator's estimate of a window depends on that window, its meta row and the
    estimator's parameters only (:func:`_per_window`), so a window that two protocols test (the
    gravity-aligned set under ``paper-gravity`` and ``grouped``) is solved once. The key is
    the dataset's content (its ``SHA256SUMS``, which hashes every file), the registered
    estimator and its parameters, and the ``window_id``.

    Attributes
    ----------
    solved, reused
        Windows solved and windows taken from the cache, over the cache's life.
    """

    def __init__(self) -> None:
        self._store: dict[tuple[str, str], dict[int, tuple[np.ndarray, np.ndarray]]] = {}
        self.solved = 0
        self.reused = 0

    @staticmethod
    def dataset_key(path: Path) -> str:
        """The dataset's content: its ``SHA256SUMS`` (its path when it has none)."""
        sums = path / "SHA256SUMS"
        return sums.read_text(encoding="utf-8") if sums.is_file() else str(path.resolve())

    def predict(self, dataset: str, estimator: str, est: Estimator, window_ids: np.ndarray,
                windows: Any, meta: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
        """Estimates and standard deviations of the windows ``window_ids`` (rows of ``windows``
        and ``meta`` in that order), solving only those not yet in the cache.

        Parameters
        ----------
        dataset
            :meth:`dataset_key` of the dataset.
        estimator
            The registered estimator and its parameters, as text.
        est
            The estimator (per-window, unfitted).
        window_ids
            (N,) int.
        windows
            Indexable by a row array: (N, T, 3) m/s² (read only for the rows solved).
        meta
            N rows, the estimator's inputs.

        Returns
        -------
        (yhat, std)
            (N, 3) float64 each.
        """
        known = self._store.setdefault((dataset, estimator), {})
        missing = np.array([i for i, w in enumerate(window_ids) if int(w) not in known], dtype=np.int64)
        if missing.size:
            yhat, std = _predict(est, windows[missing], meta.iloc[missing].reset_index(drop=True))
            for k, i in enumerate(missing):
                known[int(window_ids[i])] = (yhat[k], std[k])
        self.solved += int(missing.size)
        self.reused += int(len(window_ids) - missing.size)
        rows = [known[int(w)] for w in window_ids]
        return (np.array([r[0] for r in rows], dtype=np.float64).reshape(-1, 3),
                np.array([r[1] for r in rows], dtype=np.float64).reshape(-1, 3))


PROCESS_CACHE = WindowCache()
"""The cache :func:`run_protocol` uses unless given one: keyed by content, so it is never stale."""


def _predict(est: Estimator, windows: np.ndarray, meta: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """Estimates and standard deviations (NaN without one), (N, 3) float64 each."""
    yhat = np.asarray(est.predict(windows, meta), dtype=np.float64)
    std = (np.asarray(est.predict_std(windows, meta), dtype=np.float64)
           if est.has_std else np.full_like(yhat, np.nan))
    return yhat, std


def run_protocol(dataset: str | Path, protocol: str, params: BenchmarkParams | None = None, *,
                 models_dir: str | Path | None = None, truth_dir: str | Path | None = None,
                 progress: bool = True, scheduler: str = "processes", cache: WindowCache | None = None,
                 ) -> tuple[pd.DataFrame, dict[str, float]]:
    """Predict every test signal of every fold with every method.

    Parameters
    ----------
    dataset
        A dataset folder (``processed/datasets/<campaign>``).
    protocol
        One of the dataset's protocols.
    params
        Methods, baselines, estimator parameters.
    models_dir
        ``ofbe-train``'s output folder: OFBENet is loaded from it (trained here when None).
    truth_dir
        The simulator's truth folder, for the oracle.
    progress
        Show a progress bar.
    scheduler
        Where parallel work would run (``ofbe-benchmark --scheduler``; the names of
        :func:`ofbe_data.core.parallel.map_progress`). Accepted so that the command line and
        the pipeline can pass it, but the runner does not parallelise: every fold and method
        runs in this process, one after the other (the physics estimators solve all test
        windows of a fold at once instead), so the value changes nothing.
    cache
        Per-window estimates kept from earlier calls (other protocols of the same dataset);
        :data:`PROCESS_CACHE` when None (the benchmark stage runs every protocol in one
        process). The results are the same with or without it.

    Returns
    -------
    predictions
        One row per (method, test signal): the columns of
        :func:`ofbe_model.benchmark.report.summarise`'s input.
    seconds
        Fit + predict time per method, s (summed over folds).
    """
    params = params or BenchmarkParams()
    ds = load_dataset(dataset)
    meta = ds.meta
    kind = str(ds.info["kind"])
    blind = meta.drop(columns=[c for c in LABEL_COLUMNS if c in meta.columns])
    splits = list(protocol_splits(meta, kind, protocol))
    models = Path(models_dir) if models_dir else None
    truth = Path(truth_dir) if truth_dir else None
    rows = []
    seconds = dict.fromkeys(params.methods, 0.0)
    bar = tqdm(total=len(splits) * len(params.methods), desc=f"benchmark {protocol}", unit="fit",
               file=sys.stderr, disable=not progress)
    # estimators that need no training and predict each window from that window alone give
    # the same numbers in every fold: they predict every test signal of the protocol in one
    # call (their batched solvers then work on all of them at once) and each fold takes its rows
    every_test = np.unique(np.concatenate([sp.test for sp in splits])) if splits else np.zeros(0, int)
    shared: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    cache = cache if cache is not None else PROCESS_CACHE
    content = WindowCache.dataset_key(Path(dataset))
    window_ids = meta["window_id"].to_numpy()
    for split in splits:
        y_test = ds.y[split.test]
        # the fold's windows and tables, taken once for every method
        x_test = ds.X[split.test]
        test_meta = blind.iloc[split.test].reset_index(drop=True)
        train: tuple[np.ndarray, np.ndarray, pd.DataFrame] | None = None
        for method in params.methods:
            t0 = time.perf_counter()
            for seed, est, fitted in _estimators(method, split, protocol, params, models, truth):
                if _per_window(est, fitted):
                    if method not in shared:
                        kwargs = params.estimator_params.get(method, {})
                        what = json.dumps({"estimator": str(kwargs.get("estimator", method)), **kwargs},
                                          sort_keys=True, default=str)
                        shared[method] = cache.predict(content, what, est, window_ids[every_test],
                                                       _Rows(ds.X, every_test),
                                                       blind.iloc[every_test].reset_index(drop=True))
                    at = np.searchsorted(every_test, split.test)
                    yhat, std = shared[method][0][at], shared[method][1][at]
                else:
                    if est.needs_fit and not fitted:
                        if train is None:
                            train = (ds.X[split.train], ds.y[split.train],
                                     blind.iloc[split.train].reset_index(drop=True))
                        est.fit(*train)
                    yhat, std = _predict(est, x_test, test_meta)
                rows.append(pd.DataFrame({
                    "dataset": split.dataset, "devices": ",".join(split.devices), "protocol": protocol,
                    "method": method, "seed": seed, "fold": split.fold,
                    "window_id": meta["window_id"].to_numpy()[split.test],
                    "device": meta["device"].to_numpy()[split.test],
                    "y_x": y_test[:, 0], "y_y": y_test[:, 1], "y_z": y_test[:, 2],
                    "yhat_x": yhat[:, 0], "yhat_y": yhat[:, 1], "yhat_z": yhat[:, 2],
                    "std_x": std[:, 0], "std_y": std[:, 1], "std_z": std[:, 2]}))
            seconds[method] += time.perf_counter() - t0
            bar.update()
    bar.close()
    return pd.concat(rows, ignore_index=True), seconds


