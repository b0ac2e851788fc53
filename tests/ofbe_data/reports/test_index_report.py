"""reports/index.md (ofbe_data.reports.index) on a small fake project tree."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from urllib.parse import unquote

import numpy as np
import pandas as pd
import pytest

from ofbe_data import __version__
from ofbe_data.cli.index import main
from ofbe_data.dataset.fidelity import MG
from ofbe_data.reports.index import build_index, markdown_section, read_timings, write_index

PNG = b"\x89PNG\r\n\x1a\n" + b"\x00" * 16
SECTIONS = [
    "## Benchmark (the paper's Table 3)",
    "## Convergence",
    "## Small-angle analysis",
    "## Label fidelity (labels against the simulator's truth)",
    "## Datasets",
    "## OFBENet training",
    "## Stage times",
]
TABLE3 = """| Dataset | Sensors | Method | Mean RMSE (m/s²) |
|---|---|---|---:|
| sim | dev-a | ls-trf | 0.1887 |
|  |  | ofbenet | **0.04630** |"""
LEGEND = "Mean RMSE: mean over the test folds of the fold RMSE (paper eq. 24). Bold: the lowest."
BENCHMARK_MD = f"""# Benchmark, protocol paper-gravity

Protocol `paper-gravity`: 1 datasets, 4 test signals, 2 methods. Errors are estimate − label, in m/s².

## Table 3

{TABLE3}

{LEGEND}

![mean RMSE per method and dataset](rmse.png)

![maximum error per method and dataset](max_error.png)

## Paired t-tests against ls-trf

| Dataset | Method | t (fold) |
|---|---|---:|
| sim | ofbenet | 75.72* |

