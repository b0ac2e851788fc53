"""Dataset folders (products.md §Dataset, format ``ofbe-windows/1``): what WindowWriter writes
opens with plain h5py and pyarrow, the two data files agree row by row, every loader returns
the same content, exports and rebuilds are byte-identical, and every corruption or bad input
ends in its exact error naming the file.

Datasets are small and synthetic: 3 devices × 6 recordings × 2–3 windows of T = 50 samples,
built with fixed seeds through ``atomic_directory`` + ``WindowWriter``.
"""

from __future__ import annotations

import json
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import yaml

from ofbe_data.core.atomic import atomic_directory
from ofbe_data.core.errors import ConfigError, OfbeError, OutputExistsError
from ofbe_data.dataset import writer as dataset_writer
from ofbe_data.dataset.store import (
    SCHEMA_VERSION,
    WINDOW_COLUMNS,
    ChecksumError,
    DatasetError,
    DatasetInfo,
    LoadedDataset,
    WindowWriter,
    export_dataset,
    fold_column,
    fold_sizes,
    load_dataset,
    read_dataset_info,
    sha256_file,
    verify_dataset,
    write_package_files,
)

pytestmark = pytest.mark.slow
"""Slow: a campaign or model fixture shared by the module (``-m "not slow"`` leaves it out)."""

T = 50
STRIDE = 25
PROTOCOLS = {
    "paper-gravity": {"description": "recordings assigned to folds at random", "n_folds": 3, "seed": 7},
    "grouped": {"description": "one device per fold; late recordings only train", "n_folds": 3, "seed": 11},
}
FOLDS = [fold_column(p) for p in PROTOCOLS]
DATA_FILES = ("windows.h5", "windows.parquet", "signals.parquet")
ALL_FILES = ("CITATION.cff", "README.md", "SHA256SUMS", "croissant.json", "datapackage.json",
             "signals.parquet", "windows.h5", "windows.parquet")


def make_info(**overrides: Any) -> DatasetInfo:
    fields: dict[str, Any] = {
        "name": "synthetic-test", "campaign": "synth", "kind": "simulated", "title": "Synthetic test windows",
        "description": "Simulated by the test suite from a fixed seed.",
        "labelling": "Known biases of the simulation.", "window_length": T, "stride": STRIDE, "fs_hz": 100.0,
        "protocols": PROTOCOLS,
        "label_fidelity": {"bias_x": {"rmse": 1e-4, "max": 3e-4}, "bias_y": {"rmse": 2e-4, "max": 5e-4}},
        "extra": {"generator": "tests"},
    }
    fields.update(overrides)
    return DatasetInfo(**fields)


def make_blocks(seed: int = 0, window_length: int = T) -> list[tuple[np.ndarray, pd.DataFrame]]:
    """One block per (device, recording): 3 devices × 6 recordings × 2–3 windows."""
    rng = np.random.default_rng(seed)
    blocks = []
    for d in range(3):
        for r in range(6):
            n = 2 + (r + d) % 2
            bias = rng.normal(0.0, 0.05, 3)
            u = rng.normal(size=3)
            u /= np.linalg.norm(u)
            X = rng.normal(0.0, 0.01, (n, window_length, 3)) + bias + 9.81 * u
            offset = [np.nan] * 3 if d == 2 else list(bias + 0.001)
            meta = pd.DataFrame({
                "campaign": "synth", "session": f"s{r // 2}", "recording": f"r{r}", "device": f"dut{d}",
                "power_cycle": np.full(n, r % 2, dtype=np.int64),
                "window_index": np.arange(n, dtype=np.int64),
                "start_sample": np.arange(n, dtype=np.int64) * STRIDE,
                "bias_x": bias[0], "bias_y": bias[1], "bias_z": bias[2],
                "offset_x": offset[0], "offset_y": offset[1], "offset_z": offset[2],
                "gravity_x": u[0], "gravity_y": u[1], "gravity_z": u[2],
                "roll_deg": float(np.degrees(np.arctan2(u[1], u[2]))),
                "pitch_deg": float(np.degrees(np.arcsin(-u[0]))), "g_local": 9.81, "fs_hz": 100.0 + d * 0.01,
                "label_method": "level", "raw_sha256": f"{d:02d}{r:02d}" + "a" * 60,
                "fold_paper-gravity": np.full(n, r % 3, dtype=np.int64),
                "fold_grouped": np.full(n, d if r < 4 else -1, dtype=np.int64),
            })
            blocks.append((X, meta))
    return blocks


