"""Time and peak memory of reading a week-long raw wearable file into GGIR's epochs.

Writes synthetic files of the three raw formats (default: 7 days at 100 Hz, 60.48 M samples;
still spells in random orientations and moving spells, a daily temperature swing):

- Axivity ``.cwa`` of valid packed ``AX`` blocks (1/256 g counts, 258 MB);
- GENEActiv ``.bin`` of 300-sample pages (12-bit counts, the header's gain and offset, 770 MB);
- ActiGraph ``.gt3x``: a deflated zip of ``info.txt`` and ``log.bin`` ``ACTIVITY`` records
  (12-bit counts at 256 per g, one record a second);

checks on a small file of each (``--check-days``) that ofbe's reader and actfast read the same
samples, then measures, each in a fresh process on one core (``OMP_NUM_THREADS=1`` …,
``taskset`` to one CPU where available, ``nice``; wall and CPU seconds both printed, as a shared
machine stretches the wall time):

- ``ofbe``: :func:`ofbe_data.freeliving.raw.read_raw_epochs` (ofbe's block readers, GGIR's
  epochs, the file's SHA-256 from the same reading) — the acceptance: ≤ 15 s and ≤ 1.5 GB peak;
- ``ofbe+ggir``: the same and :func:`~ofbe_data.freeliving.ggir.ggir_calibrate` on the epochs;
- ``ofbe+ofbe``: the same and :func:`~ofbe_data.freeliving.ofbe.ofbe_calibrate` (``--mode ofbe``,
  the default), the acceptance's "reading included";
- ``actfast``: ``actfast.read`` of the same file, which holds every sample at once.

Run: ``python benchmarks/autocal_raw.py [--days 7] [--rate 100] [--formats cwa,bin,gt3x]
[--modes ofbe,ofbe+ggir,ofbe+ofbe,actfast] [--out /tmp/ofbe-autocal-raw]``. Prints one line per
measurement: format, mode, wall and CPU seconds, peak resident memory (``ru_maxrss``), epochs.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import subprocess
import sys
import time
import zipfile
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


def write_week_bin(path: Path, days: float, rate: float, seed: int = 7) -> None:
    """The synthetic GENEActiv ``.bin`` (written in slices of 2 000 pages)."""
    from ofbe_data.freeliving.geneactiv import encode_header, encode_pages

    rng = np.random.default_rng(seed)
    per = 300
    pages = int(days * 86400 * rate) // per
    gain, offset = np.array([25875, 25734, 25538]), np.array([439, -662, -3056])
    t0 = int(np.datetime64("2024-03-04T09:00:00", "ms").astype(np.int64))
    tmp = path.with_suffix(".partial")
    with open(tmp, "wb") as fh:
        fh.write(encode_header(rate, tuple(gain), tuple(offset), pages))
        for lo in range(0, pages, 2000):
            m = min(2000, pages - lo)
            acc = _spells(rng, m * per, rate)
            counts = np.clip(np.round((acc * gain + offset) / 100.0), -2047, 2047).astype(np.int64)
            ms = t0 + np.round((lo + np.arange(m)) * per / rate * 1000).astype(np.int64)
            temp = 25.0 + 5.0 * np.sin(2 * np.pi * (ms - t0) / 86400e3)
            fh.write(encode_pages(counts.reshape(m, per, 3), ms, rate, temp, lo))
    tmp.replace(path)


def write_week_gt3x(path: Path, days: float, rate: float, seed: int = 7) -> None:
    """The synthetic ActiGraph ``.gt3x`` (``log.bin`` streamed into the zip, deflated)."""
    from ofbe_data.freeliving.actigraph import encode_activity, encode_parameters, info_text

    rng = np.random.default_rng(seed)
    r = int(rate)
    seconds = int(days * 86400)
    t0 = int(np.datetime64("2024-03-04T09:00:00", "s").astype(np.int64))
    tmp = path.with_suffix(".partial")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as z:
        with z.open("log.bin", "w", force_zip64=True) as log:
            log.write(encode_parameters(256.0, r))
            for lo in range(0, seconds, 20000):
                m = min(20000, seconds - lo)
                acc = _spells(rng, m * r, rate)
                counts = np.clip(np.round(acc * 256), -2047, 2047).astype(np.int64).reshape(m, r, 3)
                log.write(encode_activity(counts, t0 + lo + np.arange(m)))
        z.writestr("info.txt", info_text(r))
    tmp.replace(path)


WRITERS = {"cwa": write_week, "bin": write_week_bin, "gt3x": write_week_gt3x}


def check_against_actfast(path: Path) -> str:
    """ofbe's reader and actfast on one (small) file: the same samples and times, or why not."""
    import actfast

    from ofbe_data.freeliving.wearables import open_wearable, round_half_away

    w = open_wearable(path)
    chunks = list(w.chunks())
    ours = np.concatenate([c.acc_g for c in chunks], axis=1)
    t = np.concatenate([c.time_s for c in chunks])
    series = actfast.read(str(path))["timeseries"]
    high = series.get("high_frequency") or series["acceleration"]
    theirs = np.ascontiguousarray(high["acceleration"].T, dtype=np.float64)
    if path.suffix == ".gt3x":
        theirs = round_half_away(theirs, 3)
    if path.suffix == ".cwa":  # ofbe resamples .cwa as GGIRread does: compare the counts only
        return f"{path.name}: {ours.shape[1]} samples resampled (actfast: {theirs.shape[1]} raw)"
    same = ours.shape == theirs.shape and np.array_equal(ours, theirs) and np.array_equal(
        t, high["datetime"].astype(np.float64) / 1e9)
    return f"{path.name}: {ours.shape[1]} samples, {'the same as' if same else 'DIFFERENT FROM'} actfast"


