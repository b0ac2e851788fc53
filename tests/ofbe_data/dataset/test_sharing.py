"""Sharing a dataset: through a DVC remote, as docs/datasets.md describes, with a local folder as
the remote (push, lose everything, pull, and the dataset verifies and loads); and read by other
tools' own code (issue 23): Hugging Face ``datasets`` loads the shared copy as windows with their
signals, one config per protocol; frictionless-py validates ``datapackage.json``; ``mlcroissant``
validates ``croissant.json`` and reads its records. Every check compares values with
:func:`ofbe_data.load_dataset`, window by window."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from ofbe_data import load_dataset
from ofbe_data.core.atomic import atomic_directory
from ofbe_data.dataset.package import write_package_files
from ofbe_data.dataset.reader import read_dataset_info, verify_dataset
from ofbe_data.dataset.signals import SIGNAL_ROW_GROUP
from ofbe_data.dataset.store import (
    ChecksumError,
    DatasetError,
    DatasetInfo,
    WindowWriter,
    export_dataset,
    sha256_file,
)
from tests.helpers.other_tools import (
    assert_croissant_matches,
    assert_hugging_face_matches,
    card_front_matter,
    frictionless_report,
    hf_offline,  # noqa: F401 - a fixture, used by name
)

PROTOCOLS = {"grouped": {"description": "by power cycle", "n_folds": 5, "seed": 0},
             "paper-gravity": {"description": "recordings at random", "n_folds": 5, "seed": 1}}


def _tiny_dataset(path: Path, protocols: dict | None = None, shard_windows: int | None = None,
                  n_recordings: int = 10, window_length: int = 20) -> Path:
    """10 recordings × 2 windows (T = 20) of one device; recordings 1, 3, … have no offset (null)."""
    protocols = protocols or {"grouped": PROTOCOLS["grouped"]}
    info = DatasetInfo(name="share", campaign="c", kind="gravity-aligned", title="t", description="d",
                       labelling="l", window_length=window_length, stride=window_length, fs_hz=150.0,
                       protocols=protocols)
    rng = np.random.default_rng(0)
    with atomic_directory(path) as tmp, WindowWriter(tmp, info, shard_windows=shard_windows) as w:
        for i in range(n_recordings):
            meta = pd.DataFrame({
                "campaign": ["c"] * 2, "session": [f"s{i}"] * 2, "recording": ["r"] * 2, "device": ["d1"] * 2,
                "power_cycle": [i] * 2, "window_index": [0, 1], "start_sample": [0, window_length],
                **{f"bias_{a}": [0.01 * i + k] * 2 for k, a in enumerate("xyz")},
                **{f"offset_{a}": [np.nan if i % 2 else 0.002 * i] * 2 for a in "xyz"},
                "gravity_x": [0.0] * 2, "gravity_y": [0.0] * 2, "gravity_z": [1.0] * 2,
                "roll_deg": [0.0] * 2, "pitch_deg": [0.0] * 2, "g_local": [9.8] * 2, "fs_hz": [150.0] * 2,
                "label_method": ["level"] * 2, "raw_sha256": [f"{i:064d}"] * 2,
                **{f"fold_{p}": [(i + k) % 5] * 2 for k, p in enumerate(protocols)}})
            w.append(rng.normal(size=(2, window_length, 3)), meta)
    return path


def _dvc(cwd: Path, *args: str) -> None:
    subprocess.run([sys.executable, "-m", "dvc", *args], cwd=cwd, check=True, capture_output=True, text=True)


@pytest.mark.slow
def test_push_and_pull_through_a_local_remote(tmp_path) -> None:
    _tiny_dataset(tmp_path / "built")
    project = tmp_path / "project"
    project.mkdir()
    export_dataset(tmp_path / "built", project / "share")
    before = load_dataset(project / "share")
    _dvc(project, "init", "--no-scm")
    _dvc(project, "remote", "add", "-d", "storage", str(tmp_path / "remote"))
    _dvc(project, "add", "share")
    _dvc(project, "push")
    assert (project / "share.dvc").is_file() and any((tmp_path / "remote").rglob("*"))
    # a collaborator with only the .dvc file and the remote
    shutil.rmtree(project / "share")
    shutil.rmtree(project / ".dvc" / "cache")
    _dvc(project, "pull")
    after = load_dataset(project / "share")
    assert np.array_equal(after.X, before.X) and np.array_equal(after.y, before.y)
    pd.testing.assert_frame_equal(after.meta, before.meta)


# -- read by other tools' own code -----------------------------------------------------------

LAYOUTS = {"single": None, "sharded": 3}  # 20 windows: one windows.h5, or 7 shards (6 × 3 + 2)


@pytest.fixture(scope="module", params=list(LAYOUTS))
def shared(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The export of a two-protocol dataset, single-file or sharded."""
    root = tmp_path_factory.mktemp(request.param)
    _tiny_dataset(root / "built", PROTOCOLS, shard_windows=LAYOUTS[request.param])
    return export_dataset(root / "built", root / "shared")


