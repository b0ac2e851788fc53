"""Raw wearable files into GGIR's epochs (ofbe_data.freeliving.raw and its readers).

The small real files in tests/data/wearables/ are checked against the values their own test
suites state (wadpac/GGIRread tests/testthat/test_readAxivity.R and test_readGENEActiv.R, wadpac/GGIR
tests/testthat/test_greadaccfile.R and its read.gt3x_ggir test; see that folder's README), and
synthetic ``.cwa`` files written block by block check GGIR's epoch rules and a calibration
against the truth they were made from.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from ofbe_data.core.errors import RawFormatError
from ofbe_data.freeliving import (
    QC_NO_STILL,
    QC_NOT_GOOD_ENOUGH,
    QC_TOO_SHORT,
    EpochTable,
    RawFileError,
    ggir_calibrate,
    read_raw_epochs,
)
from ofbe_data.freeliving.axivity import AxivityStream
from ofbe_data.freeliving.blocks import (
    block_params,
    decode_blocks,
    encode_blocks,
    encode_header,
    packed_seconds,
    packed_timestamp,
    read_header,
)
from ofbe_data.freeliving.raw import GgirEpochs, whole_hour_epochs
from ofbe_data.freeliving.wearables import Samples, open_wearable
from ofbe_data.io.detection import Hints
from ofbe_data.io.device_options import CsvMapping
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import DeviceSpec, RecordingSpec, SessionManifest, Site, write_manifest
from tests.helpers.paths import TESTS

DATA = TESTS / "data" / "wearables"
AX3 = DATA / "ax3_testfile.cwa"
AX6 = DATA / "ax6_testfile.cwa"
CORRUPT = DATA / "ax3_testfile_corrupt_blocks_0_13_14_142_143_144.cwa"
BIN = DATA / "GENEActiv_testfile.bin"
GT3X = DATA / "actigraph_testfile.gt3x"
BERLIN_S = 3600.0
"""GGIRread's tests read the device clock in Europe/Berlin (UTC+1 in winter); ofbe reads it as UTC."""


def _read(path: Path, start: int = 0, end: int | None = None,
          **kw: int) -> tuple[AxivityStream, np.ndarray, np.ndarray, np.ndarray]:
    """GGIRread's ``readAxivity(path, start, end)``: the stream, times (n,), values (n_axes, n) and
    temperatures (n,)."""
    stream = AxivityStream(path, start, end, **kw)
    chunks = list(stream)
    if not chunks:
        return stream, np.zeros(0), np.zeros((3, 0)), np.zeros(0)
    values = np.concatenate([c.values for c in chunks], axis=1)
    return (stream, np.concatenate([c.time_s for c in chunks]), values,
            np.concatenate([c.temperature_c for c in chunks]))


def _floor_abs(values: np.ndarray) -> int:
    return math.floor(float(np.abs(values).sum()))


# --------------------------------------------------------------------------- Axivity, GGIRread's values


def test_ax3_whole_file_as_ggirread_reads_it() -> None:
    stream, t, v, temp = _read(AX3, 0, 1000)
    assert v.shape == (3, 17599)  # nrow(AX3b$data) == 17599
    assert t[4] - BERLIN_S == pytest.approx(1551174906.040, abs=1e-3)
    assert temp[2] == pytest.approx(25.5859, abs=1e-4)
    assert _floor_abs(v) == 25367
    assert stream.qc_log == [] and stream.bad_blocks == ()


def test_ax3_blocks_1_to_4_as_ggirread_reads_them() -> None:
    _, t, v, temp = _read(AX3, 1, 4)
    assert v.shape == (3, 364)
    assert t[4] - BERLIN_S == pytest.approx(1551174907.255, abs=1e-3)
    assert temp[2] == pytest.approx(26.46484, abs=1e-4)
    assert _floor_abs(v) == 603
    assert v[0, 0] == pytest.approx(0.7656, abs=1e-4)
    assert v[1, 3] == pytest.approx(-0.3125, abs=1e-4)


