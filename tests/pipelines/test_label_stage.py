"""The DVC ``label`` stage entry, and params.yaml/dvc.yaml agreeing with the code."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
import yaml

from ofbe_data.labelling.labels import load_label_params
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
    """The label length is the convergence report's unless params.yaml overrides it."""
    params = load_label_params(ROOT / "params.yaml")
    assert params.margin_s == 1.0
    doc = yaml.safe_load((ROOT / "params.yaml").read_text())
    assert "min_samples" not in doc["label"]
    stage = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"]["label"]
    assert doc["label_run"]["min_samples_from"] in stage["deps"]


def _module_file(module: str) -> str | None:
    base = module.replace(".", "/")
    for rel in (base + ".py", base + "/__init__.py"):
        if (ROOT / rel).is_file():
            return rel
    return None


def _imported_files(entry: str) -> set[str]:
    """Every ofbe_data / ofbe_model source file reachable by imports from ``entry``, with the
    ``__init__.py`` of every package above each (importing ``a.b.c`` runs ``a`` and ``a.b`` first)
    and every public module of a package that imports them all (``import_submodules``)."""
    todo, seen = [entry], set()
    while todo:
        rel = todo.pop()
        if rel in seen:
            continue
        seen.add(rel)
        parent = Path(rel).parent if rel.startswith(("ofbe_data/", "ofbe_model/")) else Path(".")
        while parent != Path(".") and (ROOT / parent / "__init__.py").is_file():
            todo.append(str(parent / "__init__.py"))
            parent = parent.parent
        tree = ast.parse((ROOT / rel).read_text())
        # a package's lazy ``__getattr__`` (ofbe_data.load_dataset) imports only when used
        tree.body = [n for n in tree.body if not (isinstance(n, ast.FunctionDef) and n.name == "__getattr__")]
        for node in ast.walk(tree):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
                    and node.func.id == "import_submodules"):
                todo += [str(p.relative_to(ROOT)) for p in sorted((ROOT / rel).parent.glob("*.py"))
                         if not p.name.startswith("_")]
                continue
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith(("ofbe_data",
                                                                                            "ofbe_model")):
                names = [node.module, *(f"{node.module}.{a.name}" for a in node.names)]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names if a.name.startswith(("ofbe_data", "ofbe_model"))]
            else:
                continue
            for name in names:
                found = _module_file(name)
                if found:
                    todo.append(found)
    return seen


@pytest.mark.parametrize("stage, entry", [("simulate", "pipelines/simulate.py"),
                                          ("convergence", "pipelines/convergence.py"),
                                          ("small_angle", "pipelines/small_angle.py"),
                                          ("label", "pipelines/label.py"),
                                          ("datasets", "pipelines/datasets.py"),
                                          ("train", "pipelines/train.py"),
                                          ("benchmark", "pipelines/benchmark.py"),
                                          ("index", "pipelines/index.py"),
                                          ("deploy", "pipelines/deploy.py")])
def test_stages_depend_on_every_module_they_run(stage, entry):
    deps = yaml.safe_load((ROOT / "dvc.yaml").read_text())["stages"][stage]["deps"]
    assert entry in deps
    missing = sorted(f for f in _imported_files(entry)
                     if not any(f == d or f.startswith(d.rstrip("/") + "/") for d in deps))
    assert missing == []


