"""``ofbe-autocal``: calibrate wearable recordings from their own still periods.

Reads raw wearable files (Axivity ``.cwa``, GENEActiv ``.bin``, ActiGraph ``.gt3x``, each in blocks;
a csv of samples that ofbe's generic reader understands), summarised
into GGIR's 10-s epochs as it does (:func:`ofbe_data.freeliving.raw.read_raw_epochs`), and
*epoch* csv files (GGIR's ``spheredata`` layout, :mod:`ofbe_data.freeliving.epochs`; a csv whose
header names ``meanx``, ``meany``, ``meanz``). Calibrates them by ofbe's calibration ladder
(``--mode ofbe``, the default: :func:`ofbe_data.freeliving.ofbe.ofbe_calibrate`) or as GGIR's
``g.calibrate`` does (``--mode ggir``: :func:`ofbe_data.freeliving.ggir.ggir_calibrate`).

Writes ``DIR/summary.csv`` and ``DIR/summary.parquet`` (one row per file read, in the order
named, a folder's ``.csv`` files sorted by name) and ``DIR/<file stem>.epochs.parquet`` per
file (its still epochs), the same bytes for the same inputs
(:mod:`ofbe_data.freeliving.summary`). A recording that cannot be calibrated is a row with its
QC message and identity coefficients, not a failure.

``--jobs`` / ``--scheduler`` calibrate files at once (ofbe's process pool or Dask); the outputs
are the same bytes whatever the choice, written in the order the files were named.

``--params FILE`` reads the settings from a YAML file's ``autocal:`` section
(:mod:`ofbe_data.freeliving.params`; flags given on the command line override it); the settings
used are written to ``DIR/autocal.params.yaml``, which ``--params`` reads back to repeat the run.
``--plots`` draws ``DIR/<file stem>.calibration.png`` per file in the worker that calibrated it
(:mod:`ofbe_data.freeliving.plots`); a file with no still epoch gets a note instead.

Exit status: 0 when every file was read; 1 when a file could not be read (one line per such
file, naming it, the line and the reason; the other files are still calibrated and the summary
written); 2 on a usage error (an unknown mode, a path that does not exist, a bad value, two
inputs whose epochs files would have one name, a parameter file that is refused).
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.checksums import file_sha256
from ofbe_data.core.cli import EXIT_DATA, add_jobs, add_scheduler, command, fail, io_failure, with_examples
from ofbe_data.core.errors import OfbeError
from ofbe_data.core.parallel import iter_ordered
from ofbe_data.core.scheduler import SchedulerError, TaskError
from ofbe_data.freeliving.ggir import GgirSettings

if TYPE_CHECKING:
    from ofbe_data.freeliving.epochs import EpochTable
    from ofbe_data.freeliving.ofbe import OfbeSettings
    from ofbe_data.freeliving.raw import RawEpochs
    from ofbe_data.io.detection import Hints

PROG = "ofbe-autocal"
SUMMARY_NAME = "summary.csv"
SUMMARY_PARQUET = "summary.parquet"
EPOCHS_SUFFIX = ".epochs.parquet"
FIGURE_SUFFIX = ".calibration.png"
"""``--plots``: ``<file stem>`` + this (:mod:`ofbe_data.freeliving.plots`)."""
EPOCH_SUFFIX = ".csv"
"""Epoch csv files, or csv files of samples."""
RAW_SUFFIXES = (".cwa", ".bin", ".gt3x")
"""Raw wearable formats (Axivity, GENEActiv, ActiGraph)."""

__all__ = ["PROG", "calibrate_file", "epochs_name", "expand_inputs", "main"]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Calibrate wearable recordings from their own still periods. Reads Axivity .cwa, "
                    "GENEActiv .bin and ActiGraph .gt3x files, csv files of samples, and epoch csv "
                    "files (columns meanx, meany, "
                    "meanz, sdx, sdy, sdz in g, optional temperature in °C: GGIR's spheredata layout). "
                    "Writes <out>/summary.csv, <out>/summary.parquet, <out>/<file>.epochs.parquet and "
                    "<out>/autocal.params.yaml (the settings used).")
    p.add_argument("paths", nargs="+", metavar="FILE_OR_FOLDER",
                   help="recordings, or folders whose .cwa, .bin, .gt3x and .csv files are read")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (made if missing)")
    p.add_argument("--mode", choices=("ofbe", "ggir"),
                   help="ofbe (the default): ofbe's calibration ladder (offset, scale-offset, full, "
                        "+temperature) with robust weights and standard errors; ggir: GGIR's "
                        "g.calibrate, reproduced")
    p.add_argument("--epoch-s", type=float,
                   help=f"length of one epoch, s, for the hours of data (default: {GgirSettings.epoch_s}, "
                        "GGIR's)")
    p.add_argument("--still-sd-g", type=float,
                   help="an epoch is still when its standard deviation is below this on every axis, g "
                        f"(default: {GgirSettings.still_sd_g}, GGIR's)")
    p.add_argument("--sphere-check", action=argparse.BooleanOptionalAction, default=None,
                   help="--no-sphere-check fits even when the still epochs do not cover the sphere (ggir: "
                        "beyond ±0.3 g on every axis; ofbe: within 45° of every signed axis); default: check")
    p.add_argument("--params", metavar="FILE",
                   help="YAML file whose 'autocal:' section sets these and every other setting (model, "
                        "coverage, idle epochs, GGIR's thresholds: docs/free-living.md); flags given here "
                        "override it")
    p.add_argument("--plots", action="store_true",
                   help="draw <out>/<file>.calibration.png per file: still epochs on the sphere and their "
                        "norm error against temperature, before and after")
    p.add_argument("--rate", type=float, metavar="HZ",
                   help="csv files of samples: the sample rate, where the file has no time column it reads")
    p.add_argument("--unit", choices=("g", "mg", "m/s2"),
                   help="csv files of samples: the acceleration unit, where the file does not say it")
    add_jobs(p, "worker processes (files calibrated at once)")
    add_scheduler(p)
    p.add_argument("--quiet", action="store_true", help="no summary line")
    return with_examples(
        p, "ofbe-autocal mine/epochs/ --out mine/autocal           # every .csv of a folder, ofbe's ladder",
        "ofbe-autocal wrist.cwa --out mine/autocal --mode ggir       # GGIR's g.calibrate, reproduced",
        "ofbe-autocal spheredata.csv --out mine/autocal             # epochs you already have",
        "ofbe-autocal study/ --out mine/autocal --params examples/autocal.yaml --plots   # settings, figures",
        "ofbe-autocal study/ --out mine/autocal --jobs 8 --scheduler dask   # thousands of files")


def expand_inputs(paths: Sequence[str], out: Path) -> list[Path]:
    """The files named, each folder replaced by its recordings sorted by name (those under
    ``out`` left out), each file once, in the order named.

    Raises
    ------
    FileNotFoundError
        A path does not exist.
    ValueError
        Two files would write one epochs file (:func:`epochs_name`).
    """
    files: list[Path] = []
    out = out.resolve()
    for name in paths:
        path = Path(name)
        if path.is_dir():
            found = sorted(p for p in path.iterdir()
                           if p.suffix.lower() in (EPOCH_SUFFIX, *RAW_SUFFIXES) and p.is_file()
                           and out not in p.resolve().parents)
            files += found
        elif path.exists():
            files.append(path)
        else:
            raise FileNotFoundError(f"{name}: no such file or folder")
    seen: set[Path] = set()
    unique = []
    names: dict[str, Path] = {}
    for f in files:
        if f.resolve() not in seen:
            seen.add(f.resolve())
            unique.append(f)
            other = names.setdefault(epochs_name(f), f)
            if other is not f:
                raise ValueError(f"{other} and {f}: expected inputs with different names (both would write "
                                 f"{epochs_name(f)}), found the same")
    return unique


def epochs_name(path: Path) -> str:
    """``<file stem>.epochs.parquet``: the name of a file's epochs in the output folder."""
    return path.stem + EPOCHS_SUFFIX


