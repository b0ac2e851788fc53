"""Peak memory of ``ofbe-session check``, ``ofbe-label`` and ``ofbe-session init`` on a 2 GB sparse
file (issue 24).

A logger that preallocates its file leaves a good log and then a tail of NUL bytes; before the
bound of :mod:`ofbe_data.io.formats.filebytes` the two commands grew to about 24 GB on such a
file. This copies a tiny example session, makes one file 2 GiB with ``truncate`` (sparse: no
disk used), runs both commands under ``/usr/bin/time -v`` and prints their peak resident
memory, wall time and exit status.

Run: ``python benchmarks/huge_file.py`` (Linux; needs /usr/bin/time).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SESSION = ROOT / "raw" / "examples" / "tiny-gravity-aligned" / "ga-pc001"


def _measure(args: list[str]) -> tuple[float, float, int]:
    done = subprocess.run(["/usr/bin/time", "-v", sys.executable, "-m", *args], capture_output=True,
                          text=True, cwd=ROOT)
    peak = float(re.search(r"Maximum resident set size \(kbytes\): (\d+)", done.stderr).group(1)) / 1024
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", done.stderr).group(1)
    seconds = sum(float(x) * 60 ** i for i, x in enumerate(reversed(wall.split(":"))))
    return peak, seconds, done.returncode


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        session = Path(tmp) / "s"
        shutil.copytree(SESSION, session)
        f = session / "rec-01" / "sparkfun-1.csv"
        data = f.stat().st_size
        os.truncate(f, 2 * 2**30)
        print(f"{f.name}: {f.stat().st_size / 1e9:.2f} GB (sparse), data in its first {data} bytes")
        loose = Path(tmp) / "loose"  # the file alone, as ofbe-session init finds it
        loose.mkdir()
        os.link(f, loose / f.name)
        for name, args in (("ofbe-session check", ["ofbe_data.cli.session", "check", str(session)]),
                           ("ofbe-label", ["ofbe_data.cli.label", str(session), "--out", str(Path(tmp) / "l"),
                                           "--quiet"]),
                           ("ofbe-session init", ["ofbe_data.cli.session", "init", str(loose)])):
            peak, seconds, code = _measure(args)
            print(f"{name:<20} peak {peak:7.1f} MB   {seconds:6.2f} s   exit {code}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
