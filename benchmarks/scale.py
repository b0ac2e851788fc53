"""Throughput of labelling and dataset building with 1 and 2 workers, process pool against a
Dask LocalCluster, and what one task costs each scheduler; the figures docs/scale.md
extrapolates from.

Usage: python benchmarks/scale.py [--devices N] [--sessions M] [--raw DIR] [--jobs 1 2]
                                  [--schedulers processes dask dask-warm] [--repeat K] [--tasks N]
                                  [--json FILE]

1. Simulates a fleet campaign (the ``fleet`` profile with ``--devices`` boards and
   ``--sessions`` power cycles: one 32 s recording of 4,800 samples per board and power cycle,
   one session per power cycle) into a temporary folder, or uses ``--raw DIR`` (a campaign
   folder of sessions, e.g. one written by ``ofbe-simulate fleet``).
2. For every scheduler (``processes``; ``dask``, an embedded LocalCluster started by each
   command, as ``--scheduler dask`` does; ``dask-warm``, a LocalCluster started once before
   the runs and joined by its address, as ``--scheduler tcp://…`` joins a running cluster)
   and worker count: labels the campaign (``label_sessions``: read,
   label, campaign fit, write) and builds its dataset from those labels (``build_dataset``:
   read the raw files again, window, split, write HDF5 and Parquet), best of ``--repeat``
   wall-clock runs of each. Prints recordings/s, MB/s and the cost of one recording in
   core-seconds (wall × workers / recordings), and the speed-up from 1 to 2 workers. It also
   checks that every run wrote the same bytes (SHA-256 of every label and dataset file) and
   prints what each step writes per recording, and the part of each run spent in the calling
   process (:data:`SERIAL`, timed by wrapping those functions): the campaign fit and the
   products' writing when labelling, the dataset writer when building. That part does not
   shrink with more workers and bounds the speed-up of a cluster.
3. Overhead per task: ``map_progress`` of a no-op (the builtin ``abs``) over one item per
   worker and over ``--tasks`` more, with each scheduler and worker count; the difference
   divided by the extra items is the wall-clock cost of one task with that many workers at
   once, and the first call is the fixed cost of starting (and closing) the workers, which
   the table's "w/o start" column takes off each run.

Every figure is wall-clock on whatever else the machine runs: run it on a quiet machine for
figures to quote. Nothing is asserted: this is a measurement. ``--json`` also writes the
figures as JSON (for docs/scale.md's extrapolation).
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import json
import logging
import shutil
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from ofbe_data.core.parallel import map_progress
from ofbe_data.dataset.build import DatasetParams, build_dataset
from ofbe_data.labelling.batch import expand_sessions, label_sessions
from ofbe_data.labelling.labels import LabelParams
from ofbe_data.simulator import simulate_campaign

WARM = "dask-warm"


@dataclass
class Run:
    """One timed configuration of one step."""

    step: str
    scheduler: str
    jobs: int
    seconds: float
    recordings: int
    megabytes: float
    digest: str
    out_megabytes: float
    serial_s: float

    @property
    def per_recording_core_s(self) -> float:
        """Core-seconds per recording: wall × workers / recordings."""
        return self.seconds * self.jobs / self.recordings


def tree_megabytes(folder: Path) -> float:
    """Megabytes of every file under ``folder``."""
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file()) / 1e6


def tree_digest(folder: Path) -> str:
    """SHA-256 over every file under ``folder`` (relative path and bytes), in path order."""
    h = hashlib.sha256()
    for path in sorted(p for p in folder.rglob("*") if p.is_file()):
        h.update(str(path.relative_to(folder)).encode() + b"\0" + path.read_bytes())
    return h.hexdigest()


#: What runs in the calling process (the client), not in the workers, whatever the scheduler:
#: labelling's campaign fit and product writing, and the dataset writer. Timed by wrapping.
SERIAL = {"label": [("ofbe_data.labelling.batch", "", "fit_campaign"),
                    ("ofbe_data.labelling.batch", "", "write_session"),
                    ("ofbe_data.labelling.batch", "", "write_campaign_fit")],
          "build": [("ofbe_data.dataset.writer", "WindowWriter", "append"),
                    ("ofbe_data.dataset.writer", "WindowWriter", "__exit__")]}


@contextlib.contextmanager
def timed_calls(targets: Sequence[tuple[str, str, str]]) -> Iterator[list[float]]:
    """Wrap functions (module, class or "", attribute) to add their seconds to the yielded
    one-element list; restored on exit."""
    import importlib

    total = [0.0]
    saved = []
    for module, cls, attr in targets:
        owner: Any = importlib.import_module(module)
        if cls:
            owner = getattr(owner, cls)
        original = getattr(owner, attr)

        def wrapper(*a: Any, __f: Callable[..., Any] = original, **k: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return __f(*a, **k)
            finally:
                total[0] += time.perf_counter() - t0

        saved.append((owner, attr, original))
        setattr(owner, attr, wrapper)
    try:
        yield total
    finally:
        for owner, attr, original in saved:
            setattr(owner, attr, original)


def best_of(repeat: int, work: Callable[[], Any], step: str) -> tuple[float, float]:
    """Smallest wall-clock seconds of ``repeat`` calls of ``work``, and that call's seconds in
    the client's serial part (:data:`SERIAL`)."""
    runs = []
    for _ in range(repeat):
        with timed_calls(SERIAL[step]) as serial:
            t0 = time.perf_counter()
            work()
            runs.append((time.perf_counter() - t0, serial[0]))
    return min(runs)


