"""Building datasets from simulated, labelled campaigns: windows equal the raw samples,
HDF5 and Parquet agree, the protocols' fold sizes and leakage guarantees hold on the written
windows, builds are deterministic, and bad inputs give their errors with nothing written."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from ofbe_data.cli import dataset as dataset_cli
from ofbe_data.core.errors import ConfigError, OutputExistsError
from ofbe_data.dataset.build import DatasetParams, build_dataset, dataset_params_from
from ofbe_data.dataset.store import ChecksumError, export_dataset, load_dataset
from ofbe_data.dataset.windows import SegmentError, WindowParams, cut_windows, iter_windows, n_windows
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.manifest import load_manifest
from ofbe_data.labelling.store import read_labels
from tests.helpers.other_tools import (
    assert_croissant_matches,
    assert_hugging_face_matches,
    card_front_matter,
    frictionless_report,
    hf_offline,  # noqa: F401 - a fixture, used by name
)

pytestmark = pytest.mark.slow
"""Slow: a campaign or model fixture shared by the module (``-m "not slow"`` leaves it out)."""

T = 1000
PARAMS = DatasetParams(window_length=T, stride=T)


@pytest.fixture(scope="module")
def campaigns(labelled_campaigns: Path) -> Path:
    """A rotated campaign (2 devices × 48 recordings, 48 tilts, a power cycle every 3) and a
    gravity-aligned one (4 devices × 10), about 24 s stationary each, labelled (the session's,
    conftest.py: read only)."""
    return labelled_campaigns


@pytest.fixture(scope="module")
def built(campaigns, tmp_path_factory) -> dict[str, Path]:
    out, datasets = {}, tmp_path_factory.mktemp("datasets")
    for c in ("rot", "ga"):
        out[c] = build_dataset(campaigns / "labels" / c, campaigns / "raw" / c, datasets / c,
                               PARAMS, truth_dir=campaigns / "raw" / c / "_truth", jobs=2,
                               progress=False).path
    return out


def _meta(path: Path) -> pd.DataFrame:
    return pq.read_table(path / "windows.parquet").to_pandas()


def _rec_key(meta: pd.DataFrame) -> pd.Series:
    return meta["session"] + "/" + meta["recording"] + "/" + meta["device"]


def test_cut_windows() -> None:
    x = np.arange(30.0).reshape(10, 3)
    w = cut_windows(x, 4, 3)
    assert w.shape == (3, 4, 3) and n_windows(10, 4, 3) == 3
    assert np.array_equal(w[1], x[3:7]) and np.array_equal(w[2], x[6:10])
    assert cut_windows(x, 11, 1).shape == (0, 11, 3) and n_windows(10, 11, 1) == 0


def test_windows_are_the_raw_samples(campaigns, built) -> None:
    """Every window is the labelled segment's samples, read straight from the raw file."""
    for c in ("rot", "ga"):
        labels = read_labels(campaigns / "labels" / c).set_index(["session", "recording", "device"])
        with h5py.File(built[c] / "windows.h5", "r") as f:
            X = f["X"][:]
        meta = _meta(built[c])
        for i in (0, 1, 2, len(meta) // 2, len(meta) - 1):
            r = meta.iloc[i]
            lab = labels.loc[(r.session, r.recording, r.device)]
            m = load_manifest(campaigns / "raw" / c / r.session)
            rec = read_device_file(m.folder / lab.raw_file, m.devices[r.device])
            a = int(np.searchsorted(rec.t, lab.segment_start_s))
            expect = rec.acc[a + r.start_sample:a + r.start_sample + T].astype(np.float32)
            assert np.array_equal(X[i], expect)
            assert r.start_sample == r.window_index * T
            assert [r.bias_x, r.bias_y, r.bias_z] == [lab.bias_x, lab.bias_y, lab.bias_z]


def test_every_recording_gives_all_its_windows(campaigns, built) -> None:
    for c in ("rot", "ga"):
        labels = read_labels(campaigns / "labels" / c)
        meta = _meta(built[c])
        per = meta.groupby(_rec_key(meta)).size()
        expect = {f"{r.session}/{r.recording}/{r.device}": n_windows(r.n_samples, T, T)
                  for r in labels.itertuples()}
        assert per.to_dict() == expect
        assert meta["window_id"].tolist() == list(range(len(meta)))


def test_h5_and_parquet_agree_row_by_row(built) -> None:
    for path in built.values():
        meta = _meta(path)
        with h5py.File(path / "windows.h5", "r") as f:
            assert f["X"].shape == (len(meta), T, 3) and f["X"].dtype == np.float32
            assert f["X"].chunks == (1, T, 3) and f["X"].fletcher32 and f["X"].compression == "gzip"
            assert np.array_equal(f["y"][:], meta[["bias_x", "bias_y", "bias_z"]].to_numpy())
            for col in meta.columns:
                h = f["meta"][col][:]
                if meta[col].dtype == object or pd.api.types.is_string_dtype(meta[col]):
                    h = np.array([v.decode() if isinstance(v, bytes) else v for v in h])
                    assert h.tolist() == meta[col].tolist(), col
                else:
                    assert np.array_equal(h, meta[col].to_numpy(), equal_nan=True), col


def test_paper_rotated_folds_test_unseen_tilts(built) -> None:
    meta = _meta(built["rot"])
    rec = meta.assign(key=_rec_key(meta)).drop_duplicates("key")
    col = "fold_paper-rotated"
    assert set(rec[col]) == {-1, 0, 1, 2, 3, 4}
    for dev, d in rec.groupby("device"):
        u = d[["gravity_x", "gravity_y", "gravity_z"]].to_numpy()
        for k in range(5):
            test, train = d[col].to_numpy() == k, d[col].to_numpy() != k
            assert test.sum() == 9, (dev, k)
            cos = np.clip(u[test] @ u[train].T, -1, 1)
            assert np.degrees(np.arccos(cos)).min() > 0.5, (dev, k)
    # the test signal of a test recording is its first window
    tests = meta[meta[col] >= 0]
    assert (tests.groupby(_rec_key(tests))["window_index"].min() == 0).all()


def test_grouped_never_splits_a_power_cycle(built) -> None:
    for path in built.values():
        meta = _meta(path)
        for k in range(5):
            test = meta[meta["fold_grouped"] == k]
            train = meta[meta["fold_grouped"] != k]
            assert len(test) > 0
            shared = set(zip(test.device, test.power_cycle, strict=True)) & set(
                zip(train.device, train.power_cycle, strict=True))
            assert shared == set(), (path.name, k)
            assert set(test.device) == set(meta.device)


def test_paper_gravity_fold_sizes(built) -> None:
    meta = _meta(built["ga"])
    rec = meta.assign(key=_rec_key(meta)).drop_duplicates("key")
    assert "fold_paper-rotated" not in meta.columns
    sizes = rec.groupby(["fold_paper-gravity", "device"]).size()
    assert sizes.to_dict() == {(k, d): 2 for k in range(5) for d in sorted(rec.device.unique())}  # 20 % of 10


def test_card_states_label_fidelity(built) -> None:
    card = (built["rot"] / "README.md").read_text()
    assert "Label fidelity" in card and "paper-rotated" in card
    info = load_dataset(built["rot"]).info
    assert info is not None


def test_build_is_deterministic(campaigns, built, tmp_path) -> None:
    again = build_dataset(campaigns / "labels" / "rot", campaigns / "raw" / "rot", tmp_path / "rot", PARAMS,
                          truth_dir=campaigns / "raw" / "rot" / "_truth", jobs=1, progress=False).path
    names = sorted(p.name for p in built["rot"].iterdir())
    assert names == sorted(p.name for p in again.iterdir())
    for name in names:
        assert (again / name).read_bytes() == (built["rot"] / name).read_bytes(), name


def test_streamed_windows_do_not_depend_on_jobs(campaigns) -> None:
    labels = read_labels(campaigns / "labels" / "ga")
    one = list(iter_windows(labels, campaigns / "raw" / "ga", WindowParams(T, 700), jobs=1))
    two = list(iter_windows(labels, campaigns / "raw" / "ga", WindowParams(T, 700), jobs=2, ahead=0))
    assert [i for i, _ in one] == [i for i, _ in two] == list(labels.index)
    assert all(np.array_equal(a, b) for (_, a), (_, b) in zip(one, two, strict=True))
    assert one[0][1].shape[0] == n_windows(int(labels.n_samples.iloc[0]), T, 700) >= 4


def test_export_and_load_round_trip(built, tmp_path) -> None:
    src = load_dataset(built["ga"])
    dest = export_dataset(built["ga"], tmp_path / "shared", title="GA windows", licence="CC0-1.0")
    got = load_dataset(dest)
    assert np.array_equal(got.X, src.X) and np.array_equal(got.y, src.y)
    pd.testing.assert_frame_equal(got.meta, src.meta)
    assert "CC0-1.0" in (dest / "datapackage.json").read_text()
    h5 = dest / "windows.h5"
    data = bytearray(h5.read_bytes())
    data[len(data) // 2] ^= 0x01
    h5.write_bytes(bytes(data))
    with pytest.raises(ChecksumError, match="windows.h5"):
        load_dataset(dest)


def test_too_short_recordings_are_left_out_and_listed(campaigns, tmp_path) -> None:
    labels = read_labels(campaigns / "labels" / "ga")
    long = int(np.median(labels.n_samples))
    res = build_dataset(campaigns / "labels" / "ga", campaigns / "raw" / "ga", tmp_path / "ga",
                        DatasetParams(window_length=long, stride=long,
                                      protocols={"gravity-aligned": ("grouped",)}),
                        progress=False)
    short = labels[labels.n_samples < long]
    assert len(res.excluded) == len(short) > 0
    assert res.n_recordings == len(labels) - len(short)
    assert "excluded_recordings" in (tmp_path / "ga" / "datapackage.json").read_text()


def test_changed_raw_file_is_refused(campaigns, tmp_path, capsys) -> None:
    raw = tmp_path / "raw"
    shutil.copytree(campaigns / "raw" / "ga", raw)
    labels = read_labels(campaigns / "labels" / "ga")
    victim = raw / labels.session.iloc[3] / labels.raw_file.iloc[3]
    data = bytearray(victim.read_bytes())
    data[-10] = ord("7") if data[-10] != ord("7") else ord("8")
    victim.write_bytes(bytes(data))
    out = tmp_path / "out"
    code = dataset_cli.main(["build", str(campaigns / "labels" / "ga"), "--raw", str(raw), "--out", str(out),
                             "--window-length", str(T), "--stride", str(T), "--quiet"])
    err = capsys.readouterr().err
    assert code == 1
    assert f"{victim}: expected SHA-256 {labels.raw_sha256.iloc[3]}" in err
    assert "changed after labelling" in err
    assert not out.exists() and not any(tmp_path.glob(".out*"))
    with pytest.raises(SegmentError, match="no such file"):
        victim.unlink()
        list(iter_windows(labels, raw, WindowParams(T, T)))


def test_existing_output_and_bad_parameters(campaigns, built, tmp_path, capsys) -> None:
    with pytest.raises(OutputExistsError):
        build_dataset(campaigns / "labels" / "ga", campaigns / "raw" / "ga", built["ga"], PARAMS,
                      progress=False)
    with pytest.raises(ConfigError, match="dataset.protocols.rotated: expected protocols among"):
        dataset_params_from({"protocols": {"rotated": ["leaky"]}}, "p.yaml")
    with pytest.raises(ConfigError, match="dataset.window_length/stride: expected integers ≥ 1"):
        dataset_params_from({"stride": 0}, "p.yaml")
    params = tmp_path / "p.yaml"
    params.write_text("dataset:\n  window_lenght: 5\n")
    ga = ["build", str(campaigns / "labels" / "ga"), "--raw", str(campaigns / "raw" / "ga")]
    assert dataset_cli.main([*ga, "--params", str(params), "--out", str(tmp_path / "o")]) == 2
    assert "dataset.window_lenght: expected one of" in capsys.readouterr().err
    assert dataset_cli.main(["build", str(tmp_path / "none"), "--raw", str(campaigns / "raw" / "ga"),
                             "--out", str(tmp_path / "o")]) == 2
    assert "none: expected a label folder, found no such folder" in capsys.readouterr().err
    # paper-rotated cannot be applied to a gravity-aligned campaign: one tilt per device
    bad = _write(tmp_path / "q.yaml", "dataset:\n  protocols: {gravity-aligned: [paper-rotated]}\n")
    assert dataset_cli.main([*ga, "--out", str(tmp_path / "o"), "--window-length", str(T), "--quiet",
                             "--params", str(bad)]) == 1
    assert "ofbe-dataset: error:" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_verify_command(built, capsys) -> None:
    assert dataset_cli.main(["verify", str(built["rot"])]) == 0
    assert "OK" in capsys.readouterr().out


def _write(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_a_full_disk_is_refused_before_the_file_is_written(campaigns, tmp_path, capsys, monkeypatch) -> None:
    """The free-space check before each file (tests/ofbe_data/core/test_full_disks.py fills real disks)."""
    import collections

    from ofbe_data.dataset import writer

    usage = collections.namedtuple("usage", "total used free")
    monkeypatch.setattr(writer.shutil, "disk_usage", lambda _: usage(2**30, 2**30 - 2**20, 2**20))
    out = tmp_path / "out"
    code = dataset_cli.main(["build", str(campaigns / "labels" / "ga"), "--raw",
                             str(campaigns / "raw" / "ga"), "--out", str(out), "--window-length", str(T),
                             "--stride", str(T), "--quiet"])
    err = capsys.readouterr().err
    assert code == 74 and err.count("\n") == 1  # EX_IOERR
    line = (re.escape(f"ofbe-dataset: error: {out}/windows.h5: expected ") + r"\d\.\d MB free for "
            r"windows\.h5 \(120 windows\), found 1\.0 MB free on its disk: the dataset could not be "
            r"written; nothing partial is kept, free space and rerun\n")
    assert re.fullmatch(line, err), err
    assert not out.exists() and not any(tmp_path.glob(".out*"))


@pytest.mark.usefixtures("hf_offline")
def test_the_shared_copy_loads_with_hugging_face_datasets_with_its_signals(built, tmp_path) -> None:
    """The export of each tiny campaign's dataset, through Hugging Face's own loader: one config per
    protocol, every window with its samples (float32 (T, 3), bit for bit), label, metadata and fold
    column as ``load_dataset`` gives them; the card's licence, size and task as the Hub reads them."""
    from ofbe_data.dataset.export import export_dataset

    for c, protocols in (("rot", ["paper-rotated", "grouped"]), ("ga", ["paper-gravity", "grouped"])):
        shared = export_dataset(built[c], tmp_path / c, licence="CC-BY-4.0")
        front = card_front_matter(shared)
        n = len(pd.read_parquet(shared / "windows.parquet"))
        assert front["license"] == "cc-by-4.0" and front["pretty_name"]
        assert front["size_categories"] == ["n<1K" if n < 1000 else "1K<n<10K"]
        assert front["task_categories"] == ["tabular-regression"]
        assert [cfg["config_name"] for cfg in front["configs"]] == protocols
        for cfg in front["configs"]:  # every config reads the samples
            assert cfg["data_files"] == [{"split": "train", "path": ["signals.parquet"]}]
            assert cfg["features"][-1] == {"name": "X", "dtype": {"array2_d": {"shape": [T, 3],
                                                                               "dtype": "float32"}}}
        assert assert_hugging_face_matches(shared, tmp_path / "hf-cache") == 2
    # a licence the Hub does not list is `other` with its SPDX name
    odd = export_dataset(built["rot"], tmp_path / "odd", licence="CC-BY-ND-4.0")
    front = card_front_matter(odd)
    assert front["license"] == "other" and front["license_name"] == "CC-BY-ND-4.0"


def test_the_built_folder_validates_in_frictionless_and_croissant(built) -> None:
    """What ``ofbe-dataset build`` writes is valid for frictionless-py's own validator (the table
    row by row, the files by size and SHA-256) and for mlcroissant, whose records match."""
    for path in built.values():
        report = frictionless_report(path)
        assert report.valid, report.flatten(["resourcePath", "type", "note"])
        rows = {task.name: task.stats.get("rows") for task in report.tasks}
        assert rows["windows"] == len(_meta(path))
    assert_croissant_matches(built["rot"])