def read_epochs(path: Path, settings: GgirSettings | OfbeSettings, hints: Hints | None = None
                ) -> tuple[EpochTable, RawEpochs | None]:
    """A recording's epochs, and what its raw file tells (None for an epoch csv); ``hints``
    settle what a csv of samples does not say itself (its rate, its unit).

    Raises
    ------
    OfbeError
        The file is none of the formats read, or its reader refuses it (the message names the
        file, and the line or byte offset where there is one).
    OSError
        The file cannot be read.
    """
    from ofbe_data.freeliving.epochs import is_epoch_csv, parse_epoch_csv
    from ofbe_data.freeliving.raw import read_raw_epochs

    if path.suffix.lower() == EPOCH_SUFFIX and is_epoch_csv(path):
        return parse_epoch_csv(path.read_bytes(), path), None
    raw = read_raw_epochs(path, settings.epoch_s, ggir_whole_hours=isinstance(settings, GgirSettings),
                          csv_hints=hints)
    return raw.epochs, raw


def calibrate_file(path: Path, settings: GgirSettings | OfbeSettings, hints: Hints | None = None
                   ) -> tuple[dict[str, object], bytes, RawEpochs | None]:
    """Read and calibrate one recording: its summary row, the bytes of its epochs file, and
    what its raw file tells (None for an epoch csv).

    ``settings`` chooses the mode (:class:`GgirSettings`: GGIR's; :class:`OfbeSettings`: ofbe's).

    Raises
    ------
    OfbeError
        The file cannot be read as a recording (:func:`read_epochs`).
    OSError
        The file cannot be read.
    """
    from ofbe_data.freeliving.ggir import ggir_calibrate
    from ofbe_data.freeliving.ofbe import ofbe_calibrate
    from ofbe_data.freeliving.summary import epochs_table, parquet_bytes, summary_row

    epochs, raw = read_epochs(path, settings, hints)
    result = (ggir_calibrate(epochs, settings) if isinstance(settings, GgirSettings)
              else ofbe_calibrate(epochs, settings))
    start = None if raw is None or raw.start_utc is None else datetime.fromisoformat(raw.start_utc)
    if start is not None and start.tzinfo is None:
        start = start.replace(tzinfo=UTC)
    sha = raw.sha256 if raw is not None and raw.sha256 else file_sha256(path)  # raw: hashed as it was read
    row = summary_row(str(path), sha, result, device=None if raw is None else raw.device,
                      start_utc=None if start is None else start.astimezone(UTC))
    return row, parquet_bytes(epochs_table(epochs, result)), raw


