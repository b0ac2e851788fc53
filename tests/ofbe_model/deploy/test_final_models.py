"""Deployable models: one OFBENet and one gravity-prior on all of a dataset's windows, their card,
and ofbe-predict on them."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from ofbe_data import load_dataset
from ofbe_data.cli.export import main as export_main
from ofbe_data.dataset.build import DatasetParams, build_dataset
from ofbe_data.labelling.batch import expand_sessions, label_sessions
from ofbe_data.labelling.labels import LabelParams
from ofbe_data.simulator import load_config, simulate_campaign
from ofbe_model.cli.predict import main as predict_main
from ofbe_model.deploy.final import (
    CARD_JSON,
    CARD_MD,
    OFBENET_NAME,
    PRIOR_NAME,
    SET_NAME,
    DeployError,
    ModelCardError,
    accuracy_problems,
    card_dataset,
    dataset_hash,
    device_rmse,
    train_final,
)
from ofbe_model.ofbenet.network import OFBENet
from ofbe_model.ofbenet.params import OFBENetParams
from tests.helpers.plain_keras import plain_keras_predict

pytestmark = pytest.mark.slow
"""Slow: a campaign or model fixture shared by the module (``-m "not slow"`` leaves it out)."""

T = 1000


@pytest.fixture(scope="module")
def deployed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("final")
    simulate_campaign(load_config("tiny-gravity-aligned", {"sessions": 6}), tmp / "raw" / "ga", seed=3,
                      jobs=2, progress=False)
    label_sessions(expand_sessions([tmp / "raw" / "ga"]), LabelParams(min_samples=1000), tmp / "labels",
                   jobs=2, progress=False)
    ds = build_dataset(tmp / "labels" / "ga", tmp / "raw" / "ga", tmp / "ds" / "ga",
                       DatasetParams(window_length=T, stride=T), progress=False).path
    report = tmp / "benchmark.json"
    report.write_text(json.dumps({"protocol": "grouped", "datasets": {"ga": {"n_folds": 5, "methods": {
        "ofbenet": {"rmse_mean": 0.05, "rmse_std": 0.01, "max_error_mean": 0.1},
        "gravity-prior-direction": {"rmse_mean": 0.03, "rmse_std": 0.005, "max_error_mean": 0.07},
        "ls-trf": {"rmse_mean": 0.2, "rmse_std": 0.01, "max_error_mean": 0.4}}}}}))
    params = OFBENetParams(max_epochs=2, es_patience=2, lr_patience=1)
    (folder,) = train_final(ds, tmp / "models", params, [report], progress=False)
    return tmp, ds, folder


def test_two_models_and_a_card_per_dataset(deployed) -> None:
    _, ds, folder = deployed
    assert folder.name == "ga"
    assert {p.name for p in folder.iterdir()} == {OFBENET_NAME, PRIOR_NAME, CARD_JSON, CARD_MD}
    card = json.loads((folder / CARD_JSON).read_text())
    assert card["training_data"]["sha256sums_sha256"] == dataset_hash(ds)
    assert card["training_data"]["n_windows"] > 0 and card["training_data"]["window_length"] == T
    assert card["benchmark"]["ofbenet"] == {"grouped": {"ga": {"rmse_mean": 0.05, "rmse_std": 0.01,
                                                               "max_error_mean": 0.1, "n_folds": 5}}}
    assert card["benchmark"]["gravity-prior"]["grouped"]["ga"]["rmse_mean"] == 0.03
    prior = json.loads((folder / PRIOR_NAME).read_text())
    assert prior["params"]["direction_model"] is True
    assert prior["training_domain"]["n_windows"] == card["training_data"]["n_windows"]
    text = (folder / CARD_MD).read_text()
    assert "tangential components are invisible" in text
    assert "| gravity-prior | grouped | ga | 0.03 ± 0.005" in text


def test_predict_runs_the_deployed_models(deployed, capsys) -> None:
    tmp, _, folder = deployed
    n = json.loads((folder / CARD_JSON).read_text())["training_data"]["n_windows"]
    session = tmp / "raw" / "ga" / "ga-pc001"
    for model in (PRIOR_NAME, OFBENET_NAME):
        length = ["--window-length", str(T)] if model == PRIOR_NAME else []
        args = [str(folder / model), str(session), *length]
        assert predict_main(args) == 0, capsys.readouterr().err
        out = json.loads(capsys.readouterr().out)
        assert out["trained_on"].startswith(f"{n} windows of {T} samples from sparkfun-1")
        assert all(len(r["bias_m_s2"]) == 3 for r in out["results"])


def test_final_keras_loads_with_plain_keras_in_an_interpreter_without_ofbe(deployed, tmp_path) -> None:
    """final.keras opens with keras.saving.load_model alone (safe mode) in a fresh interpreter that
    never imports ofbe, and predicts exactly what OFBENet.load(...).predict does."""
    _, ds, folder = deployed
    data = load_dataset(ds)
    x, meta = np.asarray(data.X[:16], dtype=np.float32), data.meta.iloc[:16].reset_index(drop=True)
    plain = plain_keras_predict(folder / OFBENET_NAME, x, tmp_path / "child")
    ours = OFBENet.load(folder / OFBENET_NAME).predict(x, meta)
    # identical, not close: the same float32 graph (predict_on_batch and predict, one batch each)
    assert np.array_equal(plain[0].astype(np.float64), ours)
    assert np.array_equal(plain[1].astype(np.float64), ours)


def test_the_card_says_where_the_training_data_is(deployed, tmp_path, monkeypatch) -> None:
    tmp, ds, folder = deployed
    card = json.loads((folder / CARD_JSON).read_text())
    assert card["training_data"]["path"] == str(ds)
    assert card["training_data"]["relative_path"] == "../../ds/ga"  # from the card's folder, machine-free
    assert card_dataset(folder / OFBENET_NAME) == (ds, None)
    # a card written before relative_path: its path, relative to the working directory ...
    old = tmp_path / "models" / "ga"
    old.mkdir(parents=True)
    (old / OFBENET_NAME).write_bytes((folder / OFBENET_NAME).read_bytes())
    data = {**card["training_data"], "path": "processed/ga"}
    del data["relative_path"]
    (old / CARD_JSON).write_text(json.dumps({**card, "training_data": data}))
    (tmp_path / "processed").mkdir()
    (tmp_path / "processed" / "ga").symlink_to(ds, target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    assert card_dataset(old / OFBENET_NAME) == (tmp_path / "processed" / "ga", None)
    # ... or to the repository (dvc.yaml) above the card, wherever the command runs
    (tmp_path / "dvc.yaml").write_text("stages: {}\n")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert card_dataset(old / OFBENET_NAME)[0] == tmp_path / "processed" / "ga"
    # a dataset rebuilt since: a warning
    (tmp_path / "processed" / "ga").unlink()
    rebuilt = tmp_path / "rebuilt"
    shutil.copytree(ds, rebuilt)
    (rebuilt / "SHA256SUMS").write_text((ds / "SHA256SUMS").read_text() + "\n")
    (tmp_path / "processed" / "ga").symlink_to(rebuilt, target_is_directory=True)
    found, warning = card_dataset(old / OFBENET_NAME)
    assert found == tmp_path / "processed" / "ga" and "changed since the model was trained" in warning
    # and nowhere: the card and where it looked
    (tmp_path / "processed" / "ga").unlink()
    with pytest.raises(ModelCardError, match=r"model_card\.json: expected the training data 'processed/ga' "
                                             r"on disk, found no such folder \(looked in "):
        card_dataset(old / OFBENET_NAME)
    with pytest.raises(ModelCardError, match=r"expected a card describing other\.keras"):
        card_dataset(old / "other.keras")
    (old / CARD_JSON).write_text(json.dumps({**card, "training_data": {"n_windows": 3}}))
    with pytest.raises(ModelCardError, match="expected the dataset's path or relative_path, found neither"):
        card_dataset(old / OFBENET_NAME)


def test_ofbe_export_tflite_takes_the_training_data_from_the_card(deployed, tmp_path, capsys) -> None:
    """Without --dataset, ofbe-export tflite quantises with the windows the card names; a card whose
    dataset is gone is a one-line usage error naming the card."""
    _, ds, folder = deployed
    assert export_main(["tflite", str(folder / OFBENET_NAME), "--out", f"{tmp_path / 'fw'}/"]) == 0
    capsys.readouterr()
    sidecar = json.loads((tmp_path / "fw" / "final.tflite.json").read_text())
    n = json.loads((folder / CARD_JSON).read_text())["training_data"]["n_windows"]
    assert sidecar["representative"]["windows_given"] == n
    assert sidecar["representative"]["source"] == (f"{ds} (the model card's training data), all windows (a "
                                                   "model trained on all of them)")
    moved = tmp_path / "moved"
    moved.mkdir()
    (moved / OFBENET_NAME).write_bytes((folder / OFBENET_NAME).read_bytes())
    card = json.loads((folder / CARD_JSON).read_text())
    card["training_data"].update(path="processed/datasets/gone", relative_path="../gone")
    (moved / CARD_JSON).write_text(json.dumps(card))
    assert export_main(["tflite", str(moved / OFBENET_NAME), "--out", str(tmp_path / "none")]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and str(moved / CARD_JSON) in err, err
    assert "tflite needs --dataset DIR" in err and "found no such folder" in err
    assert not (tmp_path / "none").exists()


def _signal_rows(ds_path) -> tuple[np.ndarray, np.ndarray, object]:
    data = load_dataset(ds_path)
    meta = data.meta.reset_index(drop=True)
    sig = np.flatnonzero(meta["window_index"].to_numpy() == 0)
    return data.X[sig], data.y[sig], meta.iloc[sig].reset_index(drop=True)


def test_the_cards_in_sample_figures_are_measured_on_the_saved_files(deployed) -> None:
    """The card's in-sample RMSE per device is what the files on disk give on the dataset's
    signals (window 0 of each recording), recomputed here from the files themselves."""
    from ofbe_model.estimators.priors import GravityPrior

    _, ds, folder = deployed
    card = json.loads((folder / CARD_JSON).read_text())
    X, y, meta = _signal_rows(ds)
    for key, model in (("ofbenet", OFBENet.load(folder / OFBENET_NAME)),
                       ("gravity-prior", GravityPrior.load(folder / PRIOR_NAME))):
        expected = device_rmse(y, model.predict(X, meta), meta["device"].to_numpy())
        assert card["accuracy"][key]["in_sample"] == expected
        assert sum(v["n_signals"] for v in expected.values()) == len(meta)
    text = (folder / CARD_MD).read_text()
    assert "## Accuracy per device" in text and "In-sample: the file above, read back from disk" in text


@pytest.fixture(scope="module")
def rotated(tmp_path_factory):
    """A rotated campaign (two boards) windowed, with a benchmark report and errors.csv."""
    tmp = tmp_path_factory.mktemp("final-rot")
    simulate_campaign(load_config("tiny-rotated", {"sessions": 3}), tmp / "raw" / "rot", seed=4, jobs=2,
                      progress=False)
    label_sessions(expand_sessions([tmp / "raw" / "rot"]), LabelParams(min_samples=1000), tmp / "labels",
                   jobs=2, progress=False)
    ds = build_dataset(tmp / "labels" / "rot", tmp / "raw" / "rot", tmp / "ds" / "rot",
                       DatasetParams(window_length=T, stride=T, n_folds=3,
                                     protocols={"rotated": ("grouped",)}),
                       progress=False).path
    return tmp, ds


def _report(folder, cv_rmse: float) -> object:
    """A benchmark report on rot/<device> whose errors.csv gives every signal an error of
    ``cv_rmse`` (so the per-device cross-validated RMSE is exactly that) for both methods."""
    folder.mkdir(parents=True, exist_ok=True)
    datasets = {f"rot/{d}": {"n_folds": 5, "methods": {m: {"rmse_mean": cv_rmse, "rmse_std": 0.0,
                                                             "max_error_mean": cv_rmse}
                                                         for m in ("ofbenet", "gravity-prior-direction")}}
                for d in ("sparkfun-1", "sparkfun-2")}
    (folder / "benchmark.json").write_text(json.dumps({"protocol": "paper-rotated", "datasets": datasets}))
    rows = ["dataset,protocol,method,seed,fold,window_id,device,err_x,err_y,err_z,err_norm"]
    for d in ("sparkfun-1", "sparkfun-2"):
        for m in ("ofbenet", "gravity-prior-direction", "ls-trf"):
            for seed in (0, 1):
                for i in range(4):
                    rows.append(f"rot/{d},paper-rotated,{m},{seed},{i},w{i},{d},{cv_rmse},0,0,{cv_rmse}")
    (folder / "errors.csv").write_text("\n".join(rows) + "\n")
    return folder / "benchmark.json"


def test_a_per_device_dataset_gets_one_model_per_device_and_predict_picks_it(rotated, tmp_path,
                                                                             capsys) -> None:
    """Rotated boards are benchmarked one by one, so they are deployed one by one (a model set with
    models.json); ofbe-predict on the set's folder gives each file its own device's model; the old
    pooled path names the folder to pass."""
    tmp, ds = rotated
    report = _report(tmp_path / "reports" / "paper-rotated", 10.0)
    params = OFBENetParams(max_epochs=2, es_patience=2, lr_patience=1)
    folders = train_final(ds, tmp_path / "models", params, [report], progress=False)
    names = [f.relative_to(tmp_path / "models").as_posix() for f in folders]
    assert names == ["rot/sparkfun-1", "rot/sparkfun-2"]
    index = json.loads((tmp_path / "models" / "rot" / SET_NAME).read_text())
    assert index["devices"] == {"sparkfun-1": "sparkfun-1", "sparkfun-2": "sparkfun-2"}
    for folder in folders:
        card = json.loads((folder / CARD_JSON).read_text())
        device = folder.name
        data = card["training_data"]
        assert data["selected_devices"] == [device] and data["devices"] == [device]
        assert set(card["accuracy"]["ofbenet"]["in_sample"]) == {device}
        assert card["accuracy"]["ofbenet"]["cross_validated"] == {
            "paper-rotated": {device: {"rmse": 10.0, "n_signals": 4, "seeds": 2}}}
        assert card["benchmark"]["ofbenet"] == {"paper-rotated": {f"rot/{device}": {
            "rmse_mean": 10.0, "rmse_std": 0.0, "max_error_mean": 10.0, "n_folds": 5}}}
    session = next((tmp / "raw" / "rot").glob("*/session.yaml")).parent
    for estimator in ("ofbenet", "gravity-prior"):
        args = [str(tmp_path / "models" / "rot"), str(session), "--estimator", estimator,
                "--window-length", str(T)]
        assert predict_main(args) == 0, capsys.readouterr().err
        out = json.loads(capsys.readouterr().out)
        assert out["results"] and all(r["model"] == str(tmp_path / "models" / "rot" / r["device"] / (
            OFBENET_NAME if estimator == "ofbenet" else PRIOR_NAME)) for r in out["results"])
    assert predict_main([str(tmp_path / "models" / "rot" / OFBENET_NAME), str(session)]) == 2
    err = capsys.readouterr().err
    rot = tmp_path / "models" / "rot"
    assert (f"{rot / OFBENET_NAME}: no such file; {rot} holds one model per device (sparkfun-1, sparkfun-2): "
            "pass the folder") in err
    # ofbe-export tflite quantises a per-device model with its own device's windows, as its card says
    one = rot / "sparkfun-1" / OFBENET_NAME
    assert export_main(["tflite", str(one), "--out", f"{tmp_path / 'fw'}/"]) == 0
    sidecar = json.loads((tmp_path / "fw" / "final.tflite.json").read_text())
    card = json.loads((rot / "sparkfun-1" / CARD_JSON).read_text())
    assert sidecar["representative"]["windows_given"] == card["training_data"]["n_windows"]
    assert sidecar["representative"]["source"].startswith(f"{ds} (the model card's training data), device "
                                                          "sparkfun-1,")


def test_the_deploy_fails_loudly_when_a_model_is_far_worse_than_its_cross_validated_figure(
        rotated, tmp_path) -> None:
    """A cross-validated figure the deployed models cannot come near (1e-9 m/s²): DeployError naming
    each model and device with both figures, and no model left behind."""
    _, ds = rotated
    report = _report(tmp_path / "reports" / "paper-rotated", 1e-9)
    params = OFBENetParams(max_epochs=1, es_patience=1, lr_patience=1)
    with pytest.raises(DeployError) as info:
        train_final(ds, tmp_path / "models", params, [report], progress=False)
    text = str(info.value)
    assert text.startswith("deployed models far worse on their own training signals than cross-validated "
                           "(no model written):")
    for device in ("sparkfun-1", "sparkfun-2"):
        for model in ("ofbenet", "gravity-prior"):
            assert f"rot/{device}: {model}, device {device}: in-sample RMSE " in text
    assert "expected at most 1.5× the cross-validated 1e-09 m/s² (paper-rotated)" in text
    assert not (tmp_path / "models" / "rot").exists()


def test_accuracy_problems_compares_each_device_with_each_quoted_figure() -> None:
    acc = {"ofbenet": {"in_sample": {"a": {"rmse": 0.15, "n_signals": 9},
                                     "b": {"rmse": None, "n_signals": 9}},
                       "cross_validated": {"p1": {"a": {"rmse": 0.1}}, "p2": {"a": {"rmse": 0.2}}}}}
    problems = accuracy_problems(acc, 1.5)
    assert problems == ["ofbenet, device b: in-sample RMSE not finite (the model gives NaN or inf on its own "
                        "training signals)"]
    assert accuracy_problems(acc, 1.4)[0] == (
        "ofbenet, device a: in-sample RMSE 0.15 m/s² on its own 9 training signals, expected at most 1.4× "
        "the cross-validated 0.1 m/s² (p1), found 1.50×")


def test_predict_refuses_a_model_whose_estimates_are_not_finite(deployed, tmp_path, capsys) -> None:
    """A final.keras whose weights hold NaN: each file gets an error, never a null bias (exit 1)."""
    tmp, _, folder = deployed
    broken = OFBENet.load(folder / OFBENET_NAME)
    weights = broken.model_.get_weights()
    weights[-1] = np.full_like(weights[-1], np.nan)
    broken.model_.set_weights(weights)
    broken.save(tmp_path / OFBENET_NAME)
    assert predict_main([str(tmp_path / OFBENET_NAME), str(tmp / "raw" / "ga" / "ga-pc001")]) == 1
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert out["results"] and all("bias_m_s2" not in r for r in out["results"])
    assert all(r["error"].startswith("the model's estimate is not finite (NaN or inf)")
               for r in out["results"])


def test_a_bare_generic_csv_is_named_once_with_the_way_to_read_it(deployed, tmp_path, capsys) -> None:
    """ofbe-predict reads bare ofbe-logger / mscip-csv files; any other bare file gets one error line
    naming the file once and saying how to make it readable (a session), with a model set too."""
    _, _, folder = deployed
    bare = tmp_path / "x.csv"
    bare.write_text("t,ax,ay,az\n" + "".join(f"{i / 100:.2f},0.01,0.02,9.81\n" for i in range(1200)))
    assert predict_main([str(folder / PRIOR_NAME), str(bare), "--window-length", str(T)]) == 1
    err = [line for line in capsys.readouterr().err.splitlines() if "error:" in line]
    assert err == [f"ofbe-predict: error: {bare}: expected a '# ofbe-logger' header line, found none in the "
                   "file; a bare file is read as ofbe-logger or mscip-csv; for any other file (a generic "
                   "csv, another logger's format) make its folder a session with `ofbe-session init "
                   "FOLDER` and pass the folder"]