![t-statistics against ls-trf](t_ls-trf.png)
"""
# Label errors (label − truth) in mg, per row and axis; row 1 has no zero-g offset.
BIAS_ERR_MG = np.array([[1.0, -2.0, 0.5], [-3.0, 2.0, 0.0]])
OFFSET_ERR_MG = np.array([[0.25, -0.75, 1.5]])
TRUE_BIAS = np.array([[0.10, -0.20, 0.05], [-0.30, 0.15, 0.02]])
TRUE_OFFSET = np.array([[0.11, -0.19, 0.04], [-0.29, 0.16, 0.03]])


def _write(path: Path, content: str | bytes) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


def _json(path: Path, obj: object) -> Path:
    return _write(path, json.dumps(obj, indent=1))


def _labels_and_truth(root: Path) -> None:
    devices = ["dev-a", "dev-b"]
    bias = TRUE_BIAS + BIAS_ERR_MG * MG
    offset = np.vstack([TRUE_OFFSET[0] + OFFSET_ERR_MG[0] * MG, np.full(3, np.nan)])
    frame = pd.DataFrame({
        "campaign": "sim", "session": "s1", "recording": "rec-01", "device": devices,
        **{f"bias_{a}": bias[:, i] for i, a in enumerate("xyz")},
        **{f"offset_{a}": offset[:, i] for i, a in enumerate("xyz")},
        # dev-a carries a fitted map 100 ppm off the truth's in one entry; dev-b none
        **{f"a_{r}{c}": [float(r == c) + (1e-4 if (r, c) == ("x", "y") else 0.0), np.nan]
           for r in "xyz" for c in "xyz"},
    })
    path = root / "processed" / "labels" / "sim" / "s1.parquet"
    path.parent.mkdir(parents=True)
    frame.to_parquet(path, engine="pyarrow", index=False)
    truth = {"format": "ofbe-truth/1", "campaign": "sim", "session": "s1",
             "devices": {"dev-a": {"A": np.eye(3).tolist()}},
             "recordings": {"rec-01": {"devices": {
                 d: {"apparent_bias": TRUE_BIAS[i].tolist(), "offset": TRUE_OFFSET[i].tolist()}
                 for i, d in enumerate(devices)}}}}
    _json(root / "raw" / "sim" / "_truth" / "s1.json", truth)
    # a real campaign: labels, no truth
    (root / "raw" / "real" / "s9").mkdir(parents=True)


def _reports(root: Path) -> None:
    bench = root / "reports" / "benchmark" / "paper-gravity"
    _write(bench / "benchmark.md", BENCHMARK_MD)
    _json(bench / "benchmark.json", {"protocol": "paper-gravity"})
    _write(bench / "errors.csv", "a,b\n1,2\n")
    for name in ("rmse.png", "max_error.png", "t_ls-trf.png"):
        _write(bench / name, PNG)
    conv = root / "reports" / "convergence"
    _json(conv / "convergence.json", {
        "format": "ofbe-convergence/1", "campaigns": ["sim"],
        "axes": {"x": {"mean": 4431.8825, "std": 534.828, "n": 400, "n_not_converged": 2}},
        "paper_band_x": [4000, 5000], "x_mean_within_paper_band": True,
        "recommendation": {"axis": "x", "statistic": "mean", "round_to": 100, "min_samples": 4500},
    })
    _write(conv / "convergence.md", "# Convergence\n")
    for name in ("convergence_histogram.png", "convergence_example.png", "allan_dev-b.png",
                 "allan_dev-a.png"):
        _write(conv / name, PNG)
    sa = root / "reports" / "small_angle"
    _json(sa / "small_angle.json", {
        "format": "ofbe-small-angle/1", "measure": "max-axis", "limit_mg": 50.0,
        "threshold_deg": {"pitch": 2.865984, "roll": 2.865984, "combined": 2.5},
        "formula": "degrees(asin(limit_g))", "formula_deg": 2.865984,
    })
    _write(sa / "small_angle.md", "# Small angle\n")
    _write(sa / "small_angle.png", PNG)  # the profile figure is left out on purpose


def _datasets_and_models(root: Path) -> None:
    ds = root / "processed" / "datasets" / "sim"
    _json(ds / "datapackage.json", {"name": "sim", "ofbe": {
        "name": "sim", "n_windows": 12, "n_recordings": 4, "window_length": 3000,
        "devices": {"dev-b": {"recordings": 2}, "dev-a": {"recordings": 2}},
        "protocols": {"paper-gravity": {"n_folds": 5}, "grouped": {"n_folds": 3}}}})
    _write(ds / "README.md", "# sim\n")
    folds = [{"fold": i, "epochs_run": e, "best_epoch": e - 5, "seconds": s}
             for i, (e, s) in enumerate([(7, 1.25), (12, 2.5), (9, 0.75)])]
    _json(root / "models" / "cv" / "sim" / "paper-gravity" / "training.json",
          {"format": "ofbe-training/1", "dataset": "sim", "protocol": "paper-gravity", "folds": folds})


@pytest.fixture
def tree(tmp_path: Path) -> Path:
    root = tmp_path / "project"
    _labels_and_truth(root)
    _reports(root)
    _datasets_and_models(root)
    return root


def _index(root: Path, timings: dict[str, float] | None = None) -> str:
    return build_index(root, ["sim", "real"], ["paper-gravity", "grouped"], timings, profile="tiny")


def _section(text: str, heading: str) -> str:
    body = markdown_section(text, heading)
    assert body is not None, heading
    return body


def test_sections_in_order(tree):
    text = _index(tree)
    assert text.startswith("# ")
    positions = [text.index(f"\n{h}\n") for h in SECTIONS]
    assert positions == sorted(positions)
    intro = text.split("\n## ")[0]
    assert "profile `tiny`" in intro and "`sim`" in intro and "`real`" in intro
    assert f"ofbe {__version__}" in intro


def test_every_link_is_relative_and_exists(tree):
    text = _index(tree)
    targets = re.findall(r"\]\(([^)\s]+)\)", text)
    assert len(targets) >= 15
    reports = tree / "reports"
    for t in targets:
        assert not t.startswith("/") and "://" not in t, t
        assert (reports / unquote(t)).resolve().is_file(), t
    for fig in ("benchmark/paper-gravity/rmse.png", "benchmark/paper-gravity/max_error.png",
                "benchmark/paper-gravity/t_ls-trf.png", "convergence/convergence_histogram.png",
                "convergence/convergence_example.png", "small_angle/small_angle.png"):
        assert re.search(rf"!\[[^\]]+\]\({re.escape(fig)}\)", text), fig
    for link in ("benchmark/paper-gravity/benchmark.md", "benchmark/paper-gravity/benchmark.json",
                 "benchmark/paper-gravity/errors.csv", "convergence/convergence.md",
                 "convergence/allan_dev-a.png", "convergence/allan_dev-b.png", "small_angle/small_angle.md",
                 "../processed/datasets/sim/README.md", "../models/cv/sim/paper-gravity/training.json"):
        assert f"]({link})" in text, link


def test_benchmark_table3_copied(tree):
    body = _section(_index(tree), "Benchmark (the paper's Table 3)")
    gravity = body.split("### grouped")[0]
    assert TABLE3 in gravity and LEGEND in gravity
    assert "Protocol `paper-gravity`: 1 datasets" in gravity
    assert "Paired t-tests" not in gravity and "75.72*" not in gravity
    assert "](rmse.png)" not in gravity  # the copied embeds are rebased, not duplicated
    assert gravity.count("benchmark/paper-gravity/rmse.png") == 1
    assert "`reports/benchmark/paper-gravity/fold_metrics.csv` (missing)" in gravity


def test_missing_protocol_is_a_sentence(tree):
    body = _section(_index(tree), "Benchmark (the paper's Table 3)")
    grouped = body.split("### grouped")[1]
    assert "Protocol `grouped` was not run" in grouped


def test_convergence_headline(tree):
    body = _section(_index(tree), "Convergence")
    assert "4432 ± 535 samples" in body
    assert "over 398 recordings" in body
    assert "inside the paper's 4000–5000 band" in body
    assert "recommended label length is 4500 samples" in body
    assert body.index("[dev-a]") < body.index("[dev-b]")


def test_small_angle_thresholds(tree):
    body = _section(_index(tree), "Small-angle analysis")
    assert "| pitch only | 2.866 |" in body
    assert "| equal roll and pitch | 2.500 |" in body
    assert "within 50 mg" in body
    assert "Figure `small_angle_profile.png` not found." in body


def _rms_max(err: np.ndarray) -> tuple[list[float], list[float]]:
    rms = [math.sqrt(sum(v * v for v in err[:, i]) / err.shape[0]) for i in range(3)]
    big = [max(abs(v) for v in err[:, i]) for i in range(3)]
    return rms, big


def test_fidelity_equals_hand_computation(tree):
    body = _section(_index(tree), "Label fidelity (labels against the simulator's truth)")
    rms, big = _rms_max(BIAS_ERR_MG)
    # by hand: x errors 1, −3 mg → RMS √5
    assert rms[0] == pytest.approx(math.sqrt(5.0))
    rows = {line.split("|")[1].strip(): [float(c) for c in line.split("|")[2:5]]
            for line in body.splitlines() if line.startswith("| ") and "(mg)" not in line}
    assert rows["apparent bias (label), RMS"] == pytest.approx(rms, abs=1e-4)
    assert rows["apparent bias (label), max"] == pytest.approx(big, abs=1e-4)
    off_rms, off_max = _rms_max(OFFSET_ERR_MG)
    assert rows["zero-g offset, RMS"] == pytest.approx(off_rms, abs=1e-4)
    assert rows["zero-g offset, max"] == pytest.approx(off_max, abs=1e-4)
    assert "2 labels" in body and "1 of them with a zero-g offset" in body
    # by hand: one of nine entries 100 ppm off → RMS 100/3 ppm
    assert ("Fitted map A against the truth's (1 device fits, each entry): 33.3 ppm RMS, 100.0 ppm at most."
            in body)
    assert "`real` (real data: no truth)" in body


def test_datasets_and_training(tree):
    text = _index(tree)
    ds = _section(text, "Datasets")
    assert "| sim | 12 | 4 | dev-a, dev-b | 3000 | paper-gravity (5 folds), grouped (3 folds) |" in ds
    assert "Not built (no datapackage.json): `real`." in ds
    tr = _section(text, "OFBENet training")
    assert "`sim`, protocol `paper-gravity`: 3 folds, 7–12 epochs (best epoch 2–7), 4.5 s in total" in tr


def test_timings_table_and_total(tree):
    body = _section(_index(tree, {"simulate": 10.0, "label": 2.5}), "Stage times")
    assert "| simulate | 10.0 |" in body and "| label | 2.5 |" in body
    assert "| **total** | **12.5** |" in body
    assert "were not recorded" in _section(_index(tree), "Stage times")


def test_deterministic(tree, tmp_path):
    assert _index(tree) == _index(tree)
    assert not re.search(r"\d{4}-\d{2}-\d{2}", _index(tree))
    out_a, out_b = tmp_path / "a.md", tmp_path / "b.md"
    args = ["--root", str(tree), "--campaigns", "sim", "--protocols", "paper-gravity", "--profile", "p",
            "--quiet"]
    assert main([*args, "--out", str(out_a)]) == 0
    assert main([*args, "--out", str(out_b)]) == 0
    assert out_a.read_bytes() == out_b.read_bytes()


def test_write_index_returns_what_it_writes(tree):
    out = tree / "reports" / "index.md"
    text = write_index(tree, out, ["sim"], ["paper-gravity"], {"a": 1.0}, profile="p")
    assert out.read_text(encoding="utf-8") == text


def test_main_defaults_and_timings_file(tree, capsys):
    _json(tree / "times.json", {"stages": {"simulate": 3.0, "train": 4.5}})
    assert main(["--root", str(tree), "--timings", str(tree / "times.json")]) == 0
    text = (tree / "reports" / "index.md").read_text(encoding="utf-8")
    assert "| **total** | **7.5** |" in text
    assert "Protocol `paper-rotated` was not run" in text
    assert "7.5 s in total" in capsys.readouterr().err
    assert main(["--root", str(tree), "--timings", str(tree / "absent.json"), "--quiet"]) == 0
    text = (tree / "reports" / "index.md").read_text(encoding="utf-8")
    assert "Stage times were not recorded." in text


def test_bad_timings_file_exits_2(tree, capsys):
    _json(tree / "times.json", {"simulate": 3.0})
    assert main(["--root", str(tree), "--timings", str(tree / "times.json")]) == 2
    _json(tree / "times.json", {"stages": {"simulate": -1}})
    assert main(["--root", str(tree), "--timings", str(tree / "times.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith("ofbe-index: error: ") for line in err)
    assert read_timings(tree / "absent.json") is None


def test_missing_reports_exits_1(tmp_path, capsys):
    assert main(["--root", str(tmp_path), "--out", str(tmp_path / "index.md")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "reports" in err[0]
    assert not (tmp_path / "index.md").exists()


def test_malformed_report_exits_1(tree, capsys):
    _write(tree / "reports" / "convergence" / "convergence.json", "{not json")
    assert main(["--root", str(tree), "--quiet"]) == 1
    assert "convergence.json" in capsys.readouterr().err


def test_empty_reports_degrades_gracefully(tmp_path):
    (tmp_path / "reports").mkdir()
    text = build_index(tmp_path, ["sim"], ["paper-gravity"], None)
    for h in SECTIONS:
        assert f"\n{h}\n" in text
    assert "Protocol `paper-gravity` was not run" in text
    assert "convergence analysis was not run" in text
    assert "small-angle analysis was not run" in text
    assert "no `raw/sim`" in text
    assert "No trained models" in text
    assert "no profile named" in text
    assert "](" not in text


PAPER_SECTION_MD = """## Against the paper's Table 3