def _read_notes(path: Path, raw: RawEpochs | None) -> list[str]:
    """What reading a raw file skipped or filled in, one line each (bad blocks named)."""
    if raw is None:
        return []
    notes = []
    if raw.bad_blocks:
        named = ", ".join(f"{b.index} (byte {b.byte_offset}, {b.reason})" for b in raw.bad_blocks[:10])
        more = f" and {len(raw.bad_blocks) - 10} more" if len(raw.bad_blocks) > 10 else ""
        done = "skipped and filled in as GGIR does" if raw.format == "Axivity CWA" else "named"
        notes.append(f"{path}: {len(raw.bad_blocks)} bad data block(s) {done}: {named}{more}")
    if raw.idle_sleep.epochs:
        notes.append(f"{path}: {raw.idle_sleep.epochs} epoch(s) of identical samples (idle sleep or a "
                     "stopped sensor), left out of ofbe's fit")
    return notes


def _task(args: tuple[Path, GgirSettings | OfbeSettings, Hints, bool]
          ) -> tuple[dict[str, object], bytes, list[str], bytes | None] | str:
    """One file in a worker: its row, epochs bytes, notes and figure (None without ``--plots``
    or still epochs), or the one line saying why it could not be read (the same line whatever
    the scheduler)."""
    path, settings, hints, plots = args
    try:
        row, epochs, raw = calibrate_file(path, settings, hints)
    except OfbeError as exc:
        return str(exc)
    except OSError as exc:
        return f"{path}: {exc.strerror or exc}"
    notes = _read_notes(path, raw)
    png = None
    if plots:
        logging.getLogger("matplotlib").setLevel(logging.ERROR)  # no font-cache notice on the terminal
        from ofbe_data.freeliving.plots import calibration_png

        png = calibration_png(row, epochs)
        if png is None:
            notes.append(f"{path}: no figure: no still epochs to draw")
    return row, epochs, notes, png


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ofbe-autocal``: 0 every file read, 1 a file could not be read, 2 usage."""
    return _run(_parser().parse_args(argv))


def _run(args: argparse.Namespace) -> int:
    """``ofbe-autocal`` on its parsed arguments; the calibration's modules are imported here,
    after parsing (docs/architecture.md, "Command lines"), and by each worker in
    :func:`calibrate_file`."""
    from ofbe_data.freeliving.params import (
        PARAMS_NAME,
        AutocalParams,
        load_autocal_params,
        params_yaml,
        with_overrides,
    )
    from ofbe_data.freeliving.summary import summary_csv, summary_parquet
    from ofbe_data.io.detection import Hints

    out = Path(args.out)
    try:
        params = load_autocal_params(args.params) if args.params else AutocalParams()
        params = with_overrides(params, mode=args.mode, epoch_s=args.epoch_s, still_sd_g=args.still_sd_g,
                                sphere_check=args.sphere_check, rate_hz=args.rate, unit=args.unit)
        settings = params.settings()
        files = expand_inputs(args.paths, out)
        hints = Hints(rate_hz=params.rate_hz, acc_unit=params.unit)
        if args.jobs < 1:
            raise ValueError(f"--jobs: expected an integer >= 1, found {args.jobs}")
    except (OfbeError, ValueError, FileNotFoundError) as exc:
        return fail(PROG, str(exc), 2)
    if out.exists() and not out.is_dir():
        return fail(PROG, f"--out {out}: expected a folder, found a file", 2)
    if not files:
        return fail(PROG, f"no .cwa, .bin, .gt3x or .csv file in {', '.join(args.paths)}", 2)
    rows, failed = [], 0
    results = iter_ordered(_task, [(path, settings, hints, args.plots) for path in files], jobs=args.jobs,
                           scheduler=args.scheduler, name=lambda task: str(task[0]))
    try:
        for path, result in zip(files, results, strict=True):
            if isinstance(result, str):
                failed += 1
                print(f"{PROG}: error: {result}", file=sys.stderr)
                continue
            row, epochs, notes, png = result
            for note in notes:
                print(f"{PROG}: note: {note}", file=sys.stderr)
            target = out / epochs_name(path)
            try:
                out.mkdir(parents=True, exist_ok=True)
                write_bytes_atomic(target, epochs)
                if png is not None:
                    target = out / (path.stem + FIGURE_SUFFIX)
                    write_bytes_atomic(target, png)
            except OSError as exc:
                return io_failure(PROG, exc, target, "the epochs could not be written")
            rows.append(row)
    except (TaskError, SchedulerError) as exc:
        return fail(PROG, str(exc), EXIT_DATA)
    target = out / SUMMARY_NAME
    try:
        out.mkdir(parents=True, exist_ok=True)
        write_bytes_atomic(out / SUMMARY_PARQUET, summary_parquet(rows))
        write_bytes_atomic(target, summary_csv(rows))
        write_bytes_atomic(out / PARAMS_NAME, params_yaml(params))
    except OSError as exc:
        return io_failure(PROG, exc, target, "the summary could not be written")
    if not args.quiet:
        done = sum(1 for r in rows if r["calibrated"])
        print(f"{PROG}: {len(rows)} read, {done} calibrated, {len(rows) - done} not (see qc), "
              f"{failed} failed -> {out / SUMMARY_NAME}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
