"""Deployable models: one OFBENet and one gravity-prior on all of a dataset's windows, their card,
and ofbe-predict on them."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from ofbe_data import load_dataset
from ofbe_data.dataset.build import DatasetParams, build_dataset
from ofbe_data.labelling.batch import expand_sessions, label_sessions
from ofbe_data.labelling.labels import LabelParams
from ofbe_data.simulator import load_config, simulate_campaign
from ofbe_model.cli.export import main as export_main
from ofbe_model.cli.predict import main as predict_main
from ofbe_model.deploy.final import (
    CARD_JSON,
    CARD_MD,
    OFBENET_NAME,
    PRIOR_NAME,
    ModelCardError,
    card_dataset,
    dataset_hash,
    train_final,
)
from ofbe_model.ofbenet.network import OFBENet
from ofbe_model.ofbenet.params import OFBENetParams
from tests.ofbe_model.plain_keras import plain_keras_predict

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
    folder = train_final(ds, tmp / "models", params, [report], progress=False)
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
