"""What each calibration format of ``ofbe-export`` does: the handlers of
:data:`~ofbe_data.calibration.exports.CALIBRATION_FORMATS`, each turning the parsed command line
into the files to write (:class:`~ofbe_data.calibration.output.ExportFile`).

SOURCE is read here (:mod:`ofbe_data.calibration.results`, :mod:`ofbe_data.calibration.autocal`),
converted by :mod:`ofbe_data.calibration.formats`; this module is imported only when a format
runs, so that ``ofbe-export --help`` does not import NumPy, pandas or the readers.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from ofbe_data import __version__
from ofbe_data.calibration import formats as fmt
from ofbe_data.calibration.autocal import (
    AutocalFile,
    AutocalFolder,
    autocal_imucal_file,
    autocal_json_file,
    calibrated_files,
    ggir_autocal_table,
    is_autocal_folder,
    read_autocal,
)
from ofbe_data.calibration.defaults import GGIR_DATA, GGIR_DATA_README
from ofbe_data.calibration.noise import RawFiles, attach_raw_times, gyro_noise_of, noise_of
from ofbe_data.calibration.output import ExportFile, ExportUsageError, written_time
from ofbe_data.calibration.registry import PROG
from ofbe_data.calibration.results import CalibrationResult, Collected, Segment, load_results
from ofbe_data.io.recording import TEMPERATURE

__all__ = ["ggir_files", "imucal_files", "json_files", "kalibr_files", "ros_files"]


def _collect(args: argparse.Namespace, need_raw: bool = False) -> tuple[Collected, RawFiles | None]:
    """The results of SOURCE with their recording times (and the raw files, when given)."""
    if is_autocal_folder(args.source):
        raise ExportUsageError(f"{args.source}: {args.format} takes a labels folder, a label file or "
                               "ofbe-predict's JSON, found an ofbe-autocal folder (it exports as ggir, json "
                               "or imucal)")
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


def _autocal(args: argparse.Namespace) -> AutocalFolder | None:
    """SOURCE read as an ofbe-autocal folder, or None when it is not one."""
    if not is_autocal_folder(args.source):
        return None
    if args.raw is not None:
        raise ExportUsageError(f"--raw: {args.source} is an ofbe-autocal folder, whose summary names every "
                               "file; expected no raw folder, found one")
    return read_autocal(args.source)


def _autocal_files(args: argparse.Namespace, folder: AutocalFolder, name: str,
                   render: Callable[[AutocalFile], bytes]) -> list[ExportFile]:
    """One file per calibrated recording of an autocal folder, ``<file stem>.<ending>``; a
    warning line for each recording not calibrated."""
    done, skipped = calibrated_files(folder)
    if args.store is not None:
        unknown = [f.file for f in done if f.device is None or f.start_utc is None]
        if unknown:
            raise ExportUsageError(f"--store: {unknown[0]}: expected a device and a start time to file the "
                                   "calibration by, found none (an epoch csv names neither); leave out "
                                   "--store")
    for line in skipped:
        print(f"{PROG}: warning: skipped {line}", file=sys.stderr)
    ending = fmt.FORMAT_EXTENSIONS[name]
    return [ExportFile(f"{f.stem}.{ending}", render(f), f.device, f.start_utc, name) for f in done]


def imucal_files(args: argparse.Namespace) -> list[ExportFile]:
    folder = _autocal(args)
    if folder is not None:
        now = written_time()
        return _autocal_files(args, folder, "imucal", lambda f: autocal_imucal_file(folder, f, now))
    collected, _ = _collect(args)
    now = written_time()
    return _calibration_files(collected, "imucal", lambda r: fmt.imucal_file(r, now))


def kalibr_files(args: argparse.Namespace) -> list[ExportFile]:
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


def ros_files(args: argparse.Namespace) -> list[ExportFile]:
    collected, _ = _collect(args)
    now = written_time()
    return _calibration_files(collected, "ros", lambda r: fmt.ros_file(r, now, args.frame_id, args.ros_node))


def ggir_files(args: argparse.Namespace) -> list[ExportFile]:
    """One ``backup.cal.coef`` for the whole run (GGIR takes one file: the ``backup.cal.coef``
    parameter of g.part1, R/g.part1.R), per-device copies for ``--store``, and with
    ``--ggir-data`` the raw files rebuilt for GGIR's csv reader."""
    folder = _autocal(args)
    if folder is not None:
        return _ggir_autocal(args, folder)
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


def _ggir_autocal(args: argparse.Namespace, folder: AutocalFolder) -> list[ExportFile]:
    """One ``backup.cal.coef`` for an autocal folder
    (:func:`ofbe_data.calibration.autocal.ggir_autocal_table`), a line for each file that is not a
    calibrated row."""
    for flag, given in (("--ggir-data", args.ggir_data), ("--store", args.store is not None),
                        ("--g-convention local", args.g_convention == "local")):
        if given:
            raise ExportUsageError(f"{flag}: {args.source} is an ofbe-autocal folder, whose GGIR export is "
                                   "one backup.cal.coef on GGIR's unit sphere for the folder's data files as "
                                   f"they are; expected no {flag}, found it")
    table, notes = ggir_autocal_table(folder)
    for note in notes:
        print(f"{PROG}: ggir: {note}", file=sys.stderr)
    return [ExportFile(fmt.GGIR_BACKUP_FILE, table)]


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


def json_files(args: argparse.Namespace) -> list[ExportFile]:
    folder = _autocal(args)
    if folder is not None:
        now = written_time()
        return _autocal_files(args, folder, "json", lambda f: autocal_json_file(folder, f, now))
    collected, _ = _collect(args)
    now = written_time()
    return _calibration_files(collected, "json", lambda r: fmt.json_file(r, now))
