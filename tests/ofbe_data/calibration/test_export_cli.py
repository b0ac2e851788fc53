"""``ofbe-export``: every calibration format from labels, the output and store layouts, one-line
errors with nothing partial written, and the format registry (ofbe-predict's JSON and the model
formats: tests/ofbe_model/cli/test_export_cli.py; an ofbe-autocal folder: test_autocal_exports.py)."""

from __future__ import annotations

import json
import os
from datetime import timedelta
from importlib.metadata import EntryPoint
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from ofbe_data import find_calibration
from ofbe_data.calibration import exports, registry
from ofbe_data.calibration.formats import FORMAT_EXTENSIONS, GGIR_BACKUP_FILE, ggir_read_settings
from ofbe_data.calibration.output import ExportFile
from ofbe_data.calibration.results import TIME_RAW
from ofbe_data.cli import export
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.manifest import load_manifest
from ofbe_data.labelling.batch import expand_sessions, label_sessions
from ofbe_data.labelling.labels import LabelParams
from ofbe_data.labelling.store import read_labels
from tests.helpers.exports import kalibr_imu_parameters
from tests.helpers.ggir_replica import backup_cal_coef, read_myacc_csv


@pytest.fixture(scope="module")
def campaign(tiny_labelled) -> Path:
    """The session's tiny labelled campaigns (conftest.py): ``raw/mp``, ``raw/ga``, ``labels/mp``,
    ``labels/ga``."""
    return tiny_labelled


def _run(capsys, *argv: str | Path) -> tuple[int, str, str]:
    code = export.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("name", ["imucal", "ros", "json"])
def test_each_format_writes_one_file_per_device_and_power_cycle(tmp_path, campaign, capsys, name) -> None:
    code, out, err = _run(capsys, name, campaign / "labels" / "mp", "--out", tmp_path / "out")
    assert code == 0, err
    ending = FORMAT_EXTENSIONS[name]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        f"sparkfun-1.pc1.{ending}", f"sparkfun-1.pc2.{ending}"]
    assert out.split() == [str(tmp_path / "out")] and "2 result files written" in err


def test_kalibr_from_labels_and_raw(tmp_path, campaign, capsys) -> None:
    code, _, err = _run(capsys, "kalibr", campaign / "labels" / "ga", "--raw", campaign / "raw" / "ga",
                        "--out", tmp_path / "k", "--rostopic", "/dut/imu",
                        "--gyro-noise-density", "1.7e-4", "--gyro-random-walk", "2e-5")
    assert code == 0, err
    files = sorted((tmp_path / "k").iterdir())
    assert [p.name for p in files] == [f"sparkfun-{d}.pc{c}.kalibr.yaml" for d in (1, 2) for c in (1, 2, 3)]
    kalibr = kalibr_imu_parameters(files[0].read_bytes())  # Kalibr's own reader takes every file
    assert kalibr["rostopic"] == "/dut/imu" and 0.002 < kalibr["accelerometer_noise_density"] < 0.006
    assert kalibr["gyroscope_noise_density"] == 1.7e-4 and kalibr["gyroscope_random_walk"] == 2e-5
    assert "UPPER BOUND" in files[0].read_text()


GYRO_SIGMA_DPS = (0.05, 0.08, 0.03)
"""Per-axis white angular-rate noise of the gyroscope session, deg/s rms per sample."""


