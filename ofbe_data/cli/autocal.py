"""``ofbe-autocal``: calibrate wearable recordings from their own still periods.

This slice reads *epoch* csv files (GGIR's ``spheredata`` layout, see
:mod:`ofbe_data.freeliving.epochs`) and calibrates them as GGIR's ``g.calibrate`` does
(``--mode ggir``, :func:`ofbe_data.freeliving.ggir.ggir_calibrate`). ``--mode ofbe`` and raw
inputs (.cwa, .bin, .gt3x, raw csv) are later slices (docs/free-living.md).

Writes ``DIR/summary.csv``: one row per file read, in the order named (a folder's ``.csv``
files sorted by name), the same bytes for the same inputs. A recording GGIR would not
calibrate is a row with GGIR's QC message and identity coefficients, not a failure.

Exit status: 0 when every file was read; 1 when a file could not be read (one line per such
file, naming it, the line and the reason; the other files are still calibrated and the summary
written); 2 on a usage error (an unknown mode, a path that does not exist, a bad value).
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import io
import sys
from collections.abc import Sequence
from pathlib import Path

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.cli import command, fail, io_failure
from ofbe_data.core.precision import UNIT_DECIMALS, round_decimals
from ofbe_data.freeliving import EpochFileError, GgirResult, GgirSettings, ggir_calibrate, parse_epoch_csv

PROG = "ofbe-autocal"
SUMMARY_NAME = "summary.csv"
EPOCH_SUFFIX = ".csv"
"""What this slice reads: epoch csv files."""
RAW_SUFFIXES = (".cwa", ".bin", ".gt3x")
"""Raw wearable formats of the slices to come."""

COLUMNS = ("file", "sha256", "hours", "n_epochs", "n_still", "mode", "model", "calibrated", "qc",
           "cal_error_start_mg", "cal_error_end_mg",
           "offset_x", "offset_y", "offset_z", "scale_x", "scale_y", "scale_z",
           "temp_offset_x", "temp_offset_y", "temp_offset_z", "temp_mean_c")
"""The columns of ``summary.csv`` this slice fills (docs/free-living.md)."""

_DECIMALS = {"hours": 9, "cal_error_start_mg": 9, "cal_error_end_mg": 9,
             **{f"offset_{a}": 12 for a in "xyz"}, **{f"scale_{a}": UNIT_DECIMALS for a in "xyz"},
             **{f"temp_offset_{a}": 12 for a in "xyz"}, "temp_mean_c": 6}
"""Decimal places of each float column (offsets in g and g/°C to 1e-12, errors in mg to 1e-9):
far below anything physical, so that the bytes do not depend on the machine's BLAS
(:mod:`ofbe_data.core.precision`)."""


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Calibrate wearable recordings from their own still periods. This version reads "
                    "epoch csv files (columns meanx, meany, meanz, sdx, sdy, sdz in g, optional "
                    "temperature in °C: GGIR's spheredata layout) and calibrates them as GGIR's "
                    "g.calibrate does (--mode ggir). Writes <out>/summary.csv.")
    p.add_argument("paths", nargs="+", metavar="FILE_OR_FOLDER",
                   help="epoch csv files, or folders whose .csv files are read")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (made if missing)")
    p.add_argument("--mode", choices=("ofbe", "ggir"), default="ofbe",
                   help="ggir: GGIR's g.calibrate, reproduced; ofbe (the default): ofbe's calibration "
                        "ladder (not yet available)")
    p.add_argument("--epoch-s", type=float, default=10.0,
                   help="length of one epoch, s, for the hours of data (default: %(default)s, GGIR's)")
    p.add_argument("--still-sd-g", type=float, default=0.013,
                   help="an epoch is still when its standard deviation is below this on every axis, g "
                        "(default: %(default)s, GGIR's)")
    p.add_argument("--no-sphere-check", action="store_true",
                   help="fit even when the still epochs do not reach beyond ±0.3 g on every axis")
    p.add_argument("--quiet", action="store_true", help="no summary line")
    return p


def expand_inputs(paths: Sequence[str], out: Path) -> list[Path]:
    """The files named, each folder replaced by its ``.csv`` files sorted by name (those under
    ``out`` left out), each file once, in the order named.

    Raises
    ------
    FileNotFoundError
        A path does not exist.
    """
    files: list[Path] = []
    out = out.resolve()
    for name in paths:
        path = Path(name)
        if path.is_dir():
            found = sorted(p for p in path.iterdir() if p.suffix.lower() == EPOCH_SUFFIX and p.is_file()
                           and out not in p.resolve().parents)
            files += found
        elif path.exists():
            files.append(path)
        else:
            raise FileNotFoundError(f"{name}: no such file or folder")
    seen: set[Path] = set()
    unique = []
    for f in files:
        if f.resolve() not in seen:
            seen.add(f.resolve())
            unique.append(f)
    return unique


def _cell(name: str, value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        rounded = round_decimals(value, _DECIMALS[name])
        return repr(rounded)
    return str(value)


def summary_row(file: str, sha256: str, result: GgirResult) -> dict[str, object]:
    """One row of ``summary.csv`` for a GGIR-mode result."""
    row: dict[str, object] = {
        "file": file, "sha256": sha256, "hours": float(result.hours), "n_epochs": result.n_epochs,
        "n_still": result.n_still, "mode": "ggir", "model": result.model, "calibrated": result.calibrated,
        "qc": result.qc,
        "cal_error_start_mg": None if result.cal_error_start is None else result.cal_error_start * 1000.0,
        "cal_error_end_mg": None if result.cal_error_end is None else result.cal_error_end * 1000.0,
        "temp_mean_c": result.temp_mean_c,
    }
    for k, axis in enumerate("xyz"):
        row[f"offset_{axis}"] = float(result.offset[k])
        row[f"scale_{axis}"] = float(result.scale[k])
        row[f"temp_offset_{axis}"] = float(result.temp_offset[k])
    return row


def summary_csv(rows: Sequence[dict[str, object]]) -> bytes:
    """``summary.csv``'s bytes: a header and one line per row, ``\\n`` line ends."""
    buf = io.StringIO()
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(COLUMNS)
    for row in rows:
        writer.writerow([_cell(c, row[c]) for c in COLUMNS])
    return buf.getvalue().encode("utf-8")