def test_ax6_gyroscope_and_accelerometer_as_ggirread_reads_them() -> None:
    _, t, v, temp = _read(AX6, 1, 4)
    assert v.shape == (6, 121)  # gx, gy, gz (°/s), then x, y, z (g)
    assert t[4] - BERLIN_S == pytest.approx(1577131447.144, abs=1e-3)
    assert temp[2] == pytest.approx(27.34375, abs=1e-4)
    assert _floor_abs(v[:3]) == 2007 and _floor_abs(v[3:]) == 10
    assert v[0, 0] == pytest.approx(0.2670288, abs=1e-7)
    assert v[1, 3] == pytest.approx(-0.5026558, abs=1e-7)
    assert v[3, 29] == pytest.approx(-0.009452909, abs=1e-7)
    _, t, v, temp = _read(AX6, 0, 1000)
    assert v.shape == (6, 11428)
    assert t[4] - BERLIN_S == pytest.approx(1577131446.740, abs=1e-3)
    assert temp[2] == pytest.approx(27.34375, abs=1e-4)
    assert _floor_abs(v[:3]) == 960046


def test_chunk_boundaries_do_not_change_a_bit() -> None:
    for path in (AX3, CORRUPT):
        _, t1, v1, temp1 = _read(path)
        _, t2, v2, temp2 = _read(path, chunk_blocks=3)
        assert np.array_equal(t1, t2) and np.array_equal(v1, v2) and np.array_equal(temp1, temp2)


def test_block_decoding_equals_actfast_samples() -> None:
    actfast = pytest.importorskip("actfast")
    for path in (AX3, AX6):
        data = path.read_bytes()
        head = read_header(path, data[:1024], len(data))
        sectors = np.frombuffer(data, dtype=np.uint8, offset=1024, count=head.n_blocks * 512).reshape(-1, 512)
        blocks = decode_blocks(sectors, 0, block_params(sectors[0]))
        keep = np.arange(blocks.samples.shape[2])[None, :] < blocks.count[:, None]
        flat = blocks.samples[:, keep]  # (n_axes, samples) in file order
        theirs = actfast.read(str(path))["timeseries"]["high_frequency"]
        assert np.array_equal(flat[-3:].T, theirs["acceleration"])
        if len(flat) == 6:
            assert np.array_equal(flat[:3].T, theirs["gyroscope"])


# --------------------------------------------------------------------------- the corrupt-block file


def test_corrupt_blocks_skipped_and_imputed_as_ggirread_does() -> None:
    _, _, good, _ = _read(AX3, 1, 12)
    stream, _, v, _ = _read(CORRUPT, 0, 12)  # block 0 bad: as if read from block 1, nothing imputed
    assert v.shape == good.shape and _floor_abs(v) == _floor_abs(good)
    assert [(q.checksum_pass, q.block_current, q.block_next, q.imputed) for q in stream.qc_log] == [
        (False, 0, 1, False)]
    stream, _, v, _ = _read(CORRUPT, 1, 20)
    assert v.shape == (3, 2306) and _floor_abs(v) == 3244
    assert [(q.checksum_pass, q.block_current, q.block_next, q.imputed) for q in stream.qc_log] == [
        (False, 13, 14, False), (False, 14, 15, False), (True, 12, 15, True)]
    n11 = good.shape[1]
    expected = good[:, -1] / np.linalg.norm(good[:, -1])  # the last value, scaled to 1 g
    assert np.allclose(v[:, n11:n11 + 360], expected[:, None], atol=1e-4, rtol=0)
    for a, b, c in (((13, 20), (14, 20), (15, 20)), ((1, 13), (1, 14), (1, 15))):
        sums = [(_read(CORRUPT, *r)[2].shape, _floor_abs(_read(CORRUPT, *r)[2])) for r in (a, b, c)]
        assert sums[0] == sums[1] == sums[2]
    ends = [_read(CORRUPT, 140, e)[2] for e in (141, 142, 143, 144, 145)]
    assert {(x.shape, _floor_abs(x)) for x in ends} == {((3, 121), 145)}


@pytest.mark.parametrize(("start", "end", "offset"), [(13, 14, 8704), (142, 145, 73728), (144, 145, 74752)])
def test_only_corrupt_blocks_requested(start: int, end: int, offset: int) -> None:
    with pytest.raises(RawFileError) as err:
        _read(CORRUPT, start, end)
    assert str(err.value) == (f"{CORRUPT} (byte {offset}): expected a valid block among those requested, "
                              "found all requested blocks bad")