@pytest.fixture(scope="module")
def gyro_session(tmp_path_factory) -> Path:
    """A generic-csv gravity-aligned session of a board that logs its gyroscope (deg/s) beside the
    accelerometer (g): 90 s at 100 Hz, white noise of known level on both, labelled."""
    tmp = tmp_path_factory.mktemp("gyro")
    folder = tmp / "raw" / "bench" / "s1"
    folder.mkdir(parents=True)
    rng = np.random.default_rng(11)
    n, fs = 9000, 100.0
    acc = np.array([0.002, -0.003, 1.004]) + 0.002 * rng.standard_normal((n, 3))
    gyro = np.array([0.4, -0.2, 0.1]) + np.array(GYRO_SIGMA_DPS) * rng.standard_normal((n, 3))
    rows = [f"{i / fs:.2f},{a[0]:.6f},{a[1]:.6f},{a[2]:.6f},{g[0]:.5f},{g[1]:.5f},{g[2]:.5f}"
            for i, (a, g) in enumerate(zip(acc, gyro, strict=True))]
    (folder / "r1.csv").write_text("time,ACC_X,ACC_Y,ACC_Z,GYR_X,GYR_Y,GYR_Z\n" + "\n".join(rows) + "\n")
    (folder / "session.yaml").write_text(
        "format: ofbe-session/1\ncampaign: bench\nsession: s1\nkind: gravity-aligned\n"
        "site: {gravity_mps2: 9.80665}\npower_cycle: 1\ndevices:\n  board:\n    model: MPU-6050\n"
        "    role: dut\n    format: csv\n    columns: {t: time, ax: ACC_X, ay: ACC_Y, az: ACC_Z, gx: GYR_X, "
        "gy: GYR_Y, gz: GYR_Z}\n    acc_unit: g\n    gyro_unit: deg/s\n"
        "recordings:\n  - id: r1\n    files: {board: r1.csv}\n")
    outcomes = label_sessions(expand_sessions([tmp / "raw" / "bench"]), LabelParams(min_samples=1000),
                              tmp / "labels", jobs=1, progress=False)
    assert [o.error for o in outcomes if o.error] == []
    return tmp


def test_kalibr_reads_the_gyroscope_columns(tmp_path, gyro_session, capsys) -> None:
    """The gyroscope's noise density comes from its own columns (deg/s → rad/s) within 10 % of
    the generated level; the user's flag, where given, wins and is said so."""
    code, _, err = _run(capsys, "kalibr", gyro_session / "labels" / "bench", "--raw",
                        gyro_session / "raw" / "bench", "--out", tmp_path / "k.yaml")
    assert code == 0, err
    kalibr = kalibr_imu_parameters((tmp_path / "k.yaml").read_bytes())
    expected = max(GYRO_SIGMA_DPS) * np.pi / 180 / np.sqrt(100.0)
    assert abs(kalibr["gyroscope_noise_density"] / expected - 1) < 0.10, kalibr
    assert abs(kalibr["accelerometer_noise_density"] / (0.002 * 9.80665 / 10) - 1) < 0.10, kalibr
    assert 0 < kalibr["gyroscope_random_walk"] < 1e-3  # the flagged upper bound of 90 s of data
    text = (tmp_path / "k.yaml").read_text()
    assert "# gyroscope_random_walk [rad/s^2/sqrt(Hz)]: UPPER BOUND" in text
    code, _, err = _run(capsys, "kalibr", gyro_session / "labels" / "bench", "--raw",
                        gyro_session / "raw" / "bench", "--out", tmp_path / "k2.yaml",
                        "--gyro-random-walk", "3e-5")
    assert code == 0, err
    again = kalibr_imu_parameters((tmp_path / "k2.yaml").read_bytes())
    assert again["gyroscope_random_walk"] == 3e-5
    assert again["gyroscope_noise_density"] == kalibr["gyroscope_noise_density"]


def test_kalibr_without_gyroscope_data_asks_for_the_values(tmp_path, campaign, capsys) -> None:
    code, out, err = _run(capsys, "kalibr", campaign / "labels" / "ga", "--raw", campaign / "raw" / "ga",
                          "--out", tmp_path / "k", "--gyro-noise-density", "1e-4")
    assert code == 2 and out == "" and err.count("\n") == 1, err
    assert "the raw files have no gyroscope columns; give --gyro-random-walk (datasheet values" in err
    assert not (tmp_path / "k").exists()
    with pytest.raises(SystemExit) as exit_:
        _run(capsys, "kalibr", campaign / "labels" / "ga", "--raw", campaign / "raw" / "ga",
             "--out", tmp_path / "k", "--gyro-noise-density", "-1")
    assert exit_.value.code == 2 and "expected a positive number, found '-1'" in capsys.readouterr().err


