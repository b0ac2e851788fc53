"""Detection of a data file's format, layout, units and rate (``ofbe_data.io.detection``), on files
written here in the layouts real loggers produce, and the stops where the file does not settle a key.

``LAYOUTS`` (also used by test_session_cli.py for the init → check round trip) writes one
simulated level recording at rest (‖f‖ ≈ g0, bias 0.1 m/s² per axis, noise 4 mg, 100 Hz,
100 s) in each odd layout, with the keys detection must find.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.detection import DetectionError, Hints, sniff_text
from ofbe_data.io.detection._names import find_triads, parse_name
from ofbe_data.io.detection._time import decide_time_unit, preamble_rate
from ofbe_data.io.detection._units import decide_acc_unit, decide_gyro_unit, offset_binary_zero
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.formats.mscip_bin import write_mscip_bin
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import DeviceSpec
from tests.helpers.paths import ROOT

EXAMPLES = ROOT / "raw" / "examples"
EPOCH_NS = 1_741_947_751_000_000_000
EPOCH_S = 1_741_947_751.0


def simulate(n: int = 10_000, fs: float = 100.0, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A level device at rest: t (s) and specific force (n, 3) m/s² (bias 0.1, noise 4 mg)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    acc = np.array([0.1, 0.1, G0 + 0.1]) + rng.normal(0.0, 0.004 * G0, (n, 3))
    return t, acc


def _rows(cols: list[np.ndarray], fmts: list[str], sep: str, end: str = "\n", trail: str = "") -> str:
    return "".join(sep.join(f.format(c[i]) for f, c in zip(fmts, cols, strict=True)) + trail + end
                   for i in range(cols[0].shape[0]))


def _g(acc: np.ndarray) -> list[np.ndarray]:
    return [acc[:, i] / G0 for i in range(3)]


def unsigned_whitespace(t: np.ndarray, acc: np.ndarray) -> bytes:
    counts = np.rint(acc / G0 * 16384).astype(np.int64) + 32768
    ms = np.rint(t * 1000).astype(np.int64)
    return _rows([ms, *counts.T], ["{:>9d}", "{:>7d}", "{:>7d}", "{:>7d}"], " ").encode()


def sample_index(t: np.ndarray, acc: np.ndarray) -> bytes:
    body = _rows([np.arange(t.size), *_g(acc)], ["{:d}"] + ["{:.6f}"] * 3, ",")
    return ("sample,ax,ay,az\n" + body).encode()


def epoch_ns(t: np.ndarray, acc: np.ndarray) -> bytes:
    ns = EPOCH_NS + np.rint(t * 1e9).astype(np.int64)
    return ("timestamp,acc_x,acc_y,acc_z\n"
            + _rows([ns, *acc.T], ["{:d}"] + ["{:.5f}"] * 3, ",")).encode()


def milli_g(t: np.ndarray, acc: np.ndarray) -> bytes:
    mg = acc / G0 * 1000
    return ("t,ax,ay,az\n" + _rows([t, *mg.T], ["{:.3f}"] + ["{:.2f}"] * 3, ",")).encode()


def fs_preamble(t: np.ndarray, acc: np.ndarray) -> bytes:
    return ("Fs,100\nax,ay,az\n" + _rows(_g(acc), ["{:.6f}"] * 3, ",")).encode()


def host_clock(t: np.ndarray, acc: np.ndarray) -> bytes:
    rng = np.random.default_rng(7)
    steps = 0.01 * (1 + 0.2 * rng.uniform(-1, 1, t.size))
    steps[[t.size // 5, 3 * t.size // 5]] = 0.03  # two gaps: the host missed a line
    stamps = EPOCH_S + np.cumsum(steps)
    return ("time,ax,ay,az\n" + _rows([stamps, *_g(acc)], ["{:.6f}"] * 4, ",")).encode()


def quoted_units(t: np.ndarray, acc: np.ndarray) -> bytes:
    head = '"Time (s)","Accel X (g)","Accel Y (g)","Accel Z (g)"\n'
    return (head + _rows([t, *_g(acc)], ["{:.4f}"] + ["{:.6f}"] * 3, ",")).encode()


def trailing_comma(t: np.ndarray, acc: np.ndarray) -> bytes:
    return ("t,ax,ay,az,\n" + _rows([t, *acc.T], ["{:.3f}"] + ["{:.5f}"] * 3, ",", trail=",")).encode()


def semicolon(t: np.ndarray, acc: np.ndarray) -> bytes:
    ms = np.rint(t * 1000).astype(np.int64)
    return ("t_ms;ax;ay;az\n" + _rows([ms, *acc.T], ["{:d}"] + ["{:.5f}"] * 3, ";")).encode()


def crlf_bom(t: np.ndarray, acc: np.ndarray) -> bytes:
    us = np.rint(t * 1e6).astype(np.int64)
    body = _rows([us, *_g(acc)], ["{:d}"] + ["{:.6f}"] * 3, ",", end="\r\n")
    return "\ufefftime_us,accel_x,accel_y,accel_z\r\n".encode() + body.encode()


def comments(t: np.ndarray, acc: np.ndarray) -> bytes:
    body = _rows([t, *acc.T], ["{:.2f}"] + ["{:.5f}"] * 3, ",").splitlines(keepends=True)
    body.insert(5000, "% operator pressed pause\n")
    return ("% Logger v2\n% fs = 100\nt,ax,ay,az\n" + "".join(body)).encode()


def tab_names(t: np.ndarray, acc: np.ndarray) -> bytes:
    head = "Sensor log 2025-03-14\nTime [ms]\tAcc X [m/s^2]\tAcc Y [m/s^2]\tAcc Z [m/s^2]\n"
    return (head + _rows([t * 1000, *acc.T], ["{:.1f}"] + ["{:.5f}"] * 3, "\t")).encode()


def decimal_comma(t: np.ndarray, acc: np.ndarray) -> bytes:
    body = _rows([t, *_g(acc)], ["{:.3f}"] + ["{:.6f}"] * 3, ";").replace(".", ",")
    return ("Zeit (s);Beschl. X (g);Beschl. Y (g);Beschl. Z (g)\n" + body).encode()


def index_and_time(t: np.ndarray, acc: np.ndarray) -> bytes:
    return _rows([np.arange(t.size), t, *_g(acc)], ["{:d}", "{:.3f}"] + ["{:.6f}"] * 3, "  ").encode()


Layout = tuple[Callable[[np.ndarray, np.ndarray], bytes], dict[str, Any], list[str]]

#: name → (writer, manifest keys detection must find, init flags the layout needs)
LAYOUTS: dict[str, Layout] = {
    "unsigned-whitespace": (unsigned_whitespace, {
        "header": False, "delimiter": "whitespace", "columns": {"t": 0, "ax": 1, "ay": 2, "az": 3},
        "time_unit": "ms", "acc_unit": "counts", "lsb_per_g": 16384.0, "zero_counts": 32768.0}, []),
    "sample-index": (sample_index, {
        "columns": {"t": "sample", "ax": "ax", "ay": "ay", "az": "az"}, "time_unit": "samples",
        "sample_rate_hz": 100.0, "acc_unit": "g"}, ["--rate", "100"]),
    "epoch-ns": (epoch_ns, {
        "columns": {"t": "timestamp", "ax": "acc_x", "ay": "acc_y", "az": "acc_z"}, "time_unit": "ns",
        "acc_unit": "m/s2"}, []),
    "mg": (milli_g, {"time_unit": "s", "acc_unit": "mg"}, []),
    "fs-preamble": (fs_preamble, {
        "skip_rows": 1, "columns": {"ax": "ax", "ay": "ay", "az": "az"}, "sample_rate_hz": 100.0,
        "acc_unit": "g"}, []),
    "host-clock": (host_clock, {"columns": {"t": "time", "ax": "ax", "ay": "ay", "az": "az"},
                                "time_unit": "s", "acc_unit": "g"}, []),
    "quoted-units": (quoted_units, {
        "columns": {"t": "Time (s)", "ax": "Accel X (g)", "ay": "Accel Y (g)", "az": "Accel Z (g)"},
        "time_unit": "s", "acc_unit": "g"}, []),
    "trailing-comma": (trailing_comma, {"columns": {"t": "t", "ax": "ax", "ay": "ay", "az": "az"},
                                        "time_unit": "s", "acc_unit": "m/s2"}, []),
    "semicolon": (semicolon, {"delimiter": ";", "columns": {"t": "t_ms", "ax": "ax", "ay": "ay", "az": "az"},
                              "time_unit": "ms", "acc_unit": "m/s2"}, []),
    "crlf-bom": (crlf_bom, {"columns": {"t": "time_us", "ax": "accel_x", "ay": "accel_y", "az": "accel_z"},
                            "time_unit": "us", "acc_unit": "g"}, []),
    "comments": (comments, {"comment": "%", "time_unit": "s", "acc_unit": "m/s2",
                            "sample_rate_hz": 100.0}, []),
    "tab-names": (tab_names, {
        "delimiter": "\t", "skip_rows": 1,
        "columns": {"t": "Time [ms]", "ax": "Acc X [m/s^2]", "ay": "Acc Y [m/s^2]", "az": "Acc Z [m/s^2]"},
        "time_unit": "ms", "acc_unit": "m/s2"}, []),
    "decimal-comma": (decimal_comma, {"delimiter": ";", "time_unit": "s", "acc_unit": "g"},
                      ["--columns", "t=Zeit (s),ax=Beschl. X (g),ay=Beschl. Y (g),az=Beschl. Z (g)"]),
    "index-and-time": (index_and_time, {
        "header": False, "delimiter": "whitespace", "columns": {"t": 1, "ax": 2, "ay": 3, "az": 4},
        "time_unit": "s", "acc_unit": "g"}, []),
}


def hints_of(flags: list[str]) -> Hints:
    """The Hints a layout's init flags give (--rate or --columns)."""
    if flags[:1] == ["--rate"]:
        return Hints(rate_hz=float(flags[1]))
    if flags[:1] == ["--columns"]:
        return Hints(columns=dict(p.split("=") for p in flags[1].split(",")))
    return Hints()


