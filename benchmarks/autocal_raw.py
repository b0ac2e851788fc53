"""Time and peak memory of reading a week-long raw wearable file into GGIR's epochs.

Writes a synthetic Axivity ``.cwa`` of valid packed ``AX`` blocks (default: 7 days at 100 Hz,
60.48 M samples, 258 MB; still spells in random orientations and moving spells, 1/256 g counts,
a daily temperature swing) and measures, each in a fresh process on one core
(``OMP_NUM_THREADS=1`` …, ``taskset`` to one CPU where available; wall and CPU seconds both
printed, as a shared machine stretches the wall time):

- ``ofbe``: :func:`ofbe_data.freeliving.raw.read_raw_epochs` (ofbe's block reader, GGIRread's
  resampling, GGIR's epochs) — the acceptance: ≤ 15 s and ≤ 1.5 GB peak;
- ``ofbe+ggir``: the same and :func:`~ofbe_data.freeliving.ggir.ggir_calibrate` on the epochs;
- ``actfast``: ``actfast.read`` of the same file, which holds every sample at once (what the
  ``.bin`` and ``.gt3x`` readers cost, per sample, since they go through it).

Run: ``python benchmarks/autocal_raw.py [--days 7] [--rate 100] [--out /tmp/ofbe-autocal-raw]``.
Prints one line per measurement: wall seconds, peak resident memory (``ru_maxrss``), epochs.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

BLOCK_SAMPLES = 120
"""Samples per packed AX3 block."""


def _spells(rng: np.random.Generator, n: int, rate: float) -> np.ndarray:
    """Shape (n, 3) acceleration, g: spells of 1–20 min, 60 % still in a random orientation
    (noise 4 mg), 40 % moving (noise 150 mg around a wandering orientation)."""
    out = np.empty((n, 3))
    i = 0
    while i < n:
        length = min(n - i, int(rng.uniform(60, 1200) * rate))
        g = rng.normal(size=3)
        g /= np.linalg.norm(g)
        if rng.random() < 0.6:
            out[i:i + length] = g * 1.003 + 0.01 + rng.normal(0, 0.004, (length, 3))
        else:
            drift = np.cumsum(rng.normal(0, 0.002, (length, 3)), axis=0)
            out[i:i + length] = g + drift + rng.normal(0, 0.15, (length, 3))
        i += length
    return out


def write_week(path: Path, days: float, rate: float, seed: int = 7) -> None:
    """The synthetic ``.cwa`` file (written in slices of 20 000 blocks)."""
    from ofbe_data.freeliving.blocks import encode_blocks, encode_header

    rng = np.random.default_rng(seed)
    n_blocks = int(days * 86400 * rate) // BLOCK_SAMPLES
    t0 = float(np.datetime64("2024-03-04T09:00:00", "s").astype(np.int64))
    block_s = BLOCK_SAMPLES / rate
    tmp = path.with_suffix(".partial")
    with open(tmp, "wb") as fh:
        fh.write(encode_header(12345, 1, rate, 8, "AX3", "synthetic week"))
        for lo in range(0, n_blocks, 20000):
            m = min(20000, n_blocks - lo)
            start = t0 + (lo + np.arange(m)) * block_s
            acc = _spells(rng, m * BLOCK_SAMPLES, rate)
            counts = np.clip(np.round(acc * 256), -511, 511).astype(np.int64).reshape(m, BLOCK_SAMPLES, 3)
            temp = 25.0 + 5.0 * np.sin(2 * np.pi * (start - t0) / 86400.0)
            fh.write(encode_blocks(counts, start, lo, 1, temp, rate, 8).tobytes())
    tmp.replace(path)


def _measure(mode: str, path: Path) -> None:
    """One measurement, in this (fresh) process; the imports are done before the clocks start."""
    if mode == "actfast":
        import actfast
    else:
        from ofbe_data.freeliving.ggir import ggir_calibrate
        from ofbe_data.freeliving.raw import read_raw_epochs
    start = resource.getrusage(resource.RUSAGE_SELF)
    cpu0 = start.ru_utime + start.ru_stime
    t = time.perf_counter()
    if mode == "actfast":
        data = actfast.read(str(path))
        n = len(data["timeseries"]["high_frequency"]["acceleration"])
        detail = f"{n} samples"
    else:
        raw = read_raw_epochs(path)
        detail = f"{raw.n_samples} samples, {raw.n_epochs} epochs"
        if mode == "ofbe+ggir":
            result = ggir_calibrate(raw.epochs)
            detail += f", {result.n_still} still; qc: {result.qc[:40]}"
    seconds = time.perf_counter() - t
    usage = resource.getrusage(resource.RUSAGE_SELF)
    cpu = usage.ru_utime + usage.ru_stime - cpu0
    peak = usage.ru_maxrss / 1024
    print(f"{mode:<10} wall {seconds:7.2f} s   cpu {cpu:7.2f} s   peak {peak:7.1f} MB   {detail}", flush=True)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--days", type=float, default=7.0)
    p.add_argument("--rate", type=float, default=100.0)
    p.add_argument("--out", type=Path, default=Path("/tmp/ofbe-autocal-raw"))
    p.add_argument("--measure", choices=("ofbe", "ofbe+ggir", "actfast"), help=argparse.SUPPRESS)
    p.add_argument("--modes", default="ofbe,ofbe+ggir,actfast")
    p.add_argument("--cpu", default="0", help="CPU to pin each measurement to ('' for none)")
    args = p.parse_args(argv)
    path = args.out / f"synthetic-{args.days:g}d-{args.rate:g}hz.cwa"
    if args.measure:
        _measure(args.measure, path)
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    if not path.exists():
        t = time.perf_counter()
        write_week(path, args.days, args.rate)
        print(f"wrote {path} ({path.stat().st_size / 1e6:.0f} MB) in {time.perf_counter() - t:.0f} s")
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    pin = ["taskset", "-c", args.cpu] if shutil.which("taskset") and args.cpu else []
    for mode in args.modes.split(","):
        cmd = [*pin, sys.executable, __file__, "--measure", mode, "--days", f"{args.days}", "--rate",
               f"{args.rate}", "--out", str(args.out)]
        done = subprocess.run(cmd, env=env)
        if done.returncode:
            print(f"{mode}: exit status {done.returncode}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
