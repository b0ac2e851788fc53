"""Calibration exports (ofbe_data.calibration) on a simulated, labelled campaign: each format's
sign and unit convention checked through the other tool's own code or formula, the noise
density against the simulator's truth, and the store's look-up."""

from __future__ import annotations

import hashlib
import io
import json
import math
from dataclasses import replace
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import yaml

import ofbe_data
from ofbe_data.calibration import formats as fmt
from ofbe_data.calibration.formats import KalibrInputError
from ofbe_data.calibration.noise import (
    RawFiles,
    attach_raw_times,
    gyro_noise_of,
    noise_from_segments,
    noise_of,
)
from ofbe_data.calibration.results import (
    APPARENT,
    TIME_LABEL_MTIME,
    TIME_RAW,
    ZERO_G_OFFSET,
    CalibrationResult,
    CalibrationSourceError,
    attach_file_times,
    results_from_labels,
    results_from_predictions,
)
from ofbe_data.calibration.store import (
    CalibrationNotFoundError,
    CalibrationStoreError,
    find_calibration,
    store_path,
    stored_calibrations,
)
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import load_manifest
from ofbe_data.labelling.conventions import MATRIX_COLUMNS
from ofbe_data.labelling.labels import LabelParams
from ofbe_data.labelling.store import read_labels
from ofbe_data.simulator import load_config
from tests.helpers.exports import kalibr_imu_parameters
from tests.helpers.ggir_replica import GgirReadError, backup_cal_coef, read_myacc_csv
from tests.helpers.paths import EXAMPLES

WRITTEN = datetime(2025, 6, 1, 12, 0, 0, tzinfo=UTC)
#: Every key of Kalibr's IMU yaml (https://github.com/ethz-asl/kalibr/wiki/yaml-formats).
KALIBR_KEYS = {"accelerometer_noise_density", "accelerometer_random_walk", "gyroscope_noise_density",
               "gyroscope_random_walk", "rostopic", "update_rate"}


@pytest.fixture(scope="module")
def campaign(tiny_labelled) -> Path:
    """The session's tiny labelled campaigns (conftest.py): ``raw/mp``, ``raw/ga``, ``labels/mp``,
    ``labels/ga``."""
    return tiny_labelled


@pytest.fixture(scope="module")
def apparent_labels(campaign, tmp_path_factory) -> Path:
    """The multi-position labels with the offsets removed and a level method: apparent biases,
    six rows per power cycle."""
    out = tmp_path_factory.mktemp("app")
    for f in sorted((campaign / "labels" / "mp").glob("*.parquet")):
        table = pq.read_table(f)
        frame = table.to_pandas()
        frame[["offset_x", "offset_y", "offset_z"]] = np.nan
        frame["label_method"] = "level"
        pq.write_table(pa.Table.from_pandas(frame, schema=table.schema, preserve_index=False), out / f.name)
    return out


@pytest.fixture(scope="module")
def scaled_labels(campaign, tmp_path_factory) -> Path:
    """The multi-position labels as a scale-offset fit would write them (fit_model, scale_x/y/z)."""
    out = tmp_path_factory.mktemp("scaled")
    for f in sorted((campaign / "labels" / "mp").glob("*.parquet")):
        table = pq.read_table(f)
        frame = table.to_pandas()
        frame["fit_model"] = "scale-offset"
        frame[["scale_x", "scale_y", "scale_z"]] = [1.012, 0.991, 1.004]
        frame[list(MATRIX_COLUMNS)] = np.nan  # a label file from before the a_* columns
        pq.write_table(pa.Table.from_pandas(frame, schema=table.schema, preserve_index=False), out / f.name)
    return out


MP_GGIR_NAME = "mp-pc002__rec-01__sparkfun-1.csv"
"""GGIR's name for the raw file :func:`_one_raw` reads (session, recording, file)."""


def _one_raw(campaign: Path, campaign_name: str, session: str, device: str) -> np.ndarray:
    m = load_manifest(campaign / "raw" / campaign_name / session)
    rec = m.recordings[0]
    return read_device_file(m.file_path(rec, device), m.devices[device]).acc


# ----------------------------------------------------------------------------- results


def _bare_result() -> CalibrationResult:
    return CalibrationResult(device="d", power_cycle=1, bias=(0.1, 0.2, 0.3), std=None, bias_kind=APPARENT,
                             method="level", scale=(1.0, 1.0, 1.0), scale_known=False, scale_note="identity",
                             g_local=9.8, fs_hz=100.0, temperature_c=None, n_rows=1, sources=(),
                             recordings=())



