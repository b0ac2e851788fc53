"""ofbe's own GENEActiv ``.bin`` and ActiGraph ``.gt3x`` readers (ofbe_data.freeliving.geneactiv,
.actigraph) against the other tools' own code: actfast reads the same files (the real test files of
the GGIR projects, and synthetic ones written here) to the same samples, times and temperatures;
ACTIVITY2 records (which actfast 1.3 does not read) against read.gt3x's rule. Damaged copies are
named with their page or record and byte offset; the file's SHA-256 comes from the same reading;
and the readers hold one block at a time, whatever the file's length."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest

from ofbe_data.core.checksums import file_sha256
from ofbe_data.freeliving import RawFileError, read_raw_epochs
from ofbe_data.freeliving import actigraph as ag
from ofbe_data.freeliving import geneactiv as ga
from ofbe_data.freeliving.hashing import HashingReader
from ofbe_data.freeliving.wearables import open_wearable, round_half_away
from tests.helpers.paths import TESTS

DATA = TESTS / "data" / "wearables"
BIN = DATA / "GENEActiv_testfile.bin"
GT3X = DATA / "actigraph_testfile.gt3x"
T0_MS = 1709542800000
"""2024-03-04 09:00:00 UTC, ms."""


def _ours(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, object]:
    w = open_wearable(path)
    chunks = list(w.chunks())
    temp = [c.temperature_c for c in chunks if c.temperature_c is not None]
    return (np.concatenate([c.time_s for c in chunks]), np.concatenate([c.acc_g for c in chunks], axis=1),
            np.concatenate(temp) if temp else None, w)


def _actfast(path: Path, gt3x: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """actfast's samples as the former actfast-based reader handed them on."""
    actfast = pytest.importorskip("actfast")
    series = actfast.read(str(path))["timeseries"]
    high = series["acceleration" if gt3x else "high_frequency"]
    acc = np.ascontiguousarray(high["acceleration"].T, dtype=np.float64)
    temp = None
    if gt3x:
        acc = round_half_away(acc, 3)
    else:
        low = series["low_frequency"]
        page = np.clip(np.searchsorted(low["datetime"], high["datetime"], side="right") - 1, 0, None)
        temp = low["temperature"][page].astype(np.float64)
    return high["datetime"].astype(np.float64) / 1e9, acc, temp