def _write(tmp_path: Path, name: str, content: bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(content)
    return path


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_each_layout_gives_its_manifest_keys(tmp_path: Path, layout: str) -> None:
    writer, expected, flags = LAYOUTS[layout]
    path = _write(tmp_path, f"{layout}.csv", writer(*simulate(2000)))
    det = sniff_text(path, hints_of(flags))
    assert det.format == "csv" and det.mapping is not None
    got = det.mapping.to_dict()
    got.setdefault("header", True)
    got.setdefault("delimiter", ",")
    got.setdefault("skip_rows", 0)
    assert {k: got.get(k) for k in expected} == expected
    assert det.rate_hz == pytest.approx(100.0, rel=0.03)
    for d in det.decisions:  # every decision carries its evidence
        assert d.evidence, d.key


def test_decisions_print_with_evidence(tmp_path: Path) -> None:
    path = _write(tmp_path, "a.csv", quoted_units(*simulate(2000)))
    lines = sniff_text(path).lines()
    acc = next(line for line in lines if line.startswith("acc_unit: g ("))
    assert "the column names say so" in acc and "‖mean‖ = 1.0" in acc
    rate = next(line for line in lines if line.startswith("rate: 100 Hz"))
    assert "jitter" in rate and "gaps" in rate


def test_host_clock_reports_jitter_and_gaps(tmp_path: Path) -> None:
    det = sniff_text(_write(tmp_path, "h.csv", host_clock(*simulate(8000))))
    rate = det.evidence("rate") or ""
    assert "2 gaps" in rate
    jitter = float(rate.split("jitter ")[1].split(" %")[0])
    assert 5 < jitter < 20
    assert "epoch seconds" in (det.evidence("time_unit") or "")


def test_epoch_nanoseconds_are_named_with_their_date(tmp_path: Path) -> None:
    det = sniff_text(_write(tmp_path, "e.csv", epoch_ns(*simulate(2000))))
    assert "epoch nanoseconds" in (det.evidence("time_unit") or "")
    assert "2025-03-14" in (det.evidence("time_unit") or "")
    assert "median step 10000000 ns" in (det.evidence("rate") or "")  # read as integers, not float64


def test_offset_binary_counts_are_found_with_their_zero(tmp_path: Path) -> None:
    det = sniff_text(_write(tmp_path, "u.txt", unsigned_whitespace(*simulate(2000))))
    assert "offset-binary" in (det.evidence("zero_counts") or "")
    assert "mid-scale 32768" in (det.evidence("zero_counts") or "")


def _adc(t: np.ndarray, acc: np.ndarray, lsb: float = 409.0, zero: int = 2048) -> bytes:
    counts = np.rint(acc / G0 * lsb).astype(np.int64) + zero
    return _rows([np.rint(t * 1000).astype(np.int64), *counts.T], ["{:d}"] * 4, " ").encode()


def test_unsigned_counts_with_an_unknown_scale_stop_and_ask(tmp_path: Path) -> None:
    path = _write(tmp_path, "adc.txt", _adc(*simulate(2000)))
    with pytest.raises(DetectionError) as info:
        sniff_text(path)
    message = str(info.value)
    assert message.startswith(f"{path}: unsigned counts around mid-scale 2048")
    assert message.endswith("give --unit counts --lsb-per-g N --zero-counts Z")
    det = sniff_text(path, Hints(acc_unit="counts", lsb_per_g=409.0, zero_counts=2048.0))
    assert det.mapping is not None
    assert (det.mapping.acc_unit, det.mapping.lsb_per_g, det.mapping.zero_counts) == ("counts", 409.0, 2048.0)


def test_given_zero_alone_finds_the_counts_per_g(tmp_path: Path) -> None:
    path = _write(tmp_path, "adc.txt", _adc(*simulate(2000), lsb=1024.0, zero=4096))
    det = sniff_text(path, Hints(zero_counts=4096.0))
    assert det.mapping is not None and det.mapping.lsb_per_g == 1024.0 and det.mapping.zero_counts == 4096.0


def test_signed_counts_get_a_power_of_two(tmp_path: Path) -> None:
    t, acc = simulate(2000)
    counts = np.rint(acc / G0 * 256).astype(np.int64)
    path = _write(tmp_path, "s.csv", ("t,ax,ay,az\n" + _rows([t, *counts.T], ["{:.2f}"] + ["{:d}"] * 3, ",")
                                      ).encode())
    det = sniff_text(path)
    assert det.mapping is not None
    assert (det.mapping.acc_unit, det.mapping.lsb_per_g, det.mapping.zero_counts) == ("counts", 256.0, 0.0)


def test_sample_index_without_a_rate_stops(tmp_path: Path) -> None:
    path = _write(tmp_path, "i.csv", sample_index(*simulate(2000)))
    with pytest.raises(DetectionError, match=r"'sample' is a sample index and the file states no rate: "
                                             r"give --rate HZ$"):
        sniff_text(path)


def test_no_time_column_and_no_rate_stops(tmp_path: Path) -> None:
    t, acc = simulate(2000)
    path = _write(tmp_path, "n.csv", ("ax,ay,az\n" + _rows(_g(acc), ["{:.6f}"] * 3, ",")).encode())
    with pytest.raises(DetectionError, match=r"no time column and no sample rate in the file: "
                                             r"give --rate HZ$"):
        sniff_text(path)
    det = sniff_text(path, Hints(rate_hz=50.0))
    assert det.mapping is not None and det.mapping.sample_rate_hz == 50.0 and "t" not in det.mapping.columns


def test_two_time_columns_stop(tmp_path: Path) -> None:
    t, acc = simulate(2000)
    text = "time,timestamp,ax,ay,az\n" + _rows([t, t + EPOCH_S, *_g(acc)], ["{:.3f}", "{:.3f}"]
                                              + ["{:.6f}"] * 3, ",")
    path = _write(tmp_path, "two.csv", text.encode())
    with pytest.raises(DetectionError, match=r"two candidate time columns \('time', 'timestamp'\): "
                                             r"give --time-column NAME$"):
        sniff_text(path)
    det = sniff_text(path, Hints(time_column="timestamp"))
    assert det.mapping is not None and det.mapping.columns["t"] == "timestamp"


def test_a_norm_that_fits_no_unit_stops(tmp_path: Path) -> None:
    t, acc = simulate(2000)
    path = _write(tmp_path, "x.csv", ("t,ax,ay,az\n" + _rows([t, *(acc.T * 3)], ["{:.2f}"] + ["{:.5f}"] * 3,
                                                             ",")).encode())
    with pytest.raises(DetectionError, match=r"fits no unit .*: give --unit U"):
        sniff_text(path)


def test_integer_milli_g_near_1024_is_a_tie(tmp_path: Path) -> None:
    t = np.arange(2000) / 100.0
    mg = np.tile([0.0, 0.0, 1012.0], (2000, 1)) + np.random.default_rng(1).integers(-4, 5, (2000, 3))
    path = _write(tmp_path, "m.csv", ("t,ax,ay,az\n" + _rows([t, *mg.astype(np.int64).T],
                                                             ["{:.2f}"] + ["{:d}"] * 3, ",")).encode())
    with pytest.raises(DetectionError, match=r"--unit mg or --unit counts --lsb-per-g 1024$"):
        sniff_text(path)


def test_unrecognised_axis_names_stop(tmp_path: Path) -> None:
    t, acc = simulate(200)
    path = _write(tmp_path, "n.csv", ("t,foo,bar,baz\n" + _rows([t, *acc.T], ["{:.2f}"] + ["{:.4f}"] * 3,
                                                               ",")).encode())
    with pytest.raises(DetectionError, match=r"give --columns t=NAME,ax=NAME,ay=NAME,az=NAME$"):
        sniff_text(path)
    det = sniff_text(path, Hints(columns={"t": "t", "ax": "foo", "ay": "bar", "az": "baz"}))
    assert det.mapping is not None
    assert det.mapping.columns == {"t": "t", "ax": "foo", "ay": "bar", "az": "baz"}


def test_temperature_column_and_its_unit(tmp_path: Path) -> None:
    t, acc = simulate(500)
    temp = np.full(t.size, 301.2)
    text = "t,ax,ay,az,Temp (K)\n" + _rows([t, *acc.T, temp], ["{:.2f}"] + ["{:.5f}"] * 3 + ["{:.1f}"], ",")
    det = sniff_text(_write(tmp_path, "t.csv", text.encode()))
    assert det.mapping is not None
    assert det.mapping.columns["temperature"] == "Temp (K)" and det.mapping.temperature_unit == "K"


def test_comment_lines_only_before_the_data_need_no_comment_key(tmp_path: Path) -> None:
    t, acc = simulate(500)
    text = "# my logger\n# fs=100\nt,ax,ay,az\n" + _rows([t, *acc.T], ["{:.2f}"] + ["{:.5f}"] * 3, ",")
    det = sniff_text(_write(tmp_path, "c.csv", text.encode()))
    assert det.mapping is not None
    assert (det.mapping.comment, det.mapping.skip_rows, det.mapping.sample_rate_hz) == (None, 2, 100.0)


def test_decimal_commas_between_blanks_are_refused(tmp_path: Path) -> None:
    lines = "".join(f"{i / 100:.2f} 0.01 0.02 1.00\n".replace(".", ",") for i in range(100))
    with pytest.raises(RawFormatError, match="decimal commas only with a ';' or tab delimiter"):
        sniff_text(_write(tmp_path, "d.txt", lines.encode()))


def test_decimal_commas_with_semicolons_are_noted(tmp_path: Path) -> None:
    det = sniff_text(_write(tmp_path, "d.csv", decimal_comma(*simulate(500))),
                     Hints(columns={"t": "Zeit (s)", "ax": "Beschl. X (g)", "ay": "Beschl. Y (g)",
                                    "az": "Beschl. Z (g)"}))
    assert "decimal mark" in (det.evidence("decimal_comma") or "")
    assert det.rate_hz == pytest.approx(100.0)


def test_known_formats_by_their_headers(tmp_path: Path) -> None:
    rec = EXAMPLES / "tiny-rotated" / "rot-pc001" / "rec-01"
    logger = sniff_text(rec / "sparkfun-1.csv")
    assert (logger.format, logger.model) == ("ofbe-logger", "ADXL345")
    mscip = sniff_text(rec / "memsense.csv")
    assert (mscip.format, mscip.model) == ("mscip-csv", "MS-IMU3025")
    with pytest.raises(RawFormatError, match="0 valid MSCIP accelerometer packets"):
        sniff_text(_write(tmp_path, "z.bin", bytes(range(256)) * 4))


def test_mscip_binary_streams(tmp_path: Path) -> None:
    t, acc = simulate(1000, fs=200.0)
    write_mscip_bin(tmp_path / "timed.bin", t, acc, "2025-03-14T10:22:31.512Z")
    det = sniff_text(tmp_path / "timed.bin")
    assert (det.format, det.options, det.rows) == ("mscip-bin", {}, 1000)
    assert det.rate_hz == pytest.approx(200.0)
    assert "valid MSCIP packets" in (det.evidence("format") or "")
    write_mscip_bin(tmp_path / "bare.bin", t, acc, None, unit="mg")
    with pytest.raises(DetectionError, match="without time sub-packets .*: give --rate HZ$"):
        sniff_text(tmp_path / "bare.bin")
    det = sniff_text(tmp_path / "bare.bin", Hints(rate_hz=200.0))
    assert det.options == {"sample_rate_hz": 200.0, "acc_unit": "mg"}


def test_ferraris_example_is_signed_counts_at_2048_per_g() -> None:
    det = sniff_text(EXAMPLES / "imucal-ferraris" / "ferraris-pc001" / "rec-x_p" / "imu.csv")
    assert det.mapping is not None
    assert det.mapping.to_dict() == {"columns": {"t": "t_s", "ax": "acc_x", "ay": "acc_y", "az": "acc_z"},
                                     "time_unit": "s", "acc_unit": "counts", "lsb_per_g": 2048.0}


@pytest.mark.parametrize(("line", "rate"), [
    ("Fs,100", 100.0), ("fs=100", 100.0), ("Sample Rate (Hz),200", 200.0), ("# sampling rate: 50 Hz", 50.0),
    ("ODR_HZ = 400", 400.0), ("Title,Fs", None), ("Device,ADXL345", None)])
def test_preamble_rate_lines(line: str, rate: float | None) -> None:
    found = preamble_rate(["banner", line], first_line=1)
    assert (found[0] if found else None) == rate
    if found:
        assert found[1].startswith("line 2:")


@pytest.mark.parametrize(("raw", "base", "unit"), [
    ("Time (s)", "time", "s"), ("t_us", "t", "us"), ("Accel X (g)", "accel_x", "g"), ("aX", "ax", None),
    ("x (g)", "x", "g"), ("acc_x[m/s^2]", "acc_x", "m/s2"), ("timestamp_ns", "timestamp", "ns"),
    ("millis", "millis", "ms"), ("AccZ_mg", "accz", "mg"), ("Temperature (°C)", "temperature", "C"),
    ("accel[0]", "accel_0", None), ("gyro_x_dps", "gyro_x", "deg/s"), ("Gyro X (deg/s)", "gyro_x", "deg/s"),
    ("w_RS_S_x [rad s^-1]", "w_rs_s_x", "rad/s"), ("gyroRotationX(rad/s)", "gyrorotationx", "rad/s")])
def test_column_names_are_taken_apart(raw: str, base: str, unit: str | None) -> None:
    name = parse_name(raw)
    assert (name.base, name.unit) == (base, unit)


def test_time_unit_rules() -> None:
    def unit(t: np.ndarray, kind: str = "time") -> str:
        return decide_time_unit("f", t, "t", None, kind).unit

    n = np.arange(1000, dtype=float)
    assert unit(n * 0.01) == "s"
    assert unit(n * 10) == "ms"
    assert unit(n * 1e4) == "us"
    assert unit(n * 1e7) == "ns"
    assert unit(n, "values") == "samples"
    assert unit(n, "time") == "ms"  # a time-named integer step of 1: millis() at 1 kHz
    assert unit(1.7e12 + n * 10) == "ms"  # epoch milliseconds
    with pytest.raises(DetectionError, match="give --time-unit U"):
        unit(n * 1e12)


def test_acc_unit_rules() -> None:
    rng = np.random.default_rng(3)
    base = np.array([0.01, -0.02, 1.0]) + rng.normal(0, 0.004, (500, 3))
    assert decide_acc_unit("f", base, 100).unit == "g"
    assert decide_acc_unit("f", base * G0, 100).unit == "m/s2"
    assert decide_acc_unit("f", base * 1000, 100).unit == "mg"
    counts = decide_acc_unit("f", np.rint(base * 4096), 100)
    assert (counts.unit, counts.lsb_per_g, counts.zero_counts) == ("counts", 4096.0, 0.0)
    mid = np.rint(base * 1024) + 2048
    assert offset_binary_zero(mid, mid.mean(axis=0)) == 2048
    assert offset_binary_zero(np.rint(base * 1024), np.rint(base * 1024).mean(axis=0)) is None


@pytest.mark.parametrize(("header", "triads"), [
    ("TIME,ACCEL_X,ACCEL_Y,ACCEL_Z,GYRO_X,GYRO_Y,GYRO_Z", [("acc", "", 1), ("gyro", "", 4)]),
    ("t,acc_0,acc_1,acc_2", [("acc", "", 1)]),
    ("t,ch_1,ch_2,ch_3", [("unknown", "ch", 1)]),
    ("t,a1x,a1y,a1z,a2x,a2y,a2z", [("acc", "1", 1), ("acc", "2", 4)]),
    ("t,acc1_x,acc1_y,acc1_z,acc2_x,acc2_y,acc2_z,gyro1_x_dps,gyro1_y_dps,gyro1_z_dps",
     [("acc", "1", 1), ("acc", "2", 4), ("gyro", "1", 7)]),
    ("time,gFx,gFy,gFz,TgF", [("acc", "", 1)]),
    ("time,seconds_elapsed,z,y,x", [("bare", "", 4)]),
    ("t,Linear Acceleration x (m/s^2),Linear Acceleration y (m/s^2),Linear Acceleration z (m/s^2)",
     [("linacc", "", 1)]),
    ("#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],a_RS_S_x [m s^-2],"
     "a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]", [("gyro", "wrss", 1), ("acc", "arss", 4)]),
    ("t,mag_x,mag_y,mag_z,x_accel,y_accel,z_accel", [("mag", "", 1), ("acc", "", 4)]),
    ("t,index,max,latency", []),
])
def test_triads_by_name(header: str, triads: list[tuple[str, str, int]]) -> None:
    names = [parse_name(n) for n in header.split(",")]
    found = find_triads("f", names, list(range(len(names))))
    assert [(tr.kind, tr.label, tr.cols["x"]) for tr in found] == triads


def test_two_columns_for_one_axis_stop() -> None:
    names = [parse_name(n) for n in "t,acc_x_raw,acc_y_raw,acc_z_raw,acc_x_g,acc_y_g,acc_z_g".split(",")]
    with pytest.raises(DetectionError, match=r"^f: two columns for the acc x axis \('acc_x_raw', "
                                             r"'acc_x_g'\): give --columns t=NAME,ax=NAME,ay=NAME,az=NAME$"):
        find_triads("f", names, list(range(7)))


def test_a_time_unit_the_steps_contradict() -> None:
    n = np.arange(1000, dtype=float)
    d = decide_time_unit("f", n * 0.01, "'t_ms'", "ms", "time")
    assert (d.unit, d.rate_hz) == ("s", pytest.approx(100.0))
    assert d.warning == ("the column name 't_ms' says ms, but its median step 0.01 would give 1e+05 Hz, "
                         "outside the 0.5–20000 Hz an accelerometer logs at; in s it gives 100 Hz: read in s "
                         "(give --time-unit ms if the name is right)")
    assert decide_time_unit("f", n * 10.0, "'time_s'", "s", "time").unit == "ms"
    assert decide_time_unit("f", n * 0.5, "'t_ms'", "ms", "time").warning is None  # 2 kHz: as named
    with pytest.raises(DetectionError) as info:
        decide_time_unit("f", n * 1e-5, "'t_ms'", "ms", "time")
    assert str(info.value) == ("f: the column name 't_ms' says ms, but its median step 1e-05 would give "
                               "1e+08 Hz, outside the 0.5–20000 Hz an accelerometer logs at: give "
                               "--time-unit U (s, ms, us or ns)")


def test_gyro_unit_rules() -> None:
    rest = np.random.default_rng(2).normal(0, 0.01, (500, 3))
    turn = rest.copy()
    turn[100:150, 2] += 90.0
    assert decide_gyro_unit(rest, "deg/s") == ("deg/s", "the column names say so")
    assert decide_gyro_unit(rest, None, "rad/s") == ("rad/s", "given with --gyro-unit")
    assert decide_gyro_unit(turn, None)[0] == "deg/s"
    unit, why = decide_gyro_unit(rest, None)
    assert unit is None and why.endswith("not mapped (give --gyro-unit rad/s or deg/s to map them)")
    assert decide_gyro_unit(np.rint(rest * 1000) + 40, None)[0] is None  # raw counts: no key for their scale


def _csv(tmp_path: Path, head: list[str], body: list[str], name: str = "f.csv") -> Path:
    return _write(tmp_path, name, ("\n".join(head + body) + "\n").encode())


def _body(n: int = 1000, sep: str = ",") -> list[str]:
    t, acc = simulate(n)
    return _rows([t, *_g(acc)], ["{:.2f}"] + ["{:.6f}"] * 3, sep).splitlines()


def test_a_numbered_first_line_is_no_data(tmp_path: Path) -> None:
    det = sniff_text(_csv(tmp_path, ["0,1,2,3"], _body()))
    assert det.mapping is not None
    assert (det.mapping.header, det.mapping.skip_rows, det.rows) == (False, 1, 1000)
    assert "line 1 ('0,1,2,3') numbers the columns" in (det.evidence("skip_rows") or "")


def test_prompt_lines_become_the_comment_prefix(tmp_path: Path) -> None:
    body = _body()
    for k, line in ((100, ">>> x = 1"), (300, "> "), (500, ">>> run()"), (700, "$GPGGA,1")):
        body.insert(k, line)
    det = sniff_text(_csv(tmp_path, ["t,ax,ay,az"], body))
    assert det.mapping is not None and det.mapping.comment == ">"
    assert det.evidence("comment") == ("3 lines start with '>', 3 of them among the data (e.g. line 102: "
                                       "'>>> x = 1'): comment or prompt lines, not garbled data")
    assert det.warnings == ["1 line among the data starts with '$' (e.g. line 702: '$GPGGA,1'); only one "
                            "comment prefix can be given, so the reader skips them as unreadable lines"]


def test_a_unit_row_gives_the_units_and_is_skipped_as_a_comment(tmp_path: Path) -> None:
    t, acc = simulate(1000)
    body = _rows([t * 1000, *(acc.T / G0 * 1000)], ["{:.1f}"] + ["{:.2f}"] * 3, ";").splitlines()
    det = sniff_text(_csv(tmp_path, ["Time;X;Y;Z", "ms;mg;mg;mg"], body))
    assert det.mapping is not None
    got = det.mapping.to_dict()
    assert (got["comment"], got["time_unit"], got["acc_unit"]) == ("ms;mg;mg;mg", "ms", "mg")
    assert got["columns"] == {"t": "Time", "ax": "X", "ay": "Y", "az": "Z"}
    assert (det.evidence("acc_unit") or "").startswith("the unit row (line 2) says so")
    assert "no manifest key skips one line after the column line" in (det.evidence("comment") or "")


def test_two_triads_give_two_parts(tmp_path: Path) -> None:
    t, acc = simulate(1000)
    body = _rows([t, *_g(acc), *acc.T], ["{:.2f}"] + ["{:.6f}"] * 3 + ["{:.5f}"] * 3, ";").splitlines()
    det = sniff_text(_csv(tmp_path, ["t;acc1_x;acc1_y;acc1_z;acc2_x;acc2_y;acc2_z"], body))
    assert [(p.label, p.mapping.columns["ax"], p.mapping.acc_unit) for p in det.parts] == [
        ("1", "acc1_x", "g"), ("2", "acc2_x", "m/s2")]
    assert [line.split(": ")[0] for line in det.lines() if line.startswith("acc_unit")] == [
        "acc_unit [1]", "acc_unit [2]"]


def test_the_rate_is_the_one_check_reports(tmp_path: Path) -> None:
    """Host-clock stamps with jitter and two gaps: 1 / median step and the mean rate (what check
    reports: samples and missing samples over the span) differ; init reports check's, and says so."""
    path = _write(tmp_path, "h.csv", host_clock(*simulate(8000)))
    det = sniff_text(path)
    assert det.mapping is not None
    rec = read_device_file(path, DeviceSpec("d", "x", "dut", "csv", csv=det.mapping))
    assert det.rate_hz == rec.fs_hz == pytest.approx(99.9907, abs=1e-4)
    assert (det.evidence("rate") or "").startswith(f"the mean rate, as check reports it: (8000 samples − 1 "
                                                   f"+ {rec.diagnostics.missing_samples} missing in gaps) / ")
    assert "; median step 0.01 s → 99.969 Hz; jitter 12 %" in (det.evidence("rate") or "")