def test_ggir_writes_one_backup_cal_coef_per_run(tmp_path, campaign, capsys, monkeypatch) -> None:
    """Issue 33: GGIR takes one ``backup.cal.coef`` file (g.part1's parameter), so one export run
    writes one, with a row per raw file of every device and power cycle; ``--store`` still files
    each device and power cycle's own rows by its recording time."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1750000000")
    labels, raw = campaign / "labels" / "ga", campaign / "raw" / "ga"
    code, out, err = _run(capsys, "ggir", labels, "--out", f"{tmp_path / 'g'}/")
    assert code == 0, err
    assert [p.name for p in (tmp_path / "g").iterdir()] == [GGIR_BACKUP_FILE]
    assert "1 result file written" in err
    data = (tmp_path / "g" / GGIR_BACKUP_FILE).read_bytes()
    table = pd.read_csv(tmp_path / "g" / GGIR_BACKUP_FILE)
    assert set(zip(table["device"], table["power_cycle"], strict=True)) == {
        (f"sparkfun-{d}", c) for d in (1, 2) for c in (1, 2, 3)}
    for name in table["filename"]:  # GGIR's own look-up finds every data file's row
        assert backup_cal_coef(data, name).scale.shape == (3,)
    code, _, err = _run(capsys, "ggir", labels, "--out", tmp_path / "mine.csv")  # a file name: that file
    assert code == 0 and (tmp_path / "mine.csv").read_bytes() == data
    code, out, err = _run(capsys, "ggir", labels, "--raw", raw, "--store", tmp_path / "store")
    assert code == 0, err
    filed = sorted((tmp_path / "store").rglob("*.ggir.csv"))
    assert len(filed) == 6 and out.split() == [str(p) for p in sorted(filed)] and "6 result files" in err
    for path in filed:
        rows = pd.read_csv(path)
        assert len(rows) == 1 and rows["device"][0] == path.parent.name
        assert backup_cal_coef(path.read_bytes(), rows["filename"][0]).scale.shape == (3,)


@pytest.fixture(scope="module")
def hostile_session(tmp_path_factory) -> Path:
    """Two power cycles of two loggers, 60 s at 150 Hz each, labelled, whose raw files hold what
    the serial link does to real ones: boot noise, a truncated line, a 0xFF byte, a non-numeric
    field, dropped samples."""
    tmp = tmp_path_factory.mktemp("hostile")
    rng = np.random.default_rng(5)
    for pc in (1, 2):
        folder = tmp / "raw" / "bench" / f"s{pc}"
        (folder / "rec-01").mkdir(parents=True)
        for d in (1, 2):
            n = 9000
            t_us = 4093012 + np.round(np.arange(n) * 1e6 / 150).astype(np.int64)
            counts = np.round(np.array([3 * d, -5, 259]) + 1.4 * rng.standard_normal((n, 3))).astype(int)
            lines = [f"{t},{x},{y},{z}".encode() for t, (x, y, z) in zip(t_us, counts, strict=True)]
            lines[1000] = lines[1000][:9]
            lines[2000] = lines[2000][:3] + b"\xff" + lines[2000][3:]
            lines[3000] = lines[3000].replace(b",", b",x", 1)
            del lines[4000:4003]
            head = (f"ets Jun  8 2016 00:22:57\r\n# ofbe-logger fw=1.4.2 board=sparkfun-thing-plus-esp32 "
                    f"chip=ADXL345 device=sparkfun-{d}\n# odr_hz=150 range_g=16 full_res=1 lsb_per_g=256\n"
                    f"# host_start_utc=2025-03-1{pc}T10:22:31.{100 * d}Z\nt_us,ax,ay,az\n").encode()
            (folder / "rec-01" / f"sparkfun-{d}.csv").write_bytes(head + b"\n".join(lines) + b"\n")
        (folder / "session.yaml").write_text(
            f"format: ofbe-session/1\ncampaign: bench\nsession: s{pc}\nkind: gravity-aligned\n"
            f"site: {{gravity_mps2: 9.80665}}\npower_cycle: {pc}\ndevices:\n"
            "  sparkfun-1: {model: ADXL345, role: dut, format: ofbe-logger}\n"
            "  sparkfun-2: {model: ADXL345, role: dut, format: ofbe-logger}\n"
            "recordings:\n  - id: rec-01\n"
            "    files: {sparkfun-1: rec-01/sparkfun-1.csv, sparkfun-2: rec-01/sparkfun-2.csv}\n")
    outcomes = label_sessions(expand_sessions([tmp / "raw" / "bench"]), LabelParams(min_samples=1000),
                              tmp / "labels", jobs=1, progress=False)
    assert [o.error for o in outcomes if o.error] == []
    return tmp


def test_ggir_data_rebuilds_the_raw_files_for_ggirs_reader(tmp_path, hostile_session, capsys) -> None:
    """Issue 33: ``--ggir-data`` used to copy the raw files byte for byte, and GGIR's csv reader
    stops at the first garbled line or fails on a 0xFF byte. Now each file is rebuilt from the
    samples ofbe's validating reader kept, under the name of its backup.cal.coef row: GGIR's
    reading with the README's rmc.* settings (replicated) takes every line, and the values are
    the reader's, bit for bit."""
    labels, raw = hostile_session / "labels" / "bench", hostile_session / "raw" / "bench"
    code, _, err = _run(capsys, "ggir", labels, "--out", tmp_path / "plain.csv")
    assert code == 0 and "pass --ggir-data --raw DIR to have them rebuilt" in err
    code, _, err = _run(capsys, "ggir", labels, "--out", tmp_path / "g", "--raw", raw, "--ggir-data")
    assert code == 0, err
    assert "4 raw files rebuilt into ggir-data/" in err
    out = tmp_path / "g"
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [GGIR_BACKUP_FILE, exports.GGIR_DATA, exports.GGIR_DATA_README])
    backup = (out / GGIR_BACKUP_FILE).read_bytes()
    table = pd.read_csv(out / GGIR_BACKUP_FILE)
    written = sorted(p.name for p in (out / "ggir-data").iterdir())
    assert written == sorted(table["filename"]) and len(written) == 4  # one GGIR row per data file
    settings = ggir_read_settings(with_temperature=False)
    readme = (out / exports.GGIR_DATA_README).read_text()
    assert all(f"{key} = {value}" in readme for key, value in settings.items())
    assert f'backup.cal.coef = "{GGIR_BACKUP_FILE}"' in readme
    for name, raw_file, device in zip(table["filename"], table["raw_file"], table["device"], strict=True):
        m = load_manifest(raw / raw_file.split("/")[0])
        rec = read_device_file(raw / raw_file, m.devices[device])
        assert len(rec.diagnostics.skipped) == 3  # the raw file is hostile
        data = (out / "ggir-data" / name).read_bytes()
        sf, frame = read_myacc_csv(data, settings, name)
        assert sf == 150.0 and len(frame) == rec.n == 9000 - 3 - 3
        np.testing.assert_array_equal(frame[["x", "y", "z"]].to_numpy(), rec.acc / 9.80665)
        assert rec.start_utc is not None
        np.testing.assert_allclose(frame["time"] - rec.start_utc.timestamp(), rec.t - rec.t[0], atol=1e-6)
        assert backup_cal_coef(backup, name).offset.shape == (3,)
    code, _, err = _run(capsys, "ggir", labels, "--out", tmp_path / "h", "--ggir-data")
    assert code == 2 and "--ggir-data needs --raw DIR" in err and not (tmp_path / "h").exists()
    changed = raw / "s2" / "rec-01" / "sparkfun-2.csv"
    original = changed.read_bytes()
    try:
        changed.write_bytes(original.replace(b"\n4", b"\n5", 1))
        code, _, err = _run(capsys, "ggir", labels, "--out", tmp_path / "k", "--raw", raw, "--ggir-data")
        assert code == 1 and "expected the bytes that were labelled" in err and not (tmp_path / "k").exists()
    finally:
        changed.write_bytes(original)


