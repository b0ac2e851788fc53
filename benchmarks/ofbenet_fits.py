"""What reusing one compiled trainer saves over a run of OFBENet fits in one worker process.

``ofbe-train`` runs its fits in a few long-lived single-threaded worker processes, one after
another. Each fit used to build and trace its own Keras training step (2–4 s, as long as the
epochs of a small fit); :mod:`ofbe_model.ofbenet.trainer` keeps one compiled trainer per process
and batch kind. This script runs the same sequence of fits in one process twice, in fresh
processes with the workers' TensorFlow settings (one thread): ``fresh`` forgets the trainer
before every fit (a trainer built for each fit, as before), ``reused`` keeps it. It prints each
mode's wall-clock and CPU seconds per fit, the ratio, and whether both gave the same weights
(they must: the script exits 1 otherwise).

The fits mimic the paper pipeline's mix: windows of 3000 × 3 samples, training sets of a few
sizes (partial last batches and whole ones), two seeds each, a fixed number of epochs (early
stopping off, so both modes do the same work).

Usage::

    python benchmarks/ofbenet_fits.py [--sizes 250 300 790] [--seeds 2] [--epochs 3]
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time
from typing import Any

from ofbe_model.ofbenet.params import WORKER_ENV


def run_child(sizes: list[int], seeds: int, epochs: int, reuse: bool) -> dict[str, Any]:
    """Run every fit in this process; wall and CPU seconds per fit, and a hash of all weights."""
    import numpy as np
    from ofbenet_speed import synthetic  # beside this script

    from ofbe_model.ofbenet import OFBENet, trainer

    digest = hashlib.sha256()
    wall, cpu = [], []
    for n in sizes:
        x, y, meta = synthetic(n, 3000, seed=n)
        for seed in range(seeds):
            if not reuse:
                trainer.clear()
            t, c = time.perf_counter(), time.process_time()
            est = OFBENet(max_epochs=epochs, es_patience=10_000, seed=seed).fit(x, y, meta)
            wall.append(time.perf_counter() - t)
            cpu.append(time.process_time() - c)
            for v in est.model_.variables:
                digest.update(np.asarray(v).tobytes())
    return {"wall": wall, "cpu": cpu, "digest": digest.hexdigest()}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[250, 300, 790],
                   help="windows per training set (default 250 300 790)")
    p.add_argument("--seeds", type=int, default=2, help="seeds per set (default 2)")
    p.add_argument("--epochs", type=int, default=3, help="epochs per fit (default 3)")
    p.add_argument("--child", choices=("fresh", "reused"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        print("RESULT " + json.dumps(run_child(args.sizes, args.seeds, args.epochs, args.child == "reused")))
        return 0
    env = {**os.environ, **WORKER_ENV}
    n_fits = len(args.sizes) * args.seeds
    print(f"OFBENet: {n_fits} fits in one single-threaded process (sets of {args.sizes} windows of 3000 x 3, "
          f"{args.seeds} seeds, {args.epochs} epochs each), {os.cpu_count()} CPU cores")
    results = {}
    for mode in ("fresh", "reused"):
        cmd = [sys.executable, __file__, "--child", mode, "--sizes",
               *map(str, args.sizes), "--seeds", str(args.seeds), "--epochs", str(args.epochs)]
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env, check=False)
        lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("RESULT ")]
        if proc.returncode != 0 or not lines:
            print(f"{mode}: failed\n{proc.stderr[-3000:]}", file=sys.stderr)
            return 1
        r = results[mode] = json.loads(lines[-1][len("RESULT "):])
        print(f"{mode:>6}: {sum(r['wall']):6.1f} s wall, {sum(r['cpu']):6.1f} s CPU; per fit "
              + " ".join(f"{w:.1f}" for w in r["wall"]))
    f, r = results["fresh"], results["reused"]
    print(f"reused / fresh: wall {sum(r['wall']) / sum(f['wall']):.2f}, "
          f"CPU {sum(r['cpu']) / sum(f['cpu']):.2f}; "
          f"after the first fit: wall {sum(r['wall'][1:]) / sum(f['wall'][1:]):.2f}")
    same = f["digest"] == r["digest"]
    print(f"same weights in both modes: {'yes' if same else 'NO'}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
