"""The ``mscip-bin`` reader and writer against Memsense's own ``py-mscip`` package.

Test streams are built with py-mscip's packet classes (``Packet``, ``Floats``, ``GetTime``), so
the decoder is checked against the vendor's encoder, and our writer's bytes go through the
vendor's own parser (``cip_parser.Parser``, ``packet_factory.create_packet``,
``verify_checksum``).
"""

from __future__ import annotations

import contextlib
import io
import os
import struct
from datetime import UTC, datetime

import numpy as np
import py_mscip.packets.cip_parser as vendor_parser
import py_mscip.packets.packet as vendor
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ofbe_data.cli.simulate import main as simulate_main
from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.formats.mscip_bin import (
    SKIP_CHECKSUM,
    SKIP_LAYOUT,
    SKIP_NO_TIME,
    SKIP_TRUNCATED,
    SKIP_UNSYNCED,
    _first_fit,
    decode_mscip,
    encode_mscip,
    gps_to_utc,
    read_mscip_bin,
    utc_to_gps,
    write_mscip_bin,
)
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import load_manifest
from ofbe_data.io.recording import SKIP_NON_INCREASING_TIME, SKIP_NON_NUMERIC
from ofbe_data.labelling.batch import expand_sessions, label_sessions
from ofbe_data.labelling.labels import LabelParams
from ofbe_data.labelling.store import read_labels

# py-mscip puts its own folder on sys.path and imports its enums as the top-level ``packets``
from packets.cip import ImuOutputCode, MsgType, verify_checksum  # noqa: E402  isort: skip

with contextlib.redirect_stdout(io.StringIO()):  # the module prints a demo packet on import
    import py_mscip.packets.packet_factory as vendor_factory

# 2025-03-14T10:22:31.512Z is a Friday of GPS week 2357: 5 days + 10:22:31.512 + 18 s leap
WEEK, SOW = 2357, 5 * 86400 + 10 * 3600 + 22 * 60 + 31.512 + 18
START = datetime(2025, 3, 14, 10, 22, 31, 512000, tzinfo=UTC)
RATE = 200.0


def _packet(acc=None, gyro=None, temp=None, time=None) -> bytes:
    """One IMU output packet built by py-mscip (time = (seconds, week, flags))."""
    p = vendor.Packet(MsgType.ImuOutput)
    if acc is not None:
        p.add_subpacket(vendor.Floats(ImuOutputCode.Accel, list(acc)))
    if gyro is not None:
        p.add_subpacket(vendor.Floats(ImuOutputCode.Gyro, list(gyro)))
    if temp is not None:
        p.add_subpacket(vendor.Floats(ImuOutputCode.Temperature, [temp]))
    if time is not None:
        p.add_subpacket(vendor.GetTime(ImuOutputCode.Time, *time))
    return bytes(p.bytes)


