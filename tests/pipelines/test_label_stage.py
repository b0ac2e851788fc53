"""The DVC ``label`` stage entry, and params.yaml/dvc.yaml agreeing with the code."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
import yaml

from ofbe_data.labels import load_label_params
from pipelines import label, simulate

ROOT = Path(__file__).resolve().parents[2]


def test_stage_labels_the_campaigns_of_params(tmp_path, monkeypatch):
    params = {"simulate": {"jobs": 1, "campaigns": {"small-rot": {"profile": "tiny-rotated", "seed": 5}}},
              "label": {"min_samples": 1000},
              "label_run": {"jobs": 1, "campaigns": ["small-rot"]}}
    (tmp_path / "params.yaml").write_text(yaml.safe_dump(params))
    monkeypatch.chdir(tmp_path)
    assert simulate.main() == 0
    assert label.main() == 0
    out = tmp_path / "processed" / "labels" / "small-rot"
    assert sorted(p.name for p in out.iterdir()) == [
        "campaign_fit.json", "rot-pc001.parquet", "rot-pc001.rejected.json",
        "rot-pc002.parquet", "rot-pc002.rejected.json"]


def test_repository_label_params_are_valid():
    params = load_label_params(ROOT / "params.yaml")
    assert params.min_samples == 4500 and params.margin_s == 1.0


def _module_file(module: str) -> str | None:
    base = module.replace(".", "/")
    for rel in (base + ".py", base + "/__init__.py"):
        if (ROOT / rel).is_file():
            return rel
    return None


def _imported_files(entry: str) -> set[str]:
    """Every ofbe_data source file reachable by imports from ``entry``."""
    todo, seen = [entry], set()
    while todo:
        rel = todo.pop()
        if rel in seen:
            continue
        seen.add(rel)
        for node in ast.walk(ast.parse((ROOT / rel).read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("ofbe_data"):
                for name in [node.module, *(f"{node.module}.{a.name}" for a in node.names)]:
                    found = _module_file(name)
                    if found:
                        todo.append(found)
    return seen


@pytest.mark.parametrize("stage, entry", [("simulate", "pipelines/simulate.py"),
                                          ("label", "pipelines/label.py")])
def test_stages_depend_on_every_module_they_run(stage, entry):
    deps = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"][stage]["deps"]
    assert entry in deps
    missing = sorted(f for f in _imported_files(entry)
                     if not any(f == d or f.startswith(d.rstrip("/") + "/") for d in deps))
    assert missing == []
