"""No silent wrong answer (issue 36): ``verify`` compares the two copies of the samples.

Every checksum of a dataset can be recomputed after an edit (``write_package_files`` rewrites
``datapackage.json``, ``croissant.json``, the card and ``SHA256SUMS``), so the hashes alone do not
show that ``signals.parquet`` (what Hugging Face ``datasets`` and Croissant read) still holds the
samples of ``windows.h5`` (what ``load_dataset`` reads), nor that every HDF5 chunk still passes
its Fletcher-32 check. ``verify_dataset`` reads both, block by block, and names the first window
that differs.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import h5py
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from ofbe_data.cli import dataset as dataset_cli
from ofbe_data.core.atomic import atomic_directory
from ofbe_data.dataset import verify_signals
from ofbe_data.dataset.export import export_dataset
from ofbe_data.dataset.package import write_package_files
from ofbe_data.dataset.reader import load_dataset, read_dataset_info, verify_dataset
from ofbe_data.dataset.store import ChecksumError, DatasetError, DatasetInfo, sha256_file
from ofbe_data.dataset.writer import WindowWriter

T = 20
N = 20  # 10 recordings × 2 windows
LAYOUTS = {"single": None, "sharded": 3}  # one windows.h5, or 7 shards (6 × 3 + 2)
PROTOCOLS = {"grouped": {"description": "by power cycle", "n_folds": 5, "seed": 0}}


def _tiny(path: Path, shard_windows: int | None = None) -> Path:
    """10 recordings × 2 windows of T = 20 samples of one device (as in test_sharing.py)."""
    info = DatasetInfo(name="tamper", campaign="c", kind="gravity-aligned", title="t", description="d",
                       labelling="l", window_length=T, stride=T, fs_hz=150.0, protocols=PROTOCOLS)
    rng = np.random.default_rng(0)
    with atomic_directory(path) as tmp, WindowWriter(tmp, info, shard_windows=shard_windows) as w:
        for i in range(N // 2):
            meta = pd.DataFrame({
                "campaign": ["c"] * 2, "session": [f"s{i}"] * 2, "recording": ["r"] * 2, "device": ["d1"] * 2,
                "power_cycle": [i] * 2, "window_index": [0, 1], "start_sample": [0, T],
                **{f"bias_{a}": [0.01 * i + k] * 2 for k, a in enumerate("xyz")},
                **{f"offset_{a}": [np.nan if i % 2 else 0.002 * i] * 2 for a in "xyz"},
                "gravity_x": [0.0] * 2, "gravity_y": [0.0] * 2, "gravity_z": [1.0] * 2,
                "roll_deg": [0.0] * 2, "pitch_deg": [0.0] * 2, "g_local": [9.8] * 2, "fs_hz": [150.0] * 2,
                "label_method": ["level"] * 2, "raw_sha256": [f"{i:064d}"] * 2, "fold_grouped": [i % 5] * 2})
            w.append(rng.normal(size=(2, T, 3)) + [0.0, 0.0, 9.8], meta)
    return path


@pytest.fixture(scope="module", params=list(LAYOUTS))
def layout(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> tuple[str, Path]:
    root = tmp_path_factory.mktemp(request.param)
    return request.param, _tiny(root / "built", LAYOUTS[request.param])


def _copy(src: Path, dest: Path) -> Path:
    return Path(shutil.copytree(src, dest))


def _recompute_every_checksum(folder: Path) -> None:
    """What a careless tool would do after an edit: every hash list made to agree with the files."""
    write_package_files(folder, read_dataset_info(folder))
    sums = dict(reversed(line.split("  ", 1)) for line in (folder / "SHA256SUMS").read_text().splitlines())
    assert all(sha256_file(folder / name) == digest for name, digest in sums.items())


def _where(sharded: bool, window_id: int) -> tuple[str, str, int]:
    """(HDF5 file, signal file, row in them) of a window."""
    if not sharded:
        return "windows.h5", "signals.parquet", window_id
    shard, row = divmod(window_id, LAYOUTS["sharded"])
    return f"windows-{shard:05d}.h5", f"signals-{shard:05d}.parquet", row


def _shift_signal_window(path: Path, row: int, delta: float) -> None:
    """Add ``delta`` m/s² to every sample of one window of a signal file (all else unchanged)."""
    table = pq.read_table(path)
    i = table.schema.get_field_index("X")
    col = table.column("X").combine_chunks()
    x = col.flatten().flatten().to_numpy().reshape(-1, T, 3).copy()
    x[row] += np.float32(delta)
    inner = pa.FixedSizeListArray.from_arrays(pa.array(x.reshape(-1), type=pa.float32()),
                                              type=col.type.value_type)
    outer = pa.FixedSizeListArray.from_arrays(inner, type=col.type)
    pq.write_table(table.set_column(i, table.schema.field(i), outer), path)


def _shift_message(folder: Path, sharded: bool, window_id: int, delta: float) -> str:
    h5_name, signal_name, row = _where(sharded, window_id)
    with h5py.File(folder / h5_name, "r") as f:
        want = f["X"][row, 0, 0]
    got = np.float32(want + np.float32(delta))
    return (f"{folder / signal_name}: X: expected the samples of {h5_name} bit for bit, "
            f"window_id {window_id} (row {row}) sample 0 axis x = {want!s}, found {got!s} "
            f"({3 * T} of {3 * T} values of that window differ)")


def _flip_x_chunk(path: Path, row: int) -> None:
    """Flip one byte in the middle of the stored (compressed) chunk of window ``row``."""
    with h5py.File(path, "r") as f:
        info = f["X"].id.get_chunk_info(row)
        at = info.byte_offset + info.size // 2
    data = bytearray(path.read_bytes())
    data[at] ^= 0xFF
    path.write_bytes(bytes(data))


# -- an untouched dataset ----------------------------------------------------------------------


def test_an_untouched_dataset_verifies(layout: tuple[str, Path], tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    name, built = layout
    summary = verify_dataset(built)
    assert summary["n_windows"] == N and summary["n_shards"] == (1 if name == "single" else 7)
    assert dataset_cli.main(["verify", str(built)]) == 0
    out = capsys.readouterr()
    assert f"{built}: OK — tamper" in out.out and out.err == ""
    signals = "signals.parquet holds" if name == "single" else "the 7 signal files hold"
    assert out.out.endswith(f"; every HDF5 chunk read; {signals} the same samples bit for bit\n")
    assert verify_dataset(export_dataset(built, tmp_path / "shared"))["n_windows"] == N


def test_blocks_smaller_than_a_file_are_compared_in_turn(layout: tuple[str, Path], tmp_path: Path,
                                                         monkeypatch: pytest.MonkeyPatch) -> None:
    """Memory stays bounded: both copies are read VERIFY_BLOCK windows at a time; a difference in
    a later block is found with its own window and row."""
    name, built = layout
    monkeypatch.setattr(verify_signals, "VERIFY_BLOCK", 2)
    verify_dataset(built)
    folder = _copy(built, tmp_path / "ds")
    _, signal_name, row = _where(name == "sharded", 13)
    _shift_signal_window(folder / signal_name, row, 0.5)
    _recompute_every_checksum(folder)
    with pytest.raises(DatasetError) as err:
        verify_dataset(folder)
    assert str(err.value) == _shift_message(folder, name == "sharded", 13, 0.5)


# -- signals.parquet changed, every checksum recomputed ----------------------------------------


def test_a_shifted_signal_window_is_found(layout: tuple[str, Path], tmp_path: Path) -> None:
    name, built = layout
    sharded = name == "sharded"
    folder = _copy(built, tmp_path / "ds")
    _, signal_name, row = _where(sharded, 7)
    _shift_signal_window(folder / signal_name, row, 0.5)
    _recompute_every_checksum(folder)
    # the hashes alone let it through: every list agrees with the changed file
    assert json.loads((folder / "croissant.json").read_text())["distribution"]
    with pytest.raises(DatasetError) as err:
        verify_dataset(folder)
    assert type(err.value) is DatasetError and err.value.path == folder / signal_name
    assert str(err.value) == _shift_message(folder, sharded, 7, 0.5)
    if not sharded:
        with h5py.File(folder / "windows.h5", "r") as f:
            want = f["X"][7, 0, 0]
        got = np.float32(want + np.float32(0.5))
        assert str(err.value) == (
            f"{folder}/signals.parquet: X: expected the samples of windows.h5 bit for bit, window_id 7 "
            f"(row 7) sample 0 axis x = {want!s}, found {got!s} (60 of 60 values of that window differ)")
    with pytest.raises(DatasetError, match="window_id 7"):
        load_dataset(folder)


def test_the_command_fails_with_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = _copy(_tiny(tmp_path / "built"), tmp_path / "ds")
    _shift_signal_window(folder / "signals.parquet", 3, 0.5)
    _recompute_every_checksum(folder)
    assert dataset_cli.main(["verify", str(folder)]) == 1
    out = capsys.readouterr()
    assert out.out == ""
    assert out.err == f"ofbe-dataset: error: {_shift_message(folder, False, 3, 0.5)}\n"
    assert out.err.count("\n") == 1 and "Traceback" not in out.err


def test_a_label_changed_in_the_signal_file_names_the_window(tmp_path: Path) -> None:
    folder = _copy(_tiny(tmp_path / "built"), tmp_path / "ds")
    table = pq.read_table(folder / "signals.parquet")
    bias = table.column("bias_x").to_numpy().copy()
    before = float(bias[5])
    bias[5] += 1.0
    table = table.set_column(table.schema.get_field_index("bias_x"), "bias_x", [bias])
    pq.write_table(table, folder / "signals.parquet")
    _recompute_every_checksum(folder)
    with pytest.raises(DatasetError) as err:
        verify_dataset(folder)
    assert str(err.value) == (f"{folder}/signals.parquet: expected the columns of windows.parquet equal "
                              f"to its rows 0..19, found bias_x = {float(bias[5])!r} in window_id 5 (row 5), "
                              f"where windows.parquet has {before!r}")


# -- a byte flipped in an HDF5 chunk, every checksum recomputed --------------------------------


def test_a_corrupted_chunk_is_found_by_verify(layout: tuple[str, Path], tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    name, built = layout
    folder = _copy(built, tmp_path / "ds")
    h5_name, _, row = _where(name == "sharded", 7)
    _flip_x_chunk(folder / h5_name, row)
    _recompute_every_checksum(folder)
    prefix = (f"{folder / h5_name}: X: expected readable X (chunks passing their Fletcher-32 checksums), "
              f"found a read error in window_id 7 (row {row}): ")
    with pytest.raises(DatasetError) as err:
        verify_dataset(folder)
    assert type(err.value) is DatasetError and err.value.path == folder / h5_name
    assert str(err.value).startswith(prefix) and "\n" not in str(err.value)
    assert dataset_cli.main(["verify", str(folder)]) == 1
    out = capsys.readouterr()
    assert out.err.startswith(f"ofbe-dataset: error: {prefix}") and out.err.count("\n") == 1
    assert "Traceback" not in out.err and out.out == ""


def test_a_corrupted_chunk_is_found_without_signal_files(tmp_path: Path) -> None:
    """A folder built before the signal files existed: X is still read whole."""
    folder = _copy(_tiny(tmp_path / "built"), tmp_path / "ds")
    (folder / "signals.parquet").unlink()
    _recompute_every_checksum(folder)
    verify_dataset(folder)
    _flip_x_chunk(folder / "windows.h5", 0)
    _recompute_every_checksum(folder)
    with pytest.raises(DatasetError, match=r"windows\.h5: X: expected readable X \(chunks passing their "
                                           r"Fletcher-32 checksums\), found a read error in window_id 0 "
                                           r"\(row 0\): "):
        verify_dataset(folder)


def test_an_unrecomputed_checksum_is_still_reported_first(tmp_path: Path) -> None:
    folder = _copy(_tiny(tmp_path / "built"), tmp_path / "ds")
    _shift_signal_window(folder / "signals.parquet", 3, 0.5)
    with pytest.raises(ChecksumError, match=r"signals\.parquet: expected sha256 [0-9a-f]{64} "
                                            r"\(from SHA256SUMS\)"):
        verify_dataset(folder)


def test_a_null_window_in_the_signal_file_is_named(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(verify_signals, "VERIFY_BLOCK", 4)  # the null in the third block
    folder = _copy(_tiny(tmp_path / "built"), tmp_path / "ds")
    path = folder / "signals.parquet"
    table = pq.read_table(path)
    i = table.schema.get_field_index("X")
    col = table.column("X").combine_chunks()
    mask = pa.array(np.arange(N) == 9)
    nulled = pa.FixedSizeListArray.from_arrays(col.flatten(), type=col.type, mask=mask)
    pq.write_table(table.set_column(i, table.schema.field(i).with_nullable(True), nulled), path)
    _recompute_every_checksum(folder)
    with pytest.raises(DatasetError) as err:
        verify_dataset(folder)
    assert str(err.value) == (f"{path}: X: expected a (T, 3) window of float32 on every row, found a null in "
                              "window_id 9 (row 9)")
