"""The benchmark end to end on a small simulated rotated campaign: every method on every
fold, the report's files, the physics the numbers must show, and ofbe-predict."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ofbe_data.dataset.build import DatasetParams, build_dataset
from ofbe_model import predict as predict_cli
from ofbe_model.benchmark.report import summarise, write_report
from ofbe_model.benchmark.runner import BenchmarkParams, WindowCache, run_protocol
from ofbe_model.cli import benchmark as benchmark_cli
from ofbe_model.cli.predict import main as predict_main
from ofbe_model.estimators.base import EstimatorError
from ofbe_model.estimators.priors import GravityPrior

pytestmark = pytest.mark.slow
"""Slow: a campaign or model fixture shared by the module (``-m "not slow"`` leaves it out)."""

T = 1000
FAST = ("level-mean", "ls-trf", "won2009", "prior-mean", "gravity-prior", "oracle")


@pytest.fixture(scope="module")
def rotated(labelled_campaigns: Path, tmp_path_factory) -> tuple[Path, Path]:
    """2 devices × 48 tilted recordings (a power cycle every 3; the session's rotated campaign,
    conftest.py: ``raw`` is its folder), windows of 1000 samples in a dataset of this module's."""
    ds = tmp_path_factory.mktemp("bench") / "ds"
    build_dataset(labelled_campaigns / "labels" / "rot", labelled_campaigns / "raw" / "rot", ds,
                  DatasetParams(window_length=T, stride=T), progress=False)
    return labelled_campaigns / "raw" / "rot", ds


@pytest.fixture(scope="module")
def grouped_run(rotated):
    tmp, ds = rotated
    pred, seconds = run_protocol(ds, "grouped", BenchmarkParams(methods=FAST),
                                 truth_dir=tmp / "_truth", progress=False)
    return pred, seconds, summarise(pred)


def test_every_method_predicts_every_test_signal(rotated, grouped_run) -> None:
    pred, seconds, _ = grouped_run
    assert set(pred["method"]) == set(FAST) and set(seconds) == set(FAST)
    per = pred.groupby("method").size()
    assert per.nunique() == 1 and per.iloc[0] == 96  # every recording is tested once under grouped
    assert set(pred["dataset"]) == {"rot/sparkfun-1", "rot/sparkfun-2"}
    assert np.isfinite(pred[["yhat_x", "yhat_y", "yhat_z"]].to_numpy()).all()


def test_the_numbers_show_the_physics(grouped_run) -> None:
    """Tilted windows: level-mean is far off; the norm-based methods fix only the along-gravity
    part; priors help; nobody beats the oracle beyond noise."""
    _, _, summary = grouped_run
    for name, ds in summary["datasets"].items():
        r = {m: v["rmse_mean"] for m, v in ds["methods"].items()}
        assert r["level-mean"] > 1.0, name          # gravity leaks in: m/s², not mg
        assert r["gravity-prior"] < r["ls-trf"], name
        assert r["gravity-prior"] <= r["prior-mean"] * 1.05, name
        assert r["oracle"] <= min(r.values()) * 1.10, name
        assert ds["methods"]["oracle"]["oracle_ratio"] == pytest.approx(1.0)


def test_report_files(tmp_path, grouped_run) -> None:
    pred, _, summary = grouped_run
    write_report(tmp_path / "rep", pred, summary, title="grouped")
    names = {p.name for p in (tmp_path / "rep").iterdir()}
    assert {"benchmark.json", "benchmark.md", "errors.csv", "rmse.png", "max_error.png",
            "t_ls-trf.png"} <= names
    doc = json.loads((tmp_path / "rep" / "benchmark.json").read_text())
    m = doc["datasets"]["rot/sparkfun-1"]["methods"]["gravity-prior"]
    assert len(m["rmse_folds"]) == 5 and set(m["t_test"]) == {"ls-trf", "won2009"}
    assert "| Dataset | Sensors | Method |" in (tmp_path / "rep" / "benchmark.md").read_text()


def test_paper_rotated_tests_nine_signals_per_fold_and_device(rotated) -> None:
    tmp, ds = rotated
    pred, _ = run_protocol(ds, "paper-rotated", BenchmarkParams(methods=("level-mean",)), progress=False)
    assert pred.groupby(["dataset", "fold"]).size().tolist() == [9] * 10


