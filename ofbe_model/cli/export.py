"""``ofbe-export FORMAT SOURCE --out PATH [--store DIR]``: results in the files other tools load.

Calibration formats (:mod:`ofbe_data.calibration`), from a labels folder
(``processed/labels/<campaign>``), one ``<session>.parquet`` or the JSON ``ofbe-predict``
prints, one file per device and power cycle (per estimate for predictions; ``ggir``: one file
per run):

- ``imucal``: imucal ``FerrarisCalibrationInfo`` JSON (gyroscope identity/zero);
- ``kalibr``: Kalibr ``imu.yaml`` noise parameters from the Allan deviation of the labelled
  stationary segments (needs ``--raw``, the campaign's raw folder); the gyroscope's from the
  recordings' gyroscope columns or ``--gyro-noise-density``/``--gyro-random-walk``;
- ``ros``: YAML with the bias to subtract and ``linear_acceleration_covariance``;
- ``ggir``: GGIR's ``backup.cal.coef`` CSV (offsets in g, GGIR's sign): one file per run, a row
  per raw file of every device and power cycle (GGIR takes one such file); ``--ggir-data``
  also rebuilds the raw files as clean CSV that GGIR's csv reader reads whole, with the
  ``rmc.*`` settings in ``ggir-data.README.txt``;
- ``json``: ofbe's own ``ofbe-calibration/1``.

One result: ``--out`` is the file (or, an existing folder, the folder it goes in); several:
``--out`` is a folder of ``<device>.pc<power_cycle>.<ending>``, built under a temporary name
and renamed. ``--store DIR`` also files each result as
``DIR/<device>/<device>_<YYYYmmddTHHMMSS[.ffffff]>.<ending>`` (the recording's UTC time; imucal
files in imucal's own layout; see :mod:`ofbe_data.calibration.store` and
:func:`ofbe_data.find_calibration`). Nothing is written unless every file can be.

Adding a format is one entry in :data:`FORMATS`: a :class:`Format` whose handler turns the
parsed arguments into :class:`~ofbe_data.calibration.output.ExportFile` objects, with its own
options and examples (``ofbe-export FORMAT --help`` shows them); writing, ``--force`` and
``--store`` are shared (:mod:`ofbe_data.calibration.output`). The model formats
(``tflite``, ``c-header``) are entries of the same kind whose handlers read a model as SOURCE.
Exit status: 0 written, 1 bad input data, 2 usage (``ofbe_data.core.cli``).
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from ofbe_data import __version__
from ofbe_data.calibration import formats as fmt
from ofbe_data.calibration.noise import RawFiles, attach_raw_times, gyro_noise_of, noise_of
from ofbe_data.calibration.output import (
    ExportFile,
    ExportUsageError,
    write_outputs,
    written_time,
)
from ofbe_data.calibration.results import CalibrationResult, Collected, Segment, load_results
from ofbe_data.calibration.ros_names import ros_node_problem
from ofbe_data.core.cli import EXIT_DATA, EXIT_OK, EXIT_USAGE, command, fail, io_failure, with_examples
from ofbe_data.core.errors import OfbeError
from ofbe_data.io.recording import TEMPERATURE

PROG = "ofbe-export"
@dataclass(frozen=True)
class Format:
    """An export format: what it makes (``help``), how (``handler``), its own options
    (``options``, added to its ``ofbe-export FORMAT`` parser) and command lines that use it
    (``examples``, shown by ``ofbe-export FORMAT --help``)."""

    handler: Callable[[argparse.Namespace], list[ExportFile]]
    help: str
    options: Callable[[argparse.ArgumentParser], None] | None = None
    examples: tuple[str, ...] = ()
    reads_raw: bool = True


# ----------------------------------------------------------------------------- calibration formats


def _ros_node(text: str) -> str:
    """``--ros-node``: a node key ROS 2's parameter-file parser accepts (:func:`ros_node_problem`)."""
    problem = ros_node_problem(text)
    if problem is not None:
        raise argparse.ArgumentTypeError(f"{problem} (ROS 2 would refuse the file), found {text!r}")
    return text