| Dataset (paper) | Paper's method | Ours | Paper RMSE (m/s²) |
|---|---|---|---:|
{rows}

Paper: the legend of {protocol}.

## Paired t-tests against ls-trf
"""


def test_paper_table_joined_from_the_protocols(tree):
    gravity = tree / "reports" / "benchmark" / "paper-gravity" / "benchmark.md"
    gravity.write_text(BENCHMARK_MD.replace(
        "## Paired t-tests against ls-trf\n",
        PAPER_SECTION_MD.format(rows="| gravity-aligned | Least Squares | `ls-trf` | 0.1767 |",
                                protocol="paper-gravity"), 1), encoding="utf-8")
    rotated = tree / "reports" / "benchmark" / "paper-rotated"
    _write(rotated / "benchmark.md", BENCHMARK_MD.replace("paper-gravity", "paper-rotated").replace(
        "## Paired t-tests against ls-trf\n",
        PAPER_SECTION_MD.format(rows="| rotated, SparkFun 1 | OFBENet | `ofbenet` | 0.0392 |\n"
                                     "|  | (beyond the paper) | `oracle` | – |",
                                protocol="paper-rotated"), 1))
    text = build_index(tree, ["sim"], ["paper-gravity", "paper-rotated", "grouped"], None)
    body = _section(text, "Benchmark (the paper's Table 3)")
    paper = body.split("### paper-gravity")[0]
    assert paper.count("### Against the paper's Table 3") == 1 and text.count("| Dataset (paper) |") == 1
    rows = [ln for ln in paper.splitlines() if ln.startswith("| ") and "Dataset (paper)" not in ln]
    assert rows == ["| gravity-aligned | Least Squares | `ls-trf` | 0.1767 |",
                    "| rotated, SparkFun 1 | OFBENet | `ofbenet` | 0.0392 |",
                    "|  | (beyond the paper) | `oracle` | – |"]
    assert "Paper: the legend of paper-gravity." in paper and "legend of paper-rotated" not in text
    # the per-protocol Table 3 copies stay as they were
    assert TABLE3 in body.split("### paper-gravity")[1]


def test_no_paper_table_without_paper_sections(tree):
    assert "Against the paper" not in _index(tree)