def test_offsets_become_one_zero_g_result_per_power_cycle(campaign) -> None:
    labels = read_labels(campaign / "labels" / "mp")
    got = results_from_labels(campaign / "labels" / "mp")
    assert got.kind == "labels" and [(r.device, r.power_cycle) for r in got.results] == [
        ("sparkfun-1", 1), ("sparkfun-1", 2)]
    for r in got.results:
        rows = labels[labels.power_cycle == r.power_cycle]
        assert r.bias_kind == ZERO_G_OFFSET and r.method == "multi-position" and r.std is None
        assert r.bias == tuple(rows[["offset_x", "offset_y", "offset_z"]].iloc[0])
        assert r.n_rows == len(rows) >= 6 and len(r.segments) == len(rows)
        # six faces, each held for up to three poses: the scale-offset fit, A diagonal
        assert set(rows["fit_model"]) == {"scale-offset"}
        assert r.scale_known and "scale-offset fit" in r.scale_note
        assert r.scale == tuple(rows[["scale_x", "scale_y", "scale_z"]].iloc[0])
        assert np.array_equal(np.array(r.matrix), np.diag(r.scale))
        assert r.stem == f"sparkfun-1.pc{r.power_cycle}"
        assert r.sources[0].sha256 == hashlib.sha256(Path(r.sources[0].path).read_bytes()).hexdigest()


def test_apparent_biases_are_averaged_with_their_std(campaign, apparent_labels) -> None:
    labels = read_labels(apparent_labels)
    for r in results_from_labels(apparent_labels).results:
        rows = labels[labels.power_cycle == r.power_cycle][["bias_x", "bias_y", "bias_z"]].to_numpy()
        assert r.bias_kind == APPARENT and r.method == "level"
        assert np.allclose(r.bias, rows.mean(axis=0), rtol=0, atol=1e-15)
        assert np.allclose(r.std, rows.std(axis=0, ddof=1), rtol=0, atol=1e-15)
    single = results_from_labels(campaign / "labels" / "ga").results
    assert len(single) == 6 and all(r.bias_kind == APPARENT and r.std is None for r in single)


def test_a_fitted_scale_is_carried(scaled_labels, apparent_labels) -> None:
    for r in results_from_labels(scaled_labels).results:
        assert r.scale == (1.012, 0.991, 1.004) and r.scale_known and "scale-offset fit" in r.scale_note
    for r in results_from_labels(apparent_labels).results:  # apparent biases: no scale applies
        assert r.scale == (1.0, 1.0, 1.0) and not r.scale_known


def test_bad_sources_are_one_line_errors(tmp_path, campaign) -> None:
    with pytest.raises(CalibrationSourceError, match="no such path"):
        results_from_labels(tmp_path / "nope")
    with pytest.raises(CalibrationSourceError, match="found none"):
        results_from_labels(tmp_path)
    (tmp_path / "x.parquet").write_bytes(b"not parquet")
    with pytest.raises(CalibrationSourceError, match=r"x\.parquet: expected an ofbe label file"):
        results_from_labels(tmp_path / "x.parquet")
    (tmp_path / "p.json").write_text('{"results": [{"device": "d", "file": "f", "g_local": 9.8, '
                                     '"bias_m_s2": [1, 2]}]}')
    with pytest.raises(CalibrationSourceError, match=r"results\[0\]: bias_m_s2: expected 3 finite numbers"):
        results_from_predictions(tmp_path / "p.json")
    (tmp_path / "q.json").write_text("{\n  oops")
    with pytest.raises(CalibrationSourceError, match=r"q\.json:2: expected the JSON that ofbe-predict"):
        results_from_predictions(tmp_path / "q.json")


# ----------------------------------------------------------------------------- imucal


def _imucal_load(tmp_path: Path, data: bytes):
    from imucal import FerrarisCalibrationInfo
    from imucal.management import load_calibration_info

    path = tmp_path / "cal.imucal.json"
    path.write_bytes(data)
    cal = load_calibration_info(path)
    assert isinstance(cal, FerrarisCalibrationInfo) and cal.CAL_TYPE == "Ferraris"
    return cal


@pytest.mark.parametrize("scaled", [False, True])
def test_imucal_corrects_as_ofbe_does(tmp_path, campaign, scaled_labels, scaled) -> None:
    """imucal's own calibrate (R⁻¹K⁻¹(f − b)) on a raw recording equals ofbe's A⁻¹(f − b)."""
    r = results_from_labels(scaled_labels if scaled else campaign / "labels" / "mp").results[0]
    assert r.scale_known
    data = fmt.imucal_file(r, WRITTEN)
    cal = _imucal_load(tmp_path, data)
    assert cal.to_json().encode() == data  # byte for byte what imucal itself writes
    assert cal.from_acc_unit == "m/s^2" and "gyroscope" in cal.comment
    assert "bias_kind: zero-g-offset" in cal.comment and r.scale_note in cal.comment
    acc = _one_raw(campaign, "mp", "mp-pc001", "sparkfun-1")
    gyr = np.random.default_rng(0).normal(size=acc.shape)
    cal_acc, cal_gyr = cal.calibrate(acc=acc, gyr=gyr, acc_unit="m/s^2", gyr_unit="deg/s")
    ours = fmt.ofbe_correct(acc, r.bias, r.matrix)
    assert np.max(np.abs(cal_acc - ours)) < 1e-9
    assert np.array_equal(cal_gyr, gyr)  # gyroscope identity/zero
    assert np.max(np.abs(np.asarray(r.bias))) > 0.05  # the sign matters: b is far from zero