def _collect(args: argparse.Namespace, need_raw: bool = False) -> tuple[Collected, RawFiles | None]:
    """The results of SOURCE with their recording times (and the raw files, when given)."""
    if need_raw and args.raw is None:
        raise ExportUsageError(f"{args.format} needs --raw DIR (the campaign's raw folder): the noise "
                               "comes from the labelled stationary segments of the raw recordings")
    collected = load_results(args.source)
    if need_raw and collected.kind != "labels":
        raise ExportUsageError(f"{args.source}: {args.format} needs a labels folder or label file as "
                               "SOURCE (the raw segments they name), found an ofbe-predict JSON")
    raw = RawFiles(args.raw) if args.raw is not None else None
    collected = attach_raw_times(collected, raw)
    for line in collected.skipped:
        print(f"{PROG}: warning: skipped {line}", file=sys.stderr)
    return collected, raw


def _calibration_files(collected: Collected, name: str, render: Callable[..., bytes]) -> list[ExportFile]:
    ending = fmt.FORMAT_EXTENSIONS[name]
    return [ExportFile(f"{r.stem}.{ending}", render(r), r.device, r.time_utc, name)
            for r in collected.results]


def _imucal(args: argparse.Namespace) -> list[ExportFile]:
    collected, _ = _collect(args)
    now = written_time()
    return _calibration_files(collected, "imucal", lambda r: fmt.imucal_file(r, now))


def _kalibr(args: argparse.Namespace) -> list[ExportFile]:
    collected, raw = _collect(args, need_raw=True)
    assert raw is not None
    now = written_time()
    given = (args.gyro_noise_density, args.gyro_random_walk)

    def render(r: CalibrationResult) -> bytes:
        gyro = None if None not in given else gyro_noise_of(r, raw)
        if gyro is None and None in given:
            missing = [f for f, v in zip(("--gyro-noise-density", "--gyro-random-walk"), given, strict=True)
                       if v is None]
            raise ExportUsageError(
                f"{args.source}: {r.what}: Kalibr requires the gyroscope's noise density and random walk and "
                f"the raw files have no gyroscope columns; give {' and '.join(missing)} (datasheet values, "
                "rad/s/sqrt(Hz) and rad/s^2/sqrt(Hz)), or map gx, gy, gz in session.yaml")
        return fmt.kalibr_file(r, noise_of(r, raw), now, args.rostopic, gyro, *given)

    return _calibration_files(collected, "kalibr", render)


def _ros(args: argparse.Namespace) -> list[ExportFile]:
    collected, _ = _collect(args)
    now = written_time()
    return _calibration_files(collected, "ros", lambda r: fmt.ros_file(r, now, args.frame_id, args.ros_node))


GGIR_DATA = "ggir-data"
"""Folder of ``--out`` that ``ggir --ggir-data`` writes the rebuilt data files into, under GGIR's names."""
GGIR_DATA_README = "ggir-data.README.txt"
"""Notes beside ``ggir-data/``: the layout of the rebuilt files and the ``rmc.*`` settings to pass."""


def _ggir(args: argparse.Namespace) -> list[ExportFile]:
    """One ``backup.cal.coef`` for the whole run (GGIR takes one file: the ``backup.cal.coef``
    parameter of g.part1, R/g.part1.R), per-device copies for ``--store``, and with
    ``--ggir-data`` the raw files rebuilt for GGIR's csv reader."""
    if args.ggir_data and args.raw is None:
        raise ExportUsageError("--ggir-data needs --raw DIR: the campaign's raw folder to rebuild the files "
                               "from")
    collected, raw = _collect(args)
    if args.ggir_data and collected.kind != "labels":
        raise ExportUsageError(f"{args.source}: --ggir-data rebuilds the raw files of labels; ofbe-predict's "
                               "JSON names files GGIR can read under their own names")
    now = written_time()
    table = fmt.ggir_table(collected.results, now, convention=args.g_convention)
    files = [ExportFile(fmt.GGIR_BACKUP_FILE, table)]
    if args.store is not None:  # a store is per device: each device and power cycle's own rows
        files += [ExportFile(f"{r.stem}.{fmt.FORMAT_EXTENSIONS['ggir']}",
                             fmt.ggir_file(r, now, convention=args.g_convention), r.device, r.time_utc,
                             "ggir", out=False)
                  for r in collected.results]
    renamed = sorted({raw_file for r in collected.results for raw_file in r.raw_files
                      if fmt.ggir_name(raw_file) != raw_file})
    if args.ggir_data:
        assert raw is not None
        data = _ggir_data_files(collected, raw, now)
        files += data
        print(f"{PROG}: ggir: {len(data) - 1} raw files rebuilt into "
              f"{GGIR_DATA}/ as clean CSV under the names GGIR matches (the filename column; raw_file says "
              f"which file each is): point GGIR's datadir there with the rmc.* settings of "
              f"{GGIR_DATA_README}", file=sys.stderr)
    elif renamed:
        print(f"{PROG}: ggir: GGIR matches a row by the data file's base name: the filename column names "
              f"each of the {len(renamed)} raw files uniquely (raw_file says which file it is); give GGIR "
              "the files under those names, or pass --ggir-data --raw DIR to have them rebuilt for GGIR",
              file=sys.stderr)
    return files


