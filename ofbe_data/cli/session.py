"""``ofbe-session``: write a session's manifest from its files (``init``), and check a session
before labelling it (``check``).

``init DIR`` detects each file's format, columns, units and rate (:mod:`ofbe_data.io.detection`),
prints every decision with its evidence (the rate as ``check`` reports it), and writes
``DIR/session.yaml`` with the evidence as YAML comments beside the keys. A file with two
accelerometer triads gives two devices naming it; ``power_cycle`` comes only from an explicit
pattern of the folder's name (``pc3``…), else 1 with a warning. A case the files do not settle
stops with the flag to give. The folder's files, devices and recordings are found by
:mod:`ofbe_data.io.detection`; ``init`` itself, with the YAML and its evidence, is
:mod:`ofbe_data.cli.session_init`.

``check DIR...`` validates each session, reads every file and runs labelling in memory (nothing
is written, the raw folder is never touched), and prints per file what was found and what
labelling would reject and why (:mod:`ofbe_data.cli.session_check`).

This module holds the parser; each subcommand's module is imported after parsing, so that
``--help`` answers without the readers (docs/architecture.md, "Command lines").

Exit status: 0 (``init``: manifest written; ``check``: every file reads and every recording of
every device under test would be labelled), 1 (a file cannot be read, or ``check`` finds
something labelling would reject), 2 (usage: a flag is needed or wrong, or ``session.yaml``
exists without ``--force``).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence

from ofbe_data.core.cli import add_params, command, with_examples
from ofbe_data.io.device_options import ACC_UNITS, COLUMN_KEYS, GYRO_KEYS, GYRO_UNITS, KINDS, TIME_UNITS

PROG = "ofbe-session"


# --------------------------------------------------------------------------- arguments


def _per_axis(text: str) -> float | tuple[float, float, float]:
    parts = [float(p) for p in text.split(",")]
    if len(parts) == 1:
        return parts[0]
    if len(parts) == 3:
        return (parts[0], parts[1], parts[2])
    raise argparse.ArgumentTypeError(f"expected N or X,Y,Z, found {text!r}")


def _positive(text: str) -> float:
    value = float(text)
    if not value > 0 or not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a number > 0, found {text!r}")
    return value


def _pair(text: str) -> tuple[str, str]:
    key, sep, value = text.partition("=")
    if not sep or not key or not value:
        raise argparse.ArgumentTypeError(f"expected ID=VALUE, found {text!r}")
    return key.strip(), value.strip()


def _columns(text: str) -> dict[str, str]:
    out = dict(_pair(p) for p in text.split(","))
    bad = [k for k in out if k not in COLUMN_KEYS]
    gyro = [k for k in GYRO_KEYS if k in out]
    if bad or not {"ax", "ay", "az"} <= set(out) or len(gyro) not in (0, 3):
        raise argparse.ArgumentTypeError("expected t=…,ax=…,ay=…,az=…[,temperature=…][,gx=…,gy=…,gz=…], "
                                         f"found {text!r}")
    return out


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG, description="Write a session's manifest from its data files "
                                "(init), or check a session before labelling it (check).")
    sub = p.add_subparsers(dest="cmd", required=True, metavar="{init,check}")
    i = sub.add_parser("init", help="write DIR/session.yaml for the data files in DIR",
                       description="Detect each data file's format, columns, units and rate, print every "
                       "decision with its evidence and write DIR/session.yaml (evidence as comments). Each "
                       "file is one recording. A case the files do not settle stops and names the flag "
                       "to give.")
    i.add_argument("dir", help="session folder holding the data files (its parent's name is the campaign)")
    i.add_argument("--kind", choices=KINDS, help="session kind (default: rotated when a device is a "
                   "reference, else gravity-aligned)")
    i.add_argument("--device", action="append", type=_pair, default=[], metavar="ID=GLOB",
                   help="files matching GLOB (relative path or file name) belong to device ID; repeat "
                   "per device (default: every file to one device 'dut'; files holding two accelerometer "
                   "triads give two devices, ID-1 and ID-2, that read the same files)")
    i.add_argument("--reference", metavar="ID", help="the reference device of a rotated session (default: "
                   "the device whose files are mscip-csv or mscip-bin)")
    i.add_argument("--model", action="append", type=_pair, default=[], metavar="ID=MODEL",
                   help="device model (default: from the file header, else 'unknown')")
    i.add_argument("--rate", type=_positive, metavar="HZ", help="sample rate: needed for files without a "
                   "time column or with a sample index; otherwise the nominal rate")
    i.add_argument("--unit", choices=ACC_UNITS, help="acceleration unit of the csv files")
    i.add_argument("--lsb-per-g", type=_per_axis, metavar="N|X,Y,Z", help="counts per g (--unit counts)")
    i.add_argument("--zero-counts", type=_per_axis, metavar="Z|X,Y,Z", help="counts at zero specific "
                   "force (--unit counts; e.g. 32768 for an unsigned 16-bit converter)")
    i.add_argument("--time-unit", choices=TIME_UNITS, help="unit of the time column")
    i.add_argument("--time-column", metavar="NAME", help="the time column (a 0-based index when the file "
                   "has no column line)")
    i.add_argument("--columns", type=_columns, metavar="t=NAME,ax=NAME,ay=NAME,az=NAME",
                   help="every column by name (0-based indices without a column line); t may be left out "
                   "with --rate; gx=,gy=,gz= map the angular rate")
    i.add_argument("--gyro-unit", choices=GYRO_UNITS, help="unit of the angular-rate columns (default: "
                   "from their names or values; left unmapped when neither says)")
    site = i.add_mutually_exclusive_group()
    site.add_argument("--site", metavar="LAT,HEIGHT_M", help="latitude (degrees) and height (m) of the "
                      "site: local gravity from WGS-84")
    site.add_argument("--gravity", type=float, metavar="G", help="local gravity, m/s²")
    i.add_argument("--power-cycle", type=int, metavar="N", help="bias-instance id (default: the number of "
                   "an explicit pattern in the session folder's name, pc3, pc-003, power_cycle_3 or cycle3; "
                   "else 1, with a warning: other digits are usually a model number)")
    i.add_argument("--force", action="store_true", help="replace an existing session.yaml")
    c = sub.add_parser("check", help="validate sessions and say what labelling would do",
                       description="Validate each session, read every file and run labelling in memory "
                       "(nothing is written); print per file the format, rows, rate, duration, units, "
                       "‖mean‖ against g_local, the stationary segment or poses, and what labelling would "
                       "reject and why. Exit 0 when every recording would be labelled.")
    c.add_argument("dirs", nargs="+", help="session folders (or campaign folders of sessions)")
    add_params(c, "label", "the labelling parameters (e.g. params.yaml)")
    with_examples(i, "ofbe-session init mine/raw/lab/unit-07 --kind multi-position --site 48.15,520",
                  "ofbe-session init mine/raw/lab/unit-07 --kind multi-position --rate 100 --unit g   # "
                  "no time column",
                  "ofbe-session init mine/raw/lab/unit-07 --kind rotated --reference memsense --force")
    with_examples(c, "ofbe-session check mine/raw/lab/unit-07",
                  "ofbe-session check mine/raw/lab --params params.yaml      # every session, the pipeline's "
                  "settings")
    return with_examples(p, "ofbe-session init mine/raw/lab/unit-07 --kind multi-position --site 48.15,520",
                         "ofbe-session check mine/raw/lab/unit-07")


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """``ofbe-session init|check``; returns the exit status."""
    return _run(_parser().parse_args(argv))


def _run(args: argparse.Namespace) -> int:
    """``ofbe-session init|check`` on its parsed arguments; each subcommand's module
    (:mod:`~ofbe_data.cli.session_init`, :mod:`~ofbe_data.cli.session_check`) is imported here,
    after parsing (docs/architecture.md, "Command lines")."""
    if args.cmd == "init":
        from ofbe_data.cli.session_init import init

        return init(args)
    from ofbe_data.cli.session_check import check

    return check(args)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
