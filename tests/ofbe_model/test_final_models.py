"""Deployable models: one OFBENet and one gravity-prior on all of a dataset's windows, their card,
and ofbe-predict on them."""

from __future__ import annotations

import json

import pytest

from ofbe_data.dataset.build import DatasetParams, build_dataset
from ofbe_data.labelling.batch import expand_sessions, label_sessions
from ofbe_data.labelling.labels import LabelParams
from ofbe_data.simulator import load_config, simulate_campaign
from ofbe_model.cli.predict import main as predict_main
from ofbe_model.deploy.final import CARD_JSON, CARD_MD, OFBENET_NAME, PRIOR_NAME, dataset_hash, train_final
from ofbe_model.ofbenet.params import OFBENetParams

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