# ----------------------------------------------------------------------------- GGIR


def _ggir_backup_coefficients(data: bytes, filename: str) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """What GGIR's g.part1 takes from the file for one data file (``scale``, ``offset``,
    ``tempoffset``, ``meantempcal``): :func:`tests.helpers.ggir_replica.backup_cal_coef`, the
    ``backup.cal.coef`` block of R/g.part1.R replicated line by line."""
    row = backup_cal_coef(data, filename)
    return row.scale, row.offset, row.tempoffset, row.meantempcal


@pytest.mark.parametrize("scaled", [False, True])
def test_ggir_formula_equals_ofbe_correction(campaign, scaled_labels, scaled) -> None:
    r = results_from_labels(scaled_labels if scaled else campaign / "labels" / "mp").results[1]
    assert r.scale_known
    table = pd.read_csv(io.BytesIO(fmt.ggir_file(r, WRITTEN, convention="local")))
    assert tuple(table.columns) == fmt.GGIR_COLUMNS and table.columns[0] == "filename"
    raw_files = [f"mp-pc002/rec-0{k}/sparkfun-1.csv" for k in range(1, 7)]
    assert list(table["raw_file"]) == raw_files and set(table["bias_kind"]) == {ZERO_G_OFFSET}
    assert list(table["filename"]) == [f.replace("/", "__") for f in raw_files]
    assert "bias_kind zero-g-offset" in table["QCmessage"][0]
    scale_g, offset_g, temp_g, _ = _ggir_backup_coefficients(fmt.ggir_file(r, WRITTEN, convention="local"),
                                                             MP_GGIR_NAME)
    assert np.all(temp_g == 0)
    assert np.all(np.sign(offset_g) == -np.sign(r.bias))  # GGIR adds its offset
    raw = _one_raw(campaign, "mp", "mp-pc002", "sparkfun-1")
    ggir = fmt.ggir_apply(raw / G0, scale_g, offset_g)  # (raw_g + offset) * scale, in g
    assert np.max(np.abs(ggir * G0 - fmt.ofbe_correct(raw, r.bias, r.matrix))) < 1e-12


def test_ggir_default_is_its_own_unit_sphere_and_no_cell_is_empty(campaign, apparent_labels) -> None:
    r = results_from_labels(campaign / "labels" / "mp").results[1]
    data = fmt.ggir_file(r, WRITTEN)  # default: GGIR's convention
    scale_g, offset_g, _, meantempcal = _ggir_backup_coefficients(data, MP_GGIR_NAME)
    assert r.temperature_c is None and meantempcal == 0.0 and "temperature unknown" in data.decode()
    raw = _one_raw(campaign, "mp", "mp-pc002", "sparkfun-1")
    ggir = fmt.ggir_apply(raw / G0, scale_g, offset_g)
    # a resting reading has norm 1 g after GGIR's correction, as its own auto-calibration makes it
    assert np.max(np.abs(ggir * r.g_local - fmt.ofbe_correct(raw, r.bias, r.matrix))) < 1e-12
    still = np.linalg.norm(ggir.mean(axis=0))
    assert abs(still - 1.0) < 2e-3 and abs(still - r.g_local / G0) > abs(still - 1.0)
    # every numeric cell of every export holds a number
    for result in results_from_labels(apparent_labels).results:
        table = pd.read_csv(io.BytesIO(fmt.ggir_file(result, WRITTEN)))
        numeric = [c for c in fmt.GGIR_COLUMNS if c.startswith(("scale.", "offset.", "temperature.")) or
                   c == "meantempcal"]
        assert table[numeric].notna().all().all()


def test_json_lists_each_recording_once(tmp_path) -> None:
    """Issue 22: a continuous recording of many poses was listed once per pose (imucal's
    continuous session: 13 poses in one recording)."""
    from ofbe_data.labelling.labels import label_session
    from ofbe_data.labelling.store import write_session

    labels = label_session(EXAMPLES / "imucal-ferraris" / "ferraris-continuous")
    path, _ = write_session(labels, LabelParams(), tmp_path)
    (r,) = results_from_labels(path).results
    doc = json.loads(fmt.json_file(r, WRITTEN))
    assert r.n_rows == 13 and doc["recordings"] == ["ferraris-continuous/rec-01"]


def test_ggir_gives_every_raw_file_its_own_row(campaign, apparent_labels) -> None:
    """GGIR matches by base name and every raw file is <device>.csv: each recording gets its own
    unique name (session and recording folders in it), and GGIR's lookup finds each one."""
    r = results_from_labels(apparent_labels).results[0]
    data = fmt.ggir_file(r, WRITTEN)
    table = pd.read_csv(io.BytesIO(data))
    raw_files = sorted({f"{s.session}/{s.raw_file}" for s in r.segments})  # poses share a file
    assert len(table) == len(raw_files) == 6 and set(table["power_cycle"]) == {1}
    assert list(table["raw_file"]) == raw_files and table["filename"].is_unique
    assert list(table["filename"]) == [f.replace("/", "__") for f in raw_files]
    for name in table["filename"]:
        scale, offset, _, _ = _ggir_backup_coefficients(data, name)
        assert np.array_equal(offset, table[["offset.x", "offset.y", "offset.z"]].to_numpy()[0])
    ga = results_from_labels(campaign / "labels" / "ga").results
    names = [n for x in ga for n in pd.read_csv(io.BytesIO(fmt.ggir_file(x, WRITTEN)))["filename"]]
    assert len(names) == len(set(names)) == 6  # 2 boards x 3 power cycles, one file each
    assert fmt.ggir_name("walk.csv") == "walk.csv"  # a prediction's file keeps its own name


