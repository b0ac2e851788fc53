"""The DVC ``simulate`` stage entry: reads params.yaml and writes raw/<campaign>."""

from __future__ import annotations

import yaml

from pipelines import simulate


def test_stage_writes_the_campaigns_of_params(tmp_path, monkeypatch):
    params = {"simulate": {"jobs": 1, "campaigns": {
        "small-ga": {"profile": "tiny-gravity-aligned", "seed": 4},
        "small-rot": {"profile": "tiny-rotated", "seed": 5}}}}
    (tmp_path / "params.yaml").write_text(yaml.safe_dump(params))
    monkeypatch.chdir(tmp_path)
    assert simulate.main() == 0
    assert sorted(p.name for p in (tmp_path / "raw").iterdir()) == ["small-ga", "small-rot"]
    assert len(list((tmp_path / "raw" / "small-rot").glob("*/session.yaml"))) == 2
    # a second run replaces the outputs (DVC re-runs the stage) with identical files
    first = (tmp_path / "raw" / "small-ga" / "ga-pc001" / "rec-01" / "sparkfun-1.csv").read_bytes()
    assert simulate.main() == 0
    assert (tmp_path / "raw" / "small-ga" / "ga-pc001" / "rec-01" / "sparkfun-1.csv"
            ).read_bytes() == first
    listed = (tmp_path / "checksums" / "simulate.sha256").read_text().splitlines()
    assert any(line.endswith("  raw/small-ga/ga-pc001/rec-01/sparkfun-1.csv") for line in listed)
    assert len(listed) == sum(1 for p in (tmp_path / "raw").rglob("*") if p.is_file())


def test_repository_params_and_dvc_stage_agree():
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    params = yaml.safe_load((root / "params.yaml").read_text())["simulate"]
    stage = yaml.safe_load((root / "dvc.yaml").read_text())["stages"]["simulate"]
    folders = [o for o in stage["outs"] if isinstance(o, str)]
    assert sorted(folders) == sorted(f"raw/{name}" for name in params["campaigns"])
    assert {"checksums/simulate.sha256": {"cache": False}} in stage["outs"]
    assert {e["profile"] for e in params["campaigns"].values()} == {"gravity-aligned", "rotated",
                                                                    "multi-position"}
