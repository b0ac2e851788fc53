"""``ofbe-convergence``: the convergence report of labelled stationary recordings
(ofbe_data.reports.convergence).
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from ofbe_data.core.cli import add_jobs, add_params, add_scheduler, command, fail, with_examples
from ofbe_data.core.errors import OfbeError
from ofbe_data.labelling.convergence import AXES, STATISTICS

PROG = "ofbe-convergence"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="ofbe-convergence",
        description="Convergence analysis of the label's running mean over labelled sessions: per-axis "
                    "statistics, histogram, example curve, Allan deviation per device, and the recommended "
                    "fewest samples per label (convergence.json, convergence.md, figures).")
    p.add_argument("paths", nargs="+", help="session folders or campaign folders (raw)")
    p.add_argument("--out", default="reports/convergence", help="report folder (default: %(default)s)")
    add_params(p, "label", "the labelling parameters, and whose 'convergence:' section the recommendation "
                           "rule (e.g. params.yaml)")
    p.add_argument("--axis", choices=AXES, help="axis of the recommendation (default: x)")
    p.add_argument("--statistic", choices=STATISTICS, help="statistic of the recommendation (default: mean)")
    p.add_argument("--example", help="SESSION/RECORDING/DEVICE for the example curve "
                                     "(default: the one closest to the mean)")
    add_jobs(p)
    add_scheduler(p)
    p.add_argument("--quiet", action="store_true", help="no progress bar, no summary")
    return with_examples(
        p, "ofbe-convergence raw/gravity-aligned --out mine/convergence --jobs 2",
        "ofbe-convergence raw/gravity-aligned --params params.yaml   # the pipeline's label settings")


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ofbe-convergence``: 0 written, 1 bad data, 2 usage."""
    return _run(_parser().parse_args(argv))


def _run(args: argparse.Namespace) -> int:
    """``ofbe-convergence`` on its parsed arguments; the report's modules are imported here, after
    parsing (docs/architecture.md, "Command lines")."""
    from ofbe_data.io.typedconfig import read_section
    from ofbe_data.labelling.batch import expand_sessions
    from ofbe_data.labelling.labels import label_params_from
    from ofbe_data.reports.convergence import analyse, convergence_params_from, write_report

    try:
        if args.jobs < 1:
            return fail(PROG, f"--jobs: expected an integer ≥ 1, found {args.jobs}", 2)
        label_data = read_section(args.params, "label") if args.params else {}
        label_data = {k: v for k, v in label_data.items() if k != "min_samples"}
        label_params = label_params_from(label_data, args.params or "command line")
        conv_data = dict(read_section(args.params, "convergence")) if args.params else {}
        if args.axis:
            conv_data["axis"] = args.axis
        if args.statistic:
            conv_data["statistic"] = args.statistic
        params = convergence_params_from(conv_data, args.params or "command line")
        folders = expand_sessions(args.paths)
    except OfbeError as exc:
        return fail(PROG, str(exc), 2)
    jobs = min(args.jobs, os.cpu_count() or 1, len(folders))
    try:
        analysis = analyse(folders, label_params, jobs, progress=not args.quiet, scheduler=args.scheduler)
        doc = write_report(analysis, Path(args.out), params, label_params, args.example)
    except OfbeError as exc:
        return fail(PROG, str(exc), 1)
    if not args.quiet:
        x = doc["axes"][params.axis]
        print(f"ofbe-convergence: {doc['n_recordings']} recordings; axis {params.axis} converges after "
              f"{x['mean']:.0f} ± {x['std']:.0f} samples; recommended label length "
              f"{doc['recommended_label_start']} -> {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