def test_ggir_table_is_one_file_for_every_device_and_power_cycle(campaign) -> None:
    """Issue 33: GGIR takes ONE calibration file per run (g.part1's ``backup.cal.coef``): the
    table holds a row per raw file of every device and power cycle, and GGIR's own look-up
    (replicated) finds each data file's row with its own result's coefficients."""
    results = (results_from_labels(campaign / "labels" / "ga").results
               + results_from_labels(campaign / "labels" / "mp").results)
    data = fmt.ggir_table(results, WRITTEN)
    table = pd.read_csv(io.BytesIO(data))
    assert tuple(table.columns) == fmt.GGIR_COLUMNS
    assert len(table) == sum(len(r.raw_files) for r in results) == 6 + 12
    assert set(zip(table["device"], table["power_cycle"], strict=True)) == {
        (r.device, r.power_cycle) for r in results}
    assert table["filename"].is_unique and table.notna().all().all()
    for r in results:
        scale, offset = fmt.ggir_coefficients(r.bias, r.matrix, G0, r.g_local)
        for raw_file in r.raw_files:
            row = backup_cal_coef(data, fmt.ggir_name(raw_file))
            np.testing.assert_array_equal(row.offset, offset)
            np.testing.assert_array_equal(row.scale, scale)
            assert not row.use_temp and row.meantempcal == 0.0
            assert f"bias_kind {r.bias_kind}" in row.qc_message
    # one result alone (what --store files per device and power cycle) holds the same rows
    single = pd.read_csv(io.BytesIO(fmt.ggir_file(results[-1], WRITTEN)))
    pd.testing.assert_frame_equal(single, table.iloc[-len(single):].reset_index(drop=True))


def test_ggir_table_refuses_names_ggir_would_not_find(campaign) -> None:
    """GGIR uses the first row of a name (``bcc.i[1]``) and rewrites names holding ``meta_``
    before its look-up: both would silently apply wrong or no coefficients, so both are refused."""
    r = results_from_labels(campaign / "labels" / "ga").results[0]
    with pytest.raises(fmt.GgirExportError, match="one backup.cal.coef row per data file name"):
        fmt.ggir_table([r, replace(r, device="other")], WRITTEN)
    assert fmt.ggir_lookup_name("s1__meta_rec__x.csv") == "rec__x.csv"
    assert fmt.ggir_lookup_name("meta_walk.csv.RData") == "walk.csv"
    with pytest.raises(fmt.GgirExportError, match="rewrites to 'rec__x.csv'"):
        fmt.ggir_table([replace(r, raw_files=("s1/meta_rec/x.csv",))], WRITTEN)
    # the replica of g.part1 agrees: such a row is found under the rewritten name only
    name = fmt.ggir_name(r.raw_files[0]).encode()
    data = fmt.ggir_table([r], WRITTEN).replace(name, b"s1__meta_rec__x.csv")
    with pytest.raises(GgirReadError, match="no backup.cal.coef row"):
        backup_cal_coef(data, "s1__meta_rec__x.csv")
    assert backup_cal_coef(data, "rec__x.csv").scale.shape == (3,)
    assert fmt.ggir_name("s/rec-01/memsense.bin") == "s__rec-01__memsense.bin.csv"  # GGIR reads by ending


HOSTILE_LOGGER = (
    b"ets Jun  8 2016 00:22:57\r\nrst:0x1 (POWERON_RESET),boot:0x13 (SPI_FAST_FLASH_BOOT)\n"
    b"# ofbe-logger fw=1.4.2 board=sparkfun-thing-plus-esp32 chip=ADXL345 device=sparkfun-1\n"
    b"# odr_hz=150 range_g=16 full_res=1 lsb_per_g=256\n"
    b"# host_start_utc=2025-03-14T10:22:31.100Z\nt_us,ax,ay,az\n")
"""Preamble of an ofbe-logger file: boot noise (one line with CR LF), header, column names."""


def _hostile_logger(path: Path, n: int = 600, seed: int = 0) -> None:
    """An ofbe-logger file of ``n`` samples at 150 Hz with what the serial link does to real
    files: a truncated line, a 0xFF byte, a non-numeric field, and two dropped samples."""
    rng = np.random.default_rng(seed)
    t_us = 4093012 + np.round(np.arange(n) * 1e6 / 150).astype(np.int64)
    counts = np.round([3, -5, 259] + 1.4 * rng.standard_normal((n, 3))).astype(int)
    lines = [f"{t},{x},{y},{z}".encode() for t, (x, y, z) in zip(t_us, counts, strict=True)]
    lines[100] = lines[100][:9]  # truncated
    lines[200] = lines[200][:3] + b"\xff" + lines[200][3:]  # a byte that is not text
    lines[300] = lines[300].replace(b",", b",x", 1)  # non-numeric field
    del lines[400:402]  # dropped by the link
    path.write_bytes(HOSTILE_LOGGER + b"\n".join(lines) + b"\n")


