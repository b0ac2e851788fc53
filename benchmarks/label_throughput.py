"""Time labelling both paper-size campaigns against a bare pyarrow CSV parse of the same files.

Usage: python benchmarks/label_throughput.py [--raw DIR] [--jobs N [N ...]] [--repeat N]
                                             [--profile] [--profile-campaign NAME] [--breakdown]

Simulates the gravity-aligned and rotated campaigns into a temporary folder (or uses
``DIR/gravity-aligned`` and ``DIR/rotated`` from ``--raw``), then measures:

- labelling both campaigns end to end (``label_sessions``: read, label, campaign fit,
  write the products) for each ``--jobs`` setting, best of ``--repeat`` runs;
- a bare parse of every data file every manifest names, single process, best of ``--repeat``
  runs like the labelling: read the bytes,
  mask bytes >= 0x80 (pyarrow decodes a malformed row as UTF-8 before its invalid-row
  handler sees it, and the simulated serial link writes such bytes), and
  ``pyarrow.csv.read_csv`` with the preamble skipped (boot and ``#`` lines of ofbe-logger
  files, the 5 lines before the column line of mscip-csv files), quoting off, malformed rows
  skipped, pyarrow's own type inference, no threads. The column line is found by a byte
  search outside the timed part.

Prints files, MB, samples, the times, samples/s and the ratio labelling / bare parse (the
issue's target is a ratio of at most 2 for one process). With ``--profile`` it also runs
cProfile over labelling one campaign in one process and prints the top 25 functions by
cumulative and by own time. With ``--breakdown`` it labels both campaigns once more in one
process with a CPU-time clock around the steps of labelling (pyarrow's CSV parse, the rest
of the readers, hashing, the manifest, tap signals and synchronisation, the static detector,
the convergence index, the checks, writing the products) and prints each step's inclusive
CPU seconds against the bare parse's: CPU time, because other processes on a shared machine
inflate wall-clock steps unevenly. Nothing is asserted: this is a measurement.
"""

from __future__ import annotations

import argparse
import cProfile
import functools
import importlib
import pstats
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from ofbe_data.io.manifest import load_manifest
from ofbe_data.labelling.batch import Outcome, expand_sessions, label_sessions
from ofbe_data.labelling.labels import LabelParams
from ofbe_data.simulator import simulate_campaign

CAMPAIGNS = ("gravity-aligned", "rotated")
TARGET_RATIO = 2.0
COLUMN_LINES = {"ofbe-logger": b"t_us,", "mscip-csv": b"Time (s),"}
FIRST_COLUMN = {"ofbe-logger": "t_us", "mscip-csv": "Time (s)"}
_MASK_NON_ASCII = bytes(range(128)) + b"?" * 128


@dataclass(frozen=True)
class DataFile:
    """One device file named by a manifest, with where its column line is."""

    path: Path
    format: str
    skip_rows: int
    size: int


def _count_lines(data: bytes) -> int:
    """Lines in ``data`` as pyarrow splits them (\\n, \\r\\n and lone \\r)."""
    return data.count(b"\n") + data.count(b"\r") - data.count(b"\r\n")


def _column_line_index(path: Path, fmt: str, skip_rows: int | None) -> int:
    """Number of lines before the column-name line (found by a byte search)."""
    if skip_rows is not None:  # generic csv: the manifest says how many
        return skip_rows
    data = path.read_bytes()
    marker = COLUMN_LINES[fmt]
    pos = data.find(marker)
    while pos > 0 and data[pos - 1 : pos] not in (b"\n", b"\r"):  # must start a line
        pos = data.find(marker, pos + 1)
    if pos < 0:
        raise SystemExit(f"{path}: no line starting with {marker!r}")
    return _count_lines(data[:pos])


def data_files(folders: Sequence[Path]) -> list[DataFile]:
    """Every device file of every recording of the given sessions, in manifest order."""
    out: list[DataFile] = []
    for folder in folders:
        m = load_manifest(folder)
        for rec in m.recordings:
            for dev_id in rec.files:
                dev = m.devices[dev_id]
                path = m.file_path(rec, dev_id)
                skip = dev.csv.skip_rows if dev.format == "csv" and dev.csv is not None else None
                out.append(DataFile(path, dev.format, _column_line_index(path, dev.format, skip),
                                    path.stat().st_size))
    return out


@dataclass
class ParseResult:
    """Bare-parse totals."""

    seconds: float
    read_mask_s: float
    rows: int
    non_numeric_files: int


