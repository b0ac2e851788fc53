"""Label many sessions: expand folders into sessions, label them in worker processes, write each
session's files and each campaign's fit."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from ofbe_data.core.errors import OfbeError
from ofbe_data.core.parallel import map_progress
from ofbe_data.io.manifest import MANIFEST_NAME
from ofbe_data.labelling.labels import (
    LabelParams,
    SessionLabels,
    label_session,
)
from ofbe_data.labelling.store import fit_campaign, write_campaign_fit, write_session


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