def _stream(n: int, seed: int = 0, timed: bool = True, sow0: float = SOW, week: int = WEEK
            ) -> tuple[list[bytes], np.ndarray, np.ndarray, np.ndarray]:
    """n vendor packets at RATE: (packets, acc g, gyro deg/s, temperature °C)."""
    rng = np.random.default_rng(seed)
    acc = rng.normal(0.0, 0.3, (n, 3)) + [0.0, 0.0, 1.0]
    gyro = rng.normal(0.0, 0.05, (n, 3))
    temp = 31.0 + rng.normal(0.0, 0.1, n)
    packets = []
    for i in range(n):
        sec = sow0 + i / RATE
        t = (sec % 604800, week + int(sec // 604800), 0x0003) if timed else None
        packets.append(_packet(acc[i], gyro[i], float(temp[i]), t))
    return packets, acc, gyro, temp


def _f32(x: np.ndarray) -> np.ndarray:
    return np.asarray(x, dtype=np.float32).astype(np.float64)


# ----------------------------------------------------------------------------- vendor bytes


VENDOR_SAMPLES = [  # the sample packets in py-mscip's packet_factory.py
    "A5A5A20E810C37A7C5AC377BA8823F800065D61A",
    "A5A5A20E820C37A7C5AC377BA8823749539C2240",
    "A5A5A2068604000003FD7CB4",
    "A5A5A22282 0C BD 9D EC 5B 3D 6F 71 4B BD 4C 13 85 81 0C 38 AD C5 C0 BC 40 19 71 BF 7E C9 0F 87 04"
    "41 DC D5 53 A8 60",
    "A5A5A20E880C410944c000000000072F00081A32",  # its checksum is wrong (vendor's verify_checksum too)
    "A5A501168002050085102020202020204D535F494D5533303230EC54",
    "A5A502030C01025E9F",
]


@pytest.mark.parametrize("hex_packet", VENDOR_SAMPLES)
def test_checksum_verdict_and_values_match_the_vendor(hex_packet):
    data = bytes.fromhex(hex_packet.replace(" ", ""))
    s = decode_mscip(data)
    valid = verify_checksum(list(data))
    assert s.packets_ok == int(valid) and s.packets_bad_checksum == int(not valid)
    if not valid:
        return
    packet = vendor_factory.create_packet(bytearray(data))
    floats = {sp.message_code.value: sp.values for sp in packet.sub_packets
              if isinstance(sp, vendor_factory.Floats)}
    if 0x81 in floats:
        np.testing.assert_array_equal(s.acc[0], floats[0x81])
        np.testing.assert_array_equal(s.gyro[0] if 0x82 in floats else [], floats.get(0x82, []))
        assert s.temperature is None if 0x87 not in floats else s.temperature[0] == floats[0x87][0]
    else:
        assert s.n == 0


def test_known_values_round_trip_exactly():
    acc, gyro = [0.025732, -0.047626, 0.998800], [1.5e-3, -2.25, 360.0]
    data = _packet(acc, gyro, 31.2, (SOW, WEEK, 0x0203))
    assert data[:4] == bytes([0xA5, 0xA5, 0xA2, 14 + 14 + 6 + 14])
    s = decode_mscip(data)
    assert (s.n, s.packets_ok, s.bytes_skipped) == (1, 1, 0)
    np.testing.assert_array_equal(s.acc[0], _f32(acc))
    np.testing.assert_array_equal(s.gyro[0], _f32(gyro))
    assert s.temperature[0] == _f32(31.2)
    assert (s.seconds[0], s.week[0], s.flags[0]) == (SOW, WEEK, 0x0203)  # float64: exact
    # a payload whose floats contain A5 A5 (and a whole fake header) decodes the same
    fake = struct.unpack(">f", b"\xa5\xa5\xa2\x30")[0]
    s = decode_mscip(_packet([fake, fake, 1.0]) * 3)
    assert s.n == 3 and s.acc[:, 0].tolist() == [fake] * 3 and s.bytes_skipped == 0


def test_gps_to_utc():
    assert gps_to_utc(WEEK, SOW) == START
    assert utc_to_gps(START) == (WEEK, SOW)
    assert gps_to_utc(0, 0.0) == datetime(1980, 1, 5, 23, 59, 42, tzinfo=UTC)


# ----------------------------------------------------------------------------- reading


def test_read_converts_units_time_and_utc(tmp_path):
    packets, acc, gyro, temp = _stream(50)
    path = tmp_path / "memsense.bin"
    path.write_bytes(b"".join(packets))
    rec = read_mscip_bin(path, device="memsense")
    assert rec.format == "mscip-bin" and rec.n == 50
    assert rec.start_utc == START
    assert rec.header["Start (UTC)"] == "2025-03-14T10:22:31.512000Z"
    assert rec.header["device"] == "memsense" and rec.header["GPS Week"] == str(WEEK)
    np.testing.assert_allclose(rec.t, np.arange(50) / RATE, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(rec.acc, _f32(acc) * G0)
    np.testing.assert_array_equal(rec.extra["Temperature (C)"], _f32(temp))
    np.testing.assert_array_equal(rec.extra["Gyro Y (deg/s)"], _f32(gyro[:, 1]))
    assert rec.line.tolist() == [54 * i for i in range(50)]  # byte offsets
    assert rec.diagnostics.skipped == () and rec.diagnostics.gaps == ()
    assert read_mscip_bin(path, acc_unit="mg").acc[0, 2] == pytest.approx(_f32(acc)[0, 2] * G0 / 1000)


def test_capture_cut_mid_packet_with_corruption_and_garbage(tmp_path):
    packets, acc, _, _ = _stream(40, seed=1)
    bad = bytearray(packets[10])
    bad[25] ^= 0x40  # one bit in an accelerometer float: the checksum catches it
    garbage = bytes(np.random.default_rng(5).integers(0, 256, 23, dtype=np.uint8)) + b"\xa5\xa5\x01"
    data = (packets[0][31:] + b"".join(packets[1:10]) + bytes(bad) + b"".join(packets[11:25])
            + garbage + b"".join(packets[25:39]) + packets[39][:40])
    path = tmp_path / "memsense.bin"
    path.write_bytes(data)
    s = decode_mscip(data)
    kept = [i for i in range(1, 39) if i != 10]
    assert s.n == len(kept) and s.packets_ok == len(kept)
    assert (s.packets_bad_checksum, s.packets_truncated) == (2, 1)  # the corrupt one, the stray header
    np.testing.assert_array_equal(s.acc, _f32(acc[kept]))
    assert s.bytes_skipped == len(data) - 54 * len(kept)
    kinds = [e.kind for e in s.skipped]
    assert kinds == [SKIP_UNSYNCED, SKIP_CHECKSUM, SKIP_UNSYNCED, SKIP_CHECKSUM, SKIP_TRUNCATED]
    # the 23 garbage bytes are header-less; the stray A5 A5 01 reaches the next packet
    assert s.skipped[3].line == 23 + 54 * 24 + 23
    assert s.skipped[2].detail.startswith("23 bytes without a packet header between packets")
    assert s.skipped[1].line == 23 + 54 * 9 and "checksum" in s.skipped[1].detail
    rec = read_mscip_bin(path)
    # UTC of the first complete packet (packet 1), t from it, the lost packet a gap
    assert rec.start_utc == gps_to_utc(WEEK, SOW + 1 / RATE)
    np.testing.assert_allclose(rec.t, (np.array(kept) - 1) / RATE, atol=1e-9)
    assert len(rec.diagnostics.gaps) == 1 and rec.diagnostics.gaps[0].missing_samples == 1
    assert rec.diagnostics.skipped_by_kind == {SKIP_UNSYNCED: 2, SKIP_CHECKSUM: 2, SKIP_TRUNCATED: 1}


def test_stream_without_time(tmp_path):
    packets, acc, _, _ = _stream(20, timed=False)
    path = tmp_path / "memsense.bin"
    path.write_bytes(b"".join(packets))
    with pytest.raises(RawFormatError) as err:
        read_mscip_bin(path)
    assert str(err.value) == (f"{path}: expected time sub-packets (0x88) or a sample_rate_hz in the "
                              "device's manifest entry, found 20 IMU packets without time (set "
                              "sample_rate_hz in the manifest)")
    rec = read_mscip_bin(path, sample_rate_hz=RATE)
    assert rec.start_utc is None and rec.nominal_rate_hz == RATE
    assert rec.header["Sample Rate (Hz)"] == "200"
    np.testing.assert_array_equal(rec.t, np.arange(20) / RATE)
    np.testing.assert_array_equal(rec.acc, _f32(acc) * G0)


def test_packets_without_time_in_a_timed_stream_and_time_going_back(tmp_path):
    packets, _, _, _ = _stream(12)
    untimed = _stream(1, timed=False)[0][0]
    back = _packet([0, 0, 1], None, None, (SOW - 5.0, WEEK, 3))  # a stamp 5 s in the past
    path = tmp_path / "memsense.bin"
    path.write_bytes(b"".join(packets[:4]) + untimed + b"".join(packets[4:8]) + back
                     + b"".join(packets[8:]))
    rec = read_mscip_bin(path)
    assert rec.n == 12
    assert rec.diagnostics.skipped_by_kind == {SKIP_NO_TIME: 1, SKIP_NON_INCREASING_TIME: 1}
    np.testing.assert_allclose(rec.t, np.arange(12) / RATE, atol=1e-9)


def test_week_rollover_keeps_time_continuous(tmp_path):
    packets, _, _, _ = _stream(10, sow0=604800 - 4.5 / RATE)
    path = tmp_path / "memsense.bin"
    path.write_bytes(b"".join(packets))
    s = decode_mscip(path.read_bytes())
    assert s.week.tolist() == [WEEK] * 5 + [WEEK + 1] * 5
    np.testing.assert_allclose(read_mscip_bin(path).t, np.arange(10) / RATE, atol=1e-9)


def test_bad_layouts_other_packets_and_no_acc(tmp_path):
    ok = _packet([0, 0, 1], time=(SOW, WEEK, 0))
    short = vendor.Packet(MsgType.ImuOutput)
    short.add_subpacket(vendor.Floats(ImuOutputCode.Accel, [0.0, 1.0]))  # 8 bytes: unknown length
    ack = vendor.Packet(MsgType.Base)
    ack.add_subpacket(vendor.Ack(vendor_factory.BaseMsgCode.Ping))
    gyro_only = _packet(None, [1, 2, 3])
    s = decode_mscip(ok + bytes(short.bytes) + bytes(ack.bytes) + gyro_only)
    assert (s.n, s.packets_ok, s.packets_bad_layout) == (1, 3, 1)
    assert (s.packets_other_type, s.packets_without_acc) == (1, 1)
    assert [e.kind for e in s.skipped] == [SKIP_LAYOUT]
    # NaN acceleration and seconds of week out of range: counted and skipped, never converted
    nan_acc = _packet([float("nan"), 0, 1], time=(SOW, WEEK, 0))
    far = _packet([0, 0, 1], time=(1e300, WEEK, 0))
    s = decode_mscip(ok + nan_acc + far + ok)
    assert (s.n, s.packets_ok, s.packets_non_finite) == (2, 4, 2)
    assert [e.kind for e in s.skipped] == [SKIP_NON_NUMERIC] * 2
    path = tmp_path / "x.bin"
    path.write_bytes(ok + nan_acc + far)
    assert read_mscip_bin(path).n == 1
    path.write_bytes(bytes(ack.bytes) + gyro_only)
    with pytest.raises(RawFormatError, match="with an accelerometer sub-packet .0x81., found 2 valid "
                                             "packets, none with accelerometer data"):
        read_mscip_bin(path)
    path.write_bytes(b"MSCIP? no: a text file\n" * 3)
    with pytest.raises(RawFormatError, match=r"x.bin: expected MSCIP packets .*found no valid packet "
                                             r"in 69 bytes"):
        read_mscip_bin(path)


def test_non_regular_files_are_refused(tmp_path):
    fifo = tmp_path / "pipe.bin"
    os.mkfifo(fifo)
    with pytest.raises(RawFormatError, match="a readable data file"):
        read_mscip_bin(fifo)
    with pytest.raises(RawFormatError, match="no such file"):
        read_mscip_bin(tmp_path / "missing.bin")


@pytest.mark.slow
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.one_of(st.binary(max_size=80), st.sampled_from(_stream(3, timed=True)[0]),
                          st.sampled_from([_packet([1, 2, 3]), b"\xa5\xa5", b"\xa5\xa5\xa2"]),
                          st.tuples(st.sampled_from(_stream(2)[0]), st.integers(0, 60), st.booleans())
                          .map(lambda x: x[0][x[1]:] if x[2] else x[0][:x[1]])), max_size=12))
def test_any_bytes_give_a_recording_or_raw_format_error(tmp_path_factory, parts):
    data = b"".join(parts)
    s = decode_mscip(data)
    assert 0 <= s.bytes_unsynced <= s.bytes_skipped <= len(data)
    assert all(0 <= e.line < max(len(data), 1) for e in s.skipped)
    path = tmp_path_factory.mktemp("fuzz") / "x.bin"
    path.write_bytes(data)
    for rate in (None, RATE):
        try:
            rec = read_mscip_bin(path, sample_rate_hz=rate)
        except RawFormatError:
            continue
        assert rec.n >= 1 and np.all(np.diff(rec.t) > 0) and np.isfinite(rec.acc).all()


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 300), st.integers(1, 40)), max_size=40))
def test_overlapping_candidates_resolve_first_come_first_kept(intervals):
    starts = np.array(sorted(s for s, _ in intervals), dtype=np.int64)
    lengths = np.array([n for _, n in sorted(intervals)], dtype=np.int64)
    ends = starts + lengths
    expected, reach = [], -1
    for s, e in zip(starts, ends, strict=True):  # the naive walk
        expected.append(bool(s >= reach))
        reach = e if s >= reach else reach
    assert _first_fit(starts, ends).tolist() == expected