def test_ggir_data_file_is_read_whole_by_ggir_and_round_trips(tmp_path) -> None:
    """Issue 33: GGIR's csv reader stops at the first garbled line or fails on a 0xFF byte of a
    raw logger file. The rebuilt file holds exactly the samples ofbe's reader kept; GGIR's
    reading (replicated: header block, column-name line, fread's field counts and numeric
    columns) takes every line, and gives back acc/g0 bit for bit and the UTC times."""
    from ofbe_data.io.formats.ofbe_logger import read_ofbe_logger

    path = tmp_path / "sparkfun-1.csv"
    _hostile_logger(path)
    rec = read_ofbe_logger(path)
    assert len(rec.diagnostics.skipped) == 3 and rec.n == 600 - 2 - 3
    assert rec.diagnostics.missing_samples == 2 + 3  # dropped and skipped samples leave gaps
    body = path.read_bytes().split(b"\n")[6:-1]  # the raw data lines as GGIR would see them
    with pytest.raises(UnicodeDecodeError):
        b"\n".join(body).decode("ascii")
    assert len({line.count(b",") for line in body}) > 1  # fread would stop early
    data = fmt.ggir_data_file(rec)
    assert data.isascii() and b"\r" not in data
    lines = data.decode().splitlines()
    assert lines[:2] == ["sample_rate,150,,", "time,x,y,z"]
    assert {line.count(",") for line in lines} == {3} and len(lines) == 2 + rec.n
    sf, frame = read_myacc_csv(data, fmt.ggir_read_settings(with_temperature=False), str(path))
    assert sf == 150.0 and list(frame.columns) == ["time", "x", "y", "z"] and len(frame) == rec.n
    np.testing.assert_array_equal(frame[["x", "y", "z"]].to_numpy(), rec.acc / G0)
    start = datetime(2025, 3, 14, 10, 22, 31, 100000, tzinfo=UTC).timestamp()
    np.testing.assert_allclose(frame["time"].to_numpy() - start, rec.t - rec.t[0], rtol=0, atol=1e-6)
    assert np.all(np.diff(frame["time"].to_numpy()) > 0)


def test_ggir_data_file_temperature_rates_and_time_origins(tmp_path) -> None:
    """A temperature column when asked (and only when every sample has one); the header's UTC
    start is ``t = 0`` for mscip-csv and the first sample elsewhere; without a start the device
    clock is written; without a nominal rate the measured one."""
    from ofbe_data.io.recording import TEMPERATURE, ReadDiagnostics, Recording

    n = 5
    t = 2.0 + np.arange(n) / 200.0
    start = datetime(2025, 3, 14, 10, 22, 31, 512000, tzinfo=UTC)
    rec = Recording(tmp_path / "m.csv", "mscip-csv", t, np.full((n, 3), 9.80665 / 3), np.zeros(n, bool),
                    np.arange(n), start, 200.0, {}, ReadDiagnostics(tmp_path / "m.csv", 6, n, n),
                    {TEMPERATURE: np.array([31.2, 31.2, 31.25, 31.3, 31.3])})
    data = fmt.ggir_data_file(rec, with_temperature=True)
    assert data.decode().splitlines()[:2] == ["sample_rate,200,,,", "time,x,y,z,temperature"]
    sf, frame = read_myacc_csv(data, fmt.ggir_read_settings(with_temperature=True))
    assert sf == 200.0
    np.testing.assert_array_equal(frame["temperature"], rec.extra[TEMPERATURE])
    np.testing.assert_allclose(frame["time"] - start.timestamp(), t, atol=1e-6)  # Time (s) from Start
    logger = fmt.ggir_data_file(replace(rec, format="ofbe-logger"))
    _, frame = read_myacc_csv(logger, fmt.ggir_read_settings(with_temperature=False))
    np.testing.assert_allclose(frame["time"] - start.timestamp(), t - t[0], atol=1e-6)  # first sample
    _, frame = read_myacc_csv(fmt.ggir_data_file(replace(rec, start_utc=None)), fmt.ggir_read_settings(False))
    np.testing.assert_allclose(frame["time"], t, atol=1e-6)
    assert fmt.ggir_sample_rate(replace(rec, nominal_rate_hz=None)) == 200.0
    with pytest.raises(fmt.GgirExportError, match="m.csv: expected a finite temperature"):
        fmt.ggir_data_file(replace(rec, extra={TEMPERATURE: np.array([31.2, np.nan, 31.0, 31.0, 31.0])}),
                           with_temperature=True)
    settings = fmt.ggir_read_settings(with_temperature=True)
    assert settings["rmc.col.temp"] == "5" and settings["rmc.firstrow.acc"] == "2"
    assert "rmc.col.temp" not in fmt.ggir_read_settings(with_temperature=False)


