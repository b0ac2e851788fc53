"""``ofbe-index``: reports/index.md, linking every table and figure (ofbe_data.reports.index)."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path

from ofbe_data.core.cli import command, fail, with_examples
from ofbe_data.core.errors import OfbeError
from ofbe_data.reports.defaults import DEFAULT_CAMPAIGNS, DEFAULT_PROTOCOLS, TIMINGS_FORMAT

PROG = "ofbe-index"

# ----------------------------------------------------------------------------- command line


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Write reports/index.md: one page linking the benchmark (the paper's Table 3), the "
                    "convergence and small-angle reports, label fidelity, datasets, training and stage "
                    "times.")
    p.add_argument("--root", default=".", help="project root (default: %(default)s)")
    p.add_argument("--out", help="output file (default: ROOT/reports/index.md); links are relative to "
                                 "ROOT/reports")
    p.add_argument("--campaigns", nargs="*", default=list(DEFAULT_CAMPAIGNS),
                   help="campaigns (default: %(default)s)")
    p.add_argument("--protocols", nargs="*", default=list(DEFAULT_PROTOCOLS),
                   help="benchmark protocols (default: %(default)s)")
    p.add_argument("--profile", help="name of the run profile, shown on the page")
    p.add_argument("--timings", help=f"JSON file of stage times, {TIMINGS_FORMAT}; a missing file is noted "
                                     "on the page")
    p.add_argument("--quiet", action="store_true", help="no summary line")
    return with_examples(p, "ofbe-index                      # reports/index.md from the pipeline's outputs")


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """Command line of ``reports/index.md``.

    Returns
    -------
    int
        0 on success; 1 when the reports folder is missing or an input cannot be read;
        2 on a bad timings file (argparse also exits 2 on bad options).
    """
    return _run(_parser().parse_args(argv))


def _run(args: argparse.Namespace) -> int:
    """``ofbe-index`` on its parsed arguments; the report's modules are imported here, after
    parsing (docs/architecture.md, "Command lines")."""
    from ofbe_data.reports.index import read_timings, write_index

    root = Path(args.root)
    out = Path(args.out) if args.out else root / "reports" / "index.md"
    try:
        timings = read_timings(args.timings) if args.timings else None
    except OfbeError as exc:
        return fail(PROG, str(exc), 2)
    try:
        write_index(root, out, list(args.campaigns), list(args.protocols), timings, profile=args.profile)
    except (OfbeError, OSError) as exc:
        return fail(PROG, str(exc), 1)
    if not args.quiet:
        total = "" if timings is None else f"; stages took {math.fsum(timings.values()):.1f} s in total"
        print(f"{PROG}: {len(args.protocols)} protocols, {len(args.campaigns)} campaigns{total} -> {out}",
              file=sys.stderr)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