# ----------------------------------------------------------------------------- writing


def test_writer_output_goes_through_the_vendor_parser(tmp_path):
    n = 25
    rng = np.random.default_rng(3)
    acc = rng.normal(0, 1, (n, 3)) * G0
    gyro, temp = rng.normal(0, 1, (n, 3)), 30 + rng.normal(0, 1, n)
    t = np.arange(n) / RATE
    path = tmp_path / "out.bin"
    write_mscip_bin(path, t, acc, "2025-03-14T10:22:31.512Z", gyro=gyro, temperature=temp)
    data = path.read_bytes()
    assert data == encode_mscip(t, acc / G0, START, gyro=gyro, temperature=temp)  # deterministic
    packets = vendor_parser.Parser().parse(data)
    assert len(packets) == n
    for i, raw in enumerate(packets):
        assert verify_checksum(raw)
        subs = {sp.message_code.value: sp for sp in vendor_factory.create_packet(bytearray(raw)).sub_packets}
        np.testing.assert_array_equal(subs[0x81].values, _f32(acc[i] / G0))
        np.testing.assert_array_equal(subs[0x82].values, _f32(gyro[i]))
        assert subs[0x87].values == [_f32(temp[i])]
        assert (subs[0x88].week, subs[0x88].flags) == (WEEK, 0)
        assert subs[0x88].second == pytest.approx(SOW + t[i], abs=1e-9)
    # the vendor's encoder gives the same bytes for the same float32 values
    assert data[:54] == _packet(_f32(acc[0] / G0), _f32(gyro[0]), float(_f32(temp[0])),
                                (SOW, WEEK, 0))
    rec = read_mscip_bin(path)
    assert rec.start_utc == START
    np.testing.assert_allclose(rec.acc, acc, rtol=1e-7, atol=1e-6)
    # without time, gyro and temperature
    bare = encode_mscip(t, acc / G0, None)
    assert len(bare) == 20 * n and decode_mscip(bare).seconds is None
    assert len(vendor_parser.Parser().parse(bare)) == n