# ----------------------------------------------------------------------------- ROS


def _ros2_parameters(data: bytes, node: str = "/**") -> dict:
    """The parameters of ``node`` in a ROS 2 parameter file, checked as rcl's YAML parameter
    parser (rcl_yaml_param_parser/src/parse.c) accepts them: a node name mapping to
    ``ros__parameters``, and every value a bool, integer, double, string or a homogeneous list of
    one of those (no null: the parser has no type for it)."""
    doc = yaml.safe_load(data)
    assert list(doc) == [node] and list(doc[node]) == ["ros__parameters"]
    params = doc[node]["ros__parameters"]
    for key, value in params.items():
        values = value if isinstance(value, list) else [value]
        assert values and all(v is not None for v in values), key
        assert len({type(v) for v in values}) == 1 and isinstance(values[0], (bool, int, float, str)), key
    return params


def test_ros_parameter_file_parses_back_exactly(apparent_labels, campaign) -> None:
    r = results_from_labels(apparent_labels).results[0]
    doc = _ros2_parameters(fmt.ros_file(r, WRITTEN, frame_id="dut_link"))
    assert doc["device"] == "sparkfun-1" and doc["power_cycle"] == 1 and doc["frame_id"] == "dut_link"
    assert doc["bias_kind"] == APPARENT
    assert doc["linear_acceleration_bias"] == list(r.bias)
    assert doc["linear_acceleration_bias_std"] == list(r.std)
    # sensor_msgs/Imu: the covariance of one measurement, the per-sample noise, not the bias' spread
    labels = read_labels(apparent_labels)
    rows = labels[(labels.device == r.device) & (labels.power_cycle == r.power_cycle)]
    noise = np.sqrt(np.mean(rows[["std_x", "std_y", "std_z"]].to_numpy() ** 2, axis=0))
    cov = doc["linear_acceleration_covariance"]
    assert len(cov) == 9 and np.allclose([cov[0], cov[4], cov[8]], noise**2, rtol=1e-12)
    assert [cov[i] for i in (1, 2, 3, 5, 6, 7)] == [0.0] * 6
    offset = results_from_labels(campaign / "labels" / "mp").results[0]
    doc = _ros2_parameters(fmt.ros_file(offset, WRITTEN, node="imu_driver"), node="imu_driver")
    assert doc["frame_id"] == fmt.DEFAULT_FRAME_ID and doc["linear_acceleration_covariance"][0] > 0
    assert doc["linear_acceleration_bias_std"] == list(offset.bias_se)  # the fit's standard errors


def test_ros_file_of_a_prediction_leaves_the_unknown_out(tmp_path) -> None:
    (tmp_path / "p.json").write_text(json.dumps({"results": [
        {"device": "d", "file": "raw/s/rec/d.csv", "g_local": 9.8, "bias_m_s2": [0.1, -0.2, 0.3]}]}))
    r = results_from_predictions(tmp_path / "p.json").results[0]
    doc = _ros2_parameters(fmt.ros_file(r, WRITTEN))
    assert "power_cycle" not in doc and "linear_acceleration_bias_std" not in doc
    assert doc["linear_acceleration_covariance"] == [0.0] * 9  # unknown, as sensor_msgs/Imu says


@pytest.mark.parametrize("x", [0.0, -0.0, 1e-5, -2.5e-7, 1e20, 5e-324, 0.1 + 0.2, -0.331111111999999, 123.0])
def test_yaml_floats_round_trip(x) -> None:
    back = yaml.safe_load(f"v: {fmt.yaml_float(x)}")["v"]
    assert isinstance(back, float) and back == x and math.copysign(1, back) == math.copysign(1, x)


# ----------------------------------------------------------------------------- JSON


def test_json_parses_back(campaign) -> None:
    r = attach_file_times(results_from_labels(campaign / "labels" / "mp")).results[0]
    doc = json.loads(fmt.json_file(r, WRITTEN))
    assert doc["format"] == "ofbe-calibration/1" and doc["ofbe_version"] == ofbe_data.__version__
    assert (doc["device"], doc["power_cycle"], doc["bias_kind"], doc["method"]) == (
        "sparkfun-1", 1, ZERO_G_OFFSET, "multi-position")
    assert doc["bias_m_s2"] == list(r.bias) and doc["bias_std_m_s2"] is None
    assert doc["written_utc"] == "2025-06-01T12:00:00Z" and doc["time_source"] == TIME_LABEL_MTIME
    (src,) = doc["source"]["files"]
    assert src["sha256"] == hashlib.sha256(Path(src["path"]).read_bytes()).hexdigest()
    assert datetime.strptime(doc["time_utc"], "%Y-%m-%dT%H:%M:%SZ")


# ----------------------------------------------------------------------------- Kalibr / noise


