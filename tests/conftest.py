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
