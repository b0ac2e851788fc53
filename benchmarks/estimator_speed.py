"""Inference throughput of every estimator: windows/s batched and single-window latency.

Usage: python benchmarks/estimator_speed.py [--dataset processed/datasets/rotated] [--n 200]
                                             [--truth raw/rotated/_truth]

Fits each estimator (those that learn) on the dataset's windows, then times ``predict`` on
``--n`` windows at once (windows/s) and on one window at a time (median latency over 20
calls). OFBENet is trained for a few epochs only: its inference cost does not depend on how
well it is trained (``benchmarks/ofbenet_speed.py`` measures training). Prints; asserts nothing.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ofbe_data import load_dataset
from ofbe_model.benchmark.runner import DEFAULT_VARIANTS
from ofbe_model.estimators.base import make_estimator

METHODS = ("level-mean", "ls-trf", "ls-trf-as-written", "ls-trf-bounded", "won2009", "prior-mean",
           "gravity-prior", "gravity-prior-direction", "ofbenet", "oracle")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", default="processed/datasets/rotated")
    ap.add_argument("--truth", default="raw/rotated/_truth")
    ap.add_argument("--n", type=int, default=200)
    args = ap.parse_args()
    ds = load_dataset(args.dataset)
    X, y, meta = ds.X, ds.y, ds.meta
    blind = meta[["device", "g_local", "power_cycle", "fs_hz"]]
    n = min(args.n, len(X))
    print(f"{args.dataset}: {len(X)} windows of {X.shape[1]} samples; timing predict on {n}")
    print(f"{'method':26s} {'batched (windows/s)':>20s} {'one window (ms)':>16s}")
    for method in METHODS:
        kwargs = dict(DEFAULT_VARIANTS.get(method, {}))
        name = kwargs.pop("estimator", method)
        if name == "oracle":
            kwargs["truth_dir"] = args.truth
        if name == "ofbenet":
            kwargs["max_epochs"] = 2
        est = make_estimator(name, **kwargs)
        if est.needs_fit:
            est.fit(X, y, blind)
        est.predict(X[:1], blind.iloc[:1])  # warm-up (graph tracing for OFBENet)
        t0 = time.perf_counter()
        est.predict(X[:n], blind.iloc[:n])
        batched = n / (time.perf_counter() - t0)
        single = []
        for i in range(20):
            t0 = time.perf_counter()
            est.predict(X[i:i + 1], blind.iloc[i:i + 1])
            single.append(time.perf_counter() - t0)
        print(f"{method:26s} {batched:20.0f} {np.median(single) * 1e3:16.2f}")


if __name__ == "__main__":
    main()
