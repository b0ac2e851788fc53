"""``ofbe-label``: label raw sessions (one or many, or whole campaign folders).

Exit status: 0 when every named session was labelled or cleanly rejected; 1 when a session
could not be read (one line per such session, naming the file and line; the other sessions
are still labelled and written); 2 on a usage or parameter error.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ofbe_data.convergence import read_recommendation
from ofbe_data.errors import OfbeError
from ofbe_data.labels import LabelParams, SessionLabels, label_params_from, label_session, read_label_section
from ofbe_data.labelstore import fit_campaign, write_campaign_fit, write_session
from ofbe_data.manifest import MANIFEST_NAME
from ofbe_data.parallel import map_progress


class UsageError(OfbeError):
    """A path on the command line is neither a session nor a campaign folder."""


def expand_sessions(paths: Sequence[str | Path]) -> list[Path]:
    """Session folders named by the arguments, in order, without repeats.

    A folder holding ``session.yaml`` (or the manifest itself) is a session; a folder whose
    subfolders hold sessions is a campaign (its sessions in name order; the simulator's truth folder and other
    folders without a manifest are ignored).

    Raises
    ------
    UsageError
        A path that does not exist or holds no session.
    """
    out: list[Path] = []
    for arg in paths:
        p = Path(arg)
        if p.is_file() and p.name == MANIFEST_NAME:
            p = p.parent
        if (p / MANIFEST_NAME).is_file():
            found = [p]
        elif p.is_dir():
            found = sorted(c for c in p.iterdir() if c.is_dir() and (c / MANIFEST_NAME).is_file())
            if not found:
                raise UsageError(f"{p}: expected a session folder (with {MANIFEST_NAME}) or a campaign "
                                 f"folder of sessions, found a folder with neither")
        else:
            raise UsageError(f"{p}: expected a session or campaign folder, found no such folder")
        for f in found:
            if f.resolve() not in {o.resolve() for o in out}:
                out.append(f)
    return out


@dataclass
class Outcome:
    """What happened to one session."""

    folder: Path
    labels: SessionLabels | None = None
    error: str = ""


def _run_one(args: tuple[Path, LabelParams]) -> Outcome:
    folder, params = args
    try:
        return Outcome(folder, label_session(folder, params))
    except OfbeError as exc:
        return Outcome(folder, error=str(exc))
    except OSError as exc:  # unreadable input the readers did not classify
        return Outcome(folder, error=f"{folder}: {type(exc).__name__}: {exc}")
    except Exception as exc:  # noqa: BLE001 - a bad session must never stop the others
        return Outcome(folder, error=f"{folder}: internal error while labelling ({type(exc).__name__}: "
                                     f"{exc}); please report it with this session")


def label_sessions(folders: Sequence[Path], params: LabelParams, out_dir: Path, jobs: int = 1,
                   progress: bool = True) -> list[Outcome]:
    """Label sessions (in parallel), fit each campaign, write the products.

    Parameters
    ----------
    folders
        Session folders.
    params
        Labelling parameters.
    out_dir
        Products go to ``out_dir/<campaign>/``.
    jobs
        Worker processes.
    progress
        Show a progress bar (when more than one session).

    Returns
    -------
    list of Outcome
        In the order of ``folders``.
    """
    work = [(f, params) for f in folders]
    outcomes = map_progress(_run_one, work, jobs=jobs, desc="labelling", unit="session", progress=progress)
    campaigns: dict[str, list[SessionLabels]] = {}
    for o in outcomes:
        if o.labels is not None:
            campaigns.setdefault(o.labels.manifest.campaign, []).append(o.labels)
    for campaign, sessions in campaigns.items():
        fits = fit_campaign(sessions, params)
        for s in sessions:
            write_session(s, params, out_dir)
        write_campaign_fit(campaign, fits, sessions, params, out_dir)
    return outcomes


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="ofbe-label",
        description="Label raw sessions: apparent bias per recording and DUT (and zero-g offsets "
                    "where the campaign fit determines them). Writes <out>/<campaign>/<session>.parquet, "
                    "<session>.rejected.json and campaign_fit.json.")
    p.add_argument("paths", nargs="+", help="session folders (with session.yaml) or campaign folders")
    p.add_argument("--out", default="processed/labels", help="output folder (default: %(default)s)")
    p.add_argument("--jobs", type=int, default=1, help="worker processes (default: %(default)s)")
    p.add_argument("--params", help="YAML file with labelling parameters (its 'label:' section "
                                    "if it has one, e.g. params.yaml)")
    p.add_argument("--min-samples", type=int, help="override label.min_samples")
    p.add_argument("--min-samples-from", metavar="REPORT",
                   help="take label.min_samples from a convergence report (reports/convergence/"
                        "convergence.json) unless --params or --min-samples set it")
    p.add_argument("--quiet", action="store_true", help="no progress bar, no summary")
    return p


def _fail(message: str, code: int) -> int:
    print(f"ofbe-label: error: {message}", file=sys.stderr)
    return code


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        data = read_label_section(args.params) if args.params else {}
        if args.min_samples_from and args.min_samples is None and "min_samples" not in data:
            data = {**data, "min_samples": read_recommendation(args.min_samples_from)}
        if args.min_samples is not None:
            data = {**data, "min_samples": args.min_samples}
        params = label_params_from(data, args.params or "command line")
        if args.jobs < 1:
            return _fail(f"--jobs: expected an integer ≥ 1, found {args.jobs}", 2)
        folders = expand_sessions(args.paths)
    except OfbeError as exc:
        return _fail(str(exc), 2)
    jobs = min(args.jobs, os.cpu_count() or 1, len(folders))
    outcomes = label_sessions(folders, params, Path(args.out), jobs, progress=not args.quiet)
    failed = [o for o in outcomes if o.error]
    for o in failed:
        print(f"ofbe-label: error: {o.error}", file=sys.stderr)
    if not args.quiet:
        done = [o.labels for o in outcomes if o.labels is not None]
        rows = sum(len(s.rows) for s in done)
        rejected = sum(len(s.rejections) for s in done)
        warnings = sum(len(s.warnings) for s in done)
        print(f"ofbe-label: {len(done)} sessions labelled, {len(failed)} failed; {rows} recordings "
              f"labelled, {rejected} rejected, {warnings} warnings -> {args.out}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
