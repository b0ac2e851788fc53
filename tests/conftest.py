"""Shared fixtures: paths to the committed examples, small file builders, and the simulated
campaigns several modules read (built once per test session, :mod:`tests.helpers.campaigns`)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers.campaigns import shared_campaign
from tests.helpers.paths import EXAMPLES


@pytest.fixture
def examples() -> Path:
    """The committed tiny example campaigns (raw/examples)."""
    return EXAMPLES


@pytest.fixture
def write_text(tmp_path: Path):
    """Write a text (or bytes) file under tmp_path and return its path."""

    def _write(rel: str, content: str | bytes) -> Path:
        path = tmp_path / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")
        return path

    return _write


def _tiny_labelled(folder: Path) -> None:
    from ofbe_data.labelling.batch import expand_sessions, label_sessions
    from ofbe_data.labelling.labels import LabelParams
    from ofbe_data.simulator import load_config, simulate_campaign

    raw = folder / "raw"
    simulate_campaign(load_config("tiny-multi-position"), raw / "mp", seed=1, jobs=1, progress=False)
    simulate_campaign(load_config("tiny-gravity-aligned"), raw / "ga", seed=2, jobs=1, progress=False)
    outcomes = label_sessions(expand_sessions([folder / "raw" / "mp", folder / "raw" / "ga"]),
                              LabelParams(min_samples=1000), folder / "labels", jobs=1, progress=False)
    assert [o.error for o in outcomes if o.error] == []


@pytest.fixture(scope="session")
def tiny_labelled(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``raw/mp``: tiny-multi-position (1 board, 2 power cycles × 6 faces, seed 1); ``raw/ga``:
    tiny-gravity-aligned (2 boards × 3 power cycles, 35 s each, seed 2); ``labels/mp`` and
    ``labels/ga``: their labels (min_samples 1000). Shared by the session: read only."""
    return shared_campaign(tmp_path_factory, "tiny-labelled", _tiny_labelled)


def _labelled_campaigns(folder: Path) -> None:
    from ofbe_data.labelling.batch import expand_sessions, label_sessions
    from ofbe_data.labelling.labels import LabelParams
    from ofbe_data.simulator import load_config, simulate_campaign

    raw = folder / "raw"
    simulate_campaign(load_config("rotated", {"sessions": 16, "stationary_s": [23.5, 24.5]}), raw / "rot",
                      seed=5, jobs=2, progress=False)
    simulate_campaign(load_config("gravity-aligned", {"sessions": 10, "stationary_s": [24.0, 24.0]}),
                      raw / "ga", seed=6, jobs=2, progress=False)
    outcomes = label_sessions(expand_sessions([raw / "rot", raw / "ga"]), LabelParams(min_samples=2000),
                              folder / "labels", jobs=2, progress=False)
    assert [o.error for o in outcomes if o.error] == []


@pytest.fixture(scope="session")
def labelled_campaigns(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``raw/rot``: a rotated campaign (2 boards × 48 recordings, 48 tilts, a power cycle every 3,
    seed 5); ``raw/ga``: a gravity-aligned one (4 boards × 10 power cycles, seed 6), about 24 s
    stationary each; ``labels/rot``, ``labels/ga``: their labels (min_samples 2000), enough for
    every protocol's 5 folds at windows of 1000 samples. Shared by the session: read only."""
    return shared_campaign(tmp_path_factory, "labelled-campaigns", _labelled_campaigns)


def _tiny_free_living(folder: Path) -> None:
    from ofbe_data.simulator import simulate_campaign

    simulate_campaign("tiny-free-living", folder / "tfl", progress=False)


@pytest.fixture(scope="session")
def tiny_free_living(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``tfl``: the tiny-free-living campaign as its profile is (its epoch files in ``tfl/epochs``,
    a recording of samples in ``tfl/wear-003``). Shared by the session: read only."""
    return shared_campaign(tmp_path_factory, "tiny-free-living", _tiny_free_living)


def _short_free_living(folder: Path) -> None:
    from ofbe_data.simulator import simulate_campaign

    simulate_campaign("tiny-free-living", folder / "fl", progress=False,
                      overrides={"sessions": 2, "free_living": {"days": 0.4, "output": "epochs"}})


@pytest.fixture(scope="session")
def short_free_living(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """``fl/epochs``: two simulated recordings of 0.4 days, as epoch files (tiny-free-living with
    two sessions). Shared by the session: read only."""
    return shared_campaign(tmp_path_factory, "short-free-living", _short_free_living)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Run the longest tests first: the whole-pipeline ones (``e2e``), then the other ``slow``
    ones, then the rest, each group in its collected order. With pytest-xdist's ``--dist
    loadfile`` (pyproject.toml) the workers then take the long files first and the short ones
    fill in the end, instead of one worker finishing a four-minute file alone (pyproject.toml's
    ``--no-loadscope-reorder`` keeps this order; xdist would otherwise hand out the files with the
    most tests first)."""
    items.sort(key=lambda item: 0 if item.get_closest_marker("e2e") else 1 if item.get_closest_marker("slow")
               else 2)
