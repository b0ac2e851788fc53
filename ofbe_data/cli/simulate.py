"""``ofbe-simulate``: the simulator's command-line entry (console script in pyproject.toml)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from ofbe_data.errors import OfbeError


def _fail(prog: str, message: str) -> int:
    print(f"{prog}: error: {message}", file=sys.stderr)
    return 2


def main(argv: Sequence[str] | None = None) -> int:
    """``ofbe-simulate CONFIG_OR_PROFILE --out raw/<campaign> [--seed N]``.

    Returns
    -------
    int
        0 on success, 2 with a one-line reason on bad input.
    """
    from ofbe_data.simulator import builtin_profiles, simulate_campaign

    parser = argparse.ArgumentParser(
        prog="ofbe-simulate",
        description="Write a simulated campaign (sessions in the raw formats plus _truth/). "
                    "Built-in profiles: " + ", ".join(builtin_profiles()) + ".",
    )
    parser.add_argument("config", metavar="CONFIG_OR_PROFILE",
                        help="built-in profile name or YAML config file (may name a base "
                             "'profile' and override any of its keys)")
    parser.add_argument("--out", required=True, help="campaign folder to create, raw/<campaign>")
    parser.add_argument("--seed", type=int, default=None, help="seed (default: the config's)")
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    parser.add_argument("--force", action="store_true", help="replace an existing --out folder")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    if args.jobs < 1:
        return _fail(parser.prog, f"--jobs: expected an integer >= 1, found {args.jobs}")
    try:
        result = simulate_campaign(args.config, args.out, seed=args.seed, jobs=args.jobs,
                                   force=args.force, progress=not args.quiet)
    except OfbeError as exc:
        return _fail(parser.prog, str(exc))
    except OSError as exc:
        return _fail(parser.prog, f"{exc.filename or args.out}: {exc.strerror or exc}")
    print(f"{result.folder}: campaign {result.campaign}, seed {result.seed}, "
          f"{result.sessions} sessions, {result.files} files, {result.bytes / 1e6:.1f} MB")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