def raw_size(folder: Path) -> tuple[int, float]:
    """Data files (not manifests or truth) and their megabytes under a campaign folder."""
    files = [p for p in folder.rglob("*") if p.is_file() and "_truth" not in p.parts
             and p.suffix.lower() in (".csv", ".txt", ".bin")]
    return len(files), sum(p.stat().st_size for p in files) / 1e6


def time_steps(raw: Path, scratch: Path, scheduler: str, jobs: int, repeat: int, name: str) -> list[Run]:
    """Label then build the campaign with one scheduler and worker count; best of ``repeat``
    (``name``: the scheduler's name in the tables)."""
    sessions = expand_sessions([raw])
    labels_root = scratch / f"labels-{name}-{jobs}"
    campaign = raw.name
    outcomes: list[Any] = []

    def label() -> None:
        shutil.rmtree(labels_root, ignore_errors=True)
        outcomes[:] = label_sessions(sessions, LabelParams(), labels_root, jobs=jobs, progress=False,
                                     scheduler=scheduler)

    label_s, label_serial = best_of(repeat, label, "label")
    failed = [o for o in outcomes if o.error]
    if failed:
        raise SystemExit(f"labelling failed: {failed[0].folder}: {failed[0].error}")
    labels_dir = next(p for p in labels_root.iterdir() if p.is_dir())
    dataset = scratch / f"dataset-{name}-{jobs}"
    built: list[Any] = []

    def build() -> None:
        built[:] = [build_dataset(labels_dir, raw, dataset, DatasetParams(), name=campaign, jobs=jobs,
                                  force=True, progress=False, scheduler=scheduler)]

    build_s, build_serial = best_of(repeat, build, "build")
    n_files, megabytes = raw_size(raw)
    return [Run("label", name, jobs, label_s, n_files, megabytes, tree_digest(labels_root),
                tree_megabytes(labels_root), label_serial),
            Run("build", name, jobs, build_s, int(built[0].n_recordings), megabytes, tree_digest(dataset),
                tree_megabytes(dataset), build_serial)]


@contextlib.contextmanager
def resolved(scheduler: str, jobs: int) -> Iterator[str]:
    """The ``--scheduler`` value for a scheduler name: ``dask-warm`` starts a LocalCluster of
    ``jobs`` single-threaded workers here and yields its address (joined like a running
    cluster, so its start is not charged to the runs); the others are themselves."""
    if scheduler != WARM:
        yield scheduler
        return
    import dask
    import distributed

    with dask.config.set({"distributed.worker.daemon": False}), distributed.LocalCluster(
            n_workers=jobs, threads_per_worker=1, processes=True, dashboard_address=None,
            silence_logs=logging.CRITICAL, scheduler_kwargs={"dashboard_address": ":0"}) as cluster:
        yield str(cluster.scheduler_address)


def task_overhead(scheduler: str, jobs: int, tasks: int) -> dict[str, float]:
    """Start-up and per-task wall-clock seconds of ``map_progress`` on a no-op.

    The start-up is a call with one item per worker (a single item would run in this process
    with ``processes``); the per-task cost is what ``tasks`` more items add, divided by them.
    """
    t0 = time.perf_counter()
    map_progress(abs, list(range(jobs)), jobs=jobs, scheduler=scheduler, progress=False)
    start = time.perf_counter() - t0
    t0 = time.perf_counter()
    map_progress(abs, list(range(jobs + tasks)), jobs=jobs, scheduler=scheduler, progress=False)
    many = time.perf_counter() - t0
    return {"start_s": start, "per_task_s": max(0.0, many - start) / tasks}


