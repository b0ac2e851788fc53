"""End to end: the whole DVC pipeline on the `tiny` profile in a copy of the repository.

Checks that ``dvc repro`` runs every stage, that the outputs have their schemas, that a
second ``dvc repro`` is a no-op, and that forcing the data stages again gives byte-identical raw
files, labels and datasets. About three minutes.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pyarrow.parquet as pq
import pytest
import yaml

from ofbe_data.dataset.store import SCHEMA_VERSION, verify_dataset
from ofbe_data.labelling.store import LABEL_SCHEMA

pytestmark = [pytest.mark.slow, pytest.mark.e2e]
"""Slow: the whole pipeline end to end (``-m "not slow"`` leaves it out)."""

ROOT = Path(__file__).resolve().parents[2]
STAGES = ("simulate", "convergence", "small_angle", "label", "datasets", "train", "benchmark", "deploy",
          "index")


def _run(cwd: Path, *args: str) -> str:
    done = subprocess.run(list(args), cwd=cwd, capture_output=True, text=True)
    assert done.returncode == 0, f"{' '.join(args)} failed:\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done.stdout + done.stderr


def _copy_repository(dest: Path) -> None:
    listed = _run(ROOT, "git", "ls-files", "-z", "--cached", "--others", "--exclude-standard")
    for rel in filter(None, listed.split("\0")):
        src = ROOT / rel
        if src.is_file():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)


def _locked_outs(repo: Path) -> dict[str, str]:
    lock = yaml.safe_load((repo / "dvc.lock").read_text())
    return {o["path"]: o["md5"] for s in lock["stages"].values() for o in s.get("outs", [])}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs git and a git checkout to copy the repository")
    repo = tmp_path_factory.mktemp("e2e") / "repo"
    repo.mkdir()
    _copy_repository(repo)
    params = (repo / "params.yaml").read_text()
    assert "\nprofile: paper" in params
    (repo / "params.yaml").write_text(params.replace("\nprofile: paper", "\nprofile: tiny", 1))
    _run(repo, "git", "init", "-q")
    _run(repo, "git", "add", "-A")
    _run(repo, "git", "-c", "user.email=ci@ofbe", "-c", "user.name=ci", "commit", "-qm", "tiny")
    _run(repo, sys.executable, "-m", "dvc", "repro")
    return repo


def test_every_stage_ran_and_outputs_have_their_schemas(tiny) -> None:
    lock = yaml.safe_load((tiny / "dvc.lock").read_text())
    assert set(STAGES) <= set(lock["stages"])
    for campaign in ("gravity-aligned", "rotated", "multi-position"):
        files = sorted((tiny / "processed" / "labels" / campaign).glob("*.parquet"))
        assert files, campaign
        schema = pq.read_schema(files[0])
        assert schema.names == LABEL_SCHEMA.names and schema.types == LABEL_SCHEMA.types
    for campaign in ("gravity-aligned", "rotated"):
        summary = verify_dataset(tiny / "processed" / "datasets" / campaign)
        assert summary["schema_version"] == SCHEMA_VERSION and summary["window_length"] == 1000
    conv = json.loads((tiny / "reports" / "convergence" / "convergence.json").read_text())
    assert conv["recommended_label_start"] > 0
    small = json.loads((tiny / "reports" / "small_angle" / "small_angle.json").read_text())
    assert abs(small["threshold_deg"]["pitch"] - 2.866) < 0.005
    for protocol in ("paper-gravity", "paper-rotated", "grouped"):
        doc = json.loads((tiny / "reports" / "benchmark" / protocol / "benchmark.json").read_text())
        assert doc["protocol"] == protocol
        for ds in doc["datasets"].values():
            assert {"ofbenet", "ls-trf", "won2009", "oracle"} <= set(ds["methods"])
            assert len(ds["methods"]["ofbenet"]["rmse_folds"]) == 3  # the tiny profile's folds
    # the deployable models and their cards, as the benchmark evaluates them: the gravity-aligned set
    # pooled, each rotated board on its own (a model set that ofbe-predict picks from per device)
    index = json.loads((tiny / "models" / "rotated" / "models.json").read_text())
    assert sorted(index["devices"]) == ["sparkfun-1", "sparkfun-2"]
    for name in ("gravity-aligned", "rotated/sparkfun-1", "rotated/sparkfun-2"):
        folder = tiny / "models" / name
        assert {p.name for p in folder.iterdir()} >= {"final.keras", "gravity-prior.json", "MODEL_CARD.md",
                                                     "model_card.json"}
        card = json.loads((folder / "model_card.json").read_text())
        assert card["benchmark"]["gravity-prior"]["grouped"], card["benchmark"]  # quotes this run's benchmark
        for model, acc in card["accuracy"].items():  # measured here, per device, and within the deploy rule
            for device, ins in acc["in_sample"].items():
                for per in acc["cross_validated"].values():
                    limit = card["max_in_sample_ratio"] * per[device]["rmse"]
                    assert ins["rmse"] <= limit, (name, model, device)
    for campaign in ("gravity-aligned", "rotated"):
        _run(tiny, sys.executable, "-m", "ofbe_model.cli.predict", str(tiny / "models" / campaign),
             str(next((tiny / "raw" / campaign).glob("*/session.yaml")).parent), "--window-length", "500",
             "--estimator", "gravity-prior")
    assert sorted((tiny / "models" / "cv").glob("*/*/training.json"))
    index = (tiny / "reports" / "index.md").read_text()
    assert index.count("| Dataset | Sensors | Method |") == 3
    assert "Label fidelity" in index and "convergence_histogram.png" in index and "small_angle.png" in index
    assert "| **total** |" in index


def test_second_repro_is_a_no_op(tiny) -> None:
    before = (tiny / "dvc.lock").read_bytes()
    out = _run(tiny, sys.executable, "-m", "dvc", "repro")
    assert "Data and pipelines are up to date" in out
    assert "Running stage" not in out
    assert (tiny / "dvc.lock").read_bytes() == before


def test_forced_rerun_is_reproducible(tiny) -> None:
    outs = _locked_outs(tiny)
    # the data stages again, from scratch: the data products are byte-identical. (Train's weights
    # are the same whatever the run and the scheduler, and the benchmark's predictions and report
    # the same bytes again: tests/ofbe_model and test_dask_e2e.py; forcing those stages here too
    # doubled this test's time for no new evidence.)
    _run(tiny, sys.executable, "-m", "dvc", "repro", "--force", "--single-item", "simulate", "label",
         "datasets")
    again = _locked_outs(tiny)
    for path in ("raw/gravity-aligned", "raw/rotated", "processed/labels", "processed/datasets"):
        assert again[path] == outs[path], path