def _ggir_data_files(collected: Collected, raw: RawFiles, now: datetime) -> list[ExportFile]:
    """Every raw file of the labels, read by the validating readers (their SHA-256 checked
    against the labels) and written back as the clean CSV GGIR's ``read.myacc.csv`` reads whole
    (:func:`ofbe_data.calibration.formats.ggir_data_file`), plus the notes on how to read them.

    A temperature column is written only when every file has a finite temperature for every
    sample: GGIR takes one ``rmc.col.temp`` for the whole run."""
    wanted: dict[str, tuple[Segment, str]] = {}
    for r in collected.results:
        for seg in r.segments:
            wanted.setdefault(f"{seg.session}/{Path(seg.raw_file).as_posix()}", (seg, r.device))
    recordings = {name: raw.recording(seg, device) for name, (seg, device) in sorted(wanted.items())}
    with_temperature = bool(recordings) and all(
        TEMPERATURE in rec.extra and bool(np.all(np.isfinite(rec.extra[TEMPERATURE])))
        for rec in recordings.values())
    files: list[ExportFile] = []
    listing: list[tuple[str, str, float, int]] = []
    for name, rec in recordings.items():
        files.append(ExportFile(f"{GGIR_DATA}/{fmt.ggir_name(name)}",
                                fmt.ggir_data_file(rec, with_temperature)))
        listing.append((fmt.ggir_name(name), name, fmt.ggir_sample_rate(rec), rec.n))
    files.append(ExportFile(GGIR_DATA_README, _ggir_data_readme(listing, with_temperature, now)))
    return files


def _ggir_data_readme(files: Sequence[tuple[str, str, float, int]], with_temperature: bool,
                     written: datetime) -> bytes:
    """The notes beside ``ggir-data/`` (:data:`GGIR_DATA_README`): what the files are and the GGIR
    call that reads them (:func:`ofbe_data.calibration.formats.ggir_read_settings`).

    Parameters
    ----------
    files
        (GGIR name, raw file, sample rate Hz, samples) of each rebuilt file.
    with_temperature
        Whether the files carry a temperature column.
    written
        When the export was made.
    """
    settings = fmt.ggir_read_settings(with_temperature)
    columns = ["time", "x", "y", "z"] + (["temperature"] if with_temperature else [])
    args = ",\n     ".join(f"{k} = {v}" for k, v in settings.items())
    lines = [
        f"{GGIR_DATA}/: written by ofbe {__version__} at {written.astimezone(UTC):%Y-%m-%dT%H:%M:%SZ}",
        "",
        "Each file is a raw recording rebuilt from the samples ofbe's validating reader kept (garbled,",
        "truncated and non-numeric lines, boot noise and bytes that are not text are left out, never",
        "guessed), as a clean CSV that GGIR's own csv reader (read.myacc.csv) reads whole, under the",
        f"name in the filename column of {fmt.GGIR_BACKUP_FILE} (its raw_file column names the raw file).",
        "",
        "Layout: line 1 the header block 'sample_rate,<Hz>' (padded to the width of the data); line 2",
        f"the column names {','.join(columns)}; then one sample per line:",
        "  time   Unix seconds (UTC): the recording's header UTC start plus the device clock since it",
        "         (without a UTC start in the raw file: the device clock, i.e. from 1970-01-01)",
        "  x,y,z  raw (uncalibrated) specific force, g (= m/s^2 / 9.80665): GGIR applies the",
        f"         coefficients of {fmt.GGIR_BACKUP_FILE} to these",
        *(["  temperature  degrees C"] if with_temperature else []),
        "",
        "Give GGIR these settings (read.myacc.csv's rmc.* parameters; GGIR >= 3.0 names, as in",
        "R/read.myacc.csv.R, R/g.inspectfile.R and R/g.readaccfile.R of wadpac/GGIR):",
        "",
        "  library(GGIR)",
        "  GGIR(datadir = \"ggir-data\", outputdir = \"<an output folder outside ggir-data>\",",
        f"     backup.cal.coef = \"{fmt.GGIR_BACKUP_FILE}\",",
        f"     {args})",
        "",
        "rmc.firstrow.acc = 2 points at the column-name line (GGIR skips it); rmc.doresample = TRUE",
        "puts the samples on a uniform grid at the header's sample rate from their time stamps",
        "(dropped samples, clock jitter); minimumFileSizeMB = 0 because g.part1 skips files under",
        "2 MB by default; desiredtz is the time zone GGIR cuts days in (the stamps are UTC instants).",
        "",
        "GGIR only analyses (g.part1 metrics) a file whose first block holds at least",
        "2 * windowsizes[3] * sample_rate + 1 samples (R/g.readaccfile.R marks it 'filetooshort'",
        "otherwise), and windowsizes[2] must be whole minutes: recordings shorter than about two",
        "minutes are read whole but not analysed, whatever the settings.",
        "",
        "Files (GGIR name, raw file, sample rate, samples):",
        *(f"  {name}  {raw}  {fs:g} Hz  {n}" for name, raw, fs, n in files),
    ]
    return ("\n".join(lines) + "\n").encode()


