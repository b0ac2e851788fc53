"""Shared fixtures: paths to the committed examples and small file builders."""

from __future__ import annotations

from pathlib import Path

import pytest

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


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Run the longest tests first: the whole-pipeline ones (``e2e``), then the other ``slow``
    ones, then the rest, each group in its collected order. With pytest-xdist's ``--dist
    loadfile`` (pyproject.toml) the workers then take the long files first and the short ones
    fill in the end, instead of one worker finishing a four-minute file alone (pyproject.toml's
    ``--no-loadscope-reorder`` keeps this order; xdist would otherwise hand out the files with the
    most tests first)."""
    items.sort(key=lambda item: 0 if item.get_closest_marker("e2e") else 1 if item.get_closest_marker("slow")
               else 2)