def calibrate_file(path: Path, settings: GgirSettings) -> dict[str, object]:
    """Read and calibrate one epoch csv; its summary row.

    Raises
    ------
    EpochFileError
        The file is not an epoch csv (the message names the file and line), or is a raw format
        of a later slice.
    OSError
        The file cannot be read.
    """
    if path.suffix.lower() in RAW_SUFFIXES:
        raise EpochFileError(path, "an epoch csv (raw .cwa, .bin and .gt3x files are not yet available "
                                   "in ofbe-autocal)", f"a {path.suffix} file")
    data = path.read_bytes()
    result = ggir_calibrate(parse_epoch_csv(data, path), settings)
    return summary_row(str(path), hashlib.sha256(data).hexdigest(), result)


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    if args.mode == "ofbe":
        return fail(PROG, "--mode ofbe: not yet available (ofbe's calibration ladder is a later slice); "
                          "use --mode ggir", 2)
    out = Path(args.out)
    try:
        settings = GgirSettings(still_sd_g=args.still_sd_g, epoch_s=args.epoch_s,
                                sphere_check=not args.no_sphere_check)
        files = expand_inputs(args.paths, out)
    except (ValueError, FileNotFoundError) as exc:
        return fail(PROG, str(exc), 2)
    if out.exists() and not out.is_dir():
        return fail(PROG, f"--out {out}: expected a folder, found a file", 2)
    if not files:
        return fail(PROG, f"no .csv file in {', '.join(args.paths)}", 2)
    rows, failed = [], 0
    for path in files:
        try:
            rows.append(calibrate_file(path, settings))
        except EpochFileError as exc:
            failed += 1
            print(f"{PROG}: error: {exc}", file=sys.stderr)
        except OSError as exc:
            failed += 1
            print(f"{PROG}: error: {path}: {exc.strerror or exc}", file=sys.stderr)
    try:
        out.mkdir(parents=True, exist_ok=True)
        write_bytes_atomic(out / SUMMARY_NAME, summary_csv(rows))
    except OSError as exc:
        return io_failure(PROG, exc, out / SUMMARY_NAME, "the summary could not be written")
    if not args.quiet:
        done = sum(1 for r in rows if r["calibrated"])
        print(f"{PROG}: {len(rows)} read, {done} calibrated, {len(rows) - done} not (see qc), "
              f"{failed} failed -> {out / SUMMARY_NAME}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
