"""Time the simulator on both paper-size campaigns and the readers on what it wrote.

Usage: python benchmarks/simulate_speed.py [--jobs N] [--out DIR]

Prints wall-clock seconds, the ratio to the issue's 60 s budget for writing both
campaigns, and reader throughput. Nothing is asserted: this is a measurement.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from ofbe_data.io.formats import read_device_file
from ofbe_data.io.manifest import load_manifest
from ofbe_data.simulator import simulate_campaign

BUDGET_S = 60.0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--out", type=Path, default=None, help="scratch folder (default: temp)")
    args = parser.parse_args()
    scratch = args.out or Path(tempfile.mkdtemp(prefix="ofbe-bench-"))
    for jobs in args.jobs:
        total_s = total_mb = 0.0
        for profile in ("gravity-aligned", "rotated"):
            start = time.perf_counter()
            result = simulate_campaign(profile, scratch / profile, jobs=jobs, force=True,
                                       progress=False)
            elapsed = time.perf_counter() - start
            total_s += elapsed
            total_mb += result.bytes / 1e6
            print(f"simulate {profile:16s} jobs={jobs}: {elapsed:6.2f} s, {result.files} files, "
                  f"{result.bytes / 1e6:6.1f} MB, {result.bytes / 1e6 / elapsed:6.1f} MB/s")
        print(f"both paper-size campaigns, jobs={jobs}: {total_s:.2f} s "
              f"= {total_s / BUDGET_S:.3f} of the {BUDGET_S:.0f} s budget ({total_mb:.0f} MB)")
    for profile in ("gravity-aligned", "rotated"):
        samples = files = 0
        start = time.perf_counter()
        for path in sorted((scratch / profile).glob("*/session.yaml")):
            manifest = load_manifest(path)
            for rec in manifest.recordings:
                for dev_id, dev in manifest.devices.items():
                    samples += read_device_file(manifest.file_path(rec, dev_id), dev).n
                    files += 1
        elapsed = time.perf_counter() - start
        print(f"read {profile:16s}: {files} files, {samples / 1e6:.2f} M samples in "
              f"{elapsed:.2f} s = {samples / elapsed / 1e6:.2f} M samples/s, "
              f"{elapsed / files * 1e3:.1f} ms per file")


if __name__ == "__main__":
    main()