@pytest.mark.usefixtures("hf_offline")
def test_the_shared_copy_loads_with_hugging_face_datasets(shared: Path, tmp_path: Path) -> None:
    assert assert_hugging_face_matches(shared, tmp_path / "hf-cache") == 2
    n_files = len(list(shared.glob("windows*.h5")))
    for config in card_front_matter(shared)["configs"]:
        (split,) = config["data_files"]
        assert len(split["path"]) == n_files  # sharded like the HDF5
        assert config["columns"][-1] == "X" and config["features"][-1]["name"] == "X"


def test_frictionless_validates_the_data_package(shared: Path, tmp_path: Path) -> None:
    report = frictionless_report(shared)
    assert report.valid, report.flatten(["resourcePath", "type", "note"])
    kinds = {task.name: task.type for task in report.tasks}
    assert kinds["windows"] == "table" and {t for n, t in kinds.items() if n != "windows"} == {"file"}
    assert report.tasks[[t.name for t in report.tasks].index("windows")].stats["rows"] == 20
    # the validator does check the files: a wrong size or hash of a signal file is an error
    copy = Path(shutil.copytree(shared, tmp_path / "copy"))
    doc = json.loads((copy / "datapackage.json").read_text())
    signal = next(r for r in doc["resources"] if r["path"].startswith("signals"))
    signal["bytes"] += 1
    (copy / "datapackage.json").write_text(json.dumps(doc))
    bad = frictionless_report(copy)
    assert not bad.valid and [e[1] for e in bad.flatten(["resourcePath", "type"])] == ["byte-count"]
    signal["bytes"] -= 1
    signal["hash"] = "sha256:" + "0" * 64
    (copy / "datapackage.json").write_text(json.dumps(doc))
    assert [e[1] for e in frictionless_report(copy).flatten(["resourcePath", "type"])] == ["hash-count"]


def test_croissant_validates_and_its_records_match(shared: Path) -> None:
    assert_croissant_matches(shared)
    doc = json.loads((shared / "croissant.json").read_text())
    assert doc["conformsTo"] == "http://mlcommons.org/croissant/1.1"
    x = next(f for rs in doc["recordSet"] if rs["@id"] == "signals" for f in rs["field"]
             if f["@id"] == "signals/X")
    assert x["isArray"] is True and x["arrayShape"] == "20,3" and x["dataType"] == "cr:Float32"


def test_the_export_is_the_same_bytes_again(shared: Path, tmp_path: Path) -> None:
    again = export_dataset(shared, tmp_path / "again")
    names = sorted(p.name for p in shared.iterdir())
    assert names == sorted(p.name for p in again.iterdir())
    assert {"croissant.json", "signals.parquet"} <= set(names) or "signals-00000.parquet" in names
    for name in names:
        assert (again / name).read_bytes() == (shared / name).read_bytes(), name