def test_kalibr_noise_density_matches_the_simulated_white_noise(campaign) -> None:
    """N = σ/√f_s from the Allan deviation of the labelled segments, within 10 % of the
    simulator's per-axis noise (the 3.9 mg quantisation adds a few percent). The 35 s segments
    cannot show a random walk: its flagged upper bound is written, and Kalibr's reader takes
    the file (the gyroscope values from the flags: the SparkFun files have no gyroscope)."""
    truth_mg = np.array(load_config("tiny-gravity-aligned").dut_model.noise_mg)
    raw = RawFiles(campaign / "raw" / "ga")
    for r in results_from_labels(campaign / "labels" / "ga").results:
        noise = noise_of(r, raw)
        expected = truth_mg * 1e-3 * G0 / math.sqrt(r.fs_hz)
        assert np.all(np.abs(np.array(noise.density) / expected - 1) < 0.10), (noise.density, expected)
        assert noise.random_walk is None  # 35 s segments cannot show the +1/2 branch
        assert gyro_noise_of(r, raw) is None
        with pytest.raises(KalibrInputError, match="--gyro-noise-density and --gyro-random-walk"):
            fmt.kalibr_file(r, noise, WRITTEN)
        data = fmt.kalibr_file(r, noise, WRITTEN, gyro_noise_density=1.7e-4, gyro_random_walk=2e-5)
        doc = yaml.safe_load(data)
        assert set(doc) == KALIBR_KEYS and all(isinstance(doc[k], float) for k in KALIBR_KEYS - {"rostopic"})
        kalibr = kalibr_imu_parameters(data)
        assert kalibr["accelerometer_noise_density"] == max(noise.density)  # one value for all axes
        assert kalibr["accelerometer_random_walk"] == max(noise.random_walk_bound)
        assert kalibr["gyroscope_noise_density"] == 1.7e-4 and kalibr["gyroscope_random_walk"] == 2e-5
        assert kalibr["rostopic"] == "/imu0" and abs(kalibr["update_rate"] - r.fs_hz) < 1e-5
        text = data.decode()
        assert "# accelerometer_random_walk [m/s^3/sqrt(Hz)]: UPPER BOUND, NOT A MEASUREMENT" in text
        assert "given by the user (--gyro-noise-density)" in text and "bias_kind: apparent" in text


def test_random_walk_is_read_only_where_the_curve_turns_up() -> None:
    rng = np.random.default_rng(3)
    fs, n, sigma, k = 100.0, 400_000, 0.03, 2e-4  # crossover √3·N/K ≈ 26 s, 4000 s of data
    walk = np.cumsum(k / math.sqrt(fs) * rng.standard_normal((n, 3)), axis=0)
    noise = noise_from_segments([sigma * rng.standard_normal((n, 3)) + walk], fs)
    assert np.allclose(noise.density, sigma / math.sqrt(fs), rtol=0.05)
    assert noise.random_walk is not None and np.allclose(noise.random_walk, k, rtol=0.35)
    white = noise_from_segments([sigma * rng.standard_normal((n, 3))], fs)
    assert white.random_walk is None
    r = _bare_result()
    data = fmt.kalibr_file(r, noise, WRITTEN, rostopic="/dut/imu", gyro=white)
    kalibr = kalibr_imu_parameters(data)
    assert kalibr["accelerometer_random_walk"] == max(noise.random_walk) and kalibr["rostopic"] == "/dut/imu"
    assert kalibr["gyroscope_noise_density"] == max(white.density)
    assert kalibr["gyroscope_random_walk"] == max(white.random_walk_bound)
    assert data.decode().count("UPPER BOUND") == 1  # the gyroscope's, not the measured accelerometer's


@pytest.mark.parametrize("seed", range(6))
def test_random_walk_bound_holds_where_the_walk_is_not_yet_visible(seed: int) -> None:
    """A walk hidden under white noise (crossover √3·N/K ≈ 260 s, 600 s of data): no K is read,
    and the upper bound is above the true K on every axis, yet within a factor of 20 of it (it
    shrinks as 1/√τ with longer data); white noise alone gives a bound near that level too."""
    rng = np.random.default_rng(seed)
    fs, n, sigma, k = 50.0, 30_000, 0.03, 2e-5
    walk = np.cumsum(k / math.sqrt(fs) * rng.standard_normal((n, 3)), axis=0)
    noise = noise_from_segments([sigma * rng.standard_normal((n, 3)) + walk], fs)
    assert noise.random_walk is None
    bound = np.array(noise.random_walk_bound)
    assert np.all(bound > k) and np.all(bound < 20 * k), bound / k
    longer = noise_from_segments([sigma * rng.standard_normal((4 * n, 3))], fs)
    assert np.all(np.array(longer.random_walk_bound) < bound)