def test_too_many_corrupt_blocks_in_a_row() -> None:
    with pytest.raises(RawFileError) as err:
        _read(CORRUPT, 1, 20, max_corrupt=1)
    assert str(err.value) == (f"{CORRUPT} (byte 8192): expected at most 1 bad blocks in a row, "
                              "found 2 (blocks 13–14)")
    with pytest.raises(RawFileError) as err:
        _read(CORRUPT, 140, 144, max_corrupt=2)
    assert str(err.value) == f"{CORRUPT} (byte 73728): expected a valid block among the last 3, found all bad"


def test_corrupt_file_read_whole_names_its_bad_blocks() -> None:
    raw = read_raw_epochs(CORRUPT, ggir_whole_hours=False)
    assert [(b.index, b.byte_offset, b.reason) for b in raw.bad_blocks] == [
        (i, 1024 + 512 * i, "checksum") for i in (0, 13, 14, 142, 143, 144)]
    assert raw.imputed_samples == 362  # blocks 12–14: from block 12's start to block 15's
    assert raw.n_samples == 16993 and raw.n_epochs == 16
    assert ggir_calibrate(raw.epochs).qc == QC_TOO_SHORT


def test_actfast_lenient_names_the_same_sectors() -> None:
    actfast = pytest.importorskip("actfast")
    with pytest.raises(ValueError, match="sector 0 .byte offset 1024. failed checksum"):
        actfast.read(str(CORRUPT))
    warnings = actfast.read(str(CORRUPT), lenient=True)["warnings"]
    ours = read_raw_epochs(CORRUPT).bad_blocks
    assert warnings == [f"sector {b.index} (byte offset {b.byte_offset}) failed checksum" for b in ours]


# --------------------------------------------------------------------------- GENEActiv and ActiGraph


def test_geneactiv_as_ggirread_reads_it() -> None:
    wearable = open_wearable(BIN)
    first = next(iter(wearable.chunks()))
    assert wearable.info.sample_rate_hz == 85.7  # GGIRread's SampleRate
    assert first.time_s[0] == 1369908774.5
    assert first.temperature_c[0] == 21.5 and first.temperature_c[299] == 21.5
    assert first.acc_g[2, 299] == pytest.approx(-0.80836403369903564453, abs=1e-7)  # float32, as GGIRread
    raw = read_raw_epochs(BIN, ggir_whole_hours=False)
    assert (raw.format, raw.device, raw.serial, raw.range_g) == (
        "GENEActiv BIN", "GENEActiv 1.1", "012967", 8.0)
    assert (raw.start_local, raw.start_utc) == (  # the header's "GMT +01:00"
        "2013-05-30T10:12:54.500", "2013-05-30T09:12:54.500Z")
    assert raw.n_samples == 5031 and raw.n_epochs == 5031 // 857


def test_actigraph_as_ggir_reads_it() -> None:
    chunks = list(open_wearable(GT3X).chunks())
    acc = np.concatenate([c.acc_g for c in chunks], axis=1)
    t = np.concatenate([c.time_s for c in chunks])
    assert acc.shape == (3, 17640)
    assert acc.sum() == pytest.approx(2732.35, abs=0.01)  # read.gt3x's values, rounded to 1 mg
    assert (acc[0, 0], acc[1, 1], acc[2, 0]) == (0.004, -0.004, -0.957)
    # GGIR's test: time[2] == "2020-08-26 10:09:00.03332" (R prints the double 1598436540.0333328…
    # cut to 5 decimals); the file's clock counts 100-ns ticks: 333 333 of them
    assert t[1] - t[0] == pytest.approx(0.0333333, abs=1e-6)
    raw = read_raw_epochs(GT3X)
    assert (raw.format, raw.device, raw.serial, raw.sample_rate_hz) == (
        "ActiGraph GT3X", "ActiGraph wGT3XBT", "MOS2E39180594", 30.0)
    assert (raw.start_local, raw.start_utc) == ("2020-08-26T10:09:00.000", "2020-08-26T08:09:00.000Z")
    assert raw.epochs.temperature_c is None and raw.ggir_temperature_ok is None
    idle = raw.idle_sleep  # idle sleep: the device wrote nothing; the gaps add up to the file's span
    assert idle.gap_stretches == 23
    assert raw.n_samples + idle.gap_samples == round((t[-1] - t[0]) * 30.0) + 1


# --------------------------------------------------------------------------- every file into epochs