def best_bare_parse(files: Sequence[DataFile], repeat: int) -> ParseResult:
    """The fastest of ``repeat`` :func:`bare_parse` runs (compared with the best labelling run)."""
    return min((bare_parse(files) for _ in range(max(1, repeat))), key=lambda r: r.seconds)


def bare_parse(files: Sequence[DataFile]) -> ParseResult:
    """Parse every file with pyarrow alone (see the module docstring); single process."""
    rows = non_numeric = 0
    read_mask_s = 0.0
    start = time.perf_counter()
    for f in files:
        t0 = time.perf_counter()
        data = f.path.read_bytes().translate(_MASK_NON_ASCII)
        read_mask_s += time.perf_counter() - t0
        table = pacsv.read_csv(
            pa.BufferReader(data),
            # one block per file, so type inference sees the whole column
            read_options=pacsv.ReadOptions(use_threads=False, skip_rows=f.skip_rows,
                                           block_size=max(1 << 20, f.size + 1)),
            parse_options=pacsv.ParseOptions(quote_char=False, invalid_row_handler=lambda _: "skip"),
        )
        if table.column_names[0] != FIRST_COLUMN.get(f.format, table.column_names[0]):
            raise SystemExit(f"{f.path}: skip_rows={f.skip_rows} lands on {table.column_names!r}")
        rows += table.num_rows
        if not all(pa.types.is_integer(t) or pa.types.is_floating(t) for t in table.schema.types):
            non_numeric += 1
    return ParseResult(time.perf_counter() - start, read_mask_s, rows, non_numeric)


def time_labelling(folders: Sequence[Path], jobs: int, repeat: int, scratch: Path
                   ) -> tuple[float, list[Outcome]]:
    """Best wall-clock seconds of ``repeat`` end-to-end labelling runs, and the last outcomes."""
    best = float("inf")
    outcomes: list[Outcome] = []
    for i in range(repeat):
        out_dir = scratch / f"labels-j{jobs}-r{i}"
        start = time.perf_counter()
        outcomes = label_sessions(folders, LabelParams(), out_dir, jobs=jobs, progress=False)
        best = min(best, time.perf_counter() - start)
    return best, outcomes


def profile_labelling(folders: Sequence[Path], out_dir: Path, top: int = 25) -> None:
    """cProfile over labelling ``folders`` in one process; print the top functions."""
    prof = cProfile.Profile()
    prof.enable()
    label_sessions(folders, LabelParams(), out_dir, jobs=1, progress=False)
    prof.disable()
    stats = pstats.Stats(prof).strip_dirs()
    for key in ("cumulative", "tottime"):
        print(f"\n--- top {top} by {key} ---")
        stats.sort_stats(key).print_stats(top)


#: The steps --breakdown times: (label, module, function). Nested steps are inclusive (the
#: readers include the parse; synchronisation includes the DUT's tap signals).
BREAKDOWN_STEPS: tuple[tuple[str, str, str], ...] = (
    ("label_session (all per-session work)", "ofbe_data.labelling.labels", "label_session"),
    ("  read_device_file (readers)", "ofbe_data.io.formats", "read_device_file"),
    ("    pyarrow.csv.read_csv (the parse)", "pyarrow.csv", "read_csv"),
    ("    _clean_times", "ofbe_data.io.formats.common", "_clean_times"),
    ("    read_file_bytes (read + SHA-256)", "ofbe_data.io.formats.filebytes", "read_file_bytes"),
    ("  sha256_file (session.yaml only)", "ofbe_data.labelling.labels", "sha256_file"),
    ("load_manifest (once per session)", "ofbe_data.io.manifest", "load_manifest"),
    ("  tap_signals (high-pass, envelope, taps)", "ofbe_data.labelling.sync", "tap_signals"),
    ("  synchronise (incl. the DUT's tap signals)", "ofbe_data.labelling.sync", "synchronise"),
    ("    _lag_at (cross-correlation)", "ofbe_data.labelling.sync", "_lag_at"),
    ("  check_static (static detector)", "ofbe_data.labelling.stationarity", "check_static"),
    ("  convergence_index", "ofbe_data.labelling.convergence", "convergence_index"),
    ("  rate_step (checks)", "ofbe_data.labelling.checks", "rate_step"),
    ("  clipped_samples (checks)", "ofbe_data.labelling.checks", "clipped_samples"),
    ("  typical_norm_problem (median norm, checks)", "ofbe_data.labelling.checks", "typical_norm_problem"),
    ("write_session (Parquet + JSON)", "ofbe_data.labelling.store", "write_session"),
    ("fit_campaign", "ofbe_data.labelling.store", "fit_campaign"),
)


