"""``ofbe-export FORMAT SOURCE --out PATH [--store DIR]``: results in the files other tools load.

Calibration formats (:mod:`ofbe_data.calibration.exports`), from a labels folder
(``processed/labels/<campaign>``), one ``<session>.parquet``, the JSON ``ofbe-predict``
prints, or (``ggir``, ``json``, ``imucal``) an ``ofbe-autocal`` output folder; one file per
device and power cycle (per estimate for predictions, per calibrated recording for an autocal
folder; ``ggir``: one file per run):

- ``imucal``: imucal ``FerrarisCalibrationInfo`` JSON (gyroscope identity/zero);
- ``kalibr``: Kalibr ``imu.yaml`` noise parameters from the Allan deviation of the labelled
  stationary segments (needs ``--raw``, the campaign's raw folder); the gyroscope's from the
  recordings' gyroscope columns or ``--gyro-noise-density``/``--gyro-random-walk``;
- ``ros``: YAML with the bias to subtract and ``linear_acceleration_covariance``;
- ``ggir``: GGIR's ``backup.cal.coef`` CSV (offsets in g, GGIR's sign): one file per run, a row
  per raw file of every device and power cycle (GGIR takes one such file); ``--ggir-data``
  also rebuilds the raw files as clean CSV that GGIR's csv reader reads whole, with the
  ``rmc.*`` settings in ``ggir-data.README.txt``; from an autocal folder, a row per recording;
- ``json``: ofbe's own ``ofbe-calibration/1``.

The model formats (``tflite``, ``c-header``) belong to the model package, which registers them
through the entry-point group ``ofbe.export_formats`` (:mod:`ofbe_data.calibration.registry`):
this module never imports it, and where it cannot be imported those formats are absent
(``ofbe-export tflite`` then says which package provides it).

One result: ``--out`` is the file (or, an existing folder, the folder it goes in); several:
``--out`` is a folder of ``<device>.pc<power_cycle>.<ending>``, built under a temporary name
and renamed. ``--store DIR`` also files each result as
``DIR/<device>/<device>_<YYYYmmddTHHMMSS[.ffffff]>.<ending>`` (the recording's UTC time; imucal
files in imucal's own layout; see :mod:`ofbe_data.calibration.store` and
:func:`ofbe_data.find_calibration`). Nothing is written unless every file can be.

Adding a format is one :class:`~ofbe_data.calibration.registry.Format` (a handler that turns the
parsed arguments into :class:`~ofbe_data.calibration.output.ExportFile` objects, with its own
options and examples; ``ofbe-export FORMAT --help`` shows them): an entry of
:data:`~ofbe_data.calibration.exports.CALIBRATION_FORMATS`, or an entry point of another
package. Writing, ``--force`` and ``--store`` are shared (:mod:`ofbe_data.calibration.output`).
Building the parser imports no format's modules: a handler imports them when its format runs.
Exit status: 0 written, 1 bad input data, 2 usage (``ofbe_data.core.cli``).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from ofbe_data.calibration.exports import export_formats
from ofbe_data.calibration.registry import PROG, Format
from ofbe_data.core.cli import EXIT_DATA, EXIT_OK, EXIT_USAGE, command, fail, io_failure, with_examples
from ofbe_data.core.errors import OfbeError

__all__ = ["PROG", "build_parser", "main"]


def _common_options(p: argparse.ArgumentParser, reads_raw: bool) -> None:
    p.add_argument("source", metavar="SOURCE", type=Path,
                   help="labels folder (processed/labels/<campaign>), a <session>.parquet, "
                        "ofbe-predict's JSON or (ggir, json, imucal) an ofbe-autocal folder; for tflite a "
                        ".keras model, for c-header a gravity-prior .json")
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


def _every_default(formats: dict[str, Format]) -> dict[str, object]:
    """Every format's options at their defaults, so that each handler sees every attribute."""
    scratch = argparse.ArgumentParser(add_help=False)
    _common_options(scratch, True)
    for f in formats.values():
        if f.options is not None:
            f.options(scratch)
    return {a.dest: a.default for a in scratch._actions if a.dest != "source"}


def build_parser(formats: dict[str, Format] | None = None) -> argparse.ArgumentParser:
    """The command-line parser of ``ofbe-export``: one subcommand per format (by default every
    format of :func:`~ofbe_data.calibration.exports.export_formats`), each with the shared
    options and its own (``ofbe-export FORMAT --help``)."""
    if formats is None:
        formats, _ = export_formats()
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Calibration results (labels, ofbe-predict estimates or an ofbe-autocal folder) in the "
                    "files other tools load, with their sign and unit conventions converted "
                    "(docs/exports.md). 'ofbe-export FORMAT --help' lists a format's options.")
    sub = p.add_subparsers(dest="format", required=True, metavar="FORMAT", help=", ".join(formats))
    defaults = _every_default(formats)
    for name, f in formats.items():
        s = sub.add_parser(name, help=f.help, description=f.help)
        _common_options(s, f.reads_raw)
        if f.options is not None:
            f.options(s)
        s.set_defaults(**defaults)
        with_examples(s, *(f.examples or (f"ofbe-export {name} SOURCE --out DIR/",)))
    return with_examples(p, *(f.examples[0] for f in formats.values() if f.examples))


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ofbe-export``: 0 written, 1 bad data, 2 usage."""
    try:
        formats, unavailable = export_formats()
    except OfbeError as exc:  # a package registered something that is not a format
        return fail(PROG, str(exc), EXIT_DATA)
    words = list(sys.argv[1:] if argv is None else argv)
    asked = next((w for w in words if not w.startswith("-")), None)
    if asked in unavailable:
        return fail(PROG, unavailable[asked].message, EXIT_USAGE)
    return _run(build_parser(formats).parse_args(words), formats)


def _run(args: argparse.Namespace, formats: dict[str, Format]) -> int:
    """``ofbe-export FORMAT`` on its parsed arguments; writing is imported here and the format's
    own modules by its handler, after parsing (docs/architecture.md, "Command lines")."""
    from ofbe_data.calibration.output import ExportUsageError, write_outputs

    raw_out = args.out
    args.out = Path(raw_out) if raw_out is not None else None
    if args.out is None and args.store is None:
        return fail(PROG, "expected --out PATH or --store DIR (or both), found neither", EXIT_USAGE)
    try:
        files = formats[args.format].files(args)
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
