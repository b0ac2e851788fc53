"""``ofbe-simulate``: the simulator's command-line entry (console script in pyproject.toml)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from importlib import resources

from ofbe_data.core.cli import (
    EXIT_DATA,
    EXIT_USAGE,
    add_jobs,
    add_scheduler,
    command,
    fail,
    io_failure,
    with_examples,
)
from ofbe_data.core.errors import OfbeError
from ofbe_data.core.scheduler import SchedulerError, TaskError

PROG = "ofbe-simulate"


def profile_names() -> list[str]:
    """The built-in profiles' names, read from ``ofbe_data/simulator/profiles/`` without importing
    the simulator (:func:`ofbe_data.simulator.builtin_profiles` gives the same list)."""
    folder = resources.files("ofbe_data").joinpath("simulator", "profiles")
    return sorted(p.name[:-5] for p in folder.iterdir() if p.name.endswith(".yaml"))


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="ofbe-simulate",
        description="Write a simulated campaign (sessions in the raw formats plus _truth/). "
                    "Built-in profiles: " + ", ".join(profile_names()) + ".",
    )
    parser.add_argument("config", metavar="CONFIG_OR_PROFILE",
                        help="built-in profile name or YAML config file (may name a base "
                             "'profile' and override any of its keys)")
    parser.add_argument("--out", required=True, help="campaign folder to create, raw/<campaign>")
    parser.add_argument("--seed", type=int, default=None, help="seed (default: the config's)")
    parser.add_argument("--reference-format", choices=("mscip-csv", "mscip-bin"), default=None,
                        help="file format of the reference IMU's recordings (default: the config's "
                             "reference_format, mscip-csv unless set)")
    add_jobs(parser)
    add_scheduler(parser)
    parser.add_argument("--force", action="store_true", help="replace an existing --out folder")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    with_examples(parser,
                  "ofbe-simulate tiny-rotated --out raw/my-tiny            # a built-in profile",
                  "ofbe-simulate rotated --out raw/rot-seed7 --seed 7 --jobs 2",
                  "ofbe-simulate lab.yaml --out raw/lab-2026          # your config: a base profile + keys",
                  "ofbe-simulate free-living --out raw/wear --jobs 2  # 50 week-long wearable recordings")
    return parser


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """``ofbe-simulate CONFIG_OR_PROFILE --out raw/<campaign> [--seed N] [--reference-format F]``.

    Returns
    -------
    int
        0 on success, 2 with a one-line reason on bad input.
    """
    return _run(_parser().parse_args(argv))


def _run(args: argparse.Namespace) -> int:
    """``ofbe-simulate`` on its parsed arguments; the simulator is imported here, after parsing
    (docs/architecture.md, "Command lines")."""
    from ofbe_data.simulator import simulate_campaign

    if args.jobs < 1:
        return fail(PROG, f"--jobs: expected an integer >= 1, found {args.jobs}", EXIT_USAGE)
    try:
        overrides = ({"reference_format": args.reference_format}
                     if args.reference_format is not None else None)
        result = simulate_campaign(args.config, args.out, seed=args.seed, jobs=args.jobs,
                                   force=args.force, progress=not args.quiet, overrides=overrides,
                                   scheduler=args.scheduler)
    except (TaskError, SchedulerError) as exc:  # a worker died, or the Dask scheduler did not answer
        return fail(PROG, str(exc), EXIT_DATA)
    except OfbeError as exc:
        return fail(PROG, str(exc), EXIT_USAGE)
    except OSError as exc:
        return io_failure(PROG, exc, args.out, "the campaign could not be written")
    print(f"{result.folder}: campaign {result.campaign}, seed {result.seed}, "
          f"{result.sessions} sessions, {result.files} files, {result.bytes / 1e6:.1f} MB")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