@contextmanager
def _timed_steps(steps: Sequence[tuple[str, str, str]]) -> Iterator[dict[str, list[float]]]:
    """Wrap each step's function (in its module and wherever it was imported by name) with
    a CPU-time clock; yield label → [seconds, calls]; restore everything after."""
    totals: dict[str, list[float]] = {label: [0.0, 0] for label, _, _ in steps}
    patched: list[tuple[Any, str, Any]] = []
    for label, module, name in steps:
        original = getattr(importlib.import_module(module), name)

        def timed(*args: Any, _f: Callable[..., Any] = original, _label: str = label, **kwargs: Any) -> Any:
            start = time.thread_time()
            try:
                return _f(*args, **kwargs)
            finally:
                totals[_label][0] += time.thread_time() - start
                totals[_label][1] += 1

        functools.update_wrapper(timed, original)
        for mod in list(sys.modules.values()):
            if getattr(mod, name, None) is original and (mod.__name__ or "").startswith(("ofbe", "pyarrow")):
                patched.append((mod, name, original))
                setattr(mod, name, timed)
    try:
        yield totals
    finally:
        for mod, name, original in patched:
            setattr(mod, name, original)


def breakdown(folders: Sequence[Path], out_dir: Path, files: Sequence[DataFile]) -> None:
    """Label ``folders`` in one process with a CPU clock around each step; print the steps."""
    bare = float("inf")
    for _ in range(3):  # the best of three, as noisy as the labelling run is not
        start = time.thread_time()
        bare_parse(files)
        bare = min(bare, time.thread_time() - start)
    with _timed_steps(BREAKDOWN_STEPS) as totals:
        start = time.thread_time()
        label_sessions(folders, LabelParams(), out_dir, jobs=1, progress=False)
        total = time.thread_time() - start
    print(f"\nbreakdown (CPU seconds, one process; bare parse {bare:.2f} s):")
    print(f"  {'label_sessions (everything)':48s} {total:7.2f} s  {total / bare:5.2f} x bare parse")
    for label, (seconds, calls) in totals.items():
        print(f"  {label:48s} {seconds:7.2f} s  {seconds / bare:5.2f} x  ({int(calls)} calls)")


def reader_speeds(folder: Path, n: int = 600_000) -> None:
    """Print each reader's cost per sample on the same n samples (ofbe-logger, generic csv in
    three layouts, mscip-csv, mscip-bin), written by the toolkit's own writers."""
    from ofbe_data.io.device_options import CsvMapping
    from ofbe_data.io.formats.generic_csv import read_generic_csv, write_generic_csv
    from ofbe_data.io.formats.mscip_bin import read_mscip_bin, write_mscip_bin
    from ofbe_data.io.formats.mscip_csv import read_mscip_csv, write_mscip_csv
    from ofbe_data.io.formats.ofbe_logger import read_ofbe_logger, write_ofbe_logger
    from ofbe_data.io.gravity import G0

    rng = np.random.default_rng(1)
    counts = np.rint(rng.normal([3.0, -5.0, 259.0], 1.5, size=(n, 3))).astype(np.int64)
    acc = counts / 256.0 * G0
    t = np.arange(n) / 150.0
    header = {"fw": "1.4.2", "board": "b", "chip": "ADXL345", "device": "d", "odr_hz": "150", "range_g": "16",
              "full_res": "1", "lsb_per_g": "256", "host_start_utc": "2025-03-14T10:22:31.100Z"}
    write_ofbe_logger(folder / "logger.csv", (t * 1e6).astype(np.int64), counts, header)
    g_csv = CsvMapping({"t": "t", "ax": "ax", "ay": "ay", "az": "az"}, "s", "g")
    write_generic_csv(folder / "generic.csv", t, acc, g_csv)
    (folder / "whitespace.txt").write_text("".join(f"  {i}\t{a} {b}  {c}\n" for i, (a, b, c) in
                                                   enumerate((counts + 512).tolist())))
    ws = CsvMapping({"t": 0, "ax": 1, "ay": 2, "az": 3}, "samples", "counts", 256.0, header=False,
                    delimiter="whitespace", sample_rate_hz=150.0, zero_counts=512.0)
    write_mscip_csv(folder / "mscip.csv", t, acc / G0, np.zeros((n, 3)), np.full(n, 25.0),
                    serial="3025-00417", rate_hz=150.0, start_utc="2025-03-14T10:22:31.512Z")
    write_mscip_bin(folder / "mscip.bin", t, acc, "2025-03-14T10:22:31.512Z")
    readers = [("ofbe-logger", lambda: read_ofbe_logger(folder / "logger.csv")),
               ("generic csv (named columns, s, g)", lambda: read_generic_csv(folder / "generic.csv", g_csv)),
               ("generic csv (headerless whitespace counts)",
                lambda: read_generic_csv(folder / "whitespace.txt", ws)),
               ("mscip-csv", lambda: read_mscip_csv(folder / "mscip.csv")),
               ("mscip-bin", lambda: read_mscip_bin(folder / "mscip.bin"))]
    base = None
    for name, read in readers:
        best = min(_seconds(read) for _ in range(3))
        base = base or best
        print(f"reader {name:44s}: {best / n * 1e9:7.1f} ns/sample ({best / base:.2f}× ofbe-logger)")