def test_read_device_file_reads_a_manifest_described_stream(tmp_path):
    folder = tmp_path / "bench-01"
    (folder / "rec-01").mkdir(parents=True)
    manifest = {
        "format": "ofbe-session/1", "campaign": "bench", "session": "bench-01", "kind": "gravity-aligned",
        "site": {"gravity_mps2": 9.7955}, "power_cycle": 1,
        "devices": {"imu": {"model": "MS-IMU3025", "role": "dut", "format": "mscip-bin",
                            "sample_rate_hz": 100, "acc_unit": "mg"}},
        "recordings": [{"id": "rec-01", "files": {"imu": "rec-01/imu.bin"}}],
    }
    (folder / "session.yaml").write_text(yaml.safe_dump(manifest, sort_keys=False))
    t = np.arange(300) / 100.0
    acc = np.tile([0.0, 0.0, 9.7955], (300, 1))
    write_mscip_bin(folder / "rec-01" / "imu.bin", t, acc, None, unit="mg")
    m = load_manifest(folder)
    rec = read_device_file(m.file_path(m.recordings[0], "imu"), m.devices["imu"])
    assert rec.format == "mscip-bin" and rec.n == 300 and rec.fs_hz == pytest.approx(100.0)
    np.testing.assert_allclose(rec.acc, acc, rtol=1e-7)
    assert rec.start_utc is None and rec.header["device"] == "imu"


