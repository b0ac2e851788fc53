"""``ofbe-autocal`` on many files: ``--scheduler dask`` against ``processes``, byte for byte, and timed.

Simulates the ``free-living`` profile with N files (default 200, the last 8 its QC scenarios)
of D days each (default 0.5: 4,320 epochs, written as epoch csv files), then runs, each in a
fresh process, ``ofbe-autocal EPOCHS --out DIR --jobs J --scheduler S`` for every scheduler asked
(default ``processes`` and ``dask``, J = 2), and compares every file the runs wrote
(``summary.csv``, ``summary.parquet``, each ``<file>.epochs.parquet``) byte for byte. Prints per
run the wall time, the CPU time of the command and its children, and the files per second.

Run: ``nice -n 10 python benchmarks/freeliving_scale.py [--files 200] [--days 0.5] [--jobs 2]
[--schedulers processes dask] [--out DIR]``. Exit status 1 when any two runs differ.
"""

from __future__ import annotations

import argparse
import hashlib
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def digests(folder: Path) -> dict[str, str]:
    """SHA-256 of every file under ``folder``, by relative path."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def run(epochs: Path, out: Path, jobs: int, scheduler: str) -> tuple[float, float]:
    """One ``ofbe-autocal`` command in a fresh process: (wall s, CPU s of it and its children)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "ofbe_data.cli.autocal", str(epochs), "--out", str(out),
                    "--jobs", str(jobs), "--scheduler", scheduler, "--quiet"], check=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--files", type=int, default=200)
    parser.add_argument("--days", type=float, default=0.5)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--schedulers", nargs="+", default=["processes", "dask"])
    parser.add_argument("--out", type=Path, default=None, help="keep the campaign and the outputs here")
    args = parser.parse_args(argv)
    from ofbe_data.simulator import load_config, simulate_campaign

    cfg = load_config("free-living", {"sessions": args.files, "free_living": {"days": args.days}})
    root = args.out or Path(tempfile.mkdtemp(prefix="ofbe-fl-scale-"))
    try:
        t0 = time.perf_counter()
        simulate_campaign(cfg, root / "campaign", force=True, progress=False)
        epochs = root / "campaign" / "epochs"
        size = sum(p.stat().st_size for p in epochs.iterdir())
        print(f"{args.files} files of {args.days:g} days ({cfg.free_living.n_epochs} epochs each, "  # type: ignore[union-attr]
              f"{size / 1e6:.1f} MB of epoch csv) simulated in {time.perf_counter() - t0:.1f} s; "
              f"{os.cpu_count()} CPUs\n")
        print("| scheduler | jobs | wall s | CPU s | files/s | CPU s per file | output files |")
        print("|---|---:|---:|---:|---:|---:|---:|")
        results: dict[str, dict[str, str]] = {}
        for scheduler in args.schedulers:
            out = root / f"autocal-{scheduler.replace(':', '_').replace('/', '_')}"
            shutil.rmtree(out, ignore_errors=True)
            wall, cpu = run(epochs, out, args.jobs, scheduler)
            results[scheduler] = digests(out)
            print(f"| {scheduler} | {args.jobs} | {wall:.1f} | {cpu:.1f} | {args.files / wall:.2f} "
                  f"| {cpu / args.files:.3f} | {len(results[scheduler])} |")
        first, *rest = args.schedulers
        same = True
        for other in rest:
            a, b = results[first], results[other]
            differ = sorted(k for k in a.keys() | b.keys() if a.get(k) != b.get(k))
            same &= not differ
            print(f"\n{other} vs {first}: " + (f"every one of {len(a)} files byte-identical" if not differ
                                                else f"{len(differ)} files differ: {', '.join(differ[:10])}"))
        return 0 if same else 1
    finally:
        if args.out is None:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