def _write_bin(path: Path, pages: int = 40, seed: int = 1, rate: float = 100.0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    counts = rng.integers(-2047, 2048, (pages, 300, 3))
    ms = T0_MS + np.arange(pages) * 3000
    path.write_bytes(ga.encode_header(rate, n_pages=pages)
                     + ga.encode_pages(counts, ms, rate, 20 + rng.random(pages) * 10))
    return counts


def _write_gt3x(path: Path, seconds: int = 50, kind: int = ag.ACTIVITY, compression: int = zipfile.ZIP_STORED,
                scale_in_info: bool = True, seed: int = 2) -> np.ndarray:
    rng = np.random.default_rng(seed)
    counts = rng.integers(-2047, 2048, (seconds, 30, 3))
    stamps = T0_MS // 1000 + np.arange(seconds)
    stamps[seconds // 2:] += 10  # ten seconds of idle sleep: nothing written
    log = ag.encode_parameters(256.0, 30) + ag.encode_activity(counts, stamps, kind)
    with zipfile.ZipFile(path, "w", compression) as z:
        z.writestr("log.bin", log)
        z.writestr("info.txt", ag.info_text(30, 256.0 if scale_in_info else None))
    return counts


# --------------------------------------------------------------------------- the same samples as actfast


@pytest.mark.parametrize("path", [BIN, GT3X], ids=["GENEActiv", "ActiGraph"])
def test_real_test_files_read_as_actfast_reads_them(path: Path) -> None:
    gt3x = path.suffix == ".gt3x"
    t, acc, temp, _ = _ours(path)
    t_ref, acc_ref, temp_ref = _actfast(path, gt3x)
    assert acc.shape == acc_ref.shape == (3, 17640 if gt3x else 5031)
    assert np.array_equal(acc, acc_ref) and np.array_equal(t, t_ref)
    assert (temp is None) if gt3x else np.array_equal(temp, temp_ref)


def test_synthetic_geneactiv_read_as_actfast_reads_it(tmp_path: Path) -> None:
    counts = _write_bin(tmp_path / "a.bin")
    t, acc, temp, _ = _ours(tmp_path / "a.bin")
    t_ref, acc_ref, temp_ref = _actfast(tmp_path / "a.bin", False)
    assert np.array_equal(acc, acc_ref) and np.array_equal(t, t_ref) and np.array_equal(temp, temp_ref)
    gain, offset = np.array([25875, 25734, 25538]), np.array([439, -662, -3056])  # (raw·100 − offset) / gain
    expected = ((counts.reshape(-1, 3) * 100.0 - offset) / gain).T
    assert np.allclose(acc, expected, rtol=1e-6, atol=0)  # float32


@pytest.mark.parametrize("compression", [zipfile.ZIP_STORED, zipfile.ZIP_DEFLATED],
                         ids=["stored", "deflated"])
def test_synthetic_actigraph_read_as_actfast_reads_it(tmp_path: Path, compression: int) -> None:
    counts = _write_gt3x(tmp_path / "a.gt3x", compression=compression)
    t, acc, _, w = _ours(tmp_path / "a.gt3x")
    t_ref, acc_ref, _ = _actfast(tmp_path / "a.gt3x", True)
    assert np.array_equal(acc, acc_ref) and np.array_equal(t, t_ref)
    assert np.array_equal(acc, round_half_away(counts.reshape(-1, 3).T / 256.0, 3))
    assert (w.gap_stretches, w.gap_samples) == (1, 300)  # ten seconds of idle sleep, closed up


def test_activity2_records_as_read_gt3x_reads_them(tmp_path: Path) -> None:
    # read.gt3x (parseGT3X.cpp, ParseActivity2): int16 little-endian x, y, z; / scale; rounded to 1 mg
    counts = _write_gt3x(tmp_path / "a.gt3x", kind=ag.ACTIVITY2, scale_in_info=False)  # scale: PARAMETERS
    _, acc, _, _ = _ours(tmp_path / "a.gt3x")
    assert np.array_equal(acc, round_half_away(counts.reshape(-1, 3).T / 256.0, 3))


def test_half_milli_g_rounds_away_from_zero() -> None:
    assert list(round_half_away(np.array([0.0005, -0.0005, 0.0015, -0.0025]), 3)) == [0.001, -0.001, 0.002,
                                                                                        -0.003]
    assert ag.decode_ssp(0x09400000) == 256.0


# --------------------------------------------------------------------------- read once, bounded


@pytest.mark.parametrize("name", ["GENEActiv_testfile.bin", "actigraph_testfile.gt3x", "ax3_testfile.cwa"])
def test_sha256_from_the_same_reading(name: str) -> None:
    raw = read_raw_epochs(DATA / name, ggir_whole_hours=False)
    assert raw.sha256 == file_sha256(DATA / name)


def test_hashing_reader_reads_each_byte_once_in_order(tmp_path: Path) -> None:
    counts = _write_gt3x(tmp_path / "a.gt3x", seconds=2000, compression=zipfile.ZIP_DEFLATED)
    assert counts.size
    size = (tmp_path / "a.gt3x").stat().st_size
    with open(tmp_path / "a.gt3x", "rb") as fh:
        reader = HashingReader(fh, catch_up=1024)
        stream = ag.Gt3xStream(tmp_path / "a.gt3x", reader, read_bytes=4096)
        assert sum(c.time_ns.size for c in stream) == 60000
        digest = reader.hexdigest()
    assert digest == file_sha256(tmp_path / "a.gt3x")
    # zipfile reads the central directory first: only it and info.txt (after log.bin) are read again
    assert 0 < reader.reread_bytes < 600 < size
    _write_bin(tmp_path / "a.bin", pages=30)
    with open(tmp_path / "a.bin", "rb") as fh:
        reader = HashingReader(fh)
        assert sum(c.time_ns.size for c in ga.BinStream(tmp_path / "a.bin", reader, block_bytes=8192)) == 9000
        assert (reader.hexdigest(), reader.reread_bytes) == (file_sha256(tmp_path / "a.bin"), 0)


def test_readers_hold_one_block_at_a_time(tmp_path: Path) -> None:
    _write_bin(tmp_path / "a.bin", pages=60)
    with open(tmp_path / "a.bin", "rb") as fh:
        small = list(ga.BinStream(tmp_path / "a.bin", fh, block_bytes=3 * 3800))
    with open(tmp_path / "a.bin", "rb") as fh:
        whole = list(ga.BinStream(tmp_path / "a.bin", fh, block_bytes=1 << 24))
    assert len(whole) == 1 and len(small) >= 10
    assert max(c.time_ns.size for c in small) <= 6 * 300  # at most two blocks of text: 6 pages
    for field in ("time_ns", "acc_g", "temperature_c"):
        joined = np.concatenate([getattr(c, field) for c in small], axis=-1)
        assert np.array_equal(joined, getattr(whole[0], field))
    _write_gt3x(tmp_path / "a.gt3x", seconds=300)
    with open(tmp_path / "a.gt3x", "rb") as fh:
        small_g = list(ag.Gt3xStream(tmp_path / "a.gt3x", fh, read_bytes=1024))
    with open(tmp_path / "a.gt3x", "rb") as fh:
        whole_g = list(ag.Gt3xStream(tmp_path / "a.gt3x", fh, read_bytes=1 << 24))
    assert len(whole_g) == 1 and len(small_g) >= 40
    assert max(c.time_ns.size for c in small_g) <= 2 * 1024 // 144 * 30  # records of 144 bytes
    assert np.array_equal(np.concatenate([c.acc_g for c in small_g], axis=1), whole_g[0].acc_g)


# --------------------------------------------------------------------------- damaged files


def test_geneactiv_page_with_bad_hex_is_skipped_and_named(tmp_path: Path) -> None:
    _write_bin(tmp_path / "a.bin", pages=10)
    data = bytearray((tmp_path / "a.bin").read_bytes())
    page3 = data.index(b"Recorded Data\r\nDevice Unique Serial Code:012967\r\nSequence Number:3\r\n")
    hex3 = data.index(b"Measurement Frequency:100\r\n", page3) + len(b"Measurement Frequency:100\r\n")
    data[hex3 + 25] = ord("G")
    (tmp_path / "bad.bin").write_bytes(bytes(data))
    _, acc, _, w = _ours(tmp_path / "bad.bin")
    _, good, _, _ = _ours(tmp_path / "a.bin")
    assert w.bad_blocks == (ga.BadBlock(3, page3, "not hexadecimal (character 25 of its data line): page "
                                                  "skipped"),)
    assert np.array_equal(acc, np.delete(good, np.s_[900:1200], axis=1))


def test_geneactiv_cut_short_keeps_its_whole_samples_and_says_so(tmp_path: Path) -> None:
    _write_bin(tmp_path / "a.bin", pages=5)
    data = (tmp_path / "a.bin").read_bytes()
    last = data.rindex(b"Recorded Data")
    hex_at = data.index(b"Measurement Frequency:100\r\n", last) + len(b"Measurement Frequency:100\r\n")
    (tmp_path / "cut.bin").write_bytes(data[: hex_at + 12 * 123 + 5])
    _, acc, _, w = _ours(tmp_path / "cut.bin")
    assert acc.shape == (3, 4 * 300 + 123)
    assert w.bad_blocks == (ga.BadBlock(4, last, "truncated: 123 of 300 samples read"),)
    (tmp_path / "cut2.bin").write_bytes(data[: last + 40])  # inside the last page's header lines
    _, acc, _, w = _ours(tmp_path / "cut2.bin")
    assert acc.shape == (3, 1200)
    assert w.bad_blocks == (ga.BadBlock(4, last, "truncated: the file ends in line 2 of its 10, no samples"),)


def test_geneactiv_out_of_layout_is_an_error_naming_page_and_byte(tmp_path: Path) -> None:
    _write_bin(tmp_path / "a.bin", pages=6)
    data = (tmp_path / "a.bin").read_bytes()
    page2 = data.index(b"Sequence Number:2\r\n")
    page2 = data.rindex(b"Recorded Data", 0, page2)
    (tmp_path / "bad.bin").write_bytes(data[:page2] + data[page2 + len(b"Recorded Data\r\n"):])  # a line lost
    with pytest.raises(RawFileError) as err:
        read_raw_epochs(tmp_path / "bad.bin")
    assert str(err.value) == (f"{tmp_path / 'bad.bin'} (byte {page2}): expected page 2: a line 'Recorded "
                              "Data' (pages of 10 lines), found b'Device Unique Serial Code:012967\\r'")
    bad_time = data.replace(b"Page Time:2024-03-04 09:00:03:000", b"Page Time:2024-03-04 9h")
    (tmp_path / "time.bin").write_bytes(bad_time)
    page1 = bad_time.index(b"Recorded Data", bad_time.index(b"Sequence Number:1\r\n") - 60)
    with pytest.raises(RawFileError) as err:
        read_raw_epochs(tmp_path / "time.bin")
    assert str(err.value) == (f"{tmp_path / 'time.bin'} (byte {page1}): expected page 1: a 'Page Time' of "
                              "the form YYYY-MM-DD hh:mm:ss:mmm, found b'2024-03-04 9h'")


def _log_of(path: Path) -> bytes:
    with zipfile.ZipFile(path) as z:
        return z.read("log.bin")


def _rezip(path: Path, log: bytes, names: tuple[str, str] = ("log.bin", "info.txt")) -> None:
    with zipfile.ZipFile(path, "w") as z:
        z.writestr(names[0], log)
        z.writestr(names[1], ag.info_text(30))


def test_actigraph_record_with_bad_checksum_is_skipped_and_named(tmp_path: Path) -> None:
    _write_gt3x(tmp_path / "a.gt3x", seconds=10)
    log = bytearray(_log_of(tmp_path / "a.gt3x"))
    params = 9 + 16  # the PARAMETERS record: 8 header bytes, 16 payload, 1 checksum
    record = params + 3 * 144  # ACTIVITY records of 30 samples: 8 + 135 + 1 bytes
    log[record + 8 + 20] ^= 0x40
    _rezip(tmp_path / "bad.gt3x", bytes(log))
    _, acc, _, w = _ours(tmp_path / "bad.gt3x")
    _, good, _, _ = _ours(tmp_path / "a.gt3x")
    assert w.bad_blocks == (ag.BadBlock(4, record, "checksum (ACTIVITY record of log.bin, its byte offset in "
                                                   "log.bin): skipped"),)
    assert np.array_equal(acc, np.delete(good, np.s_[90:120], axis=1))


def test_actigraph_damage_is_named(tmp_path: Path) -> None:
    _write_gt3x(tmp_path / "a.gt3x", seconds=10)
    data = (tmp_path / "a.gt3x").read_bytes()
    (tmp_path / "cut.gt3x").write_bytes(data[: len(data) // 2])
    with pytest.raises(RawFileError) as err:
        read_raw_epochs(tmp_path / "cut.gt3x")
    assert str(err.value) == (f"{tmp_path / 'cut.gt3x'}: expected a .gt3x file: a zip archive ending in its "
                              "central directory, found none (File is not a zip file): a truncated or "
                              "damaged file")
    log = _log_of(tmp_path / "a.gt3x")
    _rezip(tmp_path / "sep.gt3x", log[:25 + 2 * 144] + b"\x00" + log[25 + 2 * 144 + 1:])
    with pytest.raises(RawFileError) as err:
        read_raw_epochs(tmp_path / "sep.gt3x")
    assert str(err.value) == (f"{tmp_path / 'sep.gt3x'}: expected log.bin record 3 (byte 313 of log.bin): "
                              "the record separator 0x1E, found 0x00")
    _rezip(tmp_path / "tail.gt3x", log[:-50])
    _, acc, _, w = _ours(tmp_path / "tail.gt3x")
    assert acc.shape == (3, 270)
    assert w.bad_blocks == (ag.BadBlock(10, 25 + 9 * 144, "truncated: log.bin ends inside this record, the "
                                                          "records before it read"),)
    crc = bytearray(data)
    at = data.index(log[400:420])
    crc[at + 5] ^= 0xFF  # log.bin stored: its bytes change, its CRC-32 no longer matches
    (tmp_path / "crc.gt3x").write_bytes(bytes(crc))
    with pytest.raises(RawFileError) as err:
        read_raw_epochs(tmp_path / "crc.gt3x")
    assert str(err.value) == (f"{tmp_path / 'crc.gt3x'}: expected a readable log.bin in the zip archive "
                              "(its CRC-32 and compressed data intact), found Bad CRC-32 for file 'log.bin': "
                              "a damaged file")
    _rezip(tmp_path / "old.gt3x", log, ("activity.bin", "info.txt"))
    with pytest.raises(RawFileError) as err:
        read_raw_epochs(tmp_path / "old.gt3x")
    assert "found an older NHANES-style file (activity.bin), which ofbe does not read" in str(err.value)