@pytest.mark.parametrize(("name", "qc"), [(AX3.name, QC_TOO_SHORT), (AX6.name, QC_TOO_SHORT),
                                         (CORRUPT.name, QC_TOO_SHORT), (BIN.name, QC_TOO_SHORT),
                                         (GT3X.name, QC_NO_STILL)])
def test_every_file_summarised_into_epochs(name: str, qc: str) -> None:
    path = DATA / name
    ggir = read_raw_epochs(path)  # GGIR: whole hours only; every file here is shorter than an hour
    assert ggir.n_epochs == 0 and ggir.n_tail_samples == ggir.n_samples - ggir.n_zero_samples > 0
    assert ggir.ggir_too_short
    result = ggir_calibrate(ggir.epochs)
    assert (result.qc, result.calibrated, result.n_epochs) == (QC_TOO_SHORT, False, 0)
    every = read_raw_epochs(path, ggir_whole_hours=False)
    per = round(every.sample_rate_hz * 10)
    assert every.n_epochs == (every.n_samples - every.n_zero_samples) // per > 0
    # the epochs are the means and sds (n − 1) of consecutive runs of samples kept
    chunks = list(open_wearable(path).chunks())
    acc = np.concatenate([c.acc_g for c in chunks], axis=1)
    acc = acc[:, ~np.all(acc == 0.0, axis=0)][:, : every.n_epochs * per].reshape(3, every.n_epochs, per)
    assert np.allclose(every.epochs.mean_g, acc.mean(axis=2).T, rtol=0, atol=1e-12)
    assert np.allclose(every.epochs.sd_g, acc.std(axis=2, ddof=1).T, rtol=0, atol=1e-12)
    # GGIR's verdict on every epoch (not its whole hours): fewer than 52 epochs is "not enough data";
    # the ActiGraph file's 58 epochs hold 8 still ones after the first, fewer than GGIR's 10
    result = ggir_calibrate(every.epochs)
    assert (result.qc, result.calibrated) == (qc, False)


# --------------------------------------------------------------------------- csv


def test_axivity_csv_export_equals_the_cwa_samples() -> None:
    raw = read_raw_epochs(DATA / "ax3_testfile_unix_timestamps.csv", ggir_whole_hours=False)
    assert (raw.format, raw.n_samples, raw.n_epochs, raw.n_tail_samples) == ("csv", 210, 0, 210)
    assert (raw.idle_sleep.gap_stretches, raw.idle_sleep.gap_samples) == (1, 1)  # a 0.02-s step at row 22
    samples = next(iter(open_wearable(DATA / "ax3_testfile_unix_timestamps.csv").chunks()))
    data = AX3.read_bytes()
    sectors = np.frombuffer(data, dtype=np.uint8, offset=1024, count=2 * 512).reshape(-1, 512)
    cwa = decode_blocks(sectors, 0, block_params(sectors[0])).samples.reshape(3, -1)
    cwa = np.delete(cwa, 22, axis=1)[:, :210]  # the export leaves out the .cwa's sample 22
    assert np.allclose(samples.acc_g, cwa, rtol=0, atol=1e-12)  # g → m/s² → g
    hinted = read_raw_epochs(DATA / "ax6_testfile_formatted_timestamps.csv", ggir_whole_hours=False,
                             csv_hints=Hints(rate_hz=100.0, acc_unit="g"))
    assert (hinted.n_samples, hinted.start_utc, hinted.start_local) == (210, None, None)


