"""End to end on a tiny campaign: ``ofbe-simulate`` → ``ofbe-label`` → ``ofbe-dataset build`` →
``ofbe-train`` (one fold, two seeds, two epochs), each run with ``--scheduler processes --jobs 2``
and with ``--scheduler dask --jobs 2`` into two folders, whose files must be byte-identical
(products.md §Commands: the outputs do not depend on the scheduler)."""

from __future__ import annotations

import contextlib
import json
import re
import zipfile
from pathlib import Path

import pytest

from ofbe_data.cli.dataset import main as dataset_main
from ofbe_data.cli.label import main as label_main
from ofbe_data.cli.simulate import main as simulate_main

pytestmark = [pytest.mark.slow, pytest.mark.e2e]
"""Slow: the whole pipeline end to end (``-m "not slow"`` leaves it out)."""

SCHEDULERS = ("processes", "dask")


def _run(root: Path, scheduler: str) -> Path:
    """The commands in ``root`` with relative paths (the products name them), like the pipeline."""
    flags = ["--jobs", "2", "--scheduler", scheduler]
    root.mkdir(parents=True)
    (root / "params.yaml").write_text("dataset: {window_length: 1000, stride: 1000, n_folds: 3}\n")
    with contextlib.chdir(root):
        assert simulate_main(["tiny-gravity-aligned", "--out", "raw/ga", "--quiet", *flags]) == 0
        assert label_main(["raw/ga", "--out", "labels", "--min-samples", "2000", "--quiet", *flags]) == 0
        assert dataset_main(["build", "labels/ga", "--raw", "raw/ga", "--out", "datasets/ga", "--params",
                             "params.yaml", "--quiet", *flags]) == 0
    return root


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    base = tmp_path_factory.mktemp("dask-e2e")
    return {s: _run(base / s, s) for s in SCHEDULERS}


def _files(folder: Path) -> dict[str, bytes]:
    return {p.relative_to(folder).as_posix(): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


@pytest.mark.parametrize("product", ["raw/ga", "labels", "datasets/ga"])
def test_products_are_byte_identical_whatever_the_scheduler(runs, product: str) -> None:
    a, b = (_files(runs[s] / product) for s in SCHEDULERS)
    assert a, product
    assert sorted(a) == sorted(b)
    different = [name for name in a if a[name] != b[name]]
    assert different == []
    if product == "datasets/ga":
        assert any(name.endswith(".h5") for name in a)


def _keras_members(path: Path) -> dict[str, bytes]:
    """A saved model's archive members less what differs between any two runs, whatever the
    scheduler: the save date (metadata.json), Python object ids (Keras' ``shared_object_id``
    in config.json) and the fit's duration (ofbe_ofbenet.json). The weights stay as written."""
    with zipfile.ZipFile(path) as z:
        members = {n: z.read(n) for n in z.namelist() if n != "metadata.json"}
    members["config.json"] = re.sub(rb'"shared_object_id": \d+', b"", members["config.json"])
    card = json.loads(members["ofbe_ofbenet.json"])
    card.pop("fit_seconds", None)
    members["ofbe_ofbenet.json"] = json.dumps(card, sort_keys=True).encode()
    assert "model.weights.h5" in members
    return members


def test_trained_models_are_identical_whatever_the_scheduler(runs) -> None:
    from ofbe_model.cli.train import main as train_main

    for s in SCHEDULERS:
        with contextlib.chdir(runs[s]):
            assert train_main(["datasets/ga", "--protocol", "grouped", "--out", "models", "--folds", "0",
                               "--seeds", "2", "--max-epochs", "2", "--quiet", "--jobs", "2",
                               "--scheduler", s]) == 0
    a, b = (sorted((runs[s] / "models").rglob("*.keras")) for s in SCHEDULERS)
    assert len(a) == 2 and [p.name for p in a] == [p.name for p in b]
    for pa, pb in zip(a, b, strict=True):
        assert _keras_members(pa) == _keras_members(pb), pa.name
    ha, hb = (_files(runs[s] / "models") for s in SCHEDULERS)
    histories = [n for n in ha if n.endswith(".history.csv")]
    assert len(histories) == 2
    assert all(ha[n] == hb[n] for n in histories)
