"""Label many sessions: expand folders into sessions, label them in worker processes, write each
session's files and each campaign's fit."""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ofbe_data.core.errors import OfbeError
from ofbe_data.core.parallel import TaskFailure, map_progress
from ofbe_data.io.manifest import MANIFEST_NAME, SessionManifest, load_manifest
from ofbe_data.labelling.labels import (
    LabelParams,
    SessionLabels,
    label_session,
)
from ofbe_data.labelling.store import fit_campaign, write_campaign_fit, write_session


class UsageError(OfbeError):
    """A path on the command line is neither a session nor a campaign folder, or the output
    folder cannot be written."""


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


def skipped_folders(paths: Sequence[str | Path]) -> list[Path]:
    """Subfolders of the campaign folders named by ``paths`` that :func:`expand_sessions` passes
    over because they hold no ``session.yaml``, so that a command can say so.

    Folders whose names start with ``_`` or ``.`` (the simulator's folder of true values, hidden folders)
    are meant to be passed over and are not listed.
    """
    out: list[Path] = []
    for arg in paths:
        p = Path(arg)
        if p.is_dir() and not (p / MANIFEST_NAME).is_file():
            out += sorted(c for c in p.iterdir() if c.is_dir() and not c.name.startswith(("_", "."))
                          and not (c / MANIFEST_NAME).is_file())
    return out


@dataclass
class Outcome:
    """What happened to one session.

    ``removed`` lists label files of an earlier run that this run's failure removed (so that
    no stale label of the session stays readable as current).
    """

    folder: Path
    labels: SessionLabels | None = None
    error: str = ""
    removed: list[Path] = field(default_factory=list)


def check_output_folder(out_dir: Path) -> None:
    """Make sure the label products can be written under ``out_dir`` before any work is done.

    Raises
    ------
    UsageError
        ``out_dir`` is an existing file, or it cannot be created or written to.
    """
    if out_dir.exists() and not out_dir.is_dir():
        raise UsageError(f"--out {out_dir}: expected a folder for the labels, found an existing file")
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=out_dir):
            pass
    except OSError as exc:
        raise UsageError(f"--out {out_dir}: expected a folder the labels can be written to, found "
                         f"{exc.strerror or exc} (choose another --out or fix its permissions)") from None


def _manifest(folder: Path) -> SessionManifest | None:
    """A session folder's manifest, or None when it cannot be read (labelling the session then
    reads it again and fails with the reason)."""
    try:
        return load_manifest(folder)
    except (OfbeError, OSError):
        return None


def _session_id(folder: Path) -> tuple[str, str] | None:
    """(campaign, session) of a session folder's manifest, or None when it cannot be read."""
    m = _manifest(folder)
    return None if m is None else (m.campaign, m.session)


def _duplicates(folders: Sequence[Path], manifests: dict[Path, SessionManifest | None]) -> dict[Path, str]:
    """Folders whose (campaign, session) id another folder of the batch also has → the error.

    ``manifests`` holds each folder's manifest (None where it cannot be read)."""
    first: dict[tuple[str, str], Path] = {}
    errors: dict[Path, str] = {}
    for f in folders:
        m = manifests[f]
        if m is None:
            continue
        sid = (m.campaign, m.session)
        if sid in first:
            msg = (f"session {sid[0]}/{sid[1]} is in two folders of this batch, {first[sid]} and {f}: "
                   "expected one folder per session id (rename one session in its session.yaml)")
            errors[first[sid]] = errors[f] = msg
        else:
            first[sid] = f
    return errors


def _remove_stale(folder: Path, out_dir: Path) -> list[Path]:
    """Delete the label files an earlier run wrote for this (now failing) session."""
    sid = _session_id(folder)
    if sid is None:
        return []
    removed = []
    for name in (f"{sid[1]}.parquet", f"{sid[1]}.rejected.json"):
        path = out_dir / sid[0] / name
        if path.is_file():
            path.unlink()
            removed.append(path)
    return removed


def _run_one(args: tuple[Path, LabelParams, SessionManifest | None]) -> Outcome:
    folder, params, manifest = args
    try:
        return Outcome(folder, label_session(folder, params, manifest=manifest))
    except OfbeError as exc:
        return Outcome(folder, error=str(exc))
    except OSError as exc:  # unreadable input the readers did not classify
        return Outcome(folder, error=f"{folder}: {type(exc).__name__}: {exc}")
    except Exception as exc:  # noqa: BLE001 - a bad session must never stop the others
        return Outcome(folder, error=f"{folder}: internal error while labelling ({type(exc).__name__}: "
                                     f"{exc}); please report it with this session")


def label_sessions(folders: Sequence[Path], params: LabelParams, out_dir: Path, jobs: int = 1,
                   progress: bool = True, scheduler: str = "processes") -> list[Outcome]:
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
    scheduler
        Where the sessions are labelled: ``processes``, ``dask`` or ``tcp://host:port``
        (:func:`ofbe_data.core.parallel.map_progress`).

    Returns
    -------
    list of Outcome
        In the order of ``folders``. Two folders with the same (campaign, session) id both
        fail without being labelled; a session whose worker process died fails with that
        reason; a failed session's label files from an earlier run are removed
        (``Outcome.removed``).

    Raises
    ------
    OSError
        Writing the products failed (a full disk): every file is written atomically, so
        what was written is whole, and the caller reports the error.
    """
    manifests = {f: _manifest(f) for f in folders}  # read once: the duplicate check and labelling
    dup = _duplicates(folders, manifests)
    todo = [f for f in folders if f not in dup]
    results = map_progress(_run_one, [(f, params, manifests[f]) for f in todo], jobs=jobs, desc="labelling",
                           unit="session", progress=progress, scheduler=scheduler, on_error="collect")
    done = {f: (Outcome(f, error=f"{f}: {r.reason}") if isinstance(r, TaskFailure) else r)
            for f, r in zip(todo, results, strict=True)}
    outcomes = [done.get(f) or Outcome(f, error=dup[f]) for f in folders]
    for o in outcomes:
        if o.error:
            o.removed = _remove_stale(o.folder, out_dir)
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
