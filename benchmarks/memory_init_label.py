"""Peak memory and wall time of ``ofbe-session init``, ``ofbe-session check`` and ``ofbe-label`` on
large generic csv files (issue 36: memory bounded by the file's size; issue 33: ``check`` on a
20-hour 30 Hz file).

Two files are written in a temporary folder, each as a session folder of its own:

- ``big``: a ~300 MiB continuous multi-position recording as a bench logger writes it (a time
  column in s with 4 decimals, three axes in g with 5 decimals, a temperature in °C with 2
  decimals; 100 Hz, ~20 h: still poses of 15–25 min at random orientations, 20 s of handling
  between them, the temperature drifting with the lab's day);
- ``actigraph``: a 20.7-hour 30 Hz wrist export (ActiGraph-like: a 10-line banner, a column line,
  three axes in g with 3 decimals, no time column; ~2.2 M rows): a night of long still stretches
  between turns, a day of short rests between gestures and walks (thousands of still periods).

Each file gets ``ofbe-session init --kind multi-position`` (the banner's rate is given with
``--rate`` for the wearable file), ``ofbe-session check`` and ``ofbe-label`` as subprocesses; the
script prints each command's peak resident memory (the child's own ``ru_maxrss`` from
``os.wait4``), wall time, exit status, and the peak as a multiple of the file's size.

Run: ``python benchmarks/memory_init_label.py [--mib 300] [--hours 20.7] [--only big|actigraph]
[--source DIR]`` (Linux). ``--source`` runs the packages of another tree on the same files, e.g. an
older commit exported with ``git archive <commit> ofbe_data ofbe_model | tar -x -C DIR``, for a
before/after comparison. Nothing is asserted: this is a measurement.

Measured on a 2-core AMD EPYC shared with other jobs (MiB, s; before: the commit before issue 36's
bounds, after: with them; 300.3 MiB, 7.47 M rows; 41.8 MiB, 2.24 M rows):

============================  ================  ===============
command                       before            after
============================  ================  ===============
big: init                     7077 MiB, 39.8 s  1016 MiB, 16.5 s
big: check                    6642 MiB, 45.2 s  1361 MiB, 19.8 s
big: label                    5677 MiB, 33.9 s  1010 MiB, 14.3 s
actigraph: init               1319 MiB,  9.7 s   421 MiB,  9.1 s
actigraph: check (1949 poses) 1273 MiB, 66.4 s   744 MiB, 16.7 s
actigraph: label              1021 MiB, 74.7 s   623 MiB, 13.1 s
============================  ================  ===============
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

ROOT = Path(__file__).resolve().parents[1]
CHUNK = 1_000_000
"""Rows generated and written at a time (the generator's own memory stays small)."""


@dataclass(frozen=True)
class Run:
    """One command's measurement: peak resident memory (MiB), wall time (s), exit status."""

    peak_mib: float
    seconds: float
    code: int
    tail: str


def measure(args: list[str], source: Path = ROOT) -> Run:
    """Run ``python -m args`` with the ofbe packages of ``source`` and measure the child alone
    (``os.wait4``)."""
    env = dict(os.environ, PYTHONPATH=str(source))
    with tempfile.TemporaryFile() as out:
        t0 = time.perf_counter()
        proc = subprocess.Popen([sys.executable, "-m", *args], cwd=source, stdout=out,
                                stderr=subprocess.STDOUT, env=env)
        _, status, usage = os.wait4(proc.pid, 0)
        seconds = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        tail = out.read().decode("utf-8", errors="replace").strip().splitlines()[-3:]
    return Run(usage.ru_maxrss / 1024.0, seconds, proc.returncode, " | ".join(tail)[-300:])


# --------------------------------------------------------------------------- synthetic files


def _unit_vectors(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _segments(rng: np.random.Generator, rows: int, fs: float, still_s: tuple[float, float],
              move_s: float) -> Iterator[tuple[int, int, np.ndarray, np.ndarray]]:
    """(start row, end row, direction at start, at end) of alternating still and moving stretches."""
    row = 0
    here = _unit_vectors(rng, 1)[0]
    while row < rows:
        n = int(rng.uniform(*still_s) * fs)
        yield row, min(rows, row + n), here, here
        row += n
        there = _unit_vectors(rng, 1)[0]
        n = int(move_s * fs)
        if row < rows:
            yield row, min(rows, row + n), here, there
        row += n
        here = there


def _gravity_g(rng: np.random.Generator, rows: int, fs: float, still_s: tuple[float, float],
               move_s: float) -> np.ndarray:
    """(rows, 3) specific force in g of still stretches joined by handling (a turn with jolts)."""
    out = np.empty((rows, 3), dtype=np.float64)
    for a, b, u, v in _segments(rng, rows, fs, still_s, move_s):
        if np.array_equal(u, v):
            out[a:b] = u
            continue
        s = np.linspace(0.0, 1.0, b - a)[:, None]
        d = (1.0 - s) * u + s * v
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        out[a:b] = d + 0.15 * rng.normal(size=(b - a, 3)) * np.sin(np.pi * s)
    return out


def _write_rows(fh, columns: list[pa.Array]) -> None:
    table = pa.table(columns, names=[f"c{i}" for i in range(len(columns))])
    pacsv.write_csv(table, fh, pacsv.WriteOptions(include_header=False, quoting_style="none"))


def _fixed(values: np.ndarray, decimals: int) -> pa.Array:
    from ofbe_data.io.formats.writing import fixed_point
    return fixed_point(values, decimals)


def write_bench_file(path: Path, mib: float, seed: int = 36) -> int:
    """A continuous multi-position 100 Hz recording of about ``mib`` MiB; returns its rows."""
    rng = np.random.default_rng(seed)
    fs = 100.0
    rows = int(mib * 2**20 / 42.1)  # ~42.1 bytes a line
    acc = _gravity_g(rng, rows, fs, (900.0, 1500.0), 20.0)
    offset = np.array([0.012, -0.008, 0.021])
    with open(path, "wb") as fh:
        fh.write(b"Time (s),AccX (g),AccY (g),AccZ (g),Temperature (C)\n")
        for a in range(0, rows, CHUNK):
            b = min(rows, a + CHUNK)
            i = np.arange(a, b)
            t = i / fs
            temp = 24.0 + 3.0 * np.sin(2 * np.pi * t / 86400.0) + 0.02 * rng.normal(size=b - a)
            x = acc[a:b] * 1.002 + offset + 3e-4 * rng.normal(size=(b - a, 3))
            _write_rows(fh, [_fixed(t, 4), *(_fixed(x[:, k], 5) for k in range(3)), _fixed(temp, 2)])
    return rows


ACTIGRAPH_BANNER = (
    "------------ Data File Created By ActiGraph GT3X+ ActiLife v6.13.4 Firmware v3.2.1 date format "
    "M/d/yyyy at 30 Hz  Filter Normal -----------\n"
    "Serial Number: MOS2E22180349\nStart Time 10:00:00\nStart Date 3/14/2023\n"
    "Epoch Period (hh:mm:ss) 00:00:00\nDownload Time 07:02:11\nDownload Date 3/15/2023\n"
    "Current Memory Address: 0\nCurrent Battery Voltage: 4.12     Mode = 12\n"
    "--------------------------------------------------\n"
    "Accelerometer X,Accelerometer Y,Accelerometer Z\n")


def _wrist_g(rng: np.random.Generator, rows: int, fs: float, start_h: float) -> np.ndarray:
    """(rows, 3) specific force in g of a wrist over a day: at night long still stretches (10–60 min)
    between turns in bed, by day short rests (a lognormal around 8 s, a few minutes at most) between
    gestures and walks (1.8 Hz steps of ±0.4 g)."""
    out = np.empty((rows, 3), dtype=np.float64)
    here = _unit_vectors(rng, 1)[0]
    row = 0
    while row < rows:
        hour = (start_h + row / fs / 3600.0) % 24.0
        night = hour >= 23.0 or hour < 7.0
        still = rng.lognormal(np.log(1800.0), 0.5) if night else min(rng.lognormal(np.log(8.0), 1.2), 600.0)
        n = max(1, int(still * fs))
        out[row:row + n] = here
        row += n
        there = _unit_vectors(rng, 1)[0]
        n = int((rng.uniform(2.0, 10.0) if night else rng.lognormal(np.log(5.0), 0.8)) * fs) + 2
        s = np.linspace(0.0, 1.0, n)[:, None]
        d = (1.0 - s) * here + s * there
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        t = np.arange(n)[:, None] / fs
        walk = not night and rng.random() < 0.3
        swing = 0.4 * np.sin(2 * np.pi * 1.8 * t) * _unit_vectors(rng, 1) if walk else 0.0
        out[row:row + n] = (d + swing + 0.08 * rng.normal(size=(n, 3)) * np.sin(np.pi * s))[:rows - row]
        row += n
        here = there
    return out


def write_actigraph_file(path: Path, hours: float, seed: int = 33) -> int:
    """A 30 Hz wrist export of ``hours`` hours from 10:00 (3 decimals in g, no time column); returns rows."""
    rng = np.random.default_rng(seed)
    fs = 30.0
    rows = int(hours * 3600 * fs)
    acc = _wrist_g(rng, rows, fs, 10.0)
    with open(path, "wb") as fh:
        fh.write(ACTIGRAPH_BANNER.encode())
        for a in range(0, rows, CHUNK):
            b = min(rows, a + CHUNK)
            x = acc[a:b] + np.array([0.004, -0.011, 0.007]) + 1.5e-3 * rng.normal(size=(b - a, 3))
            _write_rows(fh, [_fixed(x[:, k], 3) for k in range(3)])
    return rows


# --------------------------------------------------------------------------- the runs


def bench(name: str, folder: Path, init_extra: list[str], labels: Path, source: Path) -> None:
    """init, check and label one session folder with the packages of ``source``; one line each."""
    size = sum(f.stat().st_size for f in folder.iterdir())
    runs = (("init", ["ofbe_data.cli.session", "init", str(folder), "--kind", "multi-position", *init_extra]),
            ("check", ["ofbe_data.cli.session", "check", str(folder)]),
            ("label", ["ofbe_data.cli.label", str(folder), "--out", str(labels), "--quiet"]))
    for cmd, args in runs:
        r = measure(args, source)
        print(f"{name:<10} {cmd:<6} peak {r.peak_mib:8.1f} MiB ({r.peak_mib * 2**20 / size:4.2f}× the file)  "
              f"{r.seconds:8.1f} s  exit {r.code}   {r.tail}", flush=True)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--mib", type=float, default=300.0, help="size of the bench file, MiB")
    p.add_argument("--hours", type=float, default=20.7, help="length of the wearable file, h")
    p.add_argument("--only", choices=("big", "actigraph"), help="one of the two files")
    p.add_argument("--source", type=Path, default=ROOT, help="folder holding the ofbe packages to run "
                   "(default: this repository; e.g. an export of an older commit, to compare)")
    args = p.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        camp = Path(tmp) / "bench"
        if args.only in (None, "big"):
            big = camp / "big"
            big.mkdir(parents=True)
            rows = write_bench_file(big / "logger.csv", args.mib)
            size = (big / "logger.csv").stat().st_size
            print(f"big: {size / 2**20:.1f} MiB, {rows} rows at 100 Hz ({rows / 360000:.1f} h)", flush=True)
            bench("big", big, [], Path(tmp) / "labels", args.source)
        if args.only in (None, "actigraph"):
            wear = camp / "actigraph"
            wear.mkdir(parents=True)
            rows = write_actigraph_file(wear / "wrist.csv", args.hours)
            size = (wear / "wrist.csv").stat().st_size
            print(f"actigraph: {size / 2**20:.1f} MiB, {rows} rows at 30 Hz ({rows / 108000:.1f} h)",
                  flush=True)
            bench("actigraph", wear, ["--rate", "30"], Path(tmp) / "labels", args.source)
    return 0


if __name__ == "__main__":
    sys.exit(main())