def test_one_result_goes_to_the_file_named(tmp_path, campaign, capsys) -> None:
    from imucal.management import load_calibration_info

    target = tmp_path / "sub" / "cal.json"
    code, _, err = _run(capsys, "imucal", campaign / "labels" / "mp" / "mp-pc001.parquet", "--out", target)
    assert code == 0, err
    cal = load_calibration_info(target)
    labels = read_labels(campaign / "labels" / "mp" / "mp-pc001.parquet")
    assert np.array_equal(cal.b_a, labels[["offset_x", "offset_y", "offset_z"]].to_numpy()[0])
    code, _, err = _run(capsys, "json", campaign / "labels" / "mp" / "mp-pc001.parquet", "--out", tmp_path)
    assert code == 0 and (tmp_path / "sparkfun-1.pc1.json").is_file()  # an existing folder: file inside


def test_outputs_are_never_partial_or_silently_replaced(tmp_path, campaign, capsys) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / "sparkfun-1.pc1.ros.yaml").write_text("mine")
    code, _, err = _run(capsys, "ros", campaign / "labels" / "mp", "--out", out)
    assert code == 1 and "--force" in err and err.count("\n") == 1
    assert sorted(p.name for p in out.iterdir()) == ["sparkfun-1.pc1.ros.yaml"]  # nothing else written
    assert (out / "sparkfun-1.pc1.ros.yaml").read_text() == "mine"
    assert _run(capsys, "ros", campaign / "labels" / "mp", "--out", out, "--force")[0] == 0
    assert yaml.safe_load((out / "sparkfun-1.pc1.ros.yaml").read_text())["/**"]["ros__parameters"][
        "power_cycle"] == 1
    code, _, err = _run(capsys, "json", campaign / "labels" / "mp", "--out", tmp_path / "one.json")
    assert code == 2 and "expected a folder for 2 files" in err and not (tmp_path / "one.json").exists()