def test_a_window_two_protocols_test_is_solved_once_with_the_same_estimate(rotated, grouped_run) -> None:
    """The per-window estimators' cache (issue 25): paper-rotated after grouped on the same dataset
    solves nothing again, and every row is what a run with a cache of its own gives."""
    tmp, ds = rotated
    params = BenchmarkParams(methods=("ls-trf", "won2009", "gravity-prior", "oracle"))
    cache = WindowCache()
    truth = tmp / "_truth"
    first, _ = run_protocol(ds, "grouped", params, truth_dir=truth, progress=False, cache=cache)
    solved = cache.solved
    assert solved == 2 * 96 and cache.reused == 0  # ls-trf and won2009 (per window); the others are fitted
    second, _ = run_protocol(ds, "paper-rotated", params, truth_dir=tmp / "_truth", progress=False,
                             cache=cache)
    assert cache.solved == solved and cache.reused == 2 * second["window_id"].nunique()
    alone, _ = run_protocol(ds, "paper-rotated", params, truth_dir=tmp / "_truth", progress=False,
                            cache=WindowCache())
    pd.testing.assert_frame_equal(second, alone)
    pd.testing.assert_frame_equal(first, run_protocol(ds, "grouped", params, truth_dir=tmp / "_truth",
                                                      progress=False, cache=WindowCache())[0])
    # another parameter is another estimator: solved afresh
    variant = BenchmarkParams(methods=("won2009-min-norm",),
                              estimator_params={"won2009-min-norm": {"estimator": "won2009", "rcond": 0.01}})
    run_protocol(ds, "grouped", variant, progress=False, cache=cache)
    assert cache.solved == solved + 96


