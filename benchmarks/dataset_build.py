"""Time and peak memory of building the datasets of both paper-size campaigns.

Usage: python benchmarks/dataset_build.py [--raw DIR] [--labels DIR] [--jobs N [N ...]]

Uses ``DIR/gravity-aligned`` and ``DIR/rotated`` with their labels (``dvc repro`` writes them
to raw/ and processed/labels/). Each build runs in its own process, so its peak resident
memory (``ru_maxrss``) is its own, and is compared with:

- the size of the dataset's windows as float32 (N·T·3·4 bytes): a builder that held every
  window in memory, let alone twice, would need at least that on top of its baseline;
- the baseline of a process that imports the same libraries and reads the labels but
  writes nothing.

Also times the raw reading alone (``iter_windows`` without writing) to show what share of
the build is reading and what is compressing and writing. Prints; asserts nothing.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = r"""
import json, resource, sys, time
from pathlib import Path
from ofbe_data.dataset.build import DatasetParams, build_dataset
from ofbe_data.labelling.store import read_labels
from ofbe_data.dataset.windows import iter_windows
mode, labels, raw, out, jobs = sys.argv[1:6]
t = time.perf_counter()
n = 0
if mode == "build":
    res = build_dataset(labels, raw, out, DatasetParams(), jobs=int(jobs), progress=False)
    n = res.n_windows
elif mode == "read":
    frame = read_labels(labels)
    for _, X in iter_windows(frame, raw, DatasetParams().windows, jobs=int(jobs)):
        n += X.shape[0]
else:
    import h5py, pyarrow  # noqa: F401  the builder's libraries
    read_labels(labels)
dt = time.perf_counter() - t
print(json.dumps({"seconds": dt, "windows": n,
                  "peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}))
"""


def _run(mode: str, labels: Path, raw: Path, out: Path, jobs: int) -> dict:
    done = subprocess.run([sys.executable, "-c", CHILD, mode, str(labels), str(raw), str(out), str(jobs)],
                          check=True, capture_output=True, text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--raw", default="raw")
    ap.add_argument("--labels", default="processed/labels")
    ap.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for campaign in ("gravity-aligned", "rotated"):
            labels, raw = Path(args.labels) / campaign, Path(args.raw) / campaign
            base = _run("baseline", labels, raw, Path(tmp) / "none", 1)
            for jobs in args.jobs:
                read = _run("read", labels, raw, Path(tmp) / "none", jobs)
                out = Path(tmp) / f"{campaign}-{jobs}"
                build = _run("build", labels, raw, out, jobs)
                windows_mb = build["windows"] * 3000 * 3 * 4 / 2**20
                size_mb = sum(p.stat().st_size for p in out.iterdir()) / 2**20
                n, sec = build["windows"], build["seconds"]
                extra = build["peak_mb"] - base["peak_mb"]
                print(f"{campaign:16s} jobs {jobs}: {n} windows ({windows_mb:.0f} MiB as float32) built in "
                      f"{sec:.2f} s ({n / sec:.0f} windows/s); reading alone {read['seconds']:.2f} s "
                      f"({read['seconds'] / sec:.0%} of the build); peak RSS {build['peak_mb']:.0f} MiB "
                      f"against a {base['peak_mb']:.0f} MiB baseline: +{extra:.0f} MiB = "
                      f"{extra / windows_mb:.2f} × the windows; folder {size_mb:.1f} MiB")


if __name__ == "__main__":
    main()