def test_store_files_by_recording_time_and_finds_the_one_in_force(tmp_path, campaign, capsys) -> None:
    store = tmp_path / "store"
    code, out, err = _run(capsys, "json", campaign / "labels" / "ga", "--raw", campaign / "raw" / "ga",
                          "--store", store)
    assert code == 0, err
    files = sorted((store / "sparkfun-1").iterdir())
    assert len(files) == 3 and out.split() == [str(p) for p in sorted(store.rglob("*.json"))]
    docs = [json.loads(p.read_text()) for p in files]
    assert [d["power_cycle"] for d in docs] == [1, 2, 3] and {d["time_source"] for d in docs} == {TIME_RAW}
    m = load_manifest(campaign / "raw" / "ga" / "ga-pc002")
    start = read_device_file(m.file_path(m.recordings[0], "sparkfun-1"), m.devices["sparkfun-1"]).start_utc
    assert start.microsecond != 0  # the simulated header stamps have milliseconds: kept to the microsecond
    stamp = start.strftime('%Y%m%dT%H%M%S') + "." + f"{start.microsecond:06d}".rstrip("0")
    assert files[1].name == f"sparkfun-1_{stamp}.json" and docs[1]["time_utc"] == (
        start.strftime("%Y-%m-%dT%H:%M:%S") + stamp[15:] + "Z")
    assert find_calibration(store, "sparkfun-1", start + timedelta(minutes=5)) == files[1]
    assert find_calibration(store, "sparkfun-1", start) == files[1]
    assert find_calibration(store, "sparkfun-1", start - timedelta(microseconds=1000)) == files[0]