def test_csv_named_by_a_session_manifest(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    n, rate = 1000, 50.0
    acc = rng.normal([0.0, 0.0, 1.0], 0.004, (n, 3)).round(5)
    temp = np.linspace(20.0, 21.0, n).round(3)
    rec = tmp_path / "s1" / "rec-01"
    rec.mkdir(parents=True)
    lines = ["t,ax,ay,az,temperature"] + [f"{1.7e9 + i / rate:.3f},{a[0]},{a[1]},{a[2]},{c}"
                                          for i, (a, c) in enumerate(zip(acc, temp, strict=True))]
    (rec / "wrist.csv").write_text("\n".join(lines) + "\n")
    mapping = CsvMapping(columns={c: c for c in ("t", "ax", "ay", "az", "temperature")}, acc_unit="g",
                         sample_rate_hz=rate)
    spec = DeviceSpec("wrist", "ADXL345", "dut", "csv", None, csv=mapping)
    recording = RecordingSpec("rec-01", {"wrist": "rec-01/wrist.csv"})
    write_manifest(SessionManifest(tmp_path / "s1", "c", "s1", "multi-position", Site(gravity_mps2=G0), 1,
                                   {"wrist": spec}, (recording,)), tmp_path / "s1" / "session.yaml")
    raw = read_raw_epochs(rec / "wrist.csv", ggir_whole_hours=False)
    assert (raw.device, raw.sample_rate_hz, raw.n_epochs) == ("csv (ADXL345)", 50.0, 2)
    assert np.allclose(raw.epochs.mean_g, acc[:1000].reshape(2, 500, 3).mean(axis=1), rtol=0, atol=1e-12)
    assert np.allclose(raw.epochs.temperature_c, temp.reshape(2, 500).mean(axis=1), rtol=0, atol=1e-12)


def test_files_that_are_not_raw_samples(tmp_path: Path) -> None:
    with pytest.raises(RawFormatError) as err:
        read_raw_epochs(DATA / "ukbiobank.csv")  # 5-s summaries in mg, one column: not samples
    assert str(err.value).startswith(f"{DATA / 'ukbiobank.csv'}: expected data lines of at least 3 numeric")
    fake = tmp_path / "x.cwa"
    fake.write_bytes(b"PK\x03\x04" + bytes(2000))
    with pytest.raises(RawFileError) as err:
        read_raw_epochs(fake)
    assert str(err.value) == (f"{fake} (byte 0): expected an Axivity .cwa header ('MD', 1024 bytes), "
                              "found b'PK'")
    epochs = TESTS / "data" / "ggir-calibrate" / "spheredata.csv"
    with pytest.raises(RawFileError) as err:
        read_raw_epochs(epochs)
    assert str(err.value) == (f"{epochs}: expected a csv of samples, found an epoch csv (columns meanx … "
                              "sdz): read it with ofbe_data.freeliving.read_epoch_csv")
    other = tmp_path / "x.txt"
    other.write_text("1,2,3\n")
    with pytest.raises(RawFileError) as err:
        read_raw_epochs(other)
    assert str(err.value) == (f"{other}: expected a raw wearable file (.cwa, .bin, .gt3x, .csv), "
                              "found a .txt file")


def test_unreadable_binary_files_are_named(tmp_path: Path) -> None:
    bad = tmp_path / "broken.gt3x"
    bad.write_bytes(b"not a zip file")
    with pytest.raises(RawFileError) as err:
        read_raw_epochs(bad)
    assert str(err.value) == (f"{bad}: expected a .gt3x file: a zip archive ending in its central directory, "
                              "found none (File is not a zip file): a truncated or damaged file")
    bad = tmp_path / "broken.bin"
    bad.write_bytes(b"PK\x03\x04, not a GENEActiv file")
    with pytest.raises(RawFileError) as err:
        read_raw_epochs(bad)
    assert str(err.value) == (f"{bad} (byte 0): expected a GENEActiv .bin file (first line 'Device "
                              "Identity'), found b'PK\\x03\\x04, not a GENEActi'")


# --------------------------------------------------------------------------- GGIR's epoch rules, synthetic


def _write_cwa(path: Path, acc_g: np.ndarray, t0: float = 1.7e9, rate: float = 100.0,
               temperature_c: float | np.ndarray = 25.0) -> None:
    """A packed AX3 file of ``acc_g`` (shape (n, 3), n a multiple of 120), 1/256 g counts."""
    counts = np.clip(np.round(np.asarray(acc_g) * 256), -511, 511).astype(np.int64).reshape(-1, 120, 3)
    starts = t0 + np.arange(len(counts)) * 120 / rate
    path.write_bytes(encode_header(4242, 7, rate, 8) + encode_blocks(counts, starts, 0, 7, temperature_c,
                                                                        rate).tobytes())


def test_packed_time_stamps_round_trip() -> None:
    seconds = np.array([946684800, 1551178506, 1700000000, 2208988799])  # 2000-01-01 … 2039-12-31
    assert np.array_equal(packed_seconds(packed_timestamp(seconds)), seconds)


def test_synthetic_recording_calibrates_to_its_truth(tmp_path: Path) -> None:
    """Twelve still postures of 10 min (2 h), a known offset and scale per axis: GGIR's fit on the
    epochs ofbe makes finds them; 5 more minutes of movement fall after the last whole hour."""
    rng = np.random.default_rng(11)
    rate, per_posture = 100.0, 60000
    dirs = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],
                     [1, 1, 0], [-1, 0, 1], [0, -1, -1], [1, -1, 1], [-1, 1, -1], [1, 1, 1]], dtype=float)
    dirs /= np.linalg.norm(dirs, axis=1)[:, None]
    scale_true, offset_true = np.array([1.01, 0.99, 1.005]), np.array([0.02, -0.015, 0.01])
    still = np.repeat(dirs, per_posture, axis=0) * scale_true + offset_true
    moving = rng.normal(0.0, 0.3, (30000, 3)) + [0.0, 0.0, 1.0]
    acc = np.vstack([still + rng.normal(0.0, 0.004, still.shape), moving])
    path = tmp_path / "week.cwa"
    _write_cwa(path, acc, rate=rate)
    raw = read_raw_epochs(path)
    assert raw.n_epochs == 720  # 2 whole hours of 10-s epochs
    assert raw.n_tail_samples == raw.n_samples - 720_000 > 29_000
    assert raw.bad_blocks == () and raw.imputed_samples == 0 and not raw.ggir_too_short
    assert (raw.device, raw.serial, raw.start_utc) == ("Axivity AX3", "4242", None)
    result = ggir_calibrate(raw.epochs)
    assert result.calibrated and result.qc == QC_NOT_GOOD_ENOUGH  # 2 h: below GGIR's 72 h
    assert np.allclose(result.scale, 1.0 / scale_true, atol=2e-3)
    assert np.allclose(result.offset, -offset_true, atol=2e-3)
    assert result.cal_error_end < 2e-3 < result.cal_error_start


