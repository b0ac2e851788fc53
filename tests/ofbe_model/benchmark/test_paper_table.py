"""The paper's published Table 3 beside ours (ofbe_model.benchmark.paper), in benchmark.json and
benchmark.md."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from ofbe_model.benchmark.paper import PAPER_TABLE3, paper_markdown
from ofbe_model.benchmark.report import summarise, write_report
from tests.ofbe_model.benchmark.test_benchmark_report import make_predictions

METHODS = {"ls-trf": 0.2, "won2009-min-norm": 0.21, "ofbenet": 0.04, "gravity-prior-direction": 0.025,
           "oracle": 0.02, "won2009": 9.0}
BASELINES = ("ls-trf", "won2009-min-norm")


def _pred(protocol: str) -> pd.DataFrame:
    pred = make_predictions(seed=3, methods=METHODS)
    return pred.assign(protocol=protocol)


@pytest.fixture(scope="module")
def rotated() -> dict:
    return summarise(_pred("paper-rotated"), baselines=BASELINES)


def test_the_published_numbers_and_their_improvements() -> None:
    # the paper's improvement column follows from its RMSEs: 52.5 % on the gravity-aligned set,
    # 77-87 % over Least Squares and 78-81 % over the Mathematical Model on the rotated boards
    imp = {k: {b: round((v["rmse"][b] - v["rmse"]["OFBENet"]) / v["rmse"][b] * 100, 1)
               for b in ("Least Squares", "Mathematical Model") if b in v["rmse"]}
           for k, v in PAPER_TABLE3.items()}
    ls, mm = "Least Squares", "Mathematical Model"
    assert imp == {("paper-gravity", "gravity-aligned"): {ls: 52.5},
                   ("paper-rotated", "rotated/sparkfun-1"): {ls: 77.1, mm: 81.2},
                   ("paper-rotated", "rotated/sparkfun-2"): {ls: 87.2, mm: 78.2}}


def test_rows_beside_ours(rotated: dict) -> None:
    paper = rotated["paper"]
    assert list(paper) == ["rotated/sparkfun-1"]  # the gravity-aligned set is not a paper-rotated dataset
    block = paper["rotated/sparkfun-1"]
    assert block["paper_dataset"] == "rotated, SparkFun 1"
    rows = {r["method"]: r for r in block["rows"]}
    assert [r["method"] for r in block["rows"]] == ["ls-trf", "won2009-min-norm", "ofbenet",
                                                   "gravity-prior-direction", "oracle"]
    assert "won2009" not in rows  # the literal variant is not the paper's Mathematical Model
    ours = rotated["datasets"]["rotated/sparkfun-1"]["methods"]
    for m, pm, p in (("ls-trf", "Least Squares", 0.1711), ("won2009-min-norm", "Mathematical Model", 0.2088),
                     ("ofbenet", "OFBENet", 0.0392)):
        r = rows[m]
        assert r["paper_method"] == pm and r["paper_rmse"] == p
        assert r["rmse_mean"] == ours[m]["rmse_mean"]
        assert r["ratio"] == pytest.approx(ours[m]["rmse_mean"] / p, rel=1e-5)
        assert r["oracle_ratio"] == ours[m]["oracle_ratio"]
    ofb = rows["ofbenet"]
    assert ofb["improvement_pct"]["Least Squares"] == {"paper": 77.09,
                                                       "ours": ours["ofbenet"]["improvement_pct"]["ls-trf"]}
    assert ofb["improvement_pct"]["Mathematical Model"]["paper"] == 81.23
    crit = rotated["datasets"]["rotated/sparkfun-1"]["t_critical_fold"]["value"]
    for pb, b in zip(("Least Squares", "Mathematical Model"), BASELINES, strict=True):
        t = ours["ofbenet"]["t_test"][b]["fold"]["t"]
        assert ofb["significant"][pb] == {"paper": True, "ours": abs(t) > crit, "t": t}
    assert rows["oracle"]["paper_method"] is None and rows["oracle"]["paper_rmse"] is None
    assert rows["ls-trf"]["improvement_pct"] == {} and rows["ls-trf"]["significant"] == {}


def test_the_paper_has_no_mathematical_model_on_the_gravity_aligned_set() -> None:
    s = summarise(_pred("paper-gravity"), baselines=BASELINES)
    block = s["paper"]["gravity-aligned"]
    rows = {r["method"]: r for r in block["rows"]}
    assert rows["won2009-min-norm"]["paper_rmse"] is None and rows["won2009-min-norm"]["ratio"] is None
    ofb = rows["ofbenet"]
    assert ofb["improvement_pct"]["Least Squares"]["paper"] == 52.52
    assert ofb["improvement_pct"]["Mathematical Model"]["paper"] is None
    assert ofb["significant"]["Mathematical Model"]["paper"] is None
    assert ofb["significant"]["Mathematical Model"]["ours"] is not None


def test_one_baseline_only_and_other_protocols() -> None:
    s = summarise(_pred("paper-rotated"), baselines=("ls-trf",))
    rows = {r["paper_method"]: r for r in s["paper"]["rotated/sparkfun-1"]["rows"]}
    assert "Mathematical Model" not in rows
    assert rows["OFBENet"]["improvement_pct"]["Mathematical Model"] == {"paper": 81.23, "ours": None}
    assert rows["OFBENet"]["significant"]["Mathematical Model"]["ours"] is None
    assert summarise(_pred("grouped"), baselines=BASELINES)["paper"] == {}


def test_markdown_table(rotated: dict, tmp_path: Path) -> None:
    text = paper_markdown(rotated["paper"])
    table = [ln for ln in text.splitlines() if ln.startswith("|")]
    assert len(table) == 2 + 5 and all(ln.count("|") == 12 for ln in table)
    assert "| rotated, SparkFun 1 (`rotated/sparkfun-1`) | Least Squares | `ls-trf` | 0.1711 |" in text
    assert "| 77.1 / " in text and "yes / " in text and "(beyond the paper)" in text
    assert paper_markdown({}) == ""
    write_report(tmp_path / "rep", _pred("paper-rotated"), rotated, title="paper-rotated")
    md = (tmp_path / "rep" / "benchmark.md").read_text()
    assert "## Against the paper's Table 3" in md and md.index("## Table 3") < md.index("## Against")
    grouped = summarise(_pred("grouped"), baselines=BASELINES)
    write_report(tmp_path / "g", _pred("grouped"), grouped, title="grouped")
    assert "Against the paper" not in (tmp_path / "g" / "benchmark.md").read_text()