def _measure(mode: str, path: Path) -> None:
    """One measurement, in this (fresh) process; the imports are done before the clocks start."""
    if mode == "actfast":
        import actfast
    else:
        from ofbe_data.freeliving.ggir import ggir_calibrate
        from ofbe_data.freeliving.raw import read_raw_epochs
        if mode == "ofbe+ofbe":
            from ofbe_data.freeliving.ofbe import ofbe_calibrate
    start = resource.getrusage(resource.RUSAGE_SELF)
    cpu0 = start.ru_utime + start.ru_stime
    t = time.perf_counter()
    if mode == "actfast":
        data = actfast.read(str(path))
        series = data["timeseries"]
        n = len((series.get("high_frequency") or series["acceleration"])["acceleration"])
        detail = f"{n} samples"
    else:
        raw = read_raw_epochs(path)
        detail = f"{raw.n_samples} samples, {raw.n_epochs} epochs"
        if mode == "ofbe+ggir":
            result = ggir_calibrate(raw.epochs)
            detail += f", {result.n_still} still; qc: {result.qc[:40]}"
        elif mode == "ofbe+ofbe":
            fit = ofbe_calibrate(raw.epochs)
            detail += f", {fit.n_still} still, {fit.model}; qc: {fit.qc[:40]}"
    seconds = time.perf_counter() - t
    usage = resource.getrusage(resource.RUSAGE_SELF)
    cpu = usage.ru_utime + usage.ru_stime - cpu0
    peak = usage.ru_maxrss / 1024
    print(f"{path.suffix[1:]:<5} {mode:<10} wall {seconds:7.2f} s   cpu {cpu:7.2f} s   peak {peak:7.1f} MB   "
          f"{detail}", flush=True)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--days", type=float, default=7.0)
    p.add_argument("--rate", type=float, default=100.0)
    p.add_argument("--out", type=Path, default=Path("/tmp/ofbe-autocal-raw"))
    p.add_argument("--measure", choices=("ofbe", "ofbe+ggir", "ofbe+ofbe", "actfast"), help=argparse.SUPPRESS)
    p.add_argument("--path", type=Path, help=argparse.SUPPRESS)
    p.add_argument("--formats", default="cwa,bin,gt3x")
    p.add_argument("--modes", default="ofbe,ofbe+ggir,ofbe+ofbe,actfast")
    p.add_argument("--check-days", type=float, default=0.01,
                   help="length of the small files checked against actfast first (0: no check)")
    p.add_argument("--cpu", default="0", help="CPU to pin each measurement to ('' for none)")
    args = p.parse_args(argv)
    if args.measure:
        _measure(args.measure, args.path)
        return 0
    args.out.mkdir(parents=True, exist_ok=True)
    env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    pin = ["taskset", "-c", args.cpu] if shutil.which("taskset") and args.cpu else []
    for fmt in args.formats.split(","):
        if args.check_days > 0:
            small = args.out / f"check-{args.check_days:g}d-{args.rate:g}hz.{fmt}"
            if not small.exists():
                WRITERS[fmt](small, args.check_days, args.rate)
            print(check_against_actfast(small), flush=True)
        path = args.out / f"synthetic-{args.days:g}d-{args.rate:g}hz.{fmt}"
        if not path.exists():
            t = time.perf_counter()
            WRITERS[fmt](path, args.days, args.rate)
            mb = path.stat().st_size / 1e6
            print(f"wrote {path} ({mb:.0f} MB) in {time.perf_counter() - t:.0f} s", flush=True)
        for mode in args.modes.split(","):
            cmd = [*pin, "nice", "-n", "10", sys.executable, __file__, "--measure", mode, "--path", str(path)]
            done = subprocess.run(cmd, env=env)
            if done.returncode:
                print(f"{fmt} {mode}: exit status {done.returncode}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