def _seconds(fn: Any) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--raw", type=Path, default=None,
                        help="folder holding gravity-aligned/ and rotated/ (default: simulate into a temp)")
    parser.add_argument("--jobs", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--repeat", type=int, default=1, help="best of this many runs (default: 1)")
    parser.add_argument("--profile", action="store_true", help="cProfile labelling of one campaign")
    parser.add_argument("--profile-campaign", choices=CAMPAIGNS, default="rotated")
    parser.add_argument("--breakdown", action="store_true",
                        help="CPU time of each labelling step against the bare parse's")
    parser.add_argument("--readers", action="store_true",
                        help="only each reader's cost per sample (ofbe-logger, generic csv, mscip-csv, "
                             "mscip-bin)")
    args = parser.parse_args()
    if args.readers:
        with tempfile.TemporaryDirectory(prefix="ofbe-readers-") as tmp:
            reader_speeds(Path(tmp))
        return
    with tempfile.TemporaryDirectory(prefix="ofbe-label-bench-") as tmp:
        scratch = Path(tmp)
        raw = args.raw
        if raw is None:
            raw = scratch / "raw"
            for profile in CAMPAIGNS:
                start = time.perf_counter()
                result = simulate_campaign(profile, raw / profile, jobs=2, progress=False)
                print(f"simulated {profile:16s}: {result.sessions} sessions, "
                      f"{result.bytes / 1e6:.1f} MB in {time.perf_counter() - start:.2f} s")
        campaign_dirs = [raw / c for c in CAMPAIGNS]
        folders = expand_sessions(campaign_dirs)
        files = data_files(folders)
        total_mb = sum(f.size for f in files) / 1e6

        parse = best_bare_parse(files, args.repeat)
        samples = parse.rows
        print(f"data: {len(folders)} sessions, {len(files)} files, {total_mb:.1f} MB, "
              f"{samples / 1e6:.2f} M samples (rows the bare parse kept)")
        print(f"bare pyarrow parse, 1 process: {parse.seconds:.2f} s (best of {args.repeat}) = "
              f"{samples / parse.seconds / 1e6:.2f} M samples/s, {total_mb / parse.seconds:.0f} MB/s "
              f"(read + mask {parse.read_mask_s:.2f} s; "
              f"{parse.non_numeric_files} files with a non-numeric column from garbling)")

        times: dict[int, float] = {}
        for jobs in args.jobs:
            seconds, outcomes = time_labelling(folders, jobs, args.repeat, scratch)
            times[jobs] = seconds
            labelled = [o.labels for o in outcomes if o.labels is not None]
            rows = sum(len(s.rows) for s in labelled)
            rejected = sum(len(s.rejections) for s in labelled)
            failed = sum(1 for o in outcomes if o.error)
            print(f"label both campaigns jobs={jobs}: {seconds:.2f} s (best of {args.repeat}) = "
                  f"{samples / seconds / 1e6:.2f} M samples/s, {total_mb / seconds:.0f} MB/s; "
                  f"{rows} labelled, {rejected} rejected, {failed} sessions failed")
        for jobs, seconds in times.items():
            note = f"target <= {TARGET_RATIO:.0f}" if jobs == 1 else "the target is for jobs=1"
            print(f"ratio labelling(jobs={jobs}) / bare parse (1 process): "
                  f"{seconds / parse.seconds:.2f} ({note})")
        if 1 in times:
            for jobs, seconds in times.items():
                if jobs != 1:
                    print(f"speed-up jobs={jobs} vs jobs=1: {times[1] / seconds:.2f}x")

        if args.breakdown:
            breakdown(folders, scratch / "labels-breakdown", files)

        if args.profile:
            camp = expand_sessions([raw / args.profile_campaign])
            print(f"\nprofile: labelling {args.profile_campaign} ({len(camp)} sessions), 1 process")
            profile_labelling(camp, scratch / "labels-profile")


if __name__ == "__main__":
    main()