def _json(args: argparse.Namespace) -> list[ExportFile]:
    collected, _ = _collect(args)
    now = written_time()
    return _calibration_files(collected, "json", lambda r: fmt.json_file(r, now))


# ----------------------------------------------------------------------------- on-device formats


def _training_windows(args: argparse.Namespace) -> tuple[np.ndarray, str]:
    """The windows a model was trained on, (N, T, 3) m/s², and a description of them; without
    ``--dataset``, the dataset the model card beside SOURCE names (:func:`card_dataset`)."""
    what = ""
    selected = None
    if args.dataset is None:
        from ofbe_model.deploy.final import ModelCardError, card_dataset, card_selected_devices

        try:
            args.dataset, _ = card_dataset(args.source)  # its hash: check_card_dataset below
        except ModelCardError as exc:
            raise ExportUsageError(f"{args.format} needs --dataset DIR, the dataset the model was trained on "
                                   f"(its training windows are the int8 representative set): {exc}") from None
        what = " (the model card's training data)"
        selected = card_selected_devices(args.source) if args.device is None else None
    from ofbe_data import load_dataset
    from ofbe_model.deploy.tflite import check_card_dataset

    check_card_dataset(args.source, args.dataset)  # a card that names other training data: refused
    data = load_dataset(args.dataset)
    keep = np.ones(len(data.meta), dtype=bool)
    what = f"{args.dataset}{what}"
    if selected is not None:  # a per-device model: its own device's windows only, as the card says
        keep &= data.meta["device"].isin(selected).to_numpy()
        what += f", device {', '.join(selected)}"
    if args.device is not None:
        keep &= (data.meta["device"] == args.device).to_numpy()
        what += f", device {args.device}"
    if args.protocol is not None:
        column = f"fold_{args.protocol}"
        if column not in data.meta.columns:
            known = ", ".join(c[5:] for c in data.meta.columns if c.startswith("fold_"))
            raise ExportUsageError(f"--protocol {args.protocol}: {args.dataset} has no {column} column "
                                   f"(protocols: {known})")
        if args.fold is None:
            raise ExportUsageError("--protocol needs --fold K: the fold whose training windows are meant")
        keep &= (data.meta[column] != args.fold).to_numpy()
        what += f", training windows of {args.protocol} fold {args.fold}"
    else:
        what += ", all windows (a model trained on all of them)"
    if not keep.any():
        raise ExportUsageError(f"{what}: no window left to quantise with")
    return np.asarray(data.X[keep]), what


