"""Issue 36: ``ofbe-export tflite`` trusted a hand-edited ``model_card.json`` pointing at another
dataset and calibrated the int8 model on the wrong windows (6.2 mg rms against float instead of
0.18). The card's dataset hash is now checked against the dataset whose windows would calibrate
the model; a mismatch is an error naming the card, the hash it states and the dataset's, and
nothing is written.

The check comes before the model or the dataset is read, so the model here is a placeholder
file and each dataset a folder holding its ``SHA256SUMS`` only (the hashes are what is checked;
tests/ofbe_model/deploy/test_final_models.py exports a real model through its card).
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from ofbe_data.cli.export import main as export_main
from ofbe_model.deploy.final import CARD_FORMAT, CARD_JSON, OFBENET_NAME
from ofbe_model.deploy.tflite import CardDatasetMismatch, check_card_dataset

ADVICE = ("; pass the dataset the model was trained on (--dataset DIR), or retrain and redeploy the model on "
          "this one (its card then records it); nothing written")


def _dataset(folder: Path, text: str) -> str:
    """A dataset folder holding a SHA256SUMS; the SHA-256 of that file."""
    folder.mkdir(parents=True)
    (folder / "SHA256SUMS").write_text(text)
    return hashlib.sha256(text.encode()).hexdigest()


@pytest.fixture
def deployed(tmp_path: Path) -> tuple[Path, Path, str, Path, str]:
    """models/ga/final.keras with a card on ds/ga; ds/rot, another dataset."""
    ga_hash = _dataset(tmp_path / "ds" / "ga", "aa  windows.h5\n")
    rot_hash = _dataset(tmp_path / "ds" / "rot", "bb  windows.h5\n")
    folder = tmp_path / "models" / "ga"
    folder.mkdir(parents=True)
    (folder / OFBENET_NAME).write_bytes(b"not read: the check comes first")
    card = {"format": CARD_FORMAT, "files": {"ofbenet": OFBENET_NAME},
            "training_data": {"path": "ds/ga", "relative_path": "../../ds/ga", "sha256sums_sha256": ga_hash}}
    (folder / CARD_JSON).write_text(json.dumps(card))
    return folder / OFBENET_NAME, tmp_path / "ds" / "ga", ga_hash, tmp_path / "ds" / "rot", rot_hash


def _edit_card(model: Path, **training_data: object) -> Path:
    card_file = model.parent / CARD_JSON
    card = json.loads(card_file.read_text())
    card["training_data"].update(training_data)
    card["training_data"] = {k: v for k, v in card["training_data"].items() if v is not None}
    card_file.write_text(json.dumps(card))
    return card_file


def test_a_card_edited_to_point_at_another_dataset_is_refused(deployed, tmp_path, capsys) -> None:
    model, _, ga_hash, rot, rot_hash = deployed
    card_file = _edit_card(model, relative_path="../../ds/rot", path="ds/rot")  # the hash left as it was
    out = tmp_path / "fw"
    assert export_main(["tflite", str(model), "--out", f"{out}/"]) == 1
    assert capsys.readouterr().err == (
        f"ofbe-export: error: {card_file}: states training data whose SHA256SUMS has SHA-256 {ga_hash}, "
        f"but {rot} has {rot_hash}: the int8 model would be calibrated on windows it was not trained on"
        f"{ADVICE}\n")
    assert not out.exists()


def test_another_dataset_given_with_dataset_is_refused_too(deployed, tmp_path, capsys) -> None:
    model, _, ga_hash, rot, rot_hash = deployed
    out = tmp_path / "fw"
    assert export_main(["tflite", str(model), "--dataset", str(rot), "--out", f"{out}/"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"SHA-256 {ga_hash}, but {rot} has {rot_hash}" in err
    assert not out.exists()


def test_a_card_without_its_hash_or_a_dataset_without_sums_is_refused(deployed, tmp_path, capsys) -> None:
    model, ga, ga_hash, _, _ = deployed
    card_file = _edit_card(model, sha256sums_sha256=None)
    assert export_main(["tflite", str(model), "--out", f"{tmp_path / 'fw'}/"]) == 1
    assert capsys.readouterr().err == (
        f"ofbe-export: error: {card_file}: training_data: expected the SHA-256 of the training dataset's "
        f"SHA256SUMS (sha256sums_sha256) to check {ga} against, found none{ADVICE}\n")
    _edit_card(model, sha256sums_sha256=ga_hash)
    (ga / "SHA256SUMS").unlink()
    with pytest.raises(CardDatasetMismatch, match=f"{ga}: expected a dataset with a SHA256SUMS to check "
                                                  f"against {card_file}, found none"):
        check_card_dataset(model, ga)
    assert not (tmp_path / "fw").exists()


def test_the_dataset_the_card_records_passes(deployed, tmp_path) -> None:
    model, ga, _, rot, _ = deployed
    assert check_card_dataset(model, ga) is None
    # no card, or a card about another model file: nothing to check (--dataset is the caller's word)
    other = tmp_path / "other.keras"
    assert check_card_dataset(other, rot) is None
    assert check_card_dataset(model.parent / "fold.keras", rot) is None
    with pytest.raises(CardDatasetMismatch):
        check_card_dataset(model, rot)