# ----------------------------------------------------------------------------- simulator


@pytest.mark.slow
def test_simulated_mscip_bin_reference_labels_like_mscip_csv(tmp_path, capsys):
    assert simulate_main(["tiny-rotated", "--out", str(tmp_path / "csv" / "rot"), "--quiet"]) == 0
    assert simulate_main(["tiny-rotated", "--out", str(tmp_path / "bin" / "rot"), "--quiet",
                          "--reference-format", "mscip-bin"]) == 0
    capsys.readouterr()
    m = load_manifest(tmp_path / "bin" / "rot" / "rot-pc001")
    assert m.devices["memsense"].format == "mscip-bin"
    assert m.recordings[0].files["memsense"] == "rec-01/memsense.bin"
    assert (tmp_path / "bin" / "rot" / "rot-pc001" / "rec-01" / "memsense.bin").is_file()
    # the default writes exactly what it wrote before the option existed
    assert "reference_format" not in (tmp_path / "csv" / "rot" / "_truth" / "simulation.yaml").read_text()
    labels = {}
    for kind in ("csv", "bin"):
        outcomes = label_sessions(expand_sessions([tmp_path / kind / "rot"]), LabelParams(min_samples=1000),
                                  tmp_path / f"labels-{kind}", jobs=1, progress=False)
        assert [o.error for o in outcomes if o.error] == []
        frame = read_labels(tmp_path / f"labels-{kind}" / "rot")
        labels[kind] = frame.sort_values(["session", "recording", "device"]).reset_index(drop=True)
    a, b = labels["csv"], labels["bin"]
    assert len(a) == len(b) == 8
    for col in ("bias_x", "bias_y", "bias_z", "gravity_x", "gravity_y", "gravity_z"):
        np.testing.assert_allclose(b[col], a[col], rtol=0, atol=1e-6)
    np.testing.assert_allclose(b["sync_offset_s"], a["sync_offset_s"], rtol=0, atol=1e-6)