def test_time_jump_filled_as_ggirread_fills_it(tmp_path: Path) -> None:
    """The device clock jumps 30 s between blocks 49 and 50: GGIRread's grid runs on through the
    jump, and the blocks whose observed rate is off by more than 10 % are imputed with the last
    value scaled to 1 g."""
    rng = np.random.default_rng(1)
    acc = rng.normal([0.1, 0.2, 0.97], 0.004, (100 * 120, 3))
    counts = np.round(acc * 256).astype(np.int64).reshape(100, 120, 3)
    starts = 1.7e9 + np.arange(100) * 1.2
    starts[50:] += 30.0
    path = tmp_path / "jump.cwa"
    path.write_bytes(encode_header(1, 1) + encode_blocks(counts, starts).tobytes())
    stream, t, v, _ = _read(path)
    assert v.shape == (3, 100 * 120 + 3000 - 1)  # the 30 s are on the grid; the last block's end as GGIRread
    log = [(q.block_current, q.block_next, q.imputed) for q in stream.qc_log]
    assert log == [(49, 50, True), (50, 51, True)]
    imputed = np.flatnonzero(np.all(v == v[:, [6000]], axis=0))
    assert len(imputed) == stream.imputed_rows >= 3000
    assert np.array_equal(imputed, np.arange(imputed[0], imputed[-1] + 1))  # one stretch, over the jump
    assert t[imputed[0]] < starts[50] - 29.0 and t[imputed[-1]] > starts[50]
    assert np.linalg.norm(v[:, 6000]) == pytest.approx(1.0, abs=1e-12)


def test_idle_samples_removed_and_idle_sleep_counted(tmp_path: Path) -> None:
    """Zeros (a device's idle value) are removed before epoching; a run of a repeated sample
    (ActiGraph's idle sleep) is counted and makes epochs of sd 0."""
    rng = np.random.default_rng(5)
    acc = rng.normal([0.0, 0.0, 1.0], 0.01, (36000, 3))
    acc[6000:12000] = 0.0  # 60 s of zeros
    acc[18000:24000] = [0.25, 0.5, 0.75]  # 60 s of one repeated sample
    path = tmp_path / "idle.cwa"
    _write_cwa(path, acc)
    raw = read_raw_epochs(path, ggir_whole_hours=False)
    assert abs(raw.n_zero_samples - 6000) <= 2  # the stretch's edges are interpolated, not zero
    assert raw.n_epochs == (raw.n_samples - raw.n_zero_samples) // 1000
    assert raw.idle_sleep.stretches == 2  # the zeros and the repeated sample
    assert abs(raw.idle_sleep.samples - 12000) <= 4
    lo, hi = 18000 - raw.n_zero_samples, 24000 - raw.n_zero_samples  # the run among the samples kept
    assert raw.idle_sleep.epochs == hi // 1000 - -(-lo // 1000)  # the whole epochs inside it: sd 0
    assert np.all(raw.epochs.mean_g[np.all(raw.epochs.sd_g == 0, axis=1)] == [0.25, 0.5, 0.75])


