"""ofbe-export writes every --out and --store file or none: a store that cannot be a folder is
refused before anything is written, and a write that fails midway removes what this run made."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import pytest

import ofbe_data.calibration.output as export
from ofbe_data.calibration.output import ExportFile, write_outputs
from ofbe_data.calibration.store import CalibrationStoreError

WHEN = datetime(2025, 3, 14, 9, 0, 30, tzinfo=UTC)


def _files() -> list[ExportFile]:
    return [ExportFile("a.json", b"{}\n", "dev-a", WHEN, "json"),
            ExportFile("b.json", b"{}\n", "dev-b", WHEN, "json")]


def test_a_store_that_is_a_file_is_refused_before_anything_is_written(tmp_path: Path) -> None:
    (tmp_path / "store").write_text("not a folder")
    with pytest.raises(CalibrationStoreError, match=r"expected .*store to be a folder to write into"):
        write_outputs(_files(), tmp_path / "out", tmp_path / "store", force=False)
    with pytest.raises(CalibrationStoreError, match="found a file"):
        write_outputs(_files()[:1], tmp_path / "one.json", tmp_path / "store", force=False)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["store"]


def test_a_write_that_fails_midway_leaves_nothing_this_run_made(tmp_path: Path, monkeypatch) -> None:
    calls = []
    real = export.write_bytes_atomic

    def fail_on_third(path, data):
        calls.append(path)
        if len(calls) == 3:
            raise OSError(28, "No space left on device")
        return real(path, data)

    monkeypatch.setattr(export, "write_bytes_atomic", fail_on_third)
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "keep.txt").write_text("a user's file")
    with pytest.raises(OSError, match="No space left"):
        write_outputs(_files(), tmp_path / "out", tmp_path / "store", force=False)
    assert len(calls) == 3
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["keep.txt"]
    assert not (tmp_path / "store").exists()
