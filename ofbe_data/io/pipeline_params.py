"""Pipeline parameters with profiles: params.yaml, plus a profile's overrides.

params.yaml holds the default (paper-size) reproduction. Its top-level ``profile`` key
names a profile; any profile other than ``paper`` is a YAML file
``pipelines/profiles/<profile>.yaml`` whose sections are merged over params.yaml's
(mappings merge key by key, anything else is replaced). Switch without editing files with
``dvc exp run -S profile=tiny`` (DVC sets the key and reruns what it changes), and back
with ``-S profile=paper``.

Every DVC stage entry reads its sections through :func:`load_params`, and passes CLIs that
read params files the merged document (:func:`resolved_params_file`).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml

from ofbe_data.core.errors import ConfigError
from ofbe_data.io.mappings import closest_key, deep_merge
from ofbe_data.io.yamlio import YamlProblem, read_yaml

DEFAULT_PROFILE = "paper"
PROFILE_DIR = Path("pipelines") / "profiles"


merge = deep_merge
"""Profile overrides merge like simulator overrides (:func:`ofbe_data.io.typedconfig.deep_merge`)."""


def _read(path: Path) -> dict[str, Any]:
    try:
        data = read_yaml(path).data
    except OSError as exc:
        raise ConfigError(path, "<file>", "a readable YAML file", exc.strerror or str(exc)) from None
    except YamlProblem as exc:
        where = f" (line {exc.line})" if exc.line else ""
        raise ConfigError(path, exc.field, exc.expected, exc.found + where) from None
    if not isinstance(data, dict):
        raise ConfigError(path, "<document>", "a mapping of sections", type(data).__name__)
    return data


def load_params(params_file: str | Path = "params.yaml") -> dict[str, Any]:
    """params.yaml with its profile's overrides merged in.

    Raises
    ------
    ConfigError
        Unreadable file, or a profile with no file in ``pipelines/profiles`` (with the closest
        profile name when there is one). The keys of each section are checked by the record that
        reads it (:func:`ofbe_data.io.typedconfig.from_plain`), not here.
    """
    params_file = Path(params_file)
    data = _read(params_file)
    profile = data.get("profile", DEFAULT_PROFILE)
    if profile == DEFAULT_PROFILE:
        return data
    path = params_file.parent / PROFILE_DIR / f"{profile}.yaml"
    if not path.is_file():
        known = sorted(p.stem for p in (params_file.parent / PROFILE_DIR).glob("*.yaml"))
        match = closest_key(str(profile), [DEFAULT_PROFILE, *known])
        hint = f" (did you mean {match}?)" if match is not None else ""
        raise ConfigError(params_file, "profile", f"{DEFAULT_PROFILE} or one of {', '.join(known)}",
                          repr(profile) + hint)
    return merge(data, _read(path))


@contextmanager
def resolved_params_file(params_file: str | Path = "params.yaml") -> Iterator[str]:
    """A params file with the profile applied: ``params_file`` itself for the default profile,
    else a temporary merged copy (removed afterwards)."""
    data = load_params(params_file)
    if data.get("profile", DEFAULT_PROFILE) == DEFAULT_PROFILE:
        yield str(params_file)
        return
    fd, tmp = tempfile.mkstemp(prefix="ofbe-params-", suffix=".yaml")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            # already applied: without the key, readers do not look for the profile again
            yaml.safe_dump({k: v for k, v in data.items() if k != "profile"}, fh, sort_keys=False)
        yield tmp
    finally:
        Path(tmp).unlink(missing_ok=True)


TIMINGS_FILE = Path(".ofbe") / "timings.json"
"""Wall time of each stage's last run (not a DVC output: times differ run to run)."""


def record_time(stage: str, seconds: float, root: str | Path = ".") -> None:
    """Record a stage's wall time, s, in :data:`TIMINGS_FILE` (for reports/index.md)."""
    import json

    from ofbe_data.core.atomic import write_bytes_atomic

    path = Path(root) / TIMINGS_FILE
    path.parent.mkdir(parents=True, exist_ok=True)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        stages = dict(data.get("stages", {}))
    except (OSError, ValueError, AttributeError):
        stages = {}
    stages[stage] = round(float(seconds), 2)
    write_bytes_atomic(path, (json.dumps({"stages": stages}, indent=1, sort_keys=True) + "\n").encode())


@contextmanager
def timed(stage: str) -> Iterator[None]:
    """Record the wall time of the enclosed block as ``stage``'s."""
    import time

    t0 = time.perf_counter()
    yield
    record_time(stage, time.perf_counter() - t0)