def _tflite(args: argparse.Namespace) -> list[ExportFile]:
    from ofbe_model.deploy.tflite import export_tflite

    windows, what = _training_windows(args)
    with tempfile.TemporaryDirectory(prefix=".ofbe-export-") as tmp:
        sidecar = export_tflite(args.source, tmp, windows, name=args.source.stem, source=what)
        return [ExportFile(name, (Path(tmp) / name).read_bytes()) for name in sidecar["files"].values()]


def _c_header(args: argparse.Namespace) -> list[ExportFile]:
    from ofbe_model.deploy.c_header import export_c_header

    name = re.sub(r"[^A-Za-z0-9_]", "_", args.source.stem) or "gravity_prior"
    with tempfile.TemporaryDirectory(prefix=".ofbe-export-") as tmp:
        path = export_c_header(args.source, Path(tmp) / f"{name}.h", name=name)
        return [ExportFile(path.name, path.read_bytes())]


def _ros_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frame-id", default=fmt.DEFAULT_FRAME_ID, help="the frame_id written")
    p.add_argument("--ros-node", default=fmt.ROS_NODE, type=_ros_node,
                   help="the node the parameters are for (the default, /**, is every node that loads the "
                        "file)")


def _ggir_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--g-convention", choices=fmt.GGIR_CONVENTIONS, default="unit-sphere",
                   help="unit-sphere: GGIR's (resting readings of norm 1 g); local: ofbe's (norm g_local/g0)")
    p.add_argument("--ggir-data", action="store_true",
                   help="also rebuild the raw files (from --raw) as clean CSV that GGIR's csv reader reads "
                        "whole, in OUT/ggir-data/ under the names of the filename column, with the rmc.* "
                        "settings in OUT/ggir-data.README.txt")


def _kalibr_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--rostopic", default=fmt.DEFAULT_ROSTOPIC, help="the rostopic written")
    p.add_argument("--gyro-noise-density", type=_positive, metavar="RAD_S_SQRT_HZ",
                   help="gyroscope white-noise density, rad/s/sqrt(Hz) (datasheet); when left out, measured "
                        "from the recordings' gyroscope columns")
    p.add_argument("--gyro-random-walk", type=_positive, metavar="RAD_S2_SQRT_HZ",
                   help="gyroscope bias random walk, rad/s^2/sqrt(Hz); when left out, measured from the "
                        "gyroscope columns (or their flagged upper bound)")


def _tflite_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--dataset", type=Path, help="the dataset the model was trained on (when left out: the "
                                                "one model_card.json beside SOURCE names)")
    p.add_argument("--protocol", help="with --fold, only that fold's training windows")
    p.add_argument("--fold", type=int, help="the fold of --protocol the model was trained for")
    p.add_argument("--device", help="only this device's windows (a per-device model)")


FORMATS: dict[str, Format] = {
    "imucal": Format(_imucal, "imucal Ferraris calibration JSON (accelerometer from ofbe, gyroscope "
                              "identity)",
                     examples=("ofbe-export imucal mine/labels/lab --out mine/cal/",
                               "ofbe-export imucal mine/labels/lab --store mine/cal-store")),
    "kalibr": Format(_kalibr, "Kalibr imu.yaml: accelerometer and gyroscope noise density and random walk "
                              "from the Allan deviation (gyroscope from its columns or flags); needs --raw",
                     _kalibr_options,
                     ("ofbe-export kalibr processed/labels/rotated --raw raw/rotated --out mine/kalibr/",)),
    "ros": Format(_ros, "YAML: bias to subtract (m/s²) and linear_acceleration_covariance", _ros_options,
                  ("ofbe-export ros mine/labels/lab --out mine/ros/ --frame-id imu_link",)),
    "ggir": Format(_ggir, "GGIR backup.cal.coef CSV, one per run: scale.*, offset.* (g, GGIR's sign)",
                   _ggir_options,
                   ("ofbe-export ggir mine/labels/lab --out mine/ggir/",
                    "ofbe-export ggir mine/labels/lab --raw mine/raw/lab --ggir-data --out mine/ggir/")),
    "json": Format(_json, "ofbe-calibration/1 JSON: bias, std, kind, method, source, time, version",
                   examples=("ofbe-export json mine/labels/lab --out mine/json/",
                             "ofbe-export json predictions.json --out mine/json/   # ofbe-predict's output")),
    "tflite": Format(_tflite, "OFBENet (SOURCE: a .keras) as float32 and int8 TensorFlow Lite with a JSON "
                              "sidecar of the scaling; --dataset (default: the model card's)",
                     _tflite_options,
                     ("ofbe-export tflite models/rotated/sparkfun-1/final.keras --out mine/fw/",),
                     reads_raw=False),
    "c-header": Format(_c_header, "the gravity-prior (SOURCE: its .json) as a self-contained C header with a "
                                  "reference C function",
                       examples=("ofbe-export c-header models/rotated/sparkfun-1/gravity-prior.json "
                                 "--out mine/fw/",),
                       reads_raw=False),
}
"""FORMAT → how to export it. A new format is one more entry here."""


