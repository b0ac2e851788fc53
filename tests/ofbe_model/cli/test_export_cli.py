"""``ofbe-export`` from ofbe-predict's JSON (the estimates of a model: this package makes them),
and the model formats the model package registers with the data package's command through the
entry-point group ``ofbe.export_formats``."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from ofbe_data.calibration.exports import CALIBRATION_FORMATS, export_formats
from ofbe_data.calibration.registry import ENTRY_POINT_GROUP
from ofbe_data.cli import export
from ofbe_model.cli.export_formats import C_HEADER, TFLITE
from ofbe_model.predict import predict, targets


@pytest.fixture(scope="module")
def campaign(tiny_labelled) -> Path:
    """The session's tiny labelled campaigns (conftest.py); this module reads ``raw/ga``, ``labels/ga``."""
    return tiny_labelled


class _MeanMinusGravity:
    """A stand-in model for ofbe-predict: bias = window mean − g·z, std 0.01 m/s²."""

    name = "mean-minus-gravity"
    has_std = True
    domain_ = None

    def predict(self, X: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        return X.mean(axis=1) - np.outer(meta["g_local"].to_numpy(), [0.0, 0.0, 1.0])

    def predict_std(self, X: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        return np.full((X.shape[0], 3), 0.01)


@pytest.fixture(scope="module")
def predictions(campaign, tmp_path_factory) -> Path:
    """The JSON ofbe-predict prints for the gravity-aligned sessions, plus one entry without
    an estimate."""
    model = _MeanMinusGravity()
    items = targets(sorted((campaign / "raw" / "ga").glob("ga-pc*")), None, None)
    results = predict(model, items, 1000)
    results.append({"file": "broken.csv", "device": "sparkfun-1", "g_local": 9.8, "error": "no data"})
    path = tmp_path_factory.mktemp("predictions") / "predictions.json"
    path.write_text(json.dumps({"model": "stub.json", "method": model.name, "trained_on": None,
                                "results": results}, indent=1))
    return path


def _run(capsys, *argv: str | Path) -> tuple[int, str, str]:
    code = export.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_kalibr_needs_raw_and_labels(tmp_path, campaign, predictions, capsys) -> None:
    code, out, err = _run(capsys, "kalibr", campaign / "labels" / "ga", "--out", tmp_path / "k")
    assert code == 2 and out == "" and err.count("\n") == 1 and "--raw DIR" in err
    code, _, err = _run(capsys, "kalibr", predictions, "--raw", campaign / "raw" / "ga",
                        "--out", tmp_path / "k")
    assert code == 2 and err.count("\n") == 1 and "labels folder" in err
    assert list(tmp_path.iterdir()) == []


def test_predictions_give_one_file_per_estimate(tmp_path, predictions, capsys) -> None:
    code, _, err = _run(capsys, "ros", predictions, "--out", tmp_path / "ros")
    assert code == 0 and "warning: skipped broken.csv: no estimate (no data)" in err
    doc = json.loads(predictions.read_text())
    good = [r for r in doc["results"] if "error" not in r]
    files = sorted((tmp_path / "ros").iterdir())
    assert len(files) == len(good) == 6
    assert files[0].name == "sparkfun-1.ga-pc001_rec-01_sparkfun-1.ros.yaml"
    back = yaml.safe_load(files[0].read_text())["/**"]["ros__parameters"]
    entry = next(r for r in good if r["device"] == "sparkfun-1" and "ga-pc001" in r["file"])
    assert back["linear_acceleration_bias"] == entry["bias_m_s2"]
    # a prediction knows the uncertainty of its bias, not the per-sample noise of the recording
    assert back["linear_acceleration_bias_std"] == entry["std_m_s2"]
    assert back["linear_acceleration_covariance"] == [0.0] * 9
    assert "power_cycle" not in back and back["bias_kind"] == "apparent"
    code, _, err = _run(capsys, "json", predictions, "--out", tmp_path / "json")
    first = json.loads(sorted((tmp_path / "json").iterdir())[0].read_text())
    assert code == 0 and first["method"] == "mean-minus-gravity" and first["model"] == "stub.json"
    assert first["bias_std_m_s2"] == [0.01] * 3 and first["source"]["files"][0]["path"] == str(predictions)
    assert first["time_source"] == "recording-header-utc"  # the predicted file's own start stamp


def test_the_model_package_registers_its_formats_through_the_entry_point() -> None:
    """The data package's command finds tflite and c-header without importing the model package
    by name: they come from the installed distribution's entry points."""
    from importlib.metadata import entry_points

    registered = {ep.name: ep.value for ep in entry_points(group=ENTRY_POINT_GROUP)}
    assert registered == {"tflite": "ofbe_model.cli.export_formats:TFLITE",
                          "c-header": "ofbe_model.cli.export_formats:C_HEADER"}
    formats, unavailable = export_formats()
    assert unavailable == {} and formats["tflite"] is TFLITE and formats["c-header"] is C_HEADER
    assert list(formats)[:len(CALIBRATION_FORMATS)] == list(CALIBRATION_FORMATS)


def test_without_the_model_package_its_formats_are_absent_and_named(tmp_path, monkeypatch, capsys) -> None:
    """ofbe_model not importable (a lab that only labels): the calibration formats work, the model
    formats are not offered, and asking for one says which package provides it."""
    for name in ("ofbe_model", "ofbe_model.cli", "ofbe_model.cli.export_formats"):
        monkeypatch.setitem(sys.modules, name, None)  # import ofbe_model... raises ImportError
    formats, unavailable = export_formats()
    assert sorted(unavailable) == ["c-header", "tflite"] and "tflite" not in formats
    code, out, err = _run(capsys, "tflite", tmp_path / "final.keras", "--out", tmp_path / "fw")
    assert code == 2 and out == "" and err.count("\n") == 1
    assert err.startswith("ofbe-export: error: tflite: expected the package that provides this format, "
                          "ofbe_model (the model package), to be importable, found it is not (")
    with pytest.raises(SystemExit):
        export.main(["--help"])
    text = capsys.readouterr().out
    assert f"{', '.join(CALIBRATION_FORMATS)}\n" in text and "tflite" not in text
    assert not (tmp_path / "fw").exists()
