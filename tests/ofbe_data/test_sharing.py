"""Sharing a dataset through a DVC remote, as docs/datasets.md describes, with a local
folder as the remote: push, lose everything, pull, and the dataset verifies and loads."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from ofbe_data import load_dataset
from ofbe_data.core.atomic import atomic_directory
from ofbe_data.dataset.store import DatasetInfo, WindowWriter, export_dataset


def _tiny_dataset(path: Path) -> None:
    info = DatasetInfo(name="share", campaign="c", kind="gravity-aligned", title="t", description="d",
                       labelling="l", window_length=20, stride=20, fs_hz=150.0,
                       protocols={"grouped": {"description": "by power cycle", "n_folds": 5, "seed": 0}})
    rng = np.random.default_rng(0)
    with atomic_directory(path) as tmp, WindowWriter(tmp, info) as w:
        for i in range(10):
            meta = pd.DataFrame({
                "campaign": ["c"] * 2, "session": [f"s{i}"] * 2, "recording": ["r"] * 2, "device": ["d1"] * 2,
                "power_cycle": [i] * 2, "window_index": [0, 1], "start_sample": [0, 20],
                **{f"bias_{a}": [0.01 * i] * 2 for a in "xyz"},
                **{f"offset_{a}": [np.nan] * 2 for a in "xyz"},
                "gravity_x": [0.0] * 2, "gravity_y": [0.0] * 2, "gravity_z": [1.0] * 2,
                "roll_deg": [0.0] * 2, "pitch_deg": [0.0] * 2, "g_local": [9.8] * 2, "fs_hz": [150.0] * 2,
                "label_method": ["level"] * 2, "raw_sha256": ["0" * 64] * 2, "fold_grouped": [i // 2] * 2})
            w.append(rng.normal(size=(2, 20, 3)), meta)


def _dvc(cwd: Path, *args: str) -> None:
    subprocess.run([sys.executable, "-m", "dvc", *args], cwd=cwd, check=True, capture_output=True, text=True)


def test_push_and_pull_through_a_local_remote(tmp_path) -> None:
    _tiny_dataset(tmp_path / "built")
    project = tmp_path / "project"
    project.mkdir()
    export_dataset(tmp_path / "built", project / "share")
    before = load_dataset(project / "share")
    _dvc(project, "init", "--no-scm")
    _dvc(project, "remote", "add", "-d", "storage", str(tmp_path / "remote"))
    _dvc(project, "add", "share")
    _dvc(project, "push")
    assert (project / "share.dvc").is_file() and any((tmp_path / "remote").rglob("*"))
    # a collaborator with only the .dvc file and the remote
    shutil.rmtree(project / "share")
    shutil.rmtree(project / ".dvc" / "cache")
    _dvc(project, "pull")
    after = load_dataset(project / "share")
    assert np.array_equal(after.X, before.X) and np.array_equal(after.y, before.y)
    pd.testing.assert_frame_equal(after.meta, before.meta)