# ----------------------------------------------------------------------------- command


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive number, found {text!r}") from None
    if not (np.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, found {text!r}")
    return value


def _common_options(p: argparse.ArgumentParser, reads_raw: bool) -> None:
    p.add_argument("source", metavar="SOURCE", type=Path,
                   help="labels folder (processed/labels/<campaign>), a <session>.parquet, or "
                        "ofbe-predict's JSON; for tflite a .keras model, for c-header a gravity-prior .json")
    p.add_argument("--out", help="output file (one result) or folder (several; a trailing / makes it a "
                                 "folder for one)")
    p.add_argument("--store", type=Path,
                   help="also file each result as STORE/<device>/<device>_<YYYYmmddTHHMMSS[.ffffff]>."
                        "<ending> (imucal: STORE/<device>/<sensor_id>_<YYYY-mm-dd_HH-MM>.json, imucal's own "
                        "layout)")
    if reads_raw:
        p.add_argument("--raw", type=Path,
                       help="the campaign's raw folder: recording start times, and the segments kalibr "
                            "analyses")
    p.add_argument("--force", action="store_true", help="replace existing output files")


def _every_default() -> dict[str, object]:
    """Every format's options at their defaults, so that each handler sees every attribute."""
    scratch = argparse.ArgumentParser(add_help=False)
    _common_options(scratch, True)
    for f in FORMATS.values():
        if f.options is not None:
            f.options(scratch)
    return {a.dest: a.default for a in scratch._actions if a.dest != "source"}


def build_parser() -> argparse.ArgumentParser:
    """The command-line parser of ``ofbe-export``: one subcommand per format of :data:`FORMATS`,
    each with the shared options and its own (``ofbe-export FORMAT --help``)."""
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Calibration results (labels or ofbe-predict estimates) in the files other tools load, "
                    "with their sign and unit conventions converted (docs/exports.md). "
                    "'ofbe-export FORMAT --help' lists a format's options.")
    sub = p.add_subparsers(dest="format", required=True, metavar="FORMAT", help=", ".join(FORMATS))
    defaults = _every_default()
    for name, f in FORMATS.items():
        s = sub.add_parser(name, help=f.help, description=f.help)
        _common_options(s, f.reads_raw)
        if f.options is not None:
            f.options(s)
        s.set_defaults(**defaults)
        with_examples(s, *(f.examples or (f"ofbe-export {name} SOURCE --out DIR/",)))
    return with_examples(p, *(f.examples[0] for f in FORMATS.values() if f.examples))


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ofbe-export``: 0 written, 1 bad data, 2 usage."""
    args = build_parser().parse_args(argv)
    raw_out = args.out
    args.out = Path(raw_out) if raw_out is not None else None
    if args.out is None and args.store is None:
        return fail(PROG, "expected --out PATH or --store DIR (or both), found neither", EXIT_USAGE)
    try:
        files = FORMATS[args.format].handler(args)
        written = write_outputs(files, args.out, args.store, args.force,
                                out_is_folder=str(raw_out or "").endswith(("/", os.sep)))
    except ExportUsageError as exc:
        return fail(PROG, str(exc), EXIT_USAGE)
    except OfbeError as exc:
        return fail(PROG, str(exc), EXIT_DATA)
    except OSError as exc:
        return io_failure(PROG, exc, args.out, "the export could not be written")
    for path in written:
        print(path)
    to_out = sum(f.out for f in files) if args.out is not None else 0
    filed = (sum(f.device is not None and f.store_format is not None for f in files)
             if args.store is not None else 0)
    count = to_out + filed
    print(f"{PROG}: {args.format}: {count} result file{'s' if count != 1 else ''} written", file=sys.stderr)
    return EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
