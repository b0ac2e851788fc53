"""The benchmark summary (benchmark.json) against independent computations, Table 3, the
figures, and the report's files and their determinism."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import matplotlib.image as mpimg
import numpy as np
import pandas as pd
import pytest
from matplotlib.container import BarContainer
from scipy import stats

from ofbe_model.benchmark import figures as benchmark_figures
from ofbe_model.benchmark.report import (
    max_error_figure,
    ordered_methods,
    rmse_figure,
    summarise,
    t_figure,
    table3_markdown,
    write_report,
)
from ofbe_model.benchmark.statistics import paired_t

DATASETS = (("gravity-aligned", "imu-1,imu-2,imu-3"), ("rotated/sparkfun-1", "sparkfun-1"))
METHODS = {"ls-trf": 0.05, "won2009": 0.04, "gravity-prior": 0.012, "oracle": 0.01}
"""Error scale of each synthetic method, m/s²."""
PRIOR_STD = 0.012
N_PER_FOLD = 6
N_FOLDS = 5


def make_predictions(seed: int = 0, methods: dict[str, float] | None = None) -> pd.DataFrame:
    """2 datasets × 5 folds × 6 signals, one row per method; gravity-prior has a posterior std."""
    rng = np.random.default_rng(seed)
    methods = METHODS if methods is None else methods
    rows = []
    for dataset, devices in DATASETS:
        devs = devices.split(",")
        wid = 0
        for fold in range(N_FOLDS):
            for j in range(N_PER_FOLD):
                y = rng.normal(0.0, 0.1, 3)
                for method, scale in methods.items():
                    e = rng.normal(0.0, scale * (1 + 0.2 * fold), 3)
                    std = PRIOR_STD if method == "gravity-prior" else math.nan
                    rows.append({"dataset": dataset, "devices": devices, "protocol": "paper-gravity",
                                 "method": method, "fold": fold, "window_id": 100 + wid,
                                 "device": devs[j % len(devs)],
                                 **{f"y_{a}": y[i] for i, a in enumerate("xyz")},
                                 **{f"yhat_{a}": y[i] + e[i] for i, a in enumerate("xyz")},
                                 **{f"std_{a}": std for a in "xyz"}})
                wid += 1
    return pd.DataFrame(rows)


@pytest.fixture(scope="module")
def pred() -> pd.DataFrame:
    return make_predictions()


@pytest.fixture(scope="module")
def summary(pred: pd.DataFrame) -> dict[str, Any]:
    return summarise(pred)


def _errors(pred: pd.DataFrame, dataset: str, method: str) -> tuple[np.ndarray, np.ndarray]:
    """(N, 3) errors and (N,) folds of one method, in (fold, window_id) order."""
    g = pred[(pred["dataset"] == dataset) & (pred["method"] == method)].sort_values(["fold", "window_id"])
    e = g[["yhat_x", "yhat_y", "yhat_z"]].to_numpy() - g[["y_x", "y_y", "y_z"]].to_numpy()
    return e, g["fold"].to_numpy()


def _fold_rmse(pred: pd.DataFrame, dataset: str, method: str) -> np.ndarray:
    e, folds = _errors(pred, dataset, method)
    return np.array([math.sqrt(np.mean(np.sum(e[folds == k] ** 2, axis=1))) for k in range(N_FOLDS)])


# ----------------------------------------------------------------------------- summary


def test_summary_structure(summary: dict[str, Any]) -> None:
    assert summary["format"] == "ofbe-benchmark/1"
    assert summary["protocol"] == "paper-gravity"
    assert summary["baselines"] == ["ls-trf", "won2009"] and summary["baselines_absent"] == []
    assert summary["oracle"] == "oracle"
    assert list(summary["datasets"]) == ["gravity-aligned", "rotated/sparkfun-1"]
    ga = summary["datasets"]["gravity-aligned"]
    assert ga["devices"] == ["imu-1", "imu-2", "imu-3"]
    assert summary["datasets"]["rotated/sparkfun-1"]["devices"] == ["sparkfun-1"]
    assert ga["n_signals"] == N_FOLDS * N_PER_FOLD and ga["n_folds"] == N_FOLDS
    assert ga["t_critical_fold"] == {"alpha": 0.05, "df": 4, "value": 2.776}
    keys = {"rmse_folds", "rmse_mean", "rmse_std", "seeds", "rmse_seeds", "rmse_seed_std", "max_error_folds",
            "max_error_mean", "improvement_pct", "t_test", "oracle_ratio", "mean_std_m_s2", "coverage_1sigma",
            "coverage_1sigma_axes"}
    for ds in summary["datasets"].values():
        assert set(ds["methods"]) == set(METHODS)
        for v in ds["methods"].values():
            assert set(v) == keys
            assert len(v["rmse_folds"]) == len(v["max_error_folds"]) == N_FOLDS
            assert v["seeds"] == [0] and v["rmse_seeds"] == [v["rmse_mean"]] and v["rmse_seed_std"] is None
    # serialisable under the report's rules
    json.dumps(summary, allow_nan=False)


def test_summary_values_against_independent_computation(pred: pd.DataFrame, summary: dict[str, Any]) -> None:
    for dataset, _ in DATASETS:
        ds = summary["datasets"][dataset]
        folds = {m: _fold_rmse(pred, dataset, m) for m in METHODS}
        for m in METHODS:
            v = ds["methods"][m]
            np.testing.assert_allclose(v["rmse_folds"], folds[m], rtol=1e-5)
            assert v["rmse_mean"] == pytest.approx(folds[m].mean(), rel=1e-5)
            assert v["rmse_std"] == pytest.approx(np.std(folds[m], ddof=1), rel=1e-5)
            e, f = _errors(pred, dataset, m)
            maxima = [np.abs(e[f == k]).max() for k in range(N_FOLDS)]
            np.testing.assert_allclose(v["max_error_folds"], maxima, rtol=1e-5)
            assert v["max_error_mean"] == pytest.approx(np.mean(maxima), rel=1e-5)
            assert v["oracle_ratio"] == pytest.approx(folds[m].mean() / folds["oracle"].mean(), rel=1e-5)
            for b in ("ls-trf", "won2009"):
                if b == m:
                    continue
                expected = (folds[b].mean() - folds[m].mean()) / folds[b].mean() * 100
                assert v["improvement_pct"][b] == pytest.approx(expected, rel=1e-5)
                ref = stats.ttest_rel(folds[b], folds[m])
                assert v["t_test"][b]["fold"]["t"] == pytest.approx(ref.statistic, rel=1e-5)
                assert v["t_test"][b]["fold"]["p"] == pytest.approx(ref.pvalue, rel=1e-5)
                eb, _ = _errors(pred, dataset, b)
                ref = stats.ttest_rel(np.linalg.norm(eb, axis=1), np.linalg.norm(e, axis=1))
                assert v["t_test"][b]["signal"]["t"] == pytest.approx(ref.statistic, rel=1e-5)
                assert v["t_test"][b]["signal"]["p"] == pytest.approx(ref.pvalue, rel=1e-5)


def test_self_comparisons_absent_and_oracle_ratio_one(summary: dict[str, Any]) -> None:
    for ds in summary["datasets"].values():
        methods = ds["methods"]
        assert methods["oracle"]["oracle_ratio"] == 1.0
        assert set(methods["ls-trf"]["improvement_pct"]) == {"won2009"}
        assert set(methods["ls-trf"]["t_test"]) == {"won2009"}
        assert set(methods["won2009"]["improvement_pct"]) == {"ls-trf"}
        assert set(methods["gravity-prior"]["t_test"]) == {"ls-trf", "won2009"}
        # the better methods improve on the baselines and the t-test says so
        assert methods["gravity-prior"]["improvement_pct"]["ls-trf"] > 50
        assert methods["gravity-prior"]["t_test"]["ls-trf"]["fold"]["t"] > 2.776
        assert methods["gravity-prior"]["t_test"]["ls-trf"]["signal"]["t"] > 0


def test_posterior_std_and_coverage(pred: pd.DataFrame, summary: dict[str, Any]) -> None:
    for dataset, _ in DATASETS:
        methods = summary["datasets"][dataset]["methods"]
        gp = methods["gravity-prior"]
        assert gp["mean_std_m_s2"] == pytest.approx(PRIOR_STD)
        e, _ = _errors(pred, dataset, "gravity-prior")
        assert gp["coverage_1sigma"] == pytest.approx(np.mean(np.abs(e) <= PRIOR_STD), rel=1e-5)
        z_inside = np.mean(np.abs(e[:, 2]) <= PRIOR_STD)
        assert gp["coverage_1sigma_axes"]["z"] == pytest.approx(z_inside, rel=1e-5)
        for m in ("ls-trf", "won2009", "oracle"):
            assert methods[m]["mean_std_m_s2"] is None and methods[m]["coverage_1sigma"] is None


def test_absent_baseline_and_oracle(pred: pd.DataFrame) -> None:
    no_oracle = pred[pred["method"] != "oracle"]
    s = summarise(no_oracle, baselines=("won2009", "nonexistent", "won2009"), oracle="oracle")
    assert s["baselines"] == ["won2009"] and s["baselines_absent"] == ["nonexistent"]
    assert s["oracle"] is None
    text = json.dumps(s)
    assert "nonexistent" in json.dumps(s["baselines_absent"]) and text.count("nonexistent") == 1
    for ds in s["datasets"].values():
        assert all(v["oracle_ratio"] is None for v in ds["methods"].values())
        assert set(ds["methods"]["ls-trf"]["improvement_pct"]) == {"won2009"}


def test_summary_rejects_bad_tables(pred: pd.DataFrame) -> None:
    broken = pred.drop(pred[(pred["method"] == "oracle") & (pred["window_id"] == 107)
                            & (pred["dataset"] == "gravity-aligned")].index)
    with pytest.raises(ValueError, match=r"'oracle' lacks 1: \(dataset='gravity-aligned', fold=1, "
                                         r"window_id=107\)"):
        summarise(broken)
    mixed = pred.copy()
    mixed.loc[mixed["dataset"] == "gravity-aligned", "protocol"] = "grouped"
    with pytest.raises(ValueError, match="single protocol"):
        summarise(mixed)


def test_single_fold_has_null_std() -> None:
    one = make_predictions(seed=2)
    one = one[one["fold"] == 0]
    s = summarise(one)
    v = s["datasets"]["gravity-aligned"]["methods"]["gravity-prior"]
    assert v["rmse_std"] is None and v["t_test"]["ls-trf"]["fold"] == {"t": None, "p": None}
    assert s["datasets"]["gravity-aligned"]["t_critical_fold"]["value"] is None
    json.dumps(s, allow_nan=False)
    assert "gravity-prior" in table3_markdown(s)


# ----------------------------------------------------------------------------- Markdown


def test_method_order() -> None:
    names = ["ofbenet", "oracle", "won2009", "level-mean", "ls-trf"]
    assert ordered_methods(names, ["ls-trf", "won2009"], "oracle") == [
        "ls-trf", "won2009", "level-mean", "ofbenet", "oracle"]
    assert ordered_methods(names, ["ls-trf", "won2009"], "oracle", ["ofbenet", "absent"]) == [
        "ofbenet", "ls-trf", "won2009", "level-mean", "oracle"]


def test_table3(summary: dict[str, Any]) -> None:
    md = table3_markdown(summary)
    lines = md.splitlines()
    header = [c.strip() for c in lines[0].strip("|").split("|")]
    assert header == ["Dataset", "Sensors", "Method", "Mean RMSE (m/s²)", "STD (m/s²)",
                      "Improvement % (vs ls-trf)", "vs won2009 (%)", "t (fold) vs ls-trf", "×oracle"]
    rows = [[c.strip() for c in ln.strip("|").split("|")] for ln in lines[2:] if ln.startswith("| ")]
    assert len(rows) == len(DATASETS) * len(METHODS)
    assert all(len(r) == len(header) for r in rows)
    # one block per dataset: name and sensors on its first row, methods in the default order
    assert [r[0] for r in rows] == ["gravity-aligned", "", "", "", "rotated/sparkfun-1", "", "", ""]
    assert rows[0][1] == "imu-1, imu-2, imu-3"
    assert [r[2] for r in rows[:4]] == ["ls-trf", "won2009", "gravity-prior", "oracle"]
    # best non-oracle RMSE in bold (the oracle is better but excluded), exactly one per dataset
    assert [r[2] for r in rows if r[3].startswith("**")] == ["gravity-prior", "gravity-prior"]
    ga = summary["datasets"]["gravity-aligned"]["methods"]
    gp = rows[2]
    assert gp[5] == f"{ga['gravity-prior']['improvement_pct']['ls-trf']:.1f}"
    assert gp[7].startswith(f"{ga['gravity-prior']['t_test']['ls-trf']['fold']['t']:.2f}")
    assert gp[7].endswith("*")  # significant
    assert rows[0][5] == "–" and rows[0][7] == "–" and rows[3][8] == "1.00"
    assert "2.776" in md and "df = 4" in md
    md2 = table3_markdown(summary, method_order=["oracle", "gravity-prior"])
    assert [r.split("|")[3].strip() for r in md2.splitlines()[2:6]] == [
        "oracle", "gravity-prior", "ls-trf", "won2009"]


def test_table3_without_baselines(pred: pd.DataFrame) -> None:
    s = summarise(pred, baselines=())
    md = table3_markdown(s)
    assert "| Improvement % | t (fold) | ×oracle |" in md and "No baseline is present" in md


# ----------------------------------------------------------------------------- figures


@pytest.mark.parametrize("draw", ["rmse", "max_error", "t"])
def test_figures_are_png(summary: dict[str, Any], tmp_path: Path, draw: str) -> None:
    path = tmp_path / f"{draw}.png"
    if draw == "rmse":
        rmse_figure(summary, path)
    elif draw == "max_error":
        max_error_figure(summary, path)
    else:
        t_figure(summary, path, "won2009")
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[1] >= 800 and img.shape[0] >= 400


def _captured_axes(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    figs: list[Any] = []
    monkeypatch.setattr(benchmark_figures, "save_png", lambda fig, path: figs.append(fig) or Path(path))
    return figs


def test_log_scale_decided_by_the_data(monkeypatch: pytest.MonkeyPatch) -> None:
    figs = _captured_axes(monkeypatch)
    narrow = summarise(make_predictions(seed=1))
    wide = summarise(make_predictions(seed=1, methods={**METHODS, "ls-trf": 20.0}))
    for s in (narrow, wide):
        rmse_figure(s, "unused.png")
        max_error_figure(s, "unused.png")
        t_figure(s, "unused.png", "ls-trf")
    scales = [(f.axes[0].get_yscale(), f.axes[0].get_ylabel()) for f in figs]
    assert [s for s, _ in scales[:2]] == ["linear", "linear"]
    assert [s for s, _ in scales[3:5]] == ["log", "log"]
    assert "log scale" in scales[3][1] and "log scale" not in scales[0][1]
    assert "m/s²" in scales[0][1] and "m/s²" in scales[1][1]
    # the t figure has both critical lines and a legend naming them
    ax = figs[2].axes[0]
    ys = sorted(ln.get_ydata()[0] for ln in ax.get_lines() if ln.get_linestyle() == "--")
    assert ys == pytest.approx([-2.776, 2.776], abs=1e-3)
    assert any("critical" in t.get_text() for t in ax.get_legend().get_texts())
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert "ls-trf" not in labels and "gravity-prior" in labels

    # a method has the same colour in every figure, although the t figure leaves its baseline out
    def colours(fig: Any) -> dict[str, Any]:
        return {c.get_label(): tuple(c.patches[0].get_facecolor()) for c in fig.axes[0].containers
                if isinstance(c, BarContainer)}

    assert colours(figs[2])["won2009"] == colours(figs[0])["won2009"] != colours(figs[0])["ls-trf"]


def test_t_figure_needs_a_baseline(summary: dict[str, Any], tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="baselines"):
        t_figure(summary, tmp_path / "t.png", "gravity-prior")


# ----------------------------------------------------------------------------- files

FILES = ("benchmark.json", "benchmark.md", "errors.csv", "fold_metrics.csv", "rmse.png", "max_error.png",
         "t_ls-trf.png", "t_won2009.png")


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory, pred: pd.DataFrame, summary: dict[str, Any]) -> Path:
    out = tmp_path_factory.mktemp("bench") / "paper-gravity"
    write_report(out, pred, summary, "Benchmark, paper-gravity")
    return out


def test_report_files(report: Path, summary: dict[str, Any]) -> None:
    assert sorted(p.name for p in report.iterdir()) == sorted(FILES)
    raw = (report / "benchmark.json").read_text()
    assert raw.endswith("}\n") and "NaN" not in raw
    assert json.loads(raw) == json.loads(json.dumps(summary))
    md = (report / "benchmark.md").read_text()
    assert md.startswith("# Benchmark, paper-gravity\n")
    for name in ("rmse.png", "max_error.png", "t_ls-trf.png", "t_won2009.png"):
        assert f"]({name})" in md
    assert "## Paired t-tests against ls-trf" in md and "## Paired t-tests against won2009" in md
    assert ("| Dataset | Method | t (fold) | p (fold) | df (fold) | t (signal) | p (signal) | df (signal) |"
            in md)
    assert "## Posterior standard deviations" in md


def test_csvs(report: Path, pred: pd.DataFrame) -> None:
    err = pd.read_csv(report / "errors.csv")
    assert list(err.columns) == ["dataset", "protocol", "method", "seed", "fold", "window_id", "device",
                                 "err_x", "err_y", "err_z", "err_norm"]
    assert len(err) == len(pred)
    assert err[["dataset", "method", "fold", "window_id"]].equals(
        err[["dataset", "method", "fold", "window_id"]].sort_values(
            ["dataset", "method", "fold", "window_id"]).reset_index(drop=True))
    row = err[(err["method"] == "won2009") & (err["window_id"] == 103)
              & (err["dataset"] == "gravity-aligned")]
    src = pred[(pred["method"] == "won2009") & (pred["window_id"] == 103)
               & (pred["dataset"] == "gravity-aligned")]
    e = src[["yhat_x", "yhat_y", "yhat_z"]].to_numpy() - src[["y_x", "y_y", "y_z"]].to_numpy()
    np.testing.assert_allclose(row[["err_x", "err_y", "err_z"]].to_numpy(), e, rtol=1e-8)
    assert row["err_norm"].iloc[0] == pytest.approx(np.linalg.norm(e), rel=1e-8)
    fm = pd.read_csv(report / "fold_metrics.csv")
    assert list(fm.columns) == ["dataset", "method", "seed", "fold", "rmse", "max_error", "n"]
    assert len(fm) == len(DATASETS) * len(METHODS) * N_FOLDS
    got = fm[(fm["dataset"] == "gravity-aligned") & (fm["method"] == "oracle")]["rmse"].to_numpy()
    np.testing.assert_allclose(got, _fold_rmse(pred, "gravity-aligned", "oracle"), rtol=1e-8)


def test_report_is_byte_identical_across_runs(report: Path, pred: pd.DataFrame, tmp_path: Path) -> None:
    shuffled = pred.sample(frac=1.0, random_state=7)  # row order of the input does not matter
    again = tmp_path / "again"
    write_report(again, shuffled, summarise(shuffled), "Benchmark, paper-gravity")
    for name in FILES:
        assert (again / name).read_bytes() == (report / name).read_bytes(), name
    # replacing an existing report works and still gives the same bytes
    write_report(again, pred, summarise(pred), "Benchmark, paper-gravity")
    assert (again / "benchmark.json").read_bytes() == (report / "benchmark.json").read_bytes()


def test_write_report_rejects_a_foreign_summary(pred: pd.DataFrame, tmp_path: Path) -> None:
    other = summarise(pred[pred["method"] != "oracle"])
    with pytest.raises(ValueError, match="methods"):
        write_report(tmp_path / "r", pred, other, "t")
    assert not (tmp_path / "r").exists()


def test_several_seeds_are_averaged_before_the_tests(pred: pd.DataFrame) -> None:
    """A method with three seeds: fold RMSEs and error norms averaged over seeds feed the t-tests;
    the seed spread is the sample sd of each seed's mean RMSE; Table 3 shows it."""
    base = pred[pred["method"] == "won2009"]
    seeded = []
    for seed, shift in ((0, 0.0), (1, 0.01), (2, -0.02)):
        copy = base.assign(seed=seed, method="net")
        copy[["yhat_x", "yhat_y", "yhat_z"]] += shift
        seeded.append(copy)
    table = pd.concat([pred.assign(seed=0), *seeded], ignore_index=True)
    summary = summarise(table)
    for dataset, _ in DATASETS:
        v = summary["datasets"][dataset]["methods"]["net"]
        per_seed = []
        norms = []
        for part in seeded:
            p = part[part["dataset"] == dataset].sort_values(["fold", "window_id"])
            e = p[["yhat_x", "yhat_y", "yhat_z"]].to_numpy() - p[["y_x", "y_y", "y_z"]].to_numpy()
            f = p["fold"].to_numpy()
            per_seed.append([np.sqrt(np.mean(np.sum(e[f == k] ** 2, axis=1))) for k in range(N_FOLDS)])
            norms.append(np.linalg.norm(e, axis=1))
        per_seed = np.array(per_seed)
        assert v["seeds"] == [0, 1, 2]
        np.testing.assert_allclose(v["rmse_folds"], per_seed.mean(axis=0), rtol=1e-5)
        np.testing.assert_allclose(v["rmse_seeds"], per_seed.mean(axis=1), rtol=1e-5)
        assert v["rmse_seed_std"] == pytest.approx(np.std(per_seed.mean(axis=1), ddof=1), rel=1e-5)
        assert v["rmse_mean"] == pytest.approx(per_seed.mean(), rel=1e-5)
        ls = summary["datasets"][dataset]["methods"]["ls-trf"]
        t_fold, _ = paired_t(np.array(ls["rmse_folds"]), per_seed.mean(axis=0))
        assert v["t_test"]["ls-trf"]["fold"]["t"] == pytest.approx(t_fold, rel=1e-4)
        p_ls = pred[(pred["dataset"] == dataset) & (pred["method"] == "ls-trf")]
        p_ls = p_ls.sort_values(["fold", "window_id"])
        e_ls = p_ls[["yhat_x", "yhat_y", "yhat_z"]].to_numpy() - p_ls[["y_x", "y_y", "y_z"]].to_numpy()
        t_sig, _ = paired_t(np.linalg.norm(e_ls, axis=1), np.mean(norms, axis=0))
        assert v["t_test"]["ls-trf"]["signal"]["t"] == pytest.approx(t_sig, rel=1e-4)
        assert summary["datasets"][dataset]["n_signals"] == N_FOLDS * N_PER_FOLD
    table3 = table3_markdown(summary)
    assert " ± " in table3 and "(3 seeds)" in table3 and "net: trained with several seeds" in table3