def test_ggir_epochs_do_not_depend_on_chunks() -> None:
    rng = np.random.default_rng(9)
    n = 10_450
    acc = rng.normal(0.0, 1.0, (3, n))
    acc[:, 2000:2300] = 0.0
    temp = 25.0 + np.cumsum(rng.normal(0.0, 0.01, n))
    t = np.arange(n) / 100.0

    def run(cuts: list[int]) -> tuple[np.ndarray, ...]:
        maker = GgirEpochs(1000, True, 1000)
        for a, b in zip([0, *cuts], [*cuts, n], strict=True):
            maker.add(Samples(t[a:b], acc[:, a:b], temp[a:b]))
        return maker.finish(None)

    one, many = run([]), run([1, 999, 1000, 5001, 10_000])
    for x, y in zip(one, many, strict=True):
        assert np.array_equal(x, y)
    kept = ~np.all(acc == 0.0, axis=0)
    mean, sd, tm, start = one
    assert mean.shape == (10, 3)  # (10 450 − 300) // 1000
    blocks = acc[:, kept][:, :10_000].reshape(3, 10, 1000)
    assert np.allclose(mean, blocks.mean(axis=2).T, rtol=0, atol=1e-14)
    assert np.allclose(sd, blocks.std(axis=2, ddof=1).T, rtol=0, atol=1e-14)
    assert np.allclose(tm, temp[kept][:10_000].reshape(10, 1000).mean(axis=1), rtol=0, atol=1e-12)
    assert np.array_equal(start, t[kept][:10_000:1000])


def test_whole_hours_as_ggir_counts_them() -> None:
    assert whole_hour_epochs(360_000 * 3 - 1, 100.0, 1000) == 720  # 2 h 59 min 59.99 s: 2 whole hours
    assert whole_hour_epochs(308_520 * 2, 85.7, 857) == 720  # GENEActiv: 3600 · 85.7 samples an hour
    assert whole_hour_epochs(107_999, 30.0, 300) == 0


def test_under_two_hours_is_too_short_for_ggir(tmp_path: Path) -> None:
    """GGIR's g.readaccfile: a first block of fewer than 2 · 3600 · sf + 1 samples is "too short",
    even with a whole hour in it; every whole epoch is still there without GGIR's rules."""
    acc = np.random.default_rng(4).normal([0.0, 0.0, 1.0], 0.01, (420_000, 3))  # 70 min
    path = tmp_path / "short.cwa"
    _write_cwa(path, acc)
    ggir = read_raw_epochs(path)
    assert ggir.ggir_too_short and ggir.n_epochs == 0
    assert ggir_calibrate(ggir.epochs).qc == QC_TOO_SHORT
    every = read_raw_epochs(path, ggir_whole_hours=False)
    assert every.ggir_too_short and every.n_epochs == every.n_samples // 1000 >= 419


def test_ggir_temperature_checks_on_samples(tmp_path: Path) -> None:
    n = 36000
    acc = np.random.default_rng(2).normal([0.0, 0.0, 1.0], 0.01, (n, 3))
    flat, warm = tmp_path / "flat.cwa", tmp_path / "warm.cwa"
    _write_cwa(flat, acc, temperature_c=25.0)  # one value: sd below 0.01 °C
    _write_cwa(warm, acc, temperature_c=np.linspace(20.0, 30.0, n // 120))
    assert read_raw_epochs(flat).ggir_temperature_ok is False
    ok = read_raw_epochs(warm, ggir_whole_hours=False)
    assert ok.ggir_temperature_ok is True
    assert isinstance(ok.epochs, EpochTable) and ok.epochs.time_s is not None
    assert ok.epochs.temperature_c[0] < ok.epochs.temperature_c[-1]


def test_epoch_length_must_be_whole_samples() -> None:
    with pytest.raises(RawFileError) as err:
        read_raw_epochs(AX3, epoch_s=0.015)
    assert str(err.value) == (f"{AX3}: expected a sample rate × epoch length that is a whole number of "
                              "samples (at least 2), found 100 Hz × 0.015 s = 1.5")
