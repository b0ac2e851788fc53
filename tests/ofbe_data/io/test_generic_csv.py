"""The generic csv reader on the layouts real loggers write (raw-formats.md §Generic csv).

Every file is built here as text, with known values, so each assertion checks a number the
reader must reproduce (units, time base, line numbers of what it skipped).
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from ofbe_data.core.errors import ManifestError, RawFormatError
from ofbe_data.io.formats.generic_csv import read_generic_csv
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import CsvMapping, load_manifest
from ofbe_data.io.recording import TEMPERATURE

RNG = np.random.default_rng(7)
N = 500
FS = 100.0
TRUE_G = np.array([0.02, -0.03, 0.999])  # a resting reading in g


def _readings_g(n: int = N) -> np.ndarray:
    return TRUE_G + RNG.normal(0.0, 0.004, size=(n, 3))


def _write(tmp_path: Path, name: str, text: str | bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(text.encode("utf-8") if isinstance(text, str) else text)
    return path


def test_headerless_whitespace_unsigned_counts_offset_binary(tmp_path: Path) -> None:
    lsb = np.array([16384.0, 16500.0, 16300.0])  # a ±2 g 16-bit ADC, per-axis sensitivity
    zero = 32768.0
    g = _readings_g()
    counts = np.rint(g * lsb + zero).astype(int)
    lines = [f"  {i * 10}\t{c[0]}   {c[1]} \t{c[2]}  " for i, c in enumerate(counts)]  # t in ms
    path = _write(tmp_path, "adc.txt", "\n".join(lines) + "\n")
    mapping = CsvMapping({"t": 0, "ax": 1, "ay": 2, "az": 3}, "ms", "counts", (16384.0, 16500.0, 16300.0),
                         delimiter="whitespace", header=False, zero_counts=zero)
    rec = read_generic_csv(path, mapping)
    assert rec.n == N and rec.diagnostics.preamble_lines == 0
    np.testing.assert_allclose(rec.acc, (counts - zero) / lsb * G0, rtol=0, atol=1e-12)
    assert rec.fs_hz == pytest.approx(100.0)
    assert rec.line[0] == 1 and rec.line[-1] == N


def test_time_as_sample_index(tmp_path: Path) -> None:
    g = _readings_g()
    text = "sample,ax,ay,az\n" + "".join(f"{i + 1000},{a:.6f},{b:.6f},{c:.6f}\n"
                                         for i, (a, b, c) in enumerate(g))
    mapping = CsvMapping({"t": "sample", "ax": "ax", "ay": "ay", "az": "az"}, "samples", "g",
                         sample_rate_hz=50.0)
    rec = read_generic_csv(_write(tmp_path, "idx.csv", text), mapping)
    assert rec.t[0] == pytest.approx(20.0) and rec.t[1] - rec.t[0] == pytest.approx(0.02)
    assert rec.fs_hz == pytest.approx(50.0) and rec.nominal_rate_hz == 50.0
    np.testing.assert_allclose(rec.acc, np.round(g, 6) * G0, atol=1e-12)


def test_epoch_nanoseconds_give_the_utc_start(tmp_path: Path) -> None:
    t0 = 1_741_947_751_100_000_000  # 2025-03-14T10:22:31.1Z
    g = _readings_g()
    text = "ts,x,y,z\n" + "".join(f"{t0 + i * 10_000_000},{a:.5f},{b:.5f},{c:.5f}\n"
                                   for i, (a, b, c) in enumerate(g))
    mapping = CsvMapping({"t": "ts", "ax": "x", "ay": "y", "az": "z"}, "ns", "g")
    rec = read_generic_csv(_write(tmp_path, "ns.csv", text), mapping)
    assert rec.fs_hz == pytest.approx(100.0, rel=1e-6)
    assert rec.start_utc is not None
    assert abs((rec.start_utc - datetime(2025, 3, 14, 10, 22, 31, 100000, tzinfo=UTC)).total_seconds()) < 1e-3
    assert not rec.diagnostics.gaps


def test_mg_units(tmp_path: Path) -> None:
    g = _readings_g()
    text = "t,ax_mg,ay_mg,az_mg\n" + "".join(f"{i / FS:.2f},{a * 1000:.2f},{b * 1000:.2f},{c * 1000:.2f}\n"
                                           for i, (a, b, c) in enumerate(g))
    mapping = CsvMapping({"t": "t", "ax": "ax_mg", "ay": "ay_mg", "az": "az_mg"}, "s", "mg")
    rec = read_generic_csv(_write(tmp_path, "mg.csv", text), mapping)
    np.testing.assert_allclose(rec.acc, np.round(g * 1000, 2) * G0 / 1000, atol=1e-12)


def test_rate_preamble_without_time_column_and_a_garbled_line(tmp_path: Path) -> None:
    g = _readings_g(10)
    rows = [f"{a:.4f},{b:.4f},{c:.4f}" for a, b, c in g]
    rows[4] = "0.0201,-0.03#!,0.99"  # garbled: skipped, leaving a one-sample gap
    path = _write(tmp_path, "fs.csv", "Fs,100\nAccX,AccY,AccZ\n" + "\n".join(rows) + "\n")
    mapping = CsvMapping({"ax": "AccX", "ay": "AccY", "az": "AccZ"}, acc_unit="g", skip_rows=1,
                         sample_rate_hz=100.0)
    rec = read_generic_csv(path, mapping)
    assert rec.n == 9
    np.testing.assert_allclose(rec.t, np.delete(np.arange(10) / 100.0, 4), atol=1e-15)
    assert [s.line for s in rec.diagnostics.skipped] == [7]  # file line of the garbled row
    assert rec.diagnostics.gaps[0].line == 8 and rec.diagnostics.gaps[0].missing_samples == 1
    assert rec.fs_hz == pytest.approx(100.0)


def test_host_clock_jitter_is_reported_not_resampled(tmp_path: Path) -> None:
    steps = 0.01 + RNG.uniform(-0.003, 0.003, size=N - 1)
    steps[200] = 0.05  # a real dropout of four samples
    t = np.concatenate(([0.0], np.cumsum(steps)))
    g = _readings_g()
    text = "time,ax,ay,az\n" + "".join(f"{ti:.6f},{a:.5f},{b:.5f},{c:.5f}\n"
                                       for ti, (a, b, c) in zip(t, g, strict=True))
    mapping = CsvMapping({"t": "time", "ax": "ax", "ay": "ay", "az": "az"}, "s", "g")
    rec = read_generic_csv(_write(tmp_path, "host.csv", text), mapping)
    np.testing.assert_allclose(rec.t, np.round(t, 6), atol=1e-12)  # as logged, never resampled
    assert len(rec.diagnostics.gaps) == 1 and rec.diagnostics.gaps[0].line == 203  # sample 201
    assert rec.fs_hz == pytest.approx((N - 1 + 4) / (rec.t[-1] - rec.t[0]))  # the dropout counts
    assert float(rec.header["step_cv"]) > 0.1
    assert rec.header["step_max_s"] == "0.05"


def test_quoted_names_trailing_comma_crlf_bom(tmp_path: Path) -> None:
    g = _readings_g(20)
    text = '\ufeff"Time (s)","Accel X (g)","Accel Y (g)","Accel Z (g)",\r\n' + "".join(
        f"{i / FS:.2f},{a:.5f},{b:.5f},{c:.5f},\r\n" for i, (a, b, c) in enumerate(g))
    mapping = CsvMapping({"t": "Time (s)", "ax": "Accel X (g)", "ay": "Accel Y (g)", "az": "Accel Z (g)"},
                         "s", "g")
    rec = read_generic_csv(_write(tmp_path, "quoted.csv", text), mapping)
    assert rec.n == 20 and not rec.diagnostics.skipped
    np.testing.assert_allclose(rec.acc, np.round(g, 5) * G0, atol=1e-12)


def test_comments_anywhere_keep_line_numbers(tmp_path: Path) -> None:
    g = _readings_g(6)
    rows = [f"{i / FS:.2f};{a:.4f};{b:.4f};{c:.4f}" for i, (a, b, c) in enumerate(g)]
    rows.insert(3, "% paused by operator")
    rows[5] = "0.04;x;0.0;1.0"
    text = "% logger v2\n% range 2g\nt;ax;ay;az\n" + "\n".join(rows) + "\n"
    mapping = CsvMapping({"t": "t", "ax": "ax", "ay": "ay", "az": "az"}, "s", "g", delimiter=";",
                         comment="%")
    rec = read_generic_csv(_write(tmp_path, "comments.csv", text), mapping)
    assert rec.n == 5
    assert [s.line for s in rec.diagnostics.skipped] == [9]
    assert list(rec.line) == [4, 5, 6, 8, 10]
    assert rec.diagnostics.preamble_lines == 3


def test_decimal_comma_with_semicolons(tmp_path: Path) -> None:
    text = "t;ax;ay;az\n0,00;0,01;-0,02;1,001\n0,01;0,02;-0,01;0,999\n"
    mapping = CsvMapping({"t": "t", "ax": "ax", "ay": "ay", "az": "az"}, "s", "g", delimiter=";")
    rec = read_generic_csv(_write(tmp_path, "eu.csv", text), mapping)
    np.testing.assert_allclose(rec.acc[1], np.array([0.02, -0.01, 0.999]) * G0, atol=1e-12)


def test_temperature_in_fahrenheit_becomes_celsius(tmp_path: Path) -> None:
    text = "t,ax,ay,az,temp\n" + "".join(f"{i / FS:.2f},0,0,9.8,{77.0 + (i % 2) * 1.8:.1f}\n"
                                          for i in range(10))
    mapping = CsvMapping({"t": "t", "ax": "ax", "ay": "ay", "az": "az", "temperature": "temp"},
                         temperature_unit="F")
    rec = read_generic_csv(_write(tmp_path, "temp.csv", text), mapping)
    np.testing.assert_allclose(rec.extra[TEMPERATURE], [25.0, 26.0] * 5, atol=1e-12)


def test_gyroscope_columns_in_degrees_become_rad_per_s(tmp_path: Path) -> None:
    text = "t,ax,ay,az,wx,wy,wz\n" + "".join(f"{i / FS:.2f},0,0,9.8,{i % 3},-90,180\n" for i in range(6))
    mapping = CsvMapping({"t": "t", "ax": "ax", "ay": "ay", "az": "az", "gx": "wx", "gy": "wy", "gz": "wz"},
                         gyro_unit="deg/s")
    rec = read_generic_csv(_write(tmp_path, "gyro.csv", text), mapping)
    gyro = rec.gyro()
    assert gyro is not None
    np.testing.assert_allclose(gyro, np.radians([[i % 3, -90, 180] for i in range(6)]), rtol=1e-15)
    plain = read_generic_csv(tmp_path / "gyro.csv",
                             CsvMapping({"t": "t", "ax": "ax", "ay": "ay", "az": "az"}))
    assert plain.gyro() is None


def test_range_g_marks_saturated_samples(tmp_path: Path) -> None:
    text = "t,ax,ay,az\n0.00,0,0,1.0\n0.01,0,0,1.999\n0.02,0,2.0,1.0\n0.03,0,0,1.0\n"
    mapping = CsvMapping({"t": "t", "ax": "ax", "ay": "ay", "az": "az"}, "s", "g", range_g=2.0)
    rec = read_generic_csv(_write(tmp_path, "clip.csv", text), mapping)
    assert list(rec.saturated) == [False, True, True, False]
    assert rec.diagnostics.saturated_samples == 2


@pytest.mark.parametrize(("text", "mapping", "message"), [
    ("time,x,y\n0,1,2\n", CsvMapping({"t": "time", "ax": "x", "ay": "y", "az": "z"}),
     "bad.csv:1: expected columns time, x, y, z, found 'time,x,y' (missing z)"),
    ("0 1 2\n", CsvMapping({"t": 0, "ax": 1, "ay": 2, "az": 3}, header=False, delimiter="whitespace"),
     "bad.csv:1: expected a column 3 (az, 0-based) in the first data line, found 3 fields"),
    ("Fs,100\n", CsvMapping({"ax": "a", "ay": "b", "az": "c"}, skip_rows=1, sample_rate_hz=100.0),
     "bad.csv: expected 1 preamble rows (skip_rows) and then data, found 1 lines in all"),
    ("# only\n# comments\n", CsvMapping({"t": "t", "ax": "a", "ay": "b", "az": "c"}, comment="#"),
     "bad.csv: expected a column line and data lines, found only preamble, comment or blank lines"),
])
def test_structural_errors_name_file_and_line(tmp_path: Path, text: str, mapping: CsvMapping,
                                              message: str) -> None:
    with pytest.raises(RawFormatError) as err:
        read_generic_csv(_write(tmp_path, "bad.csv", text), mapping)
    assert str(err.value).endswith(message), str(err.value)


def _manifest(tmp_path: Path, device_keys: str) -> Path:
    folder = tmp_path / "camp" / "s1"
    folder.mkdir(parents=True)
    (folder / "session.yaml").write_text(
        "format: ofbe-session/1\ncampaign: camp\nsession: s1\nkind: gravity-aligned\n"
        "site: {gravity_mps2: 9.8}\npower_cycle: 1\ndevices:\n  dut:\n    model: X\n    role: dut\n"
        f"    format: csv\n{device_keys}recordings:\n  - id: r1\n    files: {{dut: r1.csv}}\n",
        encoding="utf-8")
    return folder


@pytest.mark.parametrize(("keys", "message"), [
    ("    columns: {ax: a, ay: b, az: c}\n",
     "devices.dut.sample_rate_hz: expected the sample rate in Hz (no t column), found it missing"),
    ("    columns: {t: n, ax: a, ay: b, az: c}\n    time_unit: samples\n",
     "devices.dut.sample_rate_hz: expected the sample rate in Hz (time_unit: samples), found it missing"),
    ("    columns: {t: t, ax: a, ay: b, az: c}\n    acc_unit: g\n    lsb_per_g: 256\n",
     "devices.dut.lsb_per_g: expected no lsb_per_g unless acc_unit is counts, found acc_unit g"),
    ("    columns: {t: t, ax: a, ay: b, az: c}\n    acc_unit: counts\n    lsb_per_g: [256, 256]\n",
     "devices.dut.lsb_per_g: expected a number in [1e-09, 1e+12] or three of them [x, y, z], "
     "found list [256, 256]"),
    ("    header: false\n    columns: {t: t, ax: 1, ay: 2, az: 3}\n",
     "devices.dut.columns.t: expected a 0-based column index (header: false), found str 't'"),
    ("    columns: {t: t, ax: a, ay: a, az: c}\n",
     "devices.dut.columns: expected a different column for each key"),
    ("    columns: {t: t, ax: a, ay: b, az: c, gx: d}\n",
     "devices.dut.columns: expected all three angular-rate columns gx, gy, gz or none of them, "
     "found only gx"),
    ("    columns: {t: t, ax: a, ay: b, az: c, wx: d}\n",
     "devices.dut.columns.wx: expected a column key among t, ax, ay, az, temperature, gx, gy, gz, "
     "found str 'wx'"),
    ("    columns: {t: t, ax: a, ay: b, az: c, gx: d, gy: e, gz: f}\n    gyro_unit: rpm\n",
     "devices.dut.gyro_unit: expected one of rad/s, deg/s, found str 'rpm'"),
])
def test_manifest_keys_are_checked(tmp_path: Path, keys: str, message: str) -> None:
    folder = _manifest(tmp_path, keys)
    with pytest.raises(ManifestError) as err:
        load_manifest(folder)
    assert message in str(err.value), str(err.value)


def test_manifest_round_trips_every_key(tmp_path: Path) -> None:
    folder = _manifest(tmp_path, "    header: false\n    skip_rows: 2\n    delimiter: whitespace\n"
                                 "    comment: '#'\n    columns: {ax: 0, ay: 1, az: 2, temperature: 3}\n"
                                 "    sample_rate_hz: 100\n    acc_unit: counts\n"
                                 "    lsb_per_g: [256, 256, 250]\n"
                                 "    zero_counts: 512\n    temperature_unit: K\n    range_g: 4\n")
    m = load_manifest(folder)
    csv = m.duts[0].csv
    assert csv is not None
    assert csv == CsvMapping({"ax": 0, "ay": 1, "az": 2, "temperature": 3}, "s", "counts",
                             (256.0, 256.0, 250.0), 2, "whitespace", False, "#", 100.0, 512.0, "K", 4.0)
    again = m.duts[0].to_dict()
    assert again["lsb_per_g"] == [256.0, 256.0, 250.0] and again["zero_counts"] == 512.0
    assert again["columns"] == {"ax": 0, "ay": 1, "az": 2, "temperature": 3}


def test_one_file_feeds_two_devices_each_by_its_own_columns(tmp_path: Path) -> None:
    """Two accelerometer triads logged in one semicolon file (a common fixture layout): each
    device reads its own columns and gets its own label; the same columns twice, or a format
    without columns, cannot share a file."""
    from ofbe_data.labelling.labels import LabelParams, label_session

    rng = np.random.default_rng(4)
    n, g = 6000, 9.80665
    bias = {"imu_a": np.array([0.02, -0.03, 0.05]), "imu_b": np.array([-0.04, 0.01, -0.02])}
    cols = {d: np.array([0.0, 0.0, g]) + b + 0.01 * rng.standard_normal((n, 3)) for d, b in bias.items()}
    both = np.hstack([cols["imu_a"], cols["imu_b"]])
    lines = ["t;a1x;a1y;a1z;a2x;a2y;a2z"] + [f"{i / 100:.2f};" + ";".join(f"{v:.5f}" for v in both[i])
                                              for i in range(n)]
    folder = tmp_path / "camp" / "s1"
    folder.mkdir(parents=True)
    (folder / "both.csv").write_text("\n".join(lines) + "\n")
    dev = ("    model: X\n    role: dut\n    format: csv\n    delimiter: ';'\n    columns: {{t: t, ax: {0}x, "
           "ay: {0}y, az: {0}z}}\n")
    (folder / "session.yaml").write_text(
        "format: ofbe-session/1\ncampaign: camp\nsession: s1\nkind: gravity-aligned\n"
        f"site: {{gravity_mps2: {g}}}\npower_cycle: 1\ndevices:\n  imu_a:\n" + dev.format("a1")
        + "  imu_b:\n" + dev.format("a2")
        + "recordings:\n  - id: r1\n    files: {imu_a: both.csv, imu_b: both.csv}\n")
    labels = label_session(folder, LabelParams(min_samples=1000))
    assert labels.rejections == [] and sorted(r["device"] for r in labels.rows) == ["imu_a", "imu_b"]
    for r in labels.rows:
        got = np.array([r[f"bias_{a}"] for a in "xyz"])
        np.testing.assert_allclose(got, bias[r["device"]], atol=1e-3)  # 0.01 m/s² noise over 6000 samples
    text = (folder / "session.yaml").read_text().replace("ax: a2x", "ax: a1x")
    (folder / "session.yaml").write_text(text)
    with pytest.raises(ManifestError, match=r"recordings\[0\]\.files\.imu_b: expected a file shared by "
                                            r"devices of one recording only when each reads its own columns"):
        load_manifest(folder)
