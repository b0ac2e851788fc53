"""How fast OFBENet trains and predicts on the paper's data shape.

Trains on a synthetic set shaped like one training fold of the paper's gravity-aligned data
(by default 990 windows of 3000 × 3 samples: ~80 % of the 1233 windows of the simulated
campaign) and reports, separately with and without XLA (``jit_compile``):

- seconds per epoch (the first epoch, which traces and compiles, separately from the rest);
- one full fold with the default parameters (early stopping decides the epochs; the default
  ``max_epochs`` bounds it) and, with ``--worst-case``, one that runs all ``max_epochs``;
- inference throughput (windows/s with :meth:`OFBENet.predict` on all windows) and the
  latency of one window (ms, median of repeated calls).

Each configuration runs in its own process, because op determinism (which ``fit`` enables
without XLA) is process-wide and Keras disables XLA once it is on.

Usage::

    python benchmarks/ofbenet_speed.py                     # both settings, paper-size data
    python benchmarks/ofbenet_speed.py --windows 200 --epochs 2 --no-fold   # a quick look
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from typing import Any

import numpy as np
import pandas as pd


def synthetic(n_windows: int, length: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, pd.DataFrame]:
    """Gravity-aligned-like windows: gravity on z, a bias per recording of 3 windows, noise.

    Returns
    -------
    X, y, meta
        (N, T, 3) float32 m/s², (N, 3) float64 m/s², N rows (device, g_local, power_cycle).
    """
    rng = np.random.default_rng(seed)
    n_rec = -(-n_windows // 3)
    bias = rng.normal(0.0, 0.3, size=(n_rec, 3)).repeat(3, axis=0)[:n_windows]
    device = np.array([f"d{i % 4}" for i in range(n_rec)]).repeat(3)[:n_windows]
    x = rng.normal(0.0, 0.04, size=(n_windows, length, 3)).astype(np.float32)
    x += (bias + np.array([0.0, 0.0, 9.81])).astype(np.float32)[:, None, :]
    meta = pd.DataFrame({"device": device, "g_local": 9.81, "power_cycle": np.arange(n_windows) // 3})
    return x, bias, meta


def run_one(n_windows: int, length: int, epochs: int, jit: bool, fold: bool,
            worst_case: bool) -> dict[str, Any]:
    """Measure one configuration in this process."""
    import keras

    from ofbe_model.ofbenet import OFBENet, OFBENetParams

    class EpochTimer(keras.callbacks.Callback):
        def on_train_begin(self, logs: Any = None) -> None:
            self.times: list[float] = []

        def on_epoch_begin(self, epoch: int, logs: Any = None) -> None:
            self._t = time.perf_counter()

        def on_epoch_end(self, epoch: int, logs: Any = None) -> None:
            self.times.append(time.perf_counter() - self._t)

    x, y, meta = synthetic(n_windows, length)
    out: dict[str, Any] = {"jit_compile": jit, "n_windows": n_windows, "window_length": length}
    # epoch timing: patience high so that every epoch runs
    timer = EpochTimer()
    est = OFBENet(max_epochs=epochs, es_patience=10_000, jit_compile=jit)
    orig_fit = keras.Model.fit

    def fit_with_timer(self: keras.Model, *args: Any, **kwargs: Any) -> Any:
        kwargs["callbacks"] = [*kwargs.get("callbacks", []), timer]
        return orig_fit(self, *args, **kwargs)

    keras.Model.fit = fit_with_timer  # type: ignore[method-assign]
    try:
        est.fit(x, y, meta)
    finally:
        keras.Model.fit = orig_fit  # type: ignore[method-assign]
    out["n_train"], out["n_val"] = est.n_train_, est.n_val_
    out["first_epoch_s"] = timer.times[0]
    out["epoch_s"] = float(np.median(timer.times[1:])) if len(timer.times) > 1 else timer.times[0]
    # inference
    est.predict(x[:64], meta.iloc[:64])  # warm-up (traces the predict function)
    t = time.perf_counter()
    est.predict(x, meta)
    out["predict_windows_per_s"] = n_windows / (time.perf_counter() - t)
    one, one_meta = x[:1], meta.iloc[:1]
    est.predict(one, one_meta)
    lat = []
    for _ in range(30):
        t = time.perf_counter()
        est.predict(one, one_meta)
        lat.append(time.perf_counter() - t)
    out["single_window_ms"] = 1000.0 * float(np.median(lat))
    if fold:
        full = OFBENet(jit_compile=jit)
        t = time.perf_counter()
        full.fit(x, y, meta)
        out["fold_s"] = time.perf_counter() - t
        out["fold_epochs"] = len(full.history_["loss"])
        out["fold_best_epoch"] = full.best_epoch_
        out["max_epochs"] = OFBENetParams.max_epochs
    if worst_case:
        full = OFBENet(jit_compile=jit, es_patience=10_000)
        t = time.perf_counter()
        full.fit(x, y, meta)
        out["worst_fold_s"] = time.perf_counter() - t
        out["worst_fold_epochs"] = len(full.history_["loss"])
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--windows", type=int, default=990, help="training windows (default 990)")
    p.add_argument("--length", type=int, default=3000, help="samples per window, T (default 3000)")
    p.add_argument("--epochs", type=int, default=4, help="epochs timed per setting (default 4)")
    p.add_argument("--jit", choices=("off", "on", "both"), default="both")
    p.add_argument("--no-fold", action="store_true", help="skip the full fold with default parameters")
    p.add_argument("--worst-case", action="store_true",
                   help="also time a fold that runs every one of the default max_epochs (no early stopping)")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        res = run_one(args.windows, args.length, args.epochs, args.jit == "on", not args.no_fold,
                      args.worst_case)
        print("RESULT " + json.dumps(res))
        return 0
    settings = ("off", "on") if args.jit == "both" else (args.jit,)
    env = {**os.environ, "TF_CPP_MIN_LOG_LEVEL": "2"}
    print(f"OFBENet speed: {args.windows} windows of {args.length} x 3, {os.cpu_count()} CPU cores")
    for s in settings:
        cmd = [sys.executable, __file__, "--child", "--windows", str(args.windows), "--length",
               str(args.length), "--epochs", str(args.epochs), "--jit", s,
               *(["--no-fold"] if args.no_fold else []), *(["--worst-case"] if args.worst_case else [])]
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
        if proc.returncode != 0 or not lines:
            print(f"jit_compile={s}: failed\n{proc.stderr[-3000:]}", file=sys.stderr)
            return 1
        r = json.loads(lines[-1][len("RESULT "):])
        print(f"jit_compile={s}: train {r['n_train']} / validate {r['n_val']} windows; "
              f"first epoch {r['first_epoch_s']:.1f} s, then {r['epoch_s']:.2f} s/epoch; "
              f"predict {r['predict_windows_per_s']:.0f} windows/s, "
              f"one window {r['single_window_ms']:.1f} ms")
        if "fold_s" in r:
            print(f"    one fold with default parameters: {r['fold_s']:.1f} s, {r['fold_epochs']} epochs "
                  f"(best {r['fold_best_epoch']}, max_epochs {r['max_epochs']})")
        if "worst_fold_s" in r:
            print(f"    one fold running all {r['worst_fold_epochs']} epochs: {r['worst_fold_s']:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