def build(dest: Path, blocks: list[tuple[np.ndarray, pd.DataFrame]] | None = None,
          info: DatasetInfo | None = None) -> Path:
    with atomic_directory(dest) as tmp, WindowWriter(tmp, info or make_info()) as writer:
        for X, meta in blocks if blocks is not None else make_blocks():
            writer.append(X, meta)
    return dest


@pytest.fixture(scope="module")
def built(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A dataset built once for the read-only tests."""
    return build(tmp_path_factory.mktemp("ds") / "synthetic-test")


@pytest.fixture
def fresh(tmp_path: Path) -> Path:
    """A dataset of its own, for tests that damage it."""
    return build(tmp_path / "synthetic-test")


def expected_arrays() -> tuple[np.ndarray, pd.DataFrame]:
    blocks = make_blocks()
    return (np.concatenate([b[0] for b in blocks]).astype(np.float32),
            pd.concat([b[1] for b in blocks], ignore_index=True))


# -- the files, read with plain libraries --------------------------------------------------


def test_files_open_with_plain_h5py_and_pyarrow_and_agree_row_by_row(built: Path) -> None:
    X_exp, meta_exp = expected_arrays()
    n = len(meta_exp)
    assert n == 3 * 6 * 2 + 9  # 2 or 3 windows per recording
    table = pq.read_table(built / "windows.parquet")
    assert table.column_names == [*WINDOW_COLUMNS, *FOLDS]
    assert WINDOW_COLUMNS[0] == "window_id" and WINDOW_COLUMNS[-1] == "raw_sha256"
    types = {f.name: f.type for f in table.schema}
    assert types["window_id"] == pa.int64() and types["campaign"] == pa.string()
    assert types["power_cycle"] == pa.int64() and types["bias_x"] == pa.float64()
    assert types["fold_grouped"] == pa.int64() and types["offset_z"] == pa.float64()
    prov = json.loads(table.schema.metadata[b"ofbe"])
    assert prov["schema_version"] == SCHEMA_VERSION and prov["format"] == "ofbe-windows"
    assert prov["window_length"] == T and prov["stride"] == STRIDE
    assert list(prov["protocols"]) == list(PROTOCOLS)
    frame = table.to_pandas()
    assert frame["window_id"].tolist() == list(range(n))
    assert frame["offset_x"].isna().sum() == (meta_exp["device"] == "dut2").sum()
    assert table.column("offset_x").null_count == (meta_exp["device"] == "dut2").sum()
    for col in meta_exp.columns:
        pd.testing.assert_series_equal(frame[col], meta_exp[col], check_dtype=False, check_names=False)

    with h5py.File(built / "windows.h5", "r") as f:
        X, y = f["X"], f["y"]
        assert X.dtype == np.float32 and X.shape == (n, T, 3) and X.maxshape == (None, T, 3)
        assert X.chunks == (1, T, 3) and X.compression == "gzip" and X.compression_opts == 4
        assert X.shuffle and X.fletcher32
        assert y.dtype == np.float64 and y.shape == (n, 3) and y.fletcher32
        np.testing.assert_array_equal(X[...], X_exp)  # exact float32 round trip
        np.testing.assert_array_equal(y[...], frame[["bias_x", "bias_y", "bias_z"]].to_numpy())
        for ds in (X, y):
            assert ds.attrs["units"] == "m/s^2" and ds.attrs["description"]
        a = f.attrs
        assert a["schema_version"] == SCHEMA_VERSION and a["units"] == "m/s^2" and a["frame"] == "sensor"
        assert int(a["window_length"]) == T and int(a["stride"]) == STRIDE and float(a["fs_hz"]) == 100.0
        assert a["name"] == "synthetic-test" and a["campaign"] == "synth" and a["toolkit_version"]
        assert json.loads(a["protocols"]) == PROTOCOLS
        meta = f["meta"]
        assert sorted(meta) == sorted(table.column_names)
        for name in table.column_names:
            col = table.column(name)
            if col.type == pa.string():
                assert meta[name].asstr()[...].tolist() == col.to_pylist(), name
            else:
                np.testing.assert_array_equal(meta[name][...], col.to_numpy(), err_msg=name)
        assert meta["offset_y"].dtype == np.float64 and np.isnan(meta["offset_y"][...]).sum() > 0
        assert meta["fold_grouped"].dtype == np.int64
    assert sorted(p.name for p in built.iterdir()) == sorted(ALL_FILES)


def test_datapackage_citation_and_sums(built: Path) -> None:
    dp = json.loads((built / "datapackage.json").read_text(encoding="utf-8"))
    assert dp["profile"] == "data-package" and "created" not in dp
    assert dp["licenses"][0]["name"] == "CC-BY-4.0" and dp["version"] == "1.0.0"
    res = {r["path"]: r for r in dp["resources"]}
    assert set(res) == set(DATA_FILES)
    for name in DATA_FILES:
        assert res[name]["hash"] == "sha256:" + sha256_file(built / name)
        if name == "windows.parquet":  # tabular: frictionless counts no bytes of a Parquet table
            assert "bytes" not in res[name] and res[name]["profile"] == "tabular-data-resource"
        else:
            assert res[name]["bytes"] == (built / name).stat().st_size and res[name]["type"] == "file"
    fields = [f["name"] for f in res["windows.parquet"]["schema"]["fields"]]
    assert fields == [*WINDOW_COLUMNS, *FOLDS]
    units = {f["name"]: f.get("unit") for f in res["windows.parquet"]["schema"]["fields"]}
    assert units["bias_x"] == "m/s^2" and units["fs_hz"] == "Hz"
    ofbe = dp["ofbe"]
    assert ofbe["schema_version"] == SCHEMA_VERSION and ofbe["frame"] == "sensor"
    assert ofbe["window_length"] == T and ofbe["units"] == "m/s^2" and ofbe["fs_hz"] == 100.0
    assert ofbe["protocols"]["paper-gravity"]["seed"] == 7 and ofbe["protocols"]["grouped"]["n_folds"] == 3
    assert set(ofbe["devices"]) == {"dut0", "dut1", "dut2"}

    cff = yaml.safe_load((built / "CITATION.cff").read_text(encoding="utf-8"))
    assert cff["cff-version"] == "1.2.0" and cff["title"] == "Synthetic test windows"
    assert cff["license"] == "CC-BY-4.0" and cff["authors"] == [{"name": "ofbe contributors"}]
    ref = cff["references"][0]
    assert ref["title"].startswith("Orientation-Free Neural Network-Based Bias Estimation")
    assert [a["family-names"] for a in ref["authors"]] == ["Levin", "Klein"]

    lines = (built / "SHA256SUMS").read_text(encoding="utf-8").splitlines()
    names = [line.split("  ", 1)[1] for line in lines]
    assert names == sorted(set(ALL_FILES) - {"SHA256SUMS"})
    for line in lines:
        digest, name = line.split("  ", 1)
        assert digest == sha256_file(built / name)


def test_fold_sizes_and_the_card(built: Path) -> None:
    _, meta = expected_arrays()
    sizes = fold_sizes(meta)
    assert list(sizes) == list(PROTOCOLS)
    # paper-gravity: fold = r % 3, two of the six recordings of each of the 3 devices per fold
    for k in range(3):
        windows = int((meta["fold_paper-gravity"] == k).sum())
        assert sizes["paper-gravity"]["folds"][k] == {"test_recordings": 6, "test_windows": windows}
    assert sizes["paper-gravity"]["train_only"] == {"recordings": 0, "windows": 0}
    assert sizes["grouped"]["folds"][1]["test_recordings"] == 4
    assert sizes["grouped"]["train_only"]["recordings"] == 6
    card = (built / "README.md").read_text(encoding="utf-8")
    for text in ("Synthetic test windows", SCHEMA_VERSION, "m/s^2", "100 Hz", "T = 50 samples", "stride 25",
                 "dut2", "### paper-gravity", "### grouped", "seed = 7", "load_dataset", "CC-BY-4.0",
                 "Levin & Klein", "Simulated by the test suite", "Known biases of the simulation",
                 "| bias_x | 0.0001 | 0.0003 |", "rmse"):
        assert text in card, text
    g = sizes["grouped"]["folds"][0]
    assert f"| 0 | {g['test_recordings']} | {g['test_windows']} |" in card


# -- loading and export ----------------------------------------------------------------------


def test_load_numpy_and_pandas(built: Path) -> None:
    X_exp, meta_exp = expected_arrays()
    ds = load_dataset(built)
    assert isinstance(ds, LoadedDataset)
    assert ds.X.dtype == np.float32 and ds.y.dtype == np.float64
    np.testing.assert_array_equal(ds.X, X_exp)
    np.testing.assert_array_equal(ds.y, meta_exp[["bias_x", "bias_y", "bias_z"]].to_numpy())
    assert ds.info["schema_version"] == SCHEMA_VERSION and ds.info["window_length"] == T
    assert ds.info["dataset_info"]["title"] == "Synthetic test windows"
    frame = load_dataset(built, as_="pandas")
    pd.testing.assert_frame_equal(frame, ds.meta)
    np.testing.assert_array_equal(frame[["bias_x", "bias_y", "bias_z"]].to_numpy(), ds.y)
    assert "X" not in frame.columns
    summary = verify_dataset(built)
    assert summary["n_windows"] == len(meta_exp) and summary["n_recordings"] == 18
    assert summary["n_devices"] == 3 and summary["protocols"] == list(PROTOCOLS)


def test_load_tf_streams_the_same_pairs(built: Path) -> None:
    tf = pytest.importorskip("tensorflow")
    ds = load_dataset(built)
    tfds = load_dataset(built, as_="tf")
    assert isinstance(tfds, tf.data.Dataset)
    assert tfds.element_spec[0].shape == (T, 3) and tfds.element_spec[0].dtype == tf.float32
    assert int(tfds.cardinality()) == len(ds.y)
    for _ in range(2):  # a second pass reads the file again
        pairs = list(tfds.as_numpy_iterator())
        assert len(pairs) == len(ds.y)
        np.testing.assert_array_equal(np.stack([p[0] for p in pairs]), ds.X)
        np.testing.assert_array_equal(np.stack([p[1] for p in pairs]), ds.y)


def test_unknown_loader_is_an_error(built: Path) -> None:
    with pytest.raises(DatasetError, match="as_ one of"):
        load_dataset(built, as_="torch")


def test_export_unchanged_is_byte_identical_and_loads_exactly(built: Path, tmp_path: Path) -> None:
    dest = export_dataset(built, tmp_path / "copy")
    for name in ALL_FILES:
        assert (dest / name).read_bytes() == (built / name).read_bytes(), name
    a, b = load_dataset(built), load_dataset(dest)
    np.testing.assert_array_equal(a.X, b.X)
    np.testing.assert_array_equal(a.y, b.y)
    pd.testing.assert_frame_equal(a.meta, b.meta)
    assert read_dataset_info(dest) == make_info()
    with pytest.raises(OutputExistsError):
        export_dataset(built, dest)


def test_export_with_overrides(built: Path, tmp_path: Path) -> None:
    dest = tmp_path / "release"
    dest.mkdir()
    (dest / "stale").write_text("old")
    export_dataset(built, dest, title="Release title", licence="CC0-1.0", authors=["A. Person", "B. Person"],
                   version="2.0.0", force=True)
    assert not (dest / "stale").exists()
    for name in DATA_FILES:
        assert (dest / name).read_bytes() == (built / name).read_bytes()
    info = read_dataset_info(dest)
    assert (info.title, info.licence, info.authors, info.version) == (
        "Release title", "CC0-1.0", ("A. Person", "B. Person"), "2.0.0")
    assert info.protocols == PROTOCOLS and info.label_fidelity == make_info().label_fidelity
    cff = yaml.safe_load((dest / "CITATION.cff").read_text(encoding="utf-8"))
    assert cff["title"] == "Release title" and cff["version"] == "2.0.0" and cff["license"] == "CC0-1.0"
    assert "Release title" in (dest / "README.md").read_text(encoding="utf-8")
    verify_dataset(dest)


def test_metadata_merged_in_batches_gives_the_same_files(built: Path, tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(dataset_writer, "_MERGE_BLOCKS", 4)  # 18 blocks: four merges and a remainder
    other = build(tmp_path / "synthetic-test")
    for name in ALL_FILES:
        assert (other / name).read_bytes() == (built / name).read_bytes(), name


def test_two_builds_are_byte_identical(tmp_path: Path) -> None:
    a = build(tmp_path / "a" / "synthetic-test")
    time.sleep(1.1)  # HDF5 timestamps have a resolution of one second
    b = build(tmp_path / "b" / "synthetic-test")
    for name in ALL_FILES:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


# -- corruption ------------------------------------------------------------------------------


def flip_middle_of_x(path: Path) -> None:
    with h5py.File(path, "r") as f:
        X = f["X"]
        info = X.id.get_chunk_info(X.id.get_num_chunks() // 2)
        at = info.byte_offset + info.size // 2
    data = bytearray(path.read_bytes())
    data[at] ^= 0xFF
    path.write_bytes(bytes(data))


def flip_middle(path: Path) -> None:
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x01
    path.write_bytes(bytes(data))


def edit_datapackage(path: Path) -> None:
    doc = json.loads(path.read_text(encoding="utf-8"))
    doc["title"] = "edited"
    path.write_text(json.dumps(doc, indent=2), encoding="utf-8")


@pytest.mark.parametrize(("name", "damage"), [("windows.h5", flip_middle_of_x),
                                              ("windows.parquet", flip_middle),
                                              ("signals.parquet", flip_middle),
                                              ("datapackage.json", edit_datapackage),
                                              ("croissant.json", edit_datapackage)])
def test_damage_is_a_checksum_error_naming_the_file(fresh: Path, name: str,
                                                    damage: Callable[[Path], None]) -> None:
    verify_dataset(fresh)
    damage(fresh / name)
    with pytest.raises(ChecksumError) as err:
        load_dataset(fresh)
    assert err.value.path == fresh / name
    assert name in str(err.value) and sha256_file(fresh / name) in str(err.value)
    assert "expected sha256" in str(err.value)


def test_flipped_x_byte_is_also_caught_by_fletcher32(fresh: Path) -> None:
    flip_middle_of_x(fresh / "windows.h5")
    assert len(load_dataset(fresh, as_="pandas", verify=False)) > 0  # metadata is fine
    with pytest.raises(DatasetError, match="windows.h5: expected readable X and y .*Fletcher-32"):
        load_dataset(fresh, verify=False)


def test_unreadable_parquet_without_verification_is_a_dataset_error(fresh: Path) -> None:
    flip_middle(fresh / "windows.parquet")
    with pytest.raises(DatasetError, match="windows.parquet: expected a readable Parquet file"):
        load_dataset(fresh, verify=False, as_="pandas")


def test_missing_file_is_a_dataset_error(fresh: Path) -> None:
    (fresh / "README.md").unlink()
    with pytest.raises(DatasetError, match="README.md: expected a file listed in SHA256SUMS") as err:
        verify_dataset(fresh)
    assert not isinstance(err.value, ChecksumError)


def refresh_hashes(folder: Path, name: str) -> None:
    """Make datapackage.json and SHA256SUMS agree with a file changed on purpose."""
    dp_path = folder / "datapackage.json"
    doc = json.loads(dp_path.read_text(encoding="utf-8"))
    for res in doc["resources"]:
        if res["path"] == name:
            res["hash"] = "sha256:" + sha256_file(folder / name)
            res["bytes"] = (folder / name).stat().st_size
    dp_path.write_text(json.dumps(doc, indent=2), encoding="utf-8")
    names = sorted(p.name for p in folder.iterdir() if p.name != "SHA256SUMS")
    (folder / "SHA256SUMS").write_text("".join(f"{sha256_file(folder / n)}  {n}\n" for n in names))


def wrong_h5_version(folder: Path) -> None:
    with h5py.File(folder / "windows.h5", "r+") as f:
        f.attrs["schema_version"] = "ofbe-windows/0"


def wrong_parquet_version(folder: Path) -> None:
    table = pq.read_table(folder / "windows.parquet")
    prov = json.loads(table.schema.metadata[b"ofbe"])
    prov["schema_version"] = "ofbe-windows/0"
    pq.write_table(table.replace_schema_metadata({b"ofbe": json.dumps(prov).encode()}),
                   folder / "windows.parquet", compression="zstd")


@pytest.mark.parametrize(("name", "damage"), [("windows.h5", wrong_h5_version),
                                              ("windows.parquet", wrong_parquet_version)])
def test_wrong_schema_version_is_a_dataset_error(fresh: Path, name: str,
                                                 damage: Callable[[Path], None]) -> None:
    damage(fresh)
    refresh_hashes(fresh, name)
    for call in (lambda: verify_dataset(fresh), lambda: load_dataset(fresh, verify=False)):
        with pytest.raises(DatasetError) as err:
            call()
        assert not isinstance(err.value, ChecksumError)
        assert err.value.path == fresh / name
        assert "expected 'ofbe-windows/1'" in str(err.value) and "found 'ofbe-windows/0'" in str(err.value)


def test_h5_meta_that_disagrees_with_parquet_is_found(fresh: Path) -> None:
    with h5py.File(fresh / "windows.h5", "r+") as f:
        f["meta/start_sample"][3] = 999
    refresh_hashes(fresh, "windows.h5")
    with pytest.raises(DatasetError, match="meta/start_sample"):
        verify_dataset(fresh)


# -- bad input to the writer -----------------------------------------------------------------


def first_block() -> tuple[np.ndarray, pd.DataFrame]:
    return make_blocks()[0]


def _drop(meta: pd.DataFrame, col: str) -> pd.DataFrame:
    return meta.drop(columns=[col])


BAD_APPENDS = {
    "X too long": (lambda X, m: (np.concatenate([X, X[:, :1]], axis=1), m),
                   "windows.h5: X: expected X of shape"),
    "X 2-D": (lambda X, m: (X[:, :, 0], m), "windows.h5: X: expected X of shape"),
    "X NaN": (lambda X, m: (np.where(np.arange(T)[None, :, None] == 3, np.nan, X), m), "finite samples"),
    "rows": (lambda X, m: (X, m.iloc[:1]), "metadata rows"),
    "missing column": (lambda X, m: (X, _drop(m, "roll_deg")), "missing \\['roll_deg'\\]"),
    "missing fold": (lambda X, m: (X, _drop(m, "fold_grouped")), "missing \\['fold_grouped'\\]"),
    "extra column": (lambda X, m: (X, m.assign(window_id=0)), "unexpected \\['window_id'\\]"),
    "float int": (lambda X, m: (X, m.assign(power_cycle=0.5)), "power_cycle: expected an integer column"),
    "null bias": (lambda X, m: (X, m.assign(bias_y=np.nan)), "bias_y: expected finite numbers"),
    "fold range": (lambda X, m: (X, m.assign(**{"fold_grouped": 3})), "fold indices in -1..2"),
    "null string": (lambda X, m: (X, m.assign(device=None)), "device: expected strings"),
}


@pytest.mark.parametrize("case", list(BAD_APPENDS))
def test_bad_append_is_a_dataset_error_and_leaves_nothing(tmp_path: Path, case: str) -> None:
    change, message = BAD_APPENDS[case]
    X, meta = change(*first_block())
    dest = tmp_path / "bad"
    with pytest.raises(DatasetError, match=message) as err:
        with atomic_directory(dest) as tmp, WindowWriter(tmp, make_info()) as writer:
            writer.append(*make_blocks()[1])
            writer.append(X, meta)
    assert err.value.path.name in ("windows.h5", "windows.parquet")
    assert "expected" in str(err.value) and "found" in str(err.value)
    assert list(tmp_path.iterdir()) == []


def test_label_that_changes_within_a_recording_is_an_error(tmp_path: Path) -> None:
    X, meta = first_block()
    meta = meta.copy()
    meta.loc[1, "fold_paper-gravity"] = 2
    with pytest.raises(DatasetError, match="fold_paper-gravity: expected one value per recording"):
        build(tmp_path / "bad", [(X, meta)])
    assert not (tmp_path / "bad").exists()


def test_zero_windows_is_an_error(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="expected at least one window, found 0"):
        build(tmp_path / "empty", [])
    X, meta = first_block()
    with pytest.raises(DatasetError, match="at least one window"):
        build(tmp_path / "empty", [(X[:0], meta.iloc[:0])])
    assert list(tmp_path.iterdir()) == []


def test_bad_info_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match="window_length"):
        make_info(window_length=0)
    with pytest.raises(ConfigError, match="protocol name"):
        make_info(protocols={"bad name": {}})
    with pytest.raises(ConfigError, match="JSON values"):
        make_info(extra={"seed": np.int64(3)})
    with pytest.raises(ConfigError, match="n_folds"):
        make_info(protocols={"p": {"n_folds": 0}})
    assert issubclass(DatasetError, OfbeError) and issubclass(ChecksumError, DatasetError)


def test_write_package_files_refuses_a_mismatched_description(fresh: Path) -> None:
    with pytest.raises(DatasetError, match="window_length"):
        write_package_files(fresh, make_info(window_length=T + 1))


# -- memory ----------------------------------------------------------------------------------


def _held_bytes(obj: Any, seen: set[int] | None = None) -> tuple[int, int]:
    """(bytes of numpy arrays reachable from obj's attributes, largest ndim among them)."""
    seen = set() if seen is None else seen
    if id(obj) in seen:
        return 0, 0
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        return obj.nbytes, obj.ndim
    if isinstance(obj, pd.DataFrame | pd.Series):
        return int(obj.memory_usage(deep=False).sum()), obj.ndim
    if isinstance(obj, dict):
        items = list(obj.values())
    elif isinstance(obj, list | tuple):
        items = list(obj)
    elif isinstance(obj, WindowWriter):
        items = list(vars(obj).values())
    else:
        return 0, 0
    total, ndim = 0, 0
    for item in items:
        b, d = _held_bytes(item, seen)
        total, ndim = total + b, max(ndim, d)
    return total, ndim


def test_writer_streams_x_and_keeps_only_metadata(tmp_path: Path) -> None:
    t, n_blocks, per_block = 1000, 50, 8
    info = make_info(window_length=t)
    template = make_blocks(window_length=t)[0][1].iloc[:2]
    rng = np.random.default_rng(3)
    x_bytes = 0
    with atomic_directory(tmp_path / "big") as tmp, WindowWriter(tmp, info) as writer:
        tracemalloc.start()
        try:
            before = tracemalloc.get_traced_memory()[0]
            for i in range(n_blocks):
                meta = pd.concat([template] * (per_block // 2), ignore_index=True).assign(
                    recording=f"r{i}", window_index=np.arange(per_block, dtype=np.int64))
                X = rng.normal(size=(per_block, t, 3)).astype(np.float32)
                x_bytes += X.nbytes
                writer.append(X, meta)
                del X
            grown = tracemalloc.get_traced_memory()[0] - before
        finally:
            tracemalloc.stop()
        held, ndim = _held_bytes(writer)
    assert x_bytes == n_blocks * per_block * t * 3 * 4  # 4.8 MB of X went through the writer
    assert ndim <= 1, "the writer holds a multi-dimensional array (X?)"
    assert held < 0.05 * x_bytes
    # Keeping X would grow the traced memory by at least x_bytes; the metadata of 400 windows
    # (30 small arrays per block) takes about half a megabyte.
    assert grown < 0.25 * x_bytes
    assert load_dataset(tmp_path / "big", as_="pandas").shape[0] == n_blocks * per_block
