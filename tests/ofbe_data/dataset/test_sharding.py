"""Sharded datasets (docs/datasets.md, "Sharded datasets"): above ``dataset.shard_windows``
windows the builder writes ``windows-00000.h5``, … indexed by ``windows.parquet``; below it the
single-file layout is unchanged byte for byte. Both layouts load to the same X, y and meta; a
sharded one lazily, shard by shard; verify covers every shard.

The campaign is ``tiny-fleet`` (4 devices × 5 power cycles × one 32 s recording), labelled with
the default parameters and cut into windows of T = 1000 samples: 20 recordings × 4 windows = 80
windows, so ``shard_windows`` = 7 gives 12 shards (11 × 7 + 3) and recordings that straddle
shard boundaries.
"""

from __future__ import annotations

import dataclasses
import json
import tracemalloc
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pyarrow.parquet as pq
import pytest

from ofbe_data.cli import dataset as dataset_cli
from ofbe_data.core.atomic import atomic_directory
from ofbe_data.core.errors import ConfigError
from ofbe_data.dataset import reader
from ofbe_data.dataset.build import DatasetParams, build_dataset, dataset_params_from
from ofbe_data.dataset.reader import LoadedDataset, load_dataset, verify_dataset
from ofbe_data.dataset.store import (
    DEFAULT_SHARD_WINDOWS,
    ChecksumError,
    DatasetError,
    DatasetInfo,
    sha256_file,
    shard_name,
)
from ofbe_data.dataset.writer import WindowWriter
from ofbe_data.labelling.batch import expand_sessions, label_sessions
from ofbe_data.labelling.labels import LabelParams
from ofbe_data.simulator import simulate_campaign
from tests.helpers.other_tools import (
    assert_croissant_matches,
    assert_hugging_face_matches,
    card_front_matter,
    frictionless_report,
    hf_offline,  # noqa: F401 - a fixture, used by name
)

T = 1000
SHARD = 7
N = 80
N_SHARDS = 12  # ceil(80 / 7)
LAST = N - SHARD * (N_SHARDS - 1)
PARAMS = DatasetParams(window_length=T, stride=T)


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    tmp = tmp_path_factory.mktemp("fleet")
    simulate_campaign("tiny-fleet", tmp / "raw" / "fleet", jobs=2, progress=False)
    outcomes = label_sessions(expand_sessions([tmp / "raw" / "fleet"]), LabelParams(), tmp / "labels",
                              jobs=2, progress=False)
    assert [o.error for o in outcomes if o.error] == []
    return tmp


def _build(campaign: Path, out: Path, params: DatasetParams = PARAMS, jobs: int = 2) -> Path:
    return build_dataset(campaign / "labels" / "fleet", campaign / "raw" / "fleet", out, params,
                         truth_dir=campaign / "raw" / "fleet" / "_truth", jobs=jobs, progress=False).path


@pytest.fixture(scope="module")
def single(campaign: Path) -> Path:
    return _build(campaign, campaign / "datasets" / "single")


@pytest.fixture(scope="module")
def sharded(campaign: Path) -> Path:
    return _build(campaign, campaign / "datasets" / "sharded",
                  dataclasses.replace(PARAMS, shard_windows=SHARD))


def _sums(folder: Path) -> dict[str, str]:
    return {line.split("  ", 1)[1]: line.split("  ", 1)[0]
            for line in (folder / "SHA256SUMS").read_text().splitlines()}


def _same_files(a: Path, b: Path) -> None:
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(p.name for p in b.iterdir())
    for name in names:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


# -- layout ----------------------------------------------------------------------------------


def test_default_keeps_the_single_file_layout_byte_for_byte(campaign: Path, single: Path,
                                                           tmp_path: Path) -> None:
    assert PARAMS.shard_windows == DEFAULT_SHARD_WINDOWS >= 2500  # the paper's datasets stay whole
    names = sorted(p.name for p in single.iterdir())
    assert names == ["CITATION.cff", "README.md", "SHA256SUMS", "croissant.json", "datapackage.json",
                     "signals.parquet", "windows.h5", "windows.parquet"]
    # exactly N windows is not "above" the shard size: the same bytes as the default build
    at_limit = _build(campaign, tmp_path / "single", dataclasses.replace(PARAMS, shard_windows=N), jobs=1)
    assert _sums(at_limit) == _sums(single)
    _same_files(at_limit, single)
    assert "shard" not in pq.read_table(single / "windows.parquet").column_names
    assert "shards" not in json.loads((single / "datapackage.json").read_text())["ofbe"]