def test_imucal_store_is_found_by_imucal_itself(tmp_path, campaign, capsys) -> None:
    """imucal files go into the store under imucal's own names, so that imucal's
    find_calibration_info_for_sensor and find_closest_calibration_info_to_date find them."""
    from imucal.management import (
        find_calibration_info_for_sensor,
        find_closest_calibration_info_to_date,
        load_calibration_info,
    )

    store = tmp_path / "store"
    code, _, err = _run(capsys, "imucal", campaign / "labels" / "ga", "--raw", campaign / "raw" / "ga",
                        "--store", store)
    assert code == 0, err
    for device, sensor in (("sparkfun-1", "sparkfun1"), ("sparkfun-2", "sparkfun2")):
        found = sorted(find_calibration_info_for_sensor(sensor, store))
        assert found == sorted((store / device).iterdir()) and len(found) == 3
        labels = read_labels(campaign / "labels" / "ga")
        for pc in (1, 2, 3):
            m = load_manifest(campaign / "raw" / "ga" / f"ga-pc00{pc}")
            start = read_device_file(m.file_path(m.recordings[0], device), m.devices[device]).start_utc
            path = find_closest_calibration_info_to_date(sensor, start.replace(tzinfo=None), store)
            assert path.name == f"{sensor}_{start.strftime('%Y-%m-%d_%H-%M')}.json"
            assert find_calibration(store, device, start, "imucal") == path  # ofbe's look-up agrees
            rows = labels[(labels.device == device) & (labels.power_cycle == pc)]
            bias = rows[["bias_x", "bias_y", "bias_z"]].to_numpy().mean(axis=0)
            np.testing.assert_allclose(load_calibration_info(path).b_a, bias, rtol=0, atol=1e-12)


def test_store_collisions_write_nothing(tmp_path, campaign, capsys) -> None:
    """Without --raw the label files' times file the results; two power cycles written in the
    same second collide, and then neither --out nor the store gets anything."""
    labels = tmp_path / "labels"
    labels.mkdir()
    for f in (campaign / "labels" / "mp").glob("*.parquet"):
        (labels / f.name).write_bytes(f.read_bytes())
        os.utime(labels / f.name, (1_700_000_000, 1_700_000_000))
    code, _, err = _run(capsys, "ros", labels, "--out", tmp_path / "out", "--store", tmp_path / "store")
    assert code == 1 and "pass --raw" in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists() and not (tmp_path / "store").exists()


def test_usage_and_data_errors_are_one_line(tmp_path, campaign, capsys) -> None:
    code, _, err = _run(capsys, "json", campaign / "labels" / "mp")
    assert code == 2 and "--out PATH or --store DIR" in err
    code, _, err = _run(capsys, "json", tmp_path / "missing", "--out", tmp_path / "o")
    assert code == 1 and err.count("\n") == 1 and "no such path" in err
    with pytest.raises(SystemExit) as exc:
        export.main(["--help"])
    text = capsys.readouterr().out
    assert exc.value.code == 0 and all(f"  {name} " in text for name in exports.export_names())


def _two_files(args) -> list[ExportFile]:
    return [ExportFile("model.bin", b"\x00\x01"), ExportFile("model.json", b"{}")]


DUMMY = registry.Format(_two_files, "two files")
"""A toy format another package would register through the entry-point group."""


def test_a_new_format_is_one_entry_point(tmp_path, campaign, capsys, monkeypatch) -> None:
    """The extension point the model formats use: an entry point of ``ofbe.export_formats``
    naming a Format; writing shared. One that names something else is refused, naming it."""
    real = registry.entry_points

    def with_dummy(group: str):
        extra = EntryPoint("dummy", f"{__name__}:DUMMY", group)
        return (*real(group=group), extra)

    monkeypatch.setattr(registry, "entry_points", with_dummy)
    code, _, err = _run(capsys, "dummy", campaign / "labels" / "mp", "--out", tmp_path / "d",
                        "--store", tmp_path / "s")
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "d").iterdir()) == ["model.bin", "model.json"]
    assert not (tmp_path / "s").exists()  # not storable: no device or time
    monkeypatch.setattr(registry, "entry_points",
                        lambda group: (EntryPoint("odd", f"{__name__}:_two_files", group),))
    code, _, err = _run(capsys, "json", campaign / "labels" / "mp", "--out", tmp_path / "e")
    assert code == 1 and err == (f"ofbe-export: error: entry point odd = '{__name__}:_two_files' of "
                                 "ofbe.export_formats: expected a Format (ofbe_data.calibration.registry), "
                                 "found function\n")
    monkeypatch.setattr(registry, "entry_points",
                        lambda group: (EntryPoint("ros", f"{__name__}:DUMMY", group),))
    code, _, err = _run(capsys, "json", campaign / "labels" / "mp", "--out", tmp_path / "e")
    assert code == 1 and "entry points ros: expected new format names" in err
    assert not (tmp_path / "e").exists()