def test_label_stage_takes_min_samples_from_the_convergence_report(tmp_path, monkeypatch):
    import json

    from ofbe_data.labelling.convergence import REPORT_FORMAT
    from ofbe_data.labelling.store import read_provenance

    campaigns = {"small-ga": {"profile": "tiny-gravity-aligned", "seed": 3}}
    params = {"simulate": {"jobs": 1, "campaigns": campaigns},
              "label": {"margin_s": 1.0},
              "label_run": {"jobs": 1, "campaigns": ["small-ga"], "min_samples_from": "conv.json"}}
    (tmp_path / "params.yaml").write_text(yaml.safe_dump(params))
    (tmp_path / "conv.json").write_text(json.dumps({"format": REPORT_FORMAT, "recommended_label_start": 777}))
    monkeypatch.chdir(tmp_path)
    assert simulate.main() == 0
    assert label.main() == 0
    files = sorted((tmp_path / "processed" / "labels" / "small-ga").glob("*.parquet"))
    assert files and all(read_provenance(f)["parameters"]["min_samples"] == 777 for f in files)
    # an explicit label.min_samples wins over the report
    params["label"]["min_samples"] = 900
    (tmp_path / "params.yaml").write_text(yaml.safe_dump(params))
    assert label.main() == 0
    assert read_provenance(files[0])["parameters"]["min_samples"] == 900


def test_datasets_stage_builds_each_campaign(tmp_path, monkeypatch):
    from ofbe_data.dataset.store import verify_dataset
    from ofbe_data.labelling.batch import expand_sessions, label_sessions
    from ofbe_data.labelling.labels import LabelParams
    from ofbe_data.simulator import load_config, simulate_campaign
    from pipelines import datasets

    simulate_campaign(load_config("gravity-aligned", {"sessions": 5, "stationary_s": [12.0, 12.0]}),
                      tmp_path / "raw" / "ga", seed=4, jobs=1, progress=False)
    label_sessions(expand_sessions([tmp_path / "raw" / "ga"]), LabelParams(min_samples=600),
                   tmp_path / "processed" / "labels", progress=False)
    params = {"dataset": {"window_length": 500, "stride": 500},
              "dataset_run": {"jobs": 1, "campaigns": ["ga"]}}
    (tmp_path / "params.yaml").write_text(yaml.safe_dump(params))
    monkeypatch.chdir(tmp_path)
    assert datasets.main() == 0
    summary = verify_dataset(tmp_path / "processed" / "datasets" / "ga")
    assert summary["n_recordings"] == 20 and summary["window_length"] == 500
    assert sorted(summary["protocols"]) == ["grouped", "paper-gravity"]


def test_profiles_merge_over_params(tmp_path):
    from ofbe_data.core.errors import ConfigError
    from ofbe_data.io.pipeline_params import load_params, merge, resolved_params_file

    assert merge({"a": {"b": 1, "c": [1]}, "d": 2}, {"a": {"c": [2]}, "e": 3}) == {
        "a": {"b": 1, "c": [2]}, "d": 2, "e": 3}
    paper = load_params(ROOT / "params.yaml")
    assert paper["profile"] == "paper" and paper["dataset"]["window_length"] == 3000
    (tmp_path / "pipelines" / "profiles").mkdir(parents=True)
    (tmp_path / "pipelines" / "profiles" / "tiny.yaml").write_text(
        (ROOT / "pipelines" / "profiles" / "tiny.yaml").read_text())
    doc = yaml.safe_load((ROOT / "params.yaml").read_text())
    doc["profile"] = "tiny"
    (tmp_path / "params.yaml").write_text(yaml.safe_dump(doc))
    tiny = load_params(tmp_path / "params.yaml")
    # the profile's keys win; the others stay params.yaml's
    assert tiny["dataset"]["window_length"] == 1000 and tiny["dataset"]["n_folds"] == 3
    assert tiny["dataset"]["test_per_fold"] == paper["dataset"]["test_per_fold"] == 9
    assert tiny["simulate"]["campaigns"]["rotated"]["overrides"]["sessions"] == 16
    with resolved_params_file(tmp_path / "params.yaml") as path:
        assert yaml.safe_load(open(path))["label"]["min_samples"] == 2000
    assert not Path(path).exists()
    doc["profile"] = "huge"
    (tmp_path / "params.yaml").write_text(yaml.safe_dump(doc))
    with pytest.raises(ConfigError, match="profile: expected paper or one of tiny, found 'huge'"):
        load_params(tmp_path / "params.yaml")
