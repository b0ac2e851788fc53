"""Campaign simulator: writes sessions in the raw formats, with truth files.

The simulator stands in for the paper's unpublished dataset. Its error model and
defaults are documented in docs/sensor-model.md; :func:`simulate_campaign` is what
``ofbe-simulate`` runs. It may import :mod:`ofbe_data.core` and :mod:`ofbe_data.io` (it writes
the same formats the readers read), never the labelling: the labeller must never depend on how
the data were made.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ofbe_data.core.atomic import atomic_directory, write_bytes_atomic
from ofbe_data.core.errors import ConfigError, OutputExistsError
from ofbe_data.core.parallel import map_progress
from ofbe_data.io.manifest import ID_PATTERN
from ofbe_data.simulator.campaign import (
    CampaignDraw,
    SessionData,
    draw_campaign,
    session_name,
    simulate_session,
    truth_config,
)
from ofbe_data.simulator.config import SimConfig, builtin_profiles, load_config, load_config_from
from ofbe_data.simulator.wearconfig import FREE_LIVING
from ofbe_data.simulator.wearfiles import write_free_living
from ofbe_data.simulator.writing import write_session

__all__ = ["CampaignResult", "builtin_profiles", "generate_sessions", "load_config",
           "simulate_campaign"]


@dataclass(frozen=True)
class CampaignResult:
    """What :func:`simulate_campaign` wrote."""

    folder: Path
    campaign: str
    seed: int
    sessions: int
    files: int
    bytes: int


def _seeds(seed: int, cfg: SimConfig) -> tuple[np.random.SeedSequence, list[np.random.SeedSequence],
                                                 list[np.random.SeedSequence]]:
    root = np.random.SeedSequence(seed)
    children = root.spawn(2 * cfg.sessions + 1)
    return children[0], children[1:cfg.sessions + 1], children[cfg.sessions + 1:]


def generate_sessions(cfg: SimConfig, seed: int | None = None, campaign: str = "sim",
                      folder: Path = Path("."), indices: list[int] | None = None,
                      ) -> tuple[CampaignDraw, list[SessionData]]:
    """Simulate sessions in memory (no files): for statistics and tests.

    Parameters
    ----------
    cfg
        Configuration.
    seed
        Seed (defaults to ``cfg.seed``).
    campaign
        Campaign id.
    folder
        Campaign folder the manifests refer to.
    indices
        Which sessions (0-based); all by default.

    Returns
    -------
    draw, sessions
        The campaign-level draws and the simulated sessions.
    """
    seed = cfg.seed if seed is None else seed
    camp_seq, sess_seqs, _ = _seeds(seed, cfg)
    draw = draw_campaign(cfg, camp_seq)
    idx = range(cfg.sessions) if indices is None else indices
    sessions = [simulate_session(cfg, draw, i, campaign, sess_seqs[i],
                                 folder / session_name(cfg, i)) for i in idx]
    return draw, sessions


def _write_one(args: tuple[SimConfig, CampaignDraw, int, str, np.random.SeedSequence,
                           np.random.SeedSequence, Path]) -> tuple[int, int]:
    cfg, draw, index, campaign, sess_seq, garble_seq, tmp = args
    name = session_name(cfg, index)
    data = simulate_session(cfg, draw, index, campaign, sess_seq, tmp / name)
    write_session(data, tmp / name, tmp / "_truth" / f"{name}.json", cfg.dut_model.garble_rate,
                  garble_seq)
    files = sum(len(r.files) for r in data.manifest.recordings) + 2
    size = sum(p.stat().st_size for p in (tmp / name).rglob("*") if p.is_file())
    return files, size


def simulate_campaign(config: str | Path | SimConfig, out: str | Path, *, seed: int | None = None,
                      jobs: int = 1, force: bool = False, progress: bool = True,
                      overrides: dict[str, Any] | None = None,
                      scheduler: str = "processes") -> CampaignResult:
    """Write a simulated campaign: one folder per session plus ``_truth/``.

    The campaign is built in a temporary folder beside ``out`` and renamed into place
    when complete, so an interrupted run leaves nothing partial.

    Parameters
    ----------
    config
        Profile name, YAML file or a loaded configuration.
    out
        Campaign folder to create (``raw/<campaign>``).
    seed
        Seed; defaults to the configuration's.
    jobs
        Worker processes.
    force
        Replace an existing ``out``.
    progress
        Show a progress bar on stderr.
    overrides
        Keys merged over the configuration (e.g. ``{"reference_format": "mscip-bin"}``).
    scheduler
        Where the sessions are written: ``processes``, ``dask`` or ``tcp://host:port``
        (:func:`ofbe_data.core.parallel.map_progress`; the workers must see ``out``'s folder).

    Returns
    -------
    CampaignResult

    Raises
    ------
    ConfigError
        Invalid configuration.
    OutputExistsError
        ``out`` exists and ``force`` is False.
    TaskError
        A session's worker process died (the campaign is not written).
    """
    if isinstance(config, SimConfig):
        cfg = load_config_from(config, overrides) if overrides else config
    else:
        cfg = load_config(config, overrides)
    out = Path(out)
    campaign = cfg.campaign or out.name
    if not ID_PATTERN.match(campaign):
        raise ConfigError(str(config), "campaign", "an id of [A-Za-z0-9._-]+ (or an --out folder "
                          "named like one)", repr(campaign))
    if out.exists() and not force:
        raise OutputExistsError(out)
    seed = cfg.seed if seed is None else seed
    if cfg.kind == FREE_LIVING:  # files of wearables, not sessions of the bench (simulator/wearfiles.py)
        files, size = write_free_living(cfg, out, seed, campaign, jobs=jobs, force=force, progress=progress,
                                        scheduler=scheduler)
        return CampaignResult(out, campaign, seed, cfg.sessions, files, size)
    camp_seq, sess_seqs, garble_seqs = _seeds(seed, cfg)
    draw = draw_campaign(cfg, camp_seq)
    with atomic_directory(out, replace=force) as tmp:
        (tmp / "_truth").mkdir()
        tasks = [(cfg, draw, i, campaign, sess_seqs[i], garble_seqs[i], tmp)
                 for i in range(cfg.sessions)]
        written = map_progress(_write_one, tasks, jobs=min(jobs, os.cpu_count() or 1),
                               desc=f"simulate {campaign}", unit="session", progress=progress,
                               scheduler=scheduler, name=lambda t: f"session {session_name(cfg, t[2])}")
        files, size = sum(f for f, _ in written), sum(s for _, s in written)
        text = yaml.safe_dump(truth_config(cfg, seed, campaign), sort_keys=False)
        write_bytes_atomic(tmp / "_truth" / "simulation.yaml", text.encode())
    return CampaignResult(out, campaign, seed, cfg.sessions, files, size)
