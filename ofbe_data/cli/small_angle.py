"""``ofbe-small-angle``: the small-angle (levelled calibration) leak report
(ofbe_data.reports.small_angle).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from ofbe_data.core.cli import command, with_examples
from ofbe_data.labelling.smallangle import MEASURES
from ofbe_data.reports.defaults import SMALL_ANGLE_OUT

PROG = "ofbe-small-angle"


def _positive(upper: float | None = None) -> Callable[[str], float]:
    """An argparse type: a finite float > 0 (and < ``upper`` when given)."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, found {text!r}") from None
        if not (math.isfinite(value) and value > 0.0 and (upper is None or value < upper)):
            bound = f" below {upper:g}" if upper is not None else ""
            raise argparse.ArgumentTypeError(f"expected a positive number{bound}, found {text!r}")
        return value

    return parse


def build_parser() -> argparse.ArgumentParser:
    """The command-line parser of ``ofbe-small-angle``."""
    p = argparse.ArgumentParser(
        prog="ofbe-small-angle",
        description="Gravity leak of a levelled calibration over roll × pitch, and the tilt at which "
                    "it reaches a limit (paper §4).")
    p.add_argument("--out", type=Path, default=SMALL_ANGLE_OUT,
                   help=f"output folder (default: {SMALL_ANGLE_OUT})")
    p.add_argument("--range-deg", type=_positive(90.0), default=10.0,
                   help="grid half-width: roll and pitch span −R…+R degrees (default: 10)")
    p.add_argument("--step-deg", type=_positive(), default=0.05,
                   help="grid spacing, degrees (default: 0.05)")
    p.add_argument("--limit-mg", type=_positive(1000.0), default=50.0,
                   help="tolerated leak, mg (default: 50)")
    p.add_argument("--measure", choices=MEASURES, default="max-axis",
                   help="leak measure: the largest per-axis leak (default) or the leak vector's norm")
    return with_examples(p, "ofbe-small-angle --out mine/small_angle",
                         "ofbe-small-angle --out mine/small_angle --limit-mg 20")


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ofbe-small-angle``.

    Returns
    -------
    int
        0 on success, 2 on bad options (argparse exits with 2 and a one-line message).
    """
    parser = build_parser()
    return _run(parser, parser.parse_args(argv))


def _run(parser: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """``ofbe-small-angle`` on its parsed arguments (``parser`` reports a grid too large); the
    report's modules are imported here, after parsing (docs/architecture.md, "Command lines")."""
    from ofbe_data.reports.small_angle import MAX_GRID_POINTS, write_report

    if args.step_deg > 2.0 * args.range_deg:
        parser.error(f"--step-deg: expected at most twice --range-deg ({2 * args.range_deg:g}), "
                     f"found {args.step_deg:g}")
    n_points = int(round(2.0 * args.range_deg / args.step_deg)) + 1
    if n_points > MAX_GRID_POINTS:
        parser.error(f"--step-deg: expected a grid of at most {MAX_GRID_POINTS} points per axis, "
                     f"found {n_points} (raise --step-deg)")
    try:
        m = write_report(args.out, args.range_deg, args.step_deg, args.limit_mg, args.measure)
    except (ValueError, OSError) as exc:
        print(f"ofbe-small-angle: {exc}", file=sys.stderr)
        return 1
    th = m["threshold_deg"]
    print(f"ofbe-small-angle: {m['limit_mg']:g} mg reached at {th['pitch']:.4f}° (pitch), "
          f"{th['roll']:.4f}° (roll), {th['combined']:.4f}° (combined, per axis); wrote {args.out}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
