"""``ofbe-label``: label raw sessions (one or many, or whole campaign folders).

Exit status: 0 when every named session was labelled or cleanly rejected; 1 when a session
could not be read (one line per such session, naming the file and line; the other sessions
are still labelled and written); 2 on a usage or parameter error.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from ofbe_data.core.atomic import folders_under, remove_new_empty_folders
from ofbe_data.core.cli import add_jobs, add_params, add_scheduler, command, fail, io_failure, with_examples
from ofbe_data.core.errors import OfbeError

if TYPE_CHECKING:
    from ofbe_data.labelling.labels import SessionLabels

PROG = "ofbe-label"


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="ofbe-label",
        description="Label raw sessions: apparent bias per recording and DUT (and zero-g offsets "
                    "where the campaign fit determines them). Writes <out>/<campaign>/<session>.parquet, "
                    "<session>.rejected.json and campaign_fit.json.")
    p.add_argument("paths", nargs="+", help="session folders (with session.yaml) or campaign folders")
    p.add_argument("--out", default="processed/labels", help="output folder (default: %(default)s)")
    add_jobs(p)
    add_scheduler(p)
    add_params(p, "label", "the labelling parameters (e.g. params.yaml)")
    p.add_argument("--min-samples", type=int, help="override label.min_samples")
    p.add_argument("--min-samples-from", metavar="REPORT",
                   help="take label.min_samples from a convergence report (reports/convergence/"
                        "convergence.json) unless --params or --min-samples set it")
    p.add_argument("--plots", action="store_true",
                   help="also draw each labelled session: <out>/<campaign>/<session>.png with ‖f‖ and the "
                        "three axes over time and every labelled interval (pose) shaded and numbered")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no summary")
    p.add_argument("--verbose", action="store_true",
                   help="also print each session's warnings and notes (information on a good session, such "
                        "as the poses found and the threshold; not counted as warnings); both are in "
                        "<session>.rejected.json either way")
    return with_examples(
        p, "ofbe-label mine/raw/lab/unit-07 --out mine/labels --plots       # one session, with a figure",
        "ofbe-label raw/rotated --out mine/labels --params params.yaml --jobs 2   # the pipeline's settings",
        "ofbe-label mine/raw/lab --out mine/labels --verbose                 # every warning and note")


def session_lines(labels: SessionLabels) -> list[str]:
    """``--verbose``: one line per warning (``warning: …``) and per note (plain) of a session."""
    where = f"{labels.manifest.campaign}/{labels.manifest.session}"
    return ([f"{PROG}: warning: {where}: {w}" for w in labels.warnings]
            + [f"{PROG}: {where}: {n}" for n in labels.notes])


def _count(n: int, what: str) -> str:
    """``1 session``, ``2 sessions``."""
    return f"{n} {what}" if n == 1 else f"{n} {what}s"


def summary(done: Sequence[SessionLabels], failed: int) -> str:
    """The run's one-line summary: sessions, labels (of how many recordings, how many of them
    poses of multi-position recordings), rejections and warnings (notes, which are information,
    are not counted).

    A label is one row: a (recording, device) pair, or one pose of it in a multi-position
    recording, so 18 poses of one recording read "18 labels of 1 recording (18 poses)".
    """
    rows = [r for s in done for r in s.rows]
    recordings = {(s.manifest.session, r["recording"]) for s in done for r in s.rows}
    poses = sum(1 for r in rows if r.get("pose") is not None and r.get("pose") == r.get("pose"))
    rejected = sum(len(s.rejections) for s in done)
    warnings = sum(len(s.warnings) for s in done)
    tail = f", {rejected} rejected, {_count(warnings, 'warning')}"
    if not rows:
        return f"{_count(len(done), 'session')} read, {failed} failed; nothing labelled" + tail
    of = f"{_count(len(rows), 'label')} of {_count(len(recordings), 'recording')}"
    if poses:
        of += f" ({_count(poses, 'pose')})"
    return f"{_count(len(done), 'session')} labelled, {failed} failed; {of}" + tail


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ofbe-label``: 0 every session labelled or cleanly rejected, 1 a session
    could not be read or nothing was labelled, 2 usage."""
    return _run(_parser().parse_args(argv))


def _run(args: argparse.Namespace) -> int:
    """``ofbe-label`` on its parsed arguments; the labelling modules are imported here, after
    parsing (docs/architecture.md, "Command lines")."""
    from ofbe_data.io.manifest import MANIFEST_NAME
    from ofbe_data.labelling.batch import (
        check_output_folder,
        expand_sessions,
        label_sessions,
        skipped_folders,
    )
    from ofbe_data.labelling.convergence import read_recommendation
    from ofbe_data.labelling.labels import label_params_from, read_label_section

    before = folders_under(args.out)  # what a failed run may not remove
    try:
        data = read_label_section(args.params) if args.params else {}
        if args.min_samples_from and args.min_samples is None and "min_samples" not in data:
            data = {**data, "min_samples": read_recommendation(args.min_samples_from)}
        if args.min_samples is not None:
            data = {**data, "min_samples": args.min_samples}
        params = label_params_from(data, args.params or "command line")
        if args.jobs < 1:
            return fail(PROG, f"--jobs: expected an integer ≥ 1, found {args.jobs}", 2)
        folders = expand_sessions(args.paths)
        skipped = skipped_folders(args.paths)
        check_output_folder(Path(args.out))
    except OfbeError as exc:
        return fail(PROG, str(exc), 2)
    jobs = min(args.jobs, os.cpu_count() or 1, len(folders))
    try:
        outcomes = label_sessions(folders, params, Path(args.out), jobs, progress=not args.quiet,
                                  scheduler=args.scheduler)
    except OfbeError as exc:  # the Dask scheduler cannot be reached
        return fail(PROG, str(exc), 1)
    except OSError as exc:
        remove_new_empty_folders(args.out, before)  # the campaign folders this run made, left empty
        return io_failure(PROG, exc, args.out, "the labels could not be written")
    failed = [o for o in outcomes if o.error]
    for o in failed:
        stale = (f" (removed its labels of an earlier run: {', '.join(map(str, o.removed))})"
                 if o.removed else "")
        print(f"ofbe-label: error: {o.error}{stale}", file=sys.stderr)
    done = [o.labels for o in outcomes if o.labels is not None]
    if args.plots:
        from ofbe_data.reports.session_plot import plot_session

        for s in done:
            plot_session(s, Path(args.out) / s.manifest.campaign / f"{s.manifest.session}.png")
    rows = sum(len(s.rows) for s in done)
    rejected = [r for s in done for r in s.rejections]
    if args.verbose:
        for s in done:
            for line in session_lines(s):
                print(line, file=sys.stderr)
    if not args.quiet:
        for folder in skipped:
            print(f"ofbe-label: note: {folder}: no {MANIFEST_NAME} in it, not a session (skipped)",
                  file=sys.stderr)
        print(f"ofbe-label: {summary(done, len(failed))} -> {args.out}"
              + (f" (with {_count(len(done), 'session figure')})" if args.plots else ""), file=sys.stderr)
    if failed:
        return 1
    if rows == 0:
        reasons = Counter(r.reason for r in rejected).most_common(3)
        why = ", ".join(f"{n} {reason}" for reason, n in reasons) or "no recordings"
        return fail(PROG, f"no recording was labelled ({why}; see the <session>.rejected.json files in "
                          f"{args.out})", 1)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