def test_signal_files_are_the_hdf5_windows_in_parquet(shared: Path) -> None:
    ref = load_dataset(shared)
    files = sorted(shared.glob("signals*.parquet"))
    table = pq.read_table(files if len(files) > 1 else files[0])
    x = np.stack([np.asarray(w, dtype=np.float32) for w in table.column("X").to_pylist()])
    assert np.array_equal(x, ref.X)
    meta = pq.read_table(shared / "windows.parquet")
    assert table.drop_columns(["X"]).replace_schema_metadata(None).equals(meta.replace_schema_metadata(None))
    pf = pq.ParquetFile(files[0])
    assert pf.metadata.num_row_groups == -(-pf.metadata.num_rows // SIGNAL_ROW_GROUP)
    prov = json.loads(pf.schema_arrow.metadata[b"ofbe"])
    assert prov["content"] == "signals" and prov["window_length"] == 20 and prov["first_window_id"] == 0


@pytest.mark.usefixtures("hf_offline")
def test_a_folder_without_signal_files_claims_no_configs_and_its_export_adds_them(tmp_path: Path) -> None:
    """A folder written before the signal files existed: still verifies; its card claims no Hugging
    Face config (the only Parquet file there has no samples) and its croissant.json no ``signals``;
    its export gets the signal files."""
    built = _tiny_dataset(tmp_path / "built", PROTOCOLS)
    for f in built.glob("signals*.parquet"):
        f.unlink()
    write_package_files(built, read_dataset_info(built))
    verify_dataset(built)
    assert "configs" not in card_front_matter(built)
    doc = json.loads((built / "croissant.json").read_text())
    assert [rs["@id"] for rs in doc["recordSet"]] == ["windows"]
    assert all(not r["path"].startswith("signals") for r in json.loads(
        (built / "datapackage.json").read_text())["resources"])
    assert frictionless_report(built).valid
    shared = export_dataset(built, tmp_path / "shared")
    assert (shared / "signals.parquet").is_file()
    assert assert_hugging_face_matches(shared, tmp_path / "hf-cache") == 2


def test_verify_checks_the_signal_files(tmp_path: Path) -> None:
    built = _tiny_dataset(tmp_path / "built", PROTOCOLS)
    info = read_dataset_info(built)
    # a label changed in the signal file alone, with every checksum made to agree
    table = pq.read_table(built / "signals.parquet")
    bias = table.column("bias_x").to_numpy().copy()
    bias[3] += 1.0
    table = table.set_column(table.schema.get_field_index("bias_x"), "bias_x", [bias])
    pq.write_table(table, built / "signals.parquet")
    write_package_files(built, info)
    with pytest.raises(DatasetError, match=r"signals\.parquet: expected the columns of windows\.parquet "):
        verify_dataset(built)
    # croissant.json naming another hash for a file, with SHA256SUMS made to agree with it
    other = _tiny_dataset(tmp_path / "other", PROTOCOLS)
    doc = json.loads((other / "croissant.json").read_text())
    entry = next(d for d in doc["distribution"] if d.get("contentUrl") == "signals.parquet")
    entry["sha256"] = "0" * 64
    (other / "croissant.json").write_text(json.dumps(doc))
    sums = other / "SHA256SUMS"
    sums.write_text("".join(f"{sha256_file(other / n)}  {n}\n" if n == "croissant.json" else f"{h}  {n}\n"
                            for h, n in (line.split("  ", 1) for line in sums.read_text().splitlines())))
    with pytest.raises(ChecksumError, match=r"signals\.parquet: expected sha256 0+ \(from croissant\.json\)"):
        verify_dataset(other)
    # one signal file of a sharded dataset missing from SHA256SUMS
    sharded = _tiny_dataset(tmp_path / "sharded", PROTOCOLS, shard_windows=3)
    sums = sharded / "SHA256SUMS"
    sums.write_text("".join(line + "\n" for line in sums.read_text().splitlines()
                            if not line.endswith("signals-00002.parquet")))
    with pytest.raises(DatasetError, match="SHA256SUMS: expected lines for the signal files signals-00000"):
        verify_dataset(sharded)