def test_sharded_layout(sharded: Path) -> None:
    shards = [shard_name(i) for i in range(N_SHARDS)]
    signals = [f"signals-{i:05d}.parquet" for i in range(N_SHARDS)]
    assert sorted(p.name for p in sharded.iterdir()) == sorted(
        ["CITATION.cff", "README.md", "SHA256SUMS", "croissant.json", "datapackage.json", "windows.parquet",
         *shards, *signals])
    table = pq.read_table(sharded / "windows.parquet")
    assert table.column_names[:3] == ["window_id", "shard", "shard_row"]
    index = table.to_pandas()
    assert index["window_id"].tolist() == list(range(N))
    assert index["shard"].tolist() == [i // SHARD for i in range(N)]
    assert index["shard_row"].tolist() == [i % SHARD for i in range(N)]
    prov = json.loads(table.schema.metadata[b"ofbe"])
    sizes = [SHARD] * (N_SHARDS - 1) + [LAST]
    assert prov["shards"] == {"windows_per_shard": SHARD,
                              "files": [{"path": s, "n_windows": k}
                                        for s, k in zip(shards, sizes, strict=True)]}
    # every shard is self-contained: X, y and meta/ of its rows, openable with plain h5py
    for i, name in enumerate(shards):
        rows = index[index["shard"] == i]
        with h5py.File(sharded / name, "r") as f:
            assert f["X"].shape == (len(rows), T, 3) and f["X"].chunks == (1, T, 3) and f["X"].fletcher32
            assert np.array_equal(f["y"][...], rows[["bias_x", "bias_y", "bias_z"]].to_numpy())
            assert f["meta/window_id"][...].tolist() == rows["window_id"].tolist()
            assert f["meta/device"].asstr()[...].tolist() == rows["device"].tolist()
            attrs = (int(f.attrs["shard"]), int(f.attrs["shard_windows"]), int(f.attrs["first_window_id"]))
            assert attrs == (i, SHARD, i * SHARD)
            assert f.attrs["schema_version"] == "ofbe-windows/1"
    # a recording whose windows straddle a boundary (4 windows a recording, 7 a shard)
    assert index.groupby(["session", "device"])["shard"].nunique().max() == 2
    # one resource, one card row and one checksum per shard
    dp = json.loads((sharded / "datapackage.json").read_text())
    res = {r["path"]: r for r in dp["resources"]}
    assert set(res) == {*shards, "windows.parquet", *signals}
    for name in (*shards, *signals):
        assert res[name]["hash"] == "sha256:" + sha256_file(sharded / name)
        assert res[name]["bytes"] == (sharded / name).stat().st_size
    assert dp["ofbe"]["shards"]["n_shards"] == N_SHARDS and dp["ofbe"]["n_windows"] == N
    assert [f["name"] for f in res["windows.parquet"]["schema"]["fields"]][:3] == ["window_id", "shard",
                                                                                   "shard_row"]
    card = (sharded / "README.md").read_text()
    assert f"Sharded: {N_SHARDS} HDF5 files of at most {SHARD} windows" in card
    assert all(f"| {name} |" in card for name in (*shards, *signals)) and "iter_shards" in card
    assert set(_sums(sharded)) == {*shards, *signals, "windows.parquet", "datapackage.json", "croissant.json",
                                   "README.md", "CITATION.cff"}
    # each signal file holds its shard's rows of the index, with X
    for i, name in enumerate(signals):
        table = pq.read_table(sharded / name)
        assert table.column("window_id").to_pylist() == index.loc[index["shard"] == i, "window_id"].tolist()
        assert table.column_names == [*index.columns, "X"]


# -- loading ---------------------------------------------------------------------------------


@pytest.mark.slow
def test_both_layouts_load_the_same_content(single: Path, sharded: Path) -> None:
    a, b = load_dataset(single), load_dataset(sharded)
    assert a.X.shape == (N, T, 3) and not a.sharded and b.sharded
    np.testing.assert_array_equal(b.X, a.X)
    np.testing.assert_array_equal(b.y, a.y)
    pd.testing.assert_frame_equal(b.meta, a.meta)
    pd.testing.assert_frame_equal(load_dataset(sharded, as_="pandas"), load_dataset(single, as_="pandas"))
    assert b.info["shards"]["windows_per_shard"] == SHARD
    assert {k: v for k, v in b.info.items() if k != "shards"} == a.info
    assert [(s.path.name, s.start, s.stop) for s in b.shards] == [
        (shard_name(i), SHARD * i, min(SHARD * (i + 1), N)) for i in range(N_SHARDS)]
    parts = list(b.iter_shards())
    assert len(parts) == N_SHARDS and [len(x) for x, _, _ in parts] == [SHARD] * (N_SHARDS - 1) + [LAST]
    np.testing.assert_array_equal(np.concatenate([x for x, _, _ in parts]), a.X)
    np.testing.assert_array_equal(np.concatenate([y for _, y, _ in parts]), a.y)
    pd.testing.assert_frame_equal(pd.concat([m for _, _, m in parts]), a.meta)
    (x1, _, m1), = list(a.iter_shards())  # the single file is one shard, already in memory
    assert np.shares_memory(x1, a.X) and x1.shape == a.X.shape and len(m1) == N


def test_sharded_x_is_read_lazily(sharded: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    reads: list[str] = []
    real = reader._read_x

    def counting(shard: reader.Shard, out: np.ndarray | None = None) -> np.ndarray:
        reads.append(shard.path.name)
        return real(shard, out)

    monkeypatch.setattr(reader, "_read_x", counting)
    ds = load_dataset(sharded)
    assert isinstance(ds, LoadedDataset) and reads == []
    first = next(ds.iter_shards())
    assert reads == [shard_name(0)] and first[0].shape == (SHARD, T, 3)
    reads.clear()
    assert ds.X.shape == (N, T, 3)
    assert reads == [shard_name(i) for i in range(N_SHARDS)]
    reads.clear()
    ds.X  # noqa: B018 - kept after the first use
    list(ds.iter_shards())  # from memory once X is loaded
    assert reads == []


@pytest.mark.slow
def test_tf_dataset_streams_from_the_shards(single: Path, sharded: Path) -> None:
    tf = pytest.importorskip("tensorflow")
    ref = load_dataset(single)
    for tfds in (load_dataset(sharded, as_="tf"), load_dataset(sharded).tf_dataset()):
        assert isinstance(tfds, tf.data.Dataset) and int(tfds.cardinality()) == N
        pairs = list(tfds.as_numpy_iterator())
        np.testing.assert_array_equal(np.stack([p[0] for p in pairs]), ref.X)
        np.testing.assert_array_equal(np.stack([p[1] for p in pairs]), ref.y)


# -- verification ----------------------------------------------------------------------------


def test_verify_covers_every_shard(sharded: Path, capsys: pytest.CaptureFixture[str]) -> None:
    summary = verify_dataset(sharded)
    assert summary["n_windows"] == N and summary["n_shards"] == N_SHARDS and summary["n_recordings"] == 20
    assert set(summary["files"]) == set(_sums(sharded))
    assert dataset_cli.main(["verify", str(sharded)]) == 0
    assert f"{N} windows" in capsys.readouterr().out


def _copy(src: Path, dest: Path) -> Path:
    import shutil

    shutil.copytree(src, dest)
    return dest


def _flip_x_chunk(path: Path) -> None:
    with h5py.File(path, "r") as f:
        info = f["X"].id.get_chunk_info(1)
        at = info.byte_offset + info.size // 2
    data = bytearray(path.read_bytes())
    data[at] ^= 0xFF
    path.write_bytes(bytes(data))


def test_a_corrupted_shard_is_found_by_verify_and_the_loader(sharded: Path, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    folder = _copy(sharded, tmp_path / "ds")
    victim = folder / "windows-00003.h5"
    recorded = _sums(folder)["windows-00003.h5"]
    _flip_x_chunk(victim)
    found = sha256_file(victim)
    message = f"{victim}: expected sha256 {recorded} (from SHA256SUMS), found sha256 {found}"
    with pytest.raises(ChecksumError) as err:
        verify_dataset(folder)
    assert str(err.value) == message and err.value.path == victim
    with pytest.raises(ChecksumError, match="windows-00003.h5"):
        load_dataset(folder)
    assert dataset_cli.main(["verify", str(folder)]) == 1
    assert capsys.readouterr().err == f"ofbe-dataset: error: {message}\n"
    # without verification the metadata loads; the shard's Fletcher-32 sums catch it when read
    ds = load_dataset(folder, verify=False)
    parts = ds.iter_shards()
    for _ in range(3):
        next(parts)
    with pytest.raises(DatasetError, match=r"windows-00003\.h5: expected readable X and y .*Fletcher-32"):
        next(parts)


def test_a_missing_or_extra_shard_is_found(sharded: Path, tmp_path: Path) -> None:
    folder = _copy(sharded, tmp_path / "missing")
    (folder / "windows-00011.h5").unlink()
    with pytest.raises(DatasetError, match=r"windows-00011\.h5: expected a file listed in SHA256SUMS, "
                                           r"found no such file"):
        verify_dataset(folder)
    folder = _copy(sharded, tmp_path / "gap")
    sums = (folder / "SHA256SUMS").read_text().splitlines()
    kept = [line for line in sums if "windows-00004.h5" not in line]
    (folder / "SHA256SUMS").write_text("".join(f"{line}\n" for line in kept))
    with pytest.raises(DatasetError, match="SHA256SUMS: expected lines for the shards windows-00000.h5, "
                                           "windows-00001.h5, … without a gap"):
        verify_dataset(folder)


def test_a_shard_that_disagrees_with_the_index_is_found(sharded: Path, tmp_path: Path) -> None:
    folder = _copy(sharded, tmp_path / "ds")
    with h5py.File(folder / "windows-00002.h5", "r+") as f:
        f["meta/start_sample"][1] = 999
    # make the checksums agree with the edit, as a careless tool would
    dp = json.loads((folder / "datapackage.json").read_text())
    for res in dp["resources"]:
        if res["path"] == "windows-00002.h5":
            res["hash"] = "sha256:" + sha256_file(folder / "windows-00002.h5")
            res["bytes"] = (folder / "windows-00002.h5").stat().st_size
    (folder / "datapackage.json").write_text(json.dumps(dp, indent=2))
    names = sorted(p.name for p in folder.iterdir() if p.name != "SHA256SUMS")
    (folder / "SHA256SUMS").write_text("".join(f"{sha256_file(folder / n)}  {n}\n" for n in names))
    with pytest.raises(DatasetError, match=r"windows-00002\.h5: meta/start_sample: expected "
                                           r"meta/start_sample equal to the column of windows.parquet"):
        verify_dataset(folder)


# -- building and writing --------------------------------------------------------------------


def test_sharded_builds_are_deterministic_and_the_flag_works(campaign: Path, sharded: Path,
                                                             tmp_path: Path) -> None:
    out = tmp_path / "cli"
    code = dataset_cli.main(["build", str(campaign / "labels" / "fleet"), "--raw",
                             str(campaign / "raw" / "fleet"), "--out", str(out), "--window-length", str(T),
                             "--stride", str(T),
                             "--shard-windows", str(SHARD), "--jobs", "1", "--quiet"])
    assert code == 0
    _same_files(out, sharded)


def test_shard_size_must_be_positive(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="dataset.shard_windows: expected an integer ≥ 1"):
        dataset_params_from({"shard_windows": 0}, "p.yaml")
    with pytest.raises(DatasetError, match="shard_windows: expected shard_windows an integer >= 1"):
        WindowWriter(tmp_path, _info(), shard_windows=0)


def _info() -> DatasetInfo:
    return DatasetInfo(name="w", campaign="c", kind="gravity-aligned", title="t", description="d",
                       labelling="l", window_length=20, stride=20, fs_hz=150.0,
                       protocols={"grouped": {"description": "by power cycle", "n_folds": 5, "seed": 0}})


def _blocks(n_recordings: int, per: int, t: int = 20) -> list[tuple[np.ndarray, pd.DataFrame]]:
    rng = np.random.default_rng(0)
    out = []
    for i in range(n_recordings):
        meta = pd.DataFrame({
            "campaign": "c", "session": f"s{i}", "recording": "r", "device": "d1",
            "power_cycle": np.full(per, i, dtype=np.int64), "window_index": np.arange(per, dtype=np.int64),
            "start_sample": np.arange(per, dtype=np.int64) * t,
            **{f"bias_{a}": 0.01 * i for a in "xyz"}, **{f"offset_{a}": np.nan for a in "xyz"},
            "gravity_x": 0.0, "gravity_y": 0.0, "gravity_z": 1.0, "roll_deg": 0.0, "pitch_deg": 0.0,
            "g_local": 9.8, "fs_hz": 150.0, "label_method": "level", "raw_sha256": "0" * 64,
            "fold_grouped": np.full(per, i % 5, dtype=np.int64)})
        out.append((rng.normal(size=(per, t, 3)), meta))
    return out


def _write(dest: Path, blocks: list[tuple[np.ndarray, pd.DataFrame]], shard_windows: int | None) -> Path:
    with atomic_directory(dest) as tmp, WindowWriter(tmp, _info(), shard_windows) as w:
        for X, meta in blocks:
            w.append(X, meta)
    return dest


@pytest.mark.slow
def test_writer_boundaries(tmp_path: Path) -> None:
    blocks = _blocks(4, 3)  # 12 windows
    whole = _write(tmp_path / "none", blocks, None)
    for s in (12, 100):  # at or above the size: the unsharded bytes
        _same_files(_write(tmp_path / f"s{s}", blocks, s), whole)
    eleven = _write(tmp_path / "s11", blocks, 11)  # one window more than a shard: a shard of one
    prov = json.loads(pq.read_schema(eleven / "windows.parquet").metadata[b"ofbe"])
    assert prov["shards"]["files"] == [{"path": "windows-00000.h5", "n_windows": 11},
                                       {"path": "windows-00001.h5", "n_windows": 1}]
    one = _write(tmp_path / "s1", blocks, 1)  # every window its own file
    assert verify_dataset(one)["n_shards"] == 12
    a, b = load_dataset(whole), load_dataset(one)
    np.testing.assert_array_equal(a.X, b.X)
    pd.testing.assert_frame_equal(a.meta, b.meta)


def test_a_failure_after_some_shards_leaves_nothing(tmp_path: Path) -> None:
    blocks = _blocks(4, 3)
    bad_X, bad_meta = _blocks(1, 3)[0]
    dest = tmp_path / "ds"
    with pytest.raises(DatasetError, match="finite samples"):
        with atomic_directory(dest) as tmp, WindowWriter(tmp, _info(), 2) as w:
            for X, meta in blocks:
                w.append(X, meta)
            assert sorted(p.name for p in tmp.iterdir() if p.suffix == ".h5") == [
                shard_name(i) for i in range(5)]
            w.append(np.full_like(bad_X, np.nan), bad_meta)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.slow
def test_the_writer_keeps_one_shard_open_and_no_x(tmp_path: Path) -> None:
    t, per, n_blocks, shard = 3000, 8, 40, 24
    template = _blocks(1, per, t)[0][1]
    rng = np.random.default_rng(1)
    x_bytes = 0
    with atomic_directory(tmp_path / "big") as tmp, WindowWriter(
            tmp, dataclasses.replace(_info(), window_length=t, stride=t), shard) as w:
        tracemalloc.start()
        try:
            before = tracemalloc.get_traced_memory()[0]
            for i in range(n_blocks):
                X = rng.normal(size=(per, t, 3)).astype(np.float32)
                x_bytes += X.nbytes
                w.append(X, template.assign(session=f"s{i}"))
                del X
                assert not list(tmp.glob(".*"))  # the open shard is in memory: nothing half-written
                # a full shard is completed when the next window comes
                assert len(list(tmp.glob("windows-*.h5"))) == ((i + 1) * per - 1) // shard
            grown = tracemalloc.get_traced_memory()[0] - before
        finally:
            tracemalloc.stop()
    assert x_bytes == n_blocks * per * t * 3 * 4  # 11.5 MB of X in 14 shards of 24 windows
    # Python holds less than one shard's X (24 windows × 36 kB = 864 kB): only the metadata (~0.3 MB);
    # the open shard's compressed image is HDF5's (C memory, one shard at a time)
    assert grown < shard * t * 3 * 4
    assert verify_dataset(tmp_path / "big")["n_shards"] == 14


def test_a_sharded_dataset_exports_whole(sharded: Path, tmp_path: Path) -> None:
    from ofbe_data.dataset.export import export_dataset

    dest = export_dataset(sharded, tmp_path / "shared", licence="CC-BY-4.0")
    assert sorted(_sums(dest)) == sorted(_sums(sharded))  # every shard, the index and the package files
    for name, digest in _sums(sharded).items():
        if name.endswith((".h5", ".parquet")):
            assert _sums(dest)[name] == digest, name  # data copied byte for byte
    np.testing.assert_array_equal(load_dataset(dest).X, load_dataset(sharded).X)


@pytest.mark.slow
@pytest.mark.usefixtures("hf_offline")
def test_the_sharded_export_loads_in_hugging_face_croissant_and_frictionless(sharded: Path,
                                                                            tmp_path: Path) -> None:
    """The shared copy of the sharded tiny-fleet dataset: every window with its samples through each
    protocol's Hugging Face config (reading the 12 signal files in order), through Croissant's
    ``signals`` record set (a FileSet over them), and a valid Frictionless package."""
    from ofbe_data.dataset.export import export_dataset

    dest = export_dataset(sharded, tmp_path / "shared")
    n_protocols = len(json.loads((dest / "datapackage.json").read_text())["ofbe"]["protocols"])
    assert assert_hugging_face_matches(dest, tmp_path / "hf-cache") == n_protocols >= 1
    (split,) = card_front_matter(dest)["configs"][0]["data_files"]
    assert split["path"] == [f"signals-{i:05d}.parquet" for i in range(N_SHARDS)]
    assert_croissant_matches(dest)
    report = frictionless_report(dest)
    assert report.valid, report.flatten(["resourcePath", "type", "note"])


def _write_chunks(dest: Path, blocks: list[tuple[np.ndarray, pd.DataFrame]], shard_windows: int | None,
                  t: int) -> Path:
    """What ``ofbe-dataset build`` does: the workers compress each block's windows, the writer
    stores the chunks with the metadata checked once for every block."""
    from ofbe_data.dataset.chunks import compress_windows

    with atomic_directory(dest) as tmp, WindowWriter(tmp, dataclasses.replace(_info(), window_length=t,
                                                                               stride=t), shard_windows) as w:
        cols = w.normalise_meta(pd.concat([m for _, m in blocks], ignore_index=True))
        at = 0
        for X, meta in blocks:
            n = len(meta)
            w.append_chunks(compress_windows(X, "test"), {k: v[at:at + n] for k, v in cols.items()})
            at += n
    return dest


@pytest.mark.parametrize(("t", "sizes", "shard"), [
    (20, [3, 1, 4, 1, 5, 9, 2, 6], None),        # all in HDF5's chunk cache until the file is written
    (20, [3, 1, 4, 1, 5, 9, 2, 6], 7),           # sharded, blocks straddling the boundaries
    (3000, [1] * 40, None),                      # more windows than the cache holds (29 of 3000 samples)
    (3000, [2, 1, 3] * 15, 32),
    (1000, [5] * 30, None),
    (90000, [1, 2], None),                        # a window larger than the cache: written at once
    (20, [1] * 600, None),                        # windows 521 apart share a hash slot of the cache
    (100, [3, 5, 2] * 60, 560),
])
@pytest.mark.slow
def test_chunks_compressed_in_the_workers_give_the_bytes_of_the_samples(tmp_path: Path, t, sizes,
                                                                        shard) -> None:
    rng = np.random.default_rng(7)
    blocks = []
    for i, k in enumerate(sizes):
        meta = _blocks(1, k, t)[0][1].assign(session=f"s{i}", power_cycle=i, fold_grouped=i % 5)
        blocks.append((rng.normal(0.0, 0.05, (k, t, 3)) + [0.0, 0.0, 9.8], meta))
    samples = tmp_path / "samples"
    with atomic_directory(samples) as tmp, WindowWriter(tmp, dataclasses.replace(_info(), window_length=t,
                                                                                  stride=t), shard) as w:
        for X, meta in blocks:
            w.append(X, meta)
    chunks = _write_chunks(tmp_path / "chunks", blocks, shard, t)
    files = sorted(p.name for p in samples.iterdir())
    assert files == sorted(p.name for p in chunks.iterdir())
    for name in files:
        assert (samples / name).read_bytes() == (chunks / name).read_bytes(), name


def test_one_writer_takes_samples_or_chunks_not_both(tmp_path: Path) -> None:
    from ofbe_data.dataset.chunks import compress_windows

    (X, meta), = _blocks(1, 2)
    with pytest.raises(DatasetError, match=r"expected windows appended one way \(append or append_chunks\), "
                                           r"found both"):
        with atomic_directory(tmp_path / "d") as tmp, WindowWriter(tmp, _info()) as w:
            w.append(X, meta)
            w.append_chunks(compress_windows(X, "x"), w.normalise_meta(meta))
    assert not (tmp_path / "d").exists()