def report(runs: Sequence[Run], overhead: dict[tuple[str, int], dict[str, float]],
           jobs: Sequence[int]) -> None:
    """Print the tables."""
    print(f"{'step':6} {'scheduler':10} {'workers':>7} {'seconds':>8} {'rec/s':>8} {'MB/s':>7} "
          f"{'core-ms/rec':>12} {'client ms/rec':>14} {'speed-up':>9}")
    for r in runs:
        base = next((b for b in runs
                     if b.step == r.step and b.scheduler == r.scheduler and b.jobs == min(jobs)), r)
        print(f"{r.step:6} {r.scheduler:10} {r.jobs:7d} {r.seconds:8.2f} {r.recordings / r.seconds:8.1f} "
              f"{r.megabytes / r.seconds:7.1f} {r.per_recording_core_s * 1e3:12.2f} "
              f"{r.serial_s / r.recordings * 1e3:14.2f} {base.seconds / r.seconds:8.2f}x")
    for step in ("label", "build"):
        mine = [r for r in runs if r.step == step]
        print(f"{step}: outputs identical across the {len(mine)} runs: "
              f"{'yes' if len({r.digest for r in mine}) == 1 else 'NO'}; "
              f"{mine[0].out_megabytes:.2f} MB written, "
              f"{mine[0].out_megabytes * 1e3 / mine[0].recordings:.1f} kB per recording")
    for (scheduler, n), o in overhead.items():
        print(f"overhead {scheduler}, {n} worker(s): start-up {o['start_s']:.2f} s, "
              f"{o['per_task_s'] * 1e3:.2f} ms per task")


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--devices", type=int, default=60, help="boards of the simulated fleet (default 60)")
    p.add_argument("--sessions", type=int, default=10, help="power cycles per board (default 10)")
    p.add_argument("--raw", type=Path, help="use this campaign folder instead of simulating one")
    p.add_argument("--jobs", type=int, nargs="+", default=[1, 2], help="worker counts (default 1 2)")
    p.add_argument("--schedulers", nargs="+", default=["processes", "dask", WARM],
                   help=f"processes, dask (an embedded LocalCluster per command, its start included) and "
                        f"{WARM} (default: all three)")
    p.add_argument("--repeat", type=int, default=2, help="runs of each configuration; the best counts")
    p.add_argument("--tasks", type=int, default=400, help="no-op tasks for the overhead (default 400)")
    p.add_argument("--json", type=Path, help="also write the figures here")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="ofbe-scale-") as tmp:
        scratch = Path(tmp)
        raw = args.raw
        sim_s = None
        if raw is None:
            raw = scratch / "fleet"
            t0 = time.perf_counter()
            simulate_campaign("fleet", raw, jobs=max(args.jobs), progress=False,
                              overrides={"duts": {"count": args.devices}, "sessions": args.sessions})
            sim_s = time.perf_counter() - t0
        n_files, megabytes = raw_size(raw)
        print(f"campaign {raw.name}: {len(expand_sessions([raw]))} sessions, {n_files} recordings, "
              f"{megabytes:.1f} MB" + (f" (simulated in {sim_s:.1f} s with {max(args.jobs)} workers)"
                                       if sim_s is not None else ""), flush=True)
        runs: list[Run] = []
        for scheduler in args.schedulers:
            for jobs in args.jobs:
                with resolved(scheduler, jobs) as address:
                    runs += time_steps(raw, scratch, address, jobs, args.repeat, scheduler)
                print(f"  {scheduler}, {jobs} worker(s): label {runs[-2].seconds:.2f} s, "
                      f"build {runs[-1].seconds:.2f} s", flush=True)
        overhead = {}
        for scheduler in args.schedulers:
            for jobs in args.jobs:
                with resolved(scheduler, jobs) as address:
                    overhead[scheduler, jobs] = task_overhead(address, jobs, args.tasks)
        report(runs, overhead, args.jobs)
        print("core-ms/rec: wall × workers / recordings; client ms/rec: the part of it spent in the calling "
              "process whatever the workers (labelling: campaign fit and writing the products; building: "
              "the dataset writer), which more workers do not shorten; speed-up: against the fewest workers; "
              f"{WARM}: a LocalCluster started before the runs and joined by address")
        if args.json:
            args.json.write_text(json.dumps({
                "campaign": raw.name, "recordings": n_files, "megabytes": megabytes,
                "samples_per_recording": 4800 if args.raw is None else None,
                "runs": [{**asdict(r), "per_recording_core_s": r.per_recording_core_s} for r in runs],
                "overhead": [{"scheduler": s, "jobs": j, **o} for (s, j), o in overhead.items()]},
                indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
