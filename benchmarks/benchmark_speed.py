"""Time the benchmark stage's physics estimators, and check the batched solvers against the
per-window ones they replace.

Usage: python benchmarks/benchmark_speed.py [--datasets DIR ...] [--methods M ...]
                                            [--protocols P ...] [--repeat N] [--reference N]

1. Stage time: ``run_protocol`` (what ``ofbe-benchmark`` runs) for every protocol of
   ``benchmark_run`` in params.yaml (or ``--protocols``) on the datasets each names, the
   non-OFBENet physics methods only by default, so the time is the estimators' own: seconds
   per method summed over protocols, best of ``--repeat`` runs. A warm-up run of
   ``level-mean`` on the first dataset comes first, so that the one-off import of the
   estimator registry (TensorFlow among it) is not charged to the first method.
2. ``--reference N``: the first N test signals (window 0 of each recording) of every
   dataset solved window by window with the reference solvers, ``numpy.linalg.lstsq`` steps
   for ``won2009`` (the method as the paper writes it) and ``scipy.optimize.least_squares``
   for every ``ls-trf`` variant (``bounded`` with its box: scipy's ``trf_bounds``), and with
   the batched estimators the runner uses: the time of each, and the largest difference of
   any estimate component, m/s².

Nothing is asserted: this is a measurement.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ofbe_data.dataset.reader import load_dataset
from ofbe_data.io.pipeline_params import load_params
from ofbe_model.benchmark.runner import DEFAULT_VARIANTS, BenchmarkParams, run_protocol
from ofbe_model.estimators.base import make_estimator
from ofbe_model.estimators.physics import ls_trf_solve

PHYSICS = ("level-mean", "ls-trf", "ls-trf-as-written", "ls-trf-bounded", "won2009")
PROTOCOLS = {"paper-gravity": ["gravity-aligned"], "paper-rotated": ["rotated"],
             "grouped": ["gravity-aligned", "rotated"]}


def won_lstsq(f: np.ndarray, g: float, tol: float = 1e-6, max_iter: int = 500,
              rcond: float | None = None) -> np.ndarray:
    """Won & Golnaraghi with one ``numpy.linalg.lstsq`` per iteration (the reference)."""
    f = np.asarray(f, dtype=np.float64)
    b = np.zeros(3)
    for _ in range(max_iter):
        u = f - b
        delta = np.linalg.lstsq(2.0 * u, np.einsum("ij,ij->i", u, u) - g * g, rcond=rcond)[0]
        b = b + delta
        if float(np.linalg.norm(delta)) < tol:
            break
    return b


def stage_time(protocols: dict[str, list[Path]], methods: Sequence[str], repeat: int) -> dict[str, float]:
    """Seconds per method over every protocol (best of ``repeat``)."""
    params = BenchmarkParams(methods=tuple(methods), estimator_params=dict(DEFAULT_VARIANTS))
    best: dict[str, float] = {}
    for _ in range(repeat):
        totals = dict.fromkeys(methods, 0.0)
        for protocol, datasets in protocols.items():
            for ds in datasets:
                _, seconds = run_protocol(ds, protocol, params, progress=False)
                for k, v in seconds.items():
                    totals[k] += v
        for k, v in totals.items():
            best[k] = min(best.get(k, np.inf), v)
    return best


def reference_check(datasets: Sequence[Path], methods: Sequence[str], n: int) -> None:
    """Per-window reference solvers against the batched estimators on n test signals each."""
    for ds_dir in datasets:
        ds = load_dataset(ds_dir)
        rows = np.flatnonzero(ds.meta["window_index"].to_numpy() == 0)[:n]
        X = np.asarray(ds.X[rows])
        meta = ds.meta.iloc[rows].reset_index(drop=True)
        g = meta["g_local"].to_numpy(dtype=np.float64)
        for method in methods:
            kwargs = dict(DEFAULT_VARIANTS.get(method, {}))
            name = str(kwargs.pop("estimator", method))
            if name not in ("ls-trf", "won2009"):
                continue
            est = make_estimator(name, **kwargs)
            start = time.perf_counter()
            batched = est.predict(X, meta)
            t_batched = time.perf_counter() - start
            start = time.perf_counter()
            if name == "won2009":
                ref = np.array([won_lstsq(X[i], g[i], tol=est.tol, max_iter=est.max_iter, rcond=est.rcond)
                                for i in range(len(rows))])
            else:
                kw = est._solver_kwargs(X.shape[1])
                ref = np.array([ls_trf_solve(np.asarray(X[i], dtype=np.float64), g[i], **kw).b
                                for i in range(len(rows))])
            t_ref = time.perf_counter() - start
            err = np.abs(batched - ref).max(axis=1)
            print(f"{ds_dir.name:16s} {method:18s} {len(rows)} windows: per-window {t_ref:7.2f} s, batched "
                  f"{t_batched:6.2f} s ({t_ref / max(t_batched, 1e-9):5.1f}x); max |Δ| {err.max():.2e} m/s², "
                  f"median {np.median(err):.1e}, windows above 1e-9: {int((err > 1e-9).sum())}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--datasets", type=Path, nargs="+",
                        default=[Path("processed/datasets") / c for c in ("gravity-aligned", "rotated")])
    parser.add_argument("--methods", nargs="+", default=list(PHYSICS))
    parser.add_argument("--protocols", nargs="+", default=None,
                        help="protocols to run (default: benchmark_run in params.yaml)")
    parser.add_argument("--params", default="params.yaml")
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--reference", type=int, default=0, metavar="N",
                        help="also solve the first N test signals of each dataset window by window")
    args = parser.parse_args()
    by_name = {d.name: d for d in args.datasets}
    try:
        plan = load_params(args.params)["benchmark_run"]["protocols"]
    except Exception:  # noqa: BLE001 - no params file: the paper's protocols
        plan = PROTOCOLS
    if args.protocols:
        plan = {p: plan.get(p, PROTOCOLS.get(p, [])) for p in args.protocols}
    protocols = {p: [by_name[c] for c in cs if c in by_name] for p, cs in plan.items()}
    protocols = {p: ds for p, ds in protocols.items() if ds}
    run_protocol(args.datasets[0], next(iter(protocols)), BenchmarkParams(methods=("level-mean",)),
                 progress=False)  # warm-up: the estimator registry's imports
    start = time.perf_counter()
    seconds = stage_time(protocols, args.methods, args.repeat)
    wall = time.perf_counter() - start
    table = pd.Series(seconds).round(2)
    print(f"protocols: {', '.join(f'{p} ({len(d)} dataset(s))' for p, d in protocols.items())}")
    print("seconds per method, summed over protocols (best of "
          f"{args.repeat}):\n{table.to_string()}\ntotal {sum(seconds.values()):.2f} s "
          f"(wall {wall:.2f} s for {args.repeat} run(s))")
    if args.reference:
        reference_check(args.datasets, args.methods, args.reference)


if __name__ == "__main__":
    main()