def test_cli_errors(rotated, tmp_path, capsys) -> None:
    tmp, ds = rotated
    assert benchmark_cli.main([str(ds), "--protocol", "paper-gravity", "--out", str(tmp_path / "o"),
                               "--quiet", "--methods", "level-mean"]) == 1
    assert "expected one of this dataset's protocols (grouped, paper-rotated), found 'paper-gravity'" in \
        capsys.readouterr().err
    assert benchmark_cli.main([str(ds), "--protocol", "grouped", "--out", str(tmp_path / "o"), "--quiet",
                           "--methods", "no-such"]) == 1
    assert "estimator: expected one of" in capsys.readouterr().err
    assert benchmark_cli.main([str(ds), "--protocol", "grouped", "--out", str(tmp_path / "o"), "--quiet",
                           "--methods", "oracle"]) == 1
    assert "oracle: expected --truth" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_predict_with_a_saved_gravity_prior(rotated, tmp_path, capsys) -> None:
    from ofbe_data import load_dataset

    tmp, ds = rotated
    data = load_dataset(ds)
    model = GravityPrior().fit(data.X, data.y, data.meta)
    path = tmp_path / "gp.json"
    model.save(path)
    session = tmp / "rot-pc001"
    assert predict_main([str(path), str(session), "--window-length", str(T)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["method"] == "gravity-prior" and len(out["results"]) == 6  # 3 recordings × 2 DUTs
    for r in out["results"]:
        assert len(r["bias_m_s2"]) == 3 and all(s > 0 for s in r["std_m_s2"])
    # the prediction for the first test window equals the estimator's own
    assert predict_main([str(path), str(session), "--window-length", str(T), "--output", "table"]) == 0
    assert "sparkfun-1" in capsys.readouterr().out
    bad = tmp_path / "model.json"
    bad.write_text("{not json")
    assert predict_main([str(bad), str(session)]) == 2
    assert "model.json" in capsys.readouterr().err
    with pytest.raises(EstimatorError, match="expected a saved OFBENet"):
        predict_cli.load_model(tmp_path / "model.pkl")


def test_predict_on_a_bare_file(rotated, tmp_path, capsys) -> None:
    from ofbe_data import load_dataset

    tmp, ds = rotated
    data = load_dataset(ds)
    path = tmp_path / "gp.json"
    GravityPrior().fit(data.X, data.y, data.meta).save(path)
    bare = tmp / "rot-pc001" / "rec-01" / "sparkfun-1.csv"
    assert predict_main([str(path), str(bare), "--device", "sparkfun-1", "--g-local", "9.80",
                             "--window-length", str(T)]) == 0
    (r,) = json.loads(capsys.readouterr().out)["results"]
    assert r["device"] == "sparkfun-1" and r["g_local"] == 9.80 and len(r["bias_m_s2"]) == 3
    # a window longer than the still run is reported, not crashed on
    assert predict_main([str(path), str(bare), "--window-length", "100000"]) == 1
    err = capsys.readouterr().err
    assert "still samples, at least 100000 needed" in err and "sparkfun-1.csv" in err


def test_predict_says_what_the_model_was_trained_on_and_refuses_another_rate(rotated, tmp_path,
                                                                              capsys) -> None:
    from ofbe_data import load_dataset

    tmp, ds = rotated
    data = load_dataset(ds)
    session = tmp / "rot-pc001"
    meta = data.meta.copy()
    meta["fs_hz"] = 400.0  # as if trained on 400 Hz loggers; the session's DUTs run at 150 Hz
    meta["device"] = meta["device"].str.replace("sparkfun-2", "other-unit")
    path = tmp_path / "gp.json"
    GravityPrior().fit(data.X, data.y, meta).save(path)
    assert json.loads(path.read_text())["training_domain"]["fs_hz"] == [400.0, 400.0]
    assert predict_main([str(path), str(session), "--window-length", str(T)]) == 1
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert "400 Hz" in out["trained_on"] and "other-unit, sparkfun-1" in out["trained_on"]
    assert all(r["error"].startswith("outside the training domain: sample rate 150 Hz is outside what the "
                                     "model was trained on (400 Hz, ±10%)") for r in out["results"])
    assert all(r["error"].endswith("(--allow-outside-domain to estimate anyway)") for r in out["results"])
    # issue 24: a device the model never saw is refused too, naming it
    unseen = "device 'sparkfun-2' is not among the 2 devices"
    assert all((unseen in r["error"]) == (r["device"] == "sparkfun-2") for r in out["results"])
    assert ("ofbe-predict: gravity-prior trained on 288 windows of 1000 samples from other-unit, "
            "sparkfun-1, 400 Hz") in captured.err
    assert predict_main([str(path), str(session), "--window-length", str(T), "--allow-outside-domain"]) == 0
    captured = capsys.readouterr()
    results = json.loads(captured.out)["results"]
    assert all(len(r["bias_m_s2"]) == 3 for r in results)
    unseen = [r for r in results if r["device"] == "sparkfun-2"]
    assert unseen
    assert all("device 'sparkfun-2' is not among the 2 devices" in r["outside_domain"] for r in unseen)
    assert all(r["outside_domain"].startswith("sample rate 150 Hz") for r in results)  # each says why
    assert "warning: " in captured.err and "sparkfun-2.csv: device 'sparkfun-2' is not among" in captured.err


def test_predict_refuses_a_gravity_direction_it_never_saw_and_non_finite_flags(rotated, tmp_path,
                                                                              capsys) -> None:
    """Issue 24: a model trained on level (z-up) windows gave wrong estimates for a tilted board;
    --g-local nan gave a misleading message and a bare NaN in the JSON."""
    from ofbe_data import load_dataset

    tmp, ds = rotated
    data = load_dataset(ds)
    u = data.X.mean(axis=1)
    level = (u[:, 2] / np.linalg.norm(u, axis=1)) > np.cos(np.radians(10))  # the near-z-up windows only
    assert 0 < level.sum() < len(u)
    path = tmp_path / "gp.json"
    GravityPrior().fit(data.X[level], data.y[level], data.meta[level].reset_index(drop=True)).save(path)
    session = tmp / "rot-pc001"
    code = predict_main([str(path), str(session), "--window-length", str(T)])
    out = json.loads(capsys.readouterr().out)["results"]
    tilted = [r for r in out if "error" in r and "gravity direction" in r["error"]]
    assert code == 1 and tilted
    assert all(re.search(r"gravity direction \(-?\d\.\d{3}, -?\d\.\d{3}, -?\d\.\d{3}\) is \d+\.\d° from "
                         r"every training window's \(at most 15°\)", r["error"]) for r in tilted)
    for bad in ("nan", "inf", "0"):
        with pytest.raises(SystemExit) as exit_:
            predict_main([str(path), str(session), "--g-local", bad])
        assert exit_.value.code == 2
        assert f"expected a finite gravity in m/s² (1 to 30), found '{bad}'" in capsys.readouterr().err
