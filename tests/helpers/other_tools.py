"""Checks shared by the dataset tests: a dataset folder read by other tools' own code (issue 23).

Hugging Face ``datasets`` (offline), MLCommons ``mlcroissant`` and frictionless-py read the folder
exactly as a user outside the toolkit would; every value is compared with
:func:`ofbe_data.load_dataset`. Test modules import :func:`hf_offline` as a fixture.
"""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture
def hf_offline(monkeypatch: pytest.MonkeyPatch):
    """Hugging Face ``datasets`` and the Hub client told to stay offline (environment and, when they
    were imported already, their module constants); returns the ``datasets`` module."""
    monkeypatch.setenv("HF_DATASETS_OFFLINE", "1")
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    import datasets
    import huggingface_hub.constants

    monkeypatch.setattr(datasets.config, "HF_HUB_OFFLINE", True)
    monkeypatch.setattr(datasets.config, "HF_DATASETS_OFFLINE", True)
    monkeypatch.setattr(huggingface_hub.constants, "HF_HUB_OFFLINE", True)
    return datasets


def card_front_matter(folder: Path) -> dict:
    """The YAML front matter of a dataset folder's README.md."""
    import yaml

    text = (folder / "README.md").read_text(encoding="utf-8")
    assert text.startswith("---\n")
    return yaml.safe_load(text.split("---\n")[1])


def _same_column(got: list, want: list, name: str) -> None:
    """Equal values; NaN and None both stand for a null float."""
    import math

    assert len(got) == len(want), name
    for i, (a, b) in enumerate(zip(got, want, strict=True)):
        a_null = a is None or (isinstance(a, float) and math.isnan(a))
        b_null = b is None or (isinstance(b, float) and math.isnan(b))
        assert a_null == b_null and (a_null or a == b), f"{name}[{i}]: {a!r} != {b!r}"


def assert_hugging_face_matches(folder: Path, cache_dir: Path) -> int:
    """Load every config of ``folder``'s card with ``datasets.load_dataset(folder, config)`` and
    check, for every window, the signal (exactly, float32 (T, 3)), the label, the metadata and the
    protocol's fold column against :func:`ofbe_data.load_dataset`; also the default config.
    Returns the number of configs checked. Call it under the ``hf_offline`` fixture."""
    import datasets
    import numpy as np

    from ofbe_data import load_dataset

    ref = load_dataset(folder)
    protocols = list(ref.info["dataset_info"]["protocols"])
    t = int(ref.info["window_length"])
    configs = card_front_matter(folder)["configs"]
    assert [c["config_name"] for c in configs] == protocols
    assert [bool(c.get("default")) for c in configs] == [True] + [False] * (len(protocols) - 1)
    folds = [c for c in ref.meta.columns if c.startswith("fold_")]
    for proto in [*protocols, None]:
        ds = datasets.load_dataset(str(folder), proto, split="train", cache_dir=str(cache_dir))
        name = proto or protocols[0]
        assert ds.config_name == name
        expected = [c for c in ref.meta.columns if c not in folds or c == f"fold_{name}"] + ["X"]
        assert ds.column_names == expected
        assert ds.features["X"] == datasets.Array2D(shape=(t, 3), dtype="float32")
        assert ds.num_rows == len(ref.meta)
        arrays = ds.with_format("numpy")
        x = np.asarray(arrays["X"])
        assert x.dtype == np.float32 and x.shape == ref.X.shape
        assert np.array_equal(arrays["window_id"], ref.meta["window_id"].to_numpy())  # same order
        assert np.array_equal(x, ref.X)  # every sample, bit for bit
        assert np.array_equal(np.column_stack([arrays[f"bias_{a}"] for a in "xyz"]), ref.y)
        one = arrays[len(ref.meta) // 2]["X"]
        assert one.shape == (t, 3) and np.array_equal(one, ref.X[len(ref.meta) // 2])
        frame = ds.remove_columns("X").to_pandas()
        for col in expected[:-1]:
            _same_column(frame[col].tolist(), ref.meta[col].tolist(), col)
    return len(protocols)


def assert_croissant_matches(folder: Path) -> None:
    """``mlcroissant`` reads ``folder/croissant.json`` with no error (and no warning but the missing
    ``datePublished``); the record set ``windows`` gives every row of ``windows.parquet``, value for
    value, and ``signals`` every window's samples (float32 (T, 3)) and label, as
    :func:`ofbe_data.load_dataset` does."""
    import mlcroissant as mlc
    import numpy as np
    import pyarrow.parquet as pq

    from ofbe_data import load_dataset

    ds = mlc.Dataset(jsonld=folder / "croissant.json")
    issues = ds.metadata.ctx.issues
    assert not issues.errors
    assert all("datePublished" in w for w in issues.warnings), issues.report()
    table = pq.read_table(folder / "windows.parquet")
    records = list(ds.records(record_set="windows"))
    assert len(records) == table.num_rows
    for col in table.column_names:
        got = [r[f"windows/{col}"] for r in records]
        got = [v.decode() if isinstance(v, bytes) else v for v in got]
        _same_column([None if v is None else (v if isinstance(v, str) else v.item()) for v in got],
                     table.column(col).to_pylist(), col)
    ref = load_dataset(folder)
    signals = list(ds.records(record_set="signals"))
    assert [int(r["signals/window_id"]) for r in signals] == ref.meta["window_id"].tolist()
    x = np.array([r["signals/X"] for r in signals], dtype=np.float32)
    assert x.shape == ref.X.shape and np.array_equal(x, ref.X)
    y = np.array([[r[f"signals/bias_{a}"] for a in "xyz"] for r in signals], dtype=np.float64)
    assert np.array_equal(y, ref.y)


def frictionless_report(folder: Path):
    """frictionless-py's own validation report of ``folder/datapackage.json`` (every resource)."""
    from frictionless import Package

    return Package(str(folder / "datapackage.json")).validate()