def test_raw_files_give_recording_times_and_are_checked(campaign, tmp_path) -> None:
    raw = RawFiles(campaign / "raw" / "mp")
    got = attach_raw_times(results_from_labels(campaign / "labels" / "mp"), raw)
    for r in got.results:
        starts = [raw.recording(s, r.device).start_utc for s in r.segments]
        assert r.time_source == TIME_RAW and r.time_utc == min(starts)  # to the millisecond of the header
    assert got.results[0].time_utc < got.results[1].time_utc
    seg = replace(got.results[0].segments[0], raw_sha256="0" * 64)
    with pytest.raises(CalibrationSourceError, match="expected the bytes that were labelled"):
        RawFiles(campaign / "raw" / "mp").recording(seg, "sparkfun-1")
    with pytest.raises(CalibrationSourceError, match="is --raw the campaign's raw folder"):
        RawFiles(tmp_path).manifest("mp-pc001")


# ----------------------------------------------------------------------------- store


def test_store_finds_the_latest_at_or_before(tmp_path) -> None:
    t0 = datetime(2025, 3, 14, 9, 0, 30, tzinfo=UTC)
    for days, f in ((0, "json"), (10, "json"), (10, "ros"), (20, "imucal")):
        p = store_path(tmp_path, "sparkfun-1", t0 + timedelta(days=days), f)
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text("x")
    expected = tmp_path / "sparkfun-1" / "sparkfun-1_20250314T090030.json"
    assert store_path(tmp_path, "sparkfun-1", t0, "json") == expected
    find = ofbe_data.find_calibration
    assert find is find_calibration
    assert find(tmp_path, "sparkfun-1", t0).name == "sparkfun-1_20250314T090030.json"
    assert find(tmp_path, "sparkfun-1", t0 + timedelta(days=5)).name == "sparkfun-1_20250314T090030.json"
    assert find(tmp_path, "sparkfun-1", t0 + timedelta(days=12), "ros").name.endswith("0324T090030.ros.yaml")
    assert find(tmp_path, "sparkfun-1", t0 + timedelta(days=30)).name == "sparkfun1_2025-04-03_09-00.json"
    naive = (t0 + timedelta(days=30)).replace(tzinfo=None)  # taken as UTC
    assert find(tmp_path, "sparkfun-1", naive, "json").name == "sparkfun-1_20250324T090030.json"
    with pytest.raises(CalibrationStoreError, match="several formats"):
        find(tmp_path, "sparkfun-1", t0 + timedelta(days=12))
    with pytest.raises(CalibrationNotFoundError, match="only later ones"):
        find(tmp_path, "sparkfun-1", t0 - timedelta(seconds=1))
    with pytest.raises(CalibrationNotFoundError, match="sparkfun-2.*found none"):
        find(tmp_path, "sparkfun-2", t0)
    with pytest.raises(LookupError):
        find(tmp_path, "sparkfun-1", t0, "kalibr")
    with pytest.raises(CalibrationStoreError, match="expected an id"):
        find(tmp_path, "..", t0)


def test_store_keeps_fractions_of_a_second_and_reads_older_names(tmp_path) -> None:
    t0 = datetime(2025, 3, 14, 9, 0, 30, 512000, tzinfo=UTC)
    p = store_path(tmp_path, "SparkFun_1", t0, "json")
    assert p.name == "SparkFun_1_20250314T090030.512.json"
    seven = store_path(tmp_path, "d", t0.replace(microsecond=7), "ros")
    assert seven.name == "d_20250314T090030.000007.ros.yaml"
    assert store_path(tmp_path, "SparkFun_1", t0, "imucal").name == "sparkfun1_2025-03-14_09-00.json"
    p.parent.mkdir()
    p.write_text("x")
    older = tmp_path / "SparkFun_1" / "SparkFun_1_20250314T090030.imucal.json"  # before imucal's layout
    older.write_text("x")
    got = stored_calibrations(tmp_path, "SparkFun_1")
    assert [(w, f, q.name) for w, f, q in got] == [
        (t0.replace(microsecond=0), "imucal", older.name), (t0, "json", p.name)]
    assert find_calibration(tmp_path, "SparkFun_1", t0 - timedelta(microseconds=1)) == older
    assert find_calibration(tmp_path, "SparkFun_1", t0) == p
    with pytest.raises(CalibrationStoreError, match="at least one letter or digit"):
        store_path(tmp_path, "-_-", t0, "imucal")


def test_an_offset_model_says_it_fits_no_map_not_that_poses_were_too_few(campaign, tmp_path) -> None:
    """Issue 36: a forced ``offset`` on many distinct poses was exported as "too few distinct poses"."""
    reason = "forced by fit_model: offset (24 poses in 24 directions)"
    for f in sorted((campaign / "labels" / "mp").glob("*.parquet")):
        table = pq.read_table(f)
        frame = table.to_pandas()
        frame["fit_model"] = "offset"
        frame["fit_model_reason"] = reason
        frame[list(MATRIX_COLUMNS)] = np.nan
        frame[["scale_x", "scale_y", "scale_z"]] = np.nan
        out = pa.Table.from_pandas(frame, schema=table.schema, preserve_index=False)
        pq.write_table(out, tmp_path / f.name)
    for r in results_from_labels(tmp_path).results:
        assert not r.scale_known and r.scale == (1.0, 1.0, 1.0)
        assert r.scale_note == ("A identity: the offset fit determined no map (the model fits offsets only: "
                                f"{reason})")
