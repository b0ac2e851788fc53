"""The ``mscip-bin`` format: the Memsense MSCIP binary byte stream as captured from the serial port.

Byte layout (raw-formats.md "mscip-bin", checked against the bytes of Memsense's own ``py-mscip``
0.1.0, ``py_mscip/packets/packet.py`` and ``cip.py``)::

    packet      A5 A5 <type:u8> <payload length L:u8> <sub-packets: L bytes> <c1:u8> <c2:u8>
    sub-packet  <code:u8> <length:u8> <length bytes>
    checksum    Fletcher over the 4 header bytes (sync bytes included) and the payload, both
                running sums taken modulo 256 (``compute_fletcher``: ``&= 0xFF``, not the
                textbook modulo 255); written c1 (sum of bytes) then c2 (sum of the sums)

IMU output packets (type 0xA2) carry, in any order: accelerometer 0x81 and gyroscope 0x82
(length 12: three big-endian float32, x y z; ``Floats``), temperature 0x87 (length 4: one
big-endian float32; ``Floats``) and time 0x88 (length 12: big-endian float64 seconds of the GPS
week, then the week and a flags word as big-endian uint16; ``GetTime``). Other sub-packets
(magnetometer, delta angles, ...) and other packet types (0x01 base, 0x02 IMU commands) are
valid and ignored. UTC = GPS − 18 s.

Decoding is vectorised over the whole buffer: every ``A5 A5`` is a candidate header, the
checksums of all candidates of one size are one matrix product, the sub-packet walk advances all
packets one sub-packet at a time, and fields are gathered with big-endian dtype views. Python
loops run over packet sizes, sub-packet depth and skipped packets only. Overlapping candidates (an
``A5 A5`` inside a packet whose checksum happens to pass) are resolved in order of position.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.errors import RawFormatError
from ofbe_data.io.device_options import BinOptions, DeviceSpec
from ofbe_data.io.formats.common import (
    MAX_STEP_S,
    MSCIP_GYRO,
    MSCIP_TEMP,
    Body,
    clean_times,
    find_gaps,
    parse_utc,
)
from ofbe_data.io.formats.filebytes import read_file_bytes
from ofbe_data.io.formats.registry import Format, register_format
from ofbe_data.io.gravity import G0
from ofbe_data.io.recording import SKIP_NON_NUMERIC, ReadDiagnostics, Recording, SkippedLine

SYNC = 0xA5
"""Both sync bytes of a packet header."""
TYPE_IMU_OUTPUT = 0xA2
CODE_ACC, CODE_GYRO, CODE_TEMP, CODE_TIME = 0x81, 0x82, 0x87, 0x88
SUB_LENGTH = {CODE_ACC: 12, CODE_GYRO: 12, CODE_TEMP: 4, CODE_TIME: 12}
"""Payload length of each decoded sub-packet; any other length makes the packet unreadable."""
GPS_EPOCH = datetime(1980, 1, 6, tzinfo=UTC)
GPS_MINUS_UTC_S = 18
"""GPS − UTC, s (leap seconds since 2017-01-01)."""
WEEK_S = 604_800
ACC_UNITS = {"g": G0, "mg": G0 / 1000.0, "m/s2": 1.0}
"""Accelerometer unit → m/s² per unit."""

#: Kinds of skipped entries; their ``line`` is the 0-based byte offset in the file.
SKIP_CHECKSUM = "bad-checksum"
SKIP_LAYOUT = "bad-layout"
SKIP_TRUNCATED = "truncated-packet"
SKIP_UNSYNCED = "no-packet-header"
SKIP_NO_TIME = "no-time"
SKIP_NON_FINITE = SKIP_NON_NUMERIC

_WEEK_US = WEEK_S * 1_000_000
_CHUNK = 65_536  # packets a block in the checksum and the writer


@dataclass(frozen=True)
class MscipStream:
    """The samples and the bookkeeping of one decoded MSCIP byte stream.

    Attributes
    ----------
    offset
        (N,) int64, byte offset of each sample's packet.
    acc
        (N, 3) float64, accelerometer sub-packet values in the stream's unit (float32 exactly).
    gyro
        (N, 3) float64 gyroscope values (NaN where a packet has none), or None when no packet has one.
    temperature
        (N,) float64 temperature (NaN where missing), or None.
    seconds
        (N,) float64 seconds of the GPS week (NaN where missing), or None when no packet has time.
    week
        (N,) int64 GPS week (−1 where missing), or None.
    flags
        (N,) int64 time flags word as sent (−1 where missing), or None.
    packets_ok
        Packets with a valid checksum and a readable layout (of any type).
    packets_bad_checksum, packets_bad_layout, packets_truncated
        Packets skipped: checksum mismatch; valid checksum but sub-packets that do not fill the
        payload, a decoded sub-packet of unexpected length or given twice; cut by the end of the
        capture.
    packets_without_acc
        Valid IMU output packets without an accelerometer sub-packet.
    packets_other_type
        Valid packets of another type than 0xA2 (command replies, ...).
    packets_non_finite
        IMU packets dropped for a NaN/inf accelerometer value or seconds of week not in [0, 604800).
    bytes_skipped
        Bytes outside the packets decoded (partial packets, corrupt packets, garbage).
    bytes_unsynced
        The part of ``bytes_skipped`` without any packet header.
    skipped
        One entry per skipped packet or run of header-less bytes; ``line`` is the byte offset.
    """

    offset: np.ndarray
    acc: np.ndarray
    gyro: np.ndarray | None
    temperature: np.ndarray | None
    seconds: np.ndarray | None
    week: np.ndarray | None
    flags: np.ndarray | None
    packets_ok: int
    packets_bad_checksum: int
    packets_bad_layout: int
    packets_truncated: int
    packets_without_acc: int
    packets_other_type: int
    packets_non_finite: int
    bytes_skipped: int
    bytes_unsynced: int
    skipped: tuple[SkippedLine, ...]

    @property
    def n(self) -> int:
        """Number of samples."""
        return int(self.offset.shape[0])


# --------------------------------------------------------------------------- decoding


def _first_fit(starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Keep intervals in order of start, each one that begins after the last kept one ends.

    ``starts`` ascending; (K,) bool. Isolated intervals (the normal case) are found with array
    operations; only runs of mutually overlapping intervals are walked, one kept interval a step.
    """
    keep = np.zeros(starts.shape[0], dtype=bool)
    if starts.size == 0:
        return keep
    reach = np.maximum.accumulate(ends)
    first = np.ones(starts.shape[0], dtype=bool)
    first[1:] = starts[1:] >= reach[:-1]
    keep |= first
    bounds = np.append(np.flatnonzero(first), starts.shape[0])
    crowded = np.flatnonzero(np.diff(bounds) > 1)
    if crowded.size:
        after = np.searchsorted(starts, ends, side="left")  # first interval starting after each
        for c in crowded:
            k, stop = int(bounds[c]), int(bounds[c + 1])
            k = int(after[k])
            while k < stop:
                keep[k] = True
                k = int(after[k])
    return keep


def _gather(b: np.ndarray, offsets: np.ndarray, width: int, dtype: str) -> np.ndarray:
    """Big-endian values of ``width`` bytes at ``offsets`` → (K, width // itemsize) array."""
    native = np.dtype(dtype).newbyteorder("=")
    if offsets.size == 0:
        return np.zeros((0, width // native.itemsize), dtype=native)
    return sliding_window_view(b, width)[offsets].view(dtype).astype(native)


def _walk(b: np.ndarray, start: np.ndarray, end: np.ndarray) -> tuple[np.ndarray, np.ndarray,
                                                                        dict[int, np.ndarray]]:
    """Walk the sub-packets of all packets at once.

    Returns (tiles, readable, offsets): whether the sub-packets fill each payload exactly,
    whether the decoded ones have their lengths and none repeats, and per decoded code the
    byte offset of its sub-packet in each packet (−1: absent).
    """
    k = start.shape[0]
    tiles = np.ones(k, dtype=bool)
    readable = np.ones(k, dtype=bool)
    offsets = {code: np.full(k, -1, dtype=np.int64) for code in SUB_LENGTH}
    pos = start + 4
    idx = np.flatnonzero(pos < end)
    while idx.size:  # one step per sub-packet depth (a few), every packet at once
        p = pos[idx]
        code, length = b[p], b[p + 1].astype(np.int64)
        nxt = p + 2 + length
        fits = nxt <= end[idx]
        tiles[idx[~fits]] = False
        for c, want in SUB_LENGTH.items():
            hit = fits & (code == c)
            sel = idx[hit]
            readable[sel[(length[hit] != want) | (offsets[c][sel] >= 0)]] = False
            offsets[c][sel] = p[hit]
        pos[idx] = nxt
        idx = idx[fits & (nxt < end[idx])]
    return tiles, readable, offsets


def _checksum_ok(b: np.ndarray, start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """MSCIP Fletcher check of bytes ``[start, end)`` against the two bytes at ``end``, (K,) bool.

    Per packet size (a loop over the few distinct sizes) the packets are the rows of a (k, size)
    matrix: c1 = Σ byte_i and c2 = Σ (size − i)·byte_i, modulo 256. Both sums stay below 2²⁴, so
    the float32 matrix product that computes c2 is exact.
    """
    size = (end - start).astype(np.uint16)
    order = np.argsort(size, kind="stable")  # radix sort of small integers
    bounds = np.concatenate(([0], np.cumsum(np.bincount(size))))
    ok = np.zeros(start.shape[0], dtype=bool)
    for m in np.flatnonzero(np.diff(bounds)):
        view = sliding_window_view(b, int(m) + 2)
        weights = np.arange(m, 0, -1, dtype=np.float32)
        for lo in range(bounds[m], bounds[m + 1], _CHUNK):
            sel = order[lo:min(lo + _CHUNK, bounds[m + 1])]
            rows = view[start[sel]]
            data = rows[:, :m].astype(np.float32)
            c1 = data.sum(axis=1).astype(np.int64) & 0xFF
            c2 = (data @ weights).astype(np.int64) & 0xFF
            ok[sel] = (c1 == rows[:, m]) & (c2 == rows[:, m + 1])
    return ok


def _candidates(b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every ``A5 A5`` as a candidate packet: (start, has a length byte, payload end, complete,
    checksum good), each (K,)."""
    n = int(b.shape[0])
    cand = np.flatnonzero((b[:-1] == SYNC) & (b[1:] == SYNC)).astype(np.int64) if n >= 2 \
        else np.zeros(0, dtype=np.int64)
    has_len = cand + 3 < n
    end = np.full(cand.shape[0], n + 2, dtype=np.int64)  # no length byte: runs past the end
    end[has_len] = cand[has_len] + 4 + b[cand[has_len] + 3]
    complete = end + 2 <= n
    good = np.zeros(cand.shape[0], dtype=bool)
    good[complete] = _checksum_ok(b, cand[complete], end[complete])
    return cand, has_len, end, complete, good


def _unsynced(starts: np.ndarray, ends: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Runs of bytes outside the disjoint intervals [starts, ends): (run starts, run ends)."""
    order = np.argsort(starts, kind="stable")
    lo = np.concatenate(([0], ends[order]))
    hi = np.concatenate((starts[order], [n]))
    run = hi > lo
    return lo[run], hi[run]


def _skip_entries(b: np.ndarray, cand: np.ndarray, has_len: np.ndarray, end: np.ndarray,
                  kinds: dict[str, np.ndarray], runs: tuple[np.ndarray, np.ndarray]) -> list[SkippedLine]:
    """One :class:`SkippedLine` (``line`` = byte offset) per skipped packet and header-less run."""
    n = int(b.shape[0])
    out: list[SkippedLine] = []
    i = kinds[SKIP_TRUNCATED]
    for at, e, known in zip(cand[i].tolist(), (end[i] + 2).tolist(), has_len[i].tolist(), strict=True):
        out.append(SkippedLine(at, SKIP_TRUNCATED, f"packet at byte {at} cut by the end of the capture "
                               f"({n - at} of {e - at} bytes)" if known else
                               f"packet header at byte {at} cut by the end of the capture"))
    i = kinds[SKIP_CHECKSUM]
    for at, e, c1, c2 in zip(cand[i].tolist(), end[i].tolist(), b[end[i]].tolist(), b[end[i] + 1].tolist(),
                             strict=True):
        out.append(SkippedLine(at, SKIP_CHECKSUM, f"packet at byte {at}: checksum {c1:02X} {c2:02X} does not "
                                                  f"match its {e - at} bytes"))
    i = kinds["frame"]
    out += [SkippedLine(at, SKIP_LAYOUT, f"packet at byte {at}: sub-packets do not fill its {m}-byte payload")
            for at, m in zip(cand[i].tolist(), b[cand[i] + 3].tolist(), strict=True)]
    out += [SkippedLine(at, SKIP_LAYOUT, f"packet at byte {at}: a sub-packet of unexpected length or given "
                        "twice (expected lengths: accelerometer 12, gyroscope 12, temperature 4, time 12)")
            for at in cand[kinds[SKIP_LAYOUT]].tolist()]
    out += [SkippedLine(at, SKIP_NON_FINITE, f"packet at byte {at}: NaN or infinite accelerometer value, or "
                        f"seconds of week outside [0, {WEEK_S})")
            for at in cand[kinds[SKIP_NON_FINITE]].tolist()]
    for lo, hi in zip(runs[0].tolist(), runs[1].tolist(), strict=True):
        where = ("at the start of the capture" if lo == 0 else
                 "at the end of the capture" if hi == n else "between packets")
        out.append(SkippedLine(lo, SKIP_UNSYNCED, f"{hi - lo} bytes without a packet header {where} "
                                                  f"(bytes {lo}-{hi - 1})"))
    out.sort(key=lambda s: s.line)
    return out


def decode_mscip(buffer: bytes) -> MscipStream:
    """Decode an MSCIP byte stream: every valid IMU output packet with accelerometer data.

    Parameters
    ----------
    buffer
        The captured bytes; may start and end mid-packet and hold corrupt packets or garbage.

    Returns
    -------
    MscipStream
        Samples in stream order with the counts of what was skipped. Never raises on content.
    """
    b = np.frombuffer(buffer, dtype=np.uint8)
    n = int(b.shape[0])
    cand, has_len, end, complete, good = _candidates(b)
    k = cand.shape[0]
    imu = np.zeros(k, dtype=bool)
    imu[has_len] = b[cand[has_len] + 2] == TYPE_IMU_OUTPUT
    tiles = np.zeros(k, dtype=bool)
    readable = np.zeros(k, dtype=bool)
    offs = {c: np.full(k, -1, dtype=np.int64) for c in SUB_LENGTH}
    gi = np.flatnonzero(good)
    t_g, r_g, o_g = _walk(b, cand[gi], end[gi])
    tiles[gi] = t_g
    readable[gi] = r_g | ~imu[gi]  # the decoded lengths are those of IMU output sub-packets
    for c in SUB_LENGTH:
        offs[c][gi] = o_g[c]
    fi = np.flatnonzero(good & tiles)
    taken = fi[_first_fit(cand[fi], end[fi] + 2)]
    # candidates outside the packets taken: corrupt or partial packets, each one counted once,
    # each reaching at most to the next packet taken
    rest = np.ones(k, dtype=bool)
    rest[taken] = False
    oi = np.flatnonzero(rest)
    j = np.searchsorted(cand[taken], cand[oi], side="right") - 1
    oi = oi[(j < 0) | (cand[oi] >= np.append(end[taken] + 2, 0)[j])]
    limit = np.append(cand[taken], n)[np.searchsorted(cand[taken], cand[oi], side="left")]
    o_end = np.minimum(end[oi] + 2, limit)
    keep = _first_fit(cand[oi], o_end)
    bad, bad_end = oi[keep], o_end[keep]
    runs = _unsynced(np.concatenate((cand[taken], cand[bad])),
                     np.concatenate((end[taken] + 2, bad_end)), n)
    ok = taken[readable[taken]]
    samples = ok[imu[ok] & (offs[CODE_ACC][ok] >= 0)]
    acc = _gather(b, offs[CODE_ACC][samples] + 2, 12, ">f4").astype(np.float64)
    finite = np.isfinite(acc).all(axis=1)
    seconds = week = flags = None
    has_t = offs[CODE_TIME][samples] >= 0
    if has_t.any():
        at = offs[CODE_TIME][samples[has_t]] + 2
        seconds = np.full(samples.shape[0], np.nan)
        seconds[has_t] = _gather(b, at, 8, ">f8")[:, 0]
        week = np.full(samples.shape[0], -1, dtype=np.int64)
        week[has_t] = _gather(b, at + 8, 2, ">u2")[:, 0]
        flags = np.full(samples.shape[0], -1, dtype=np.int64)
        flags[has_t] = _gather(b, at + 10, 2, ">u2")[:, 0]
        finite &= ~has_t | ((seconds >= 0) & (seconds < WEEK_S))  # NaN fails both

    def optional(code: int, width: int) -> np.ndarray | None:
        have = offs[code][samples] >= 0
        if not have.any():
            return None
        out = np.full((samples.shape[0], width // 4), np.nan)
        out[have] = _gather(b, offs[code][samples[have]] + 2, width, ">f4")
        return out[finite]

    gyro = optional(CODE_GYRO, 12)
    temp = optional(CODE_TEMP, 4)
    kinds = {SKIP_TRUNCATED: bad[~complete[bad]], SKIP_CHECKSUM: bad[complete[bad] & ~good[bad]],
             "frame": bad[good[bad]], SKIP_LAYOUT: taken[~readable[taken]],
             SKIP_NON_FINITE: samples[~finite]}
    unreadable = kinds[SKIP_LAYOUT]
    return MscipStream(
        offset=cand[samples[finite]], acc=acc[finite], gyro=gyro,
        temperature=None if temp is None else temp[:, 0],
        seconds=None if seconds is None else seconds[finite],
        week=None if week is None else week[finite], flags=None if flags is None else flags[finite],
        packets_ok=int(ok.shape[0]), packets_bad_checksum=int(kinds[SKIP_CHECKSUM].shape[0]),
        packets_bad_layout=int(kinds["frame"].shape[0] + unreadable.shape[0]),
        packets_truncated=int(kinds[SKIP_TRUNCATED].shape[0]),
        packets_without_acc=int(np.count_nonzero(imu[ok]) - samples.shape[0]),
        packets_other_type=int(np.count_nonzero(~imu[ok])), packets_non_finite=int((~finite).sum()),
        bytes_skipped=n - int((end[ok] + 2 - cand[ok]).sum()), bytes_unsynced=int((runs[1] - runs[0]).sum()),
        skipped=tuple(_skip_entries(b, cand, has_len, end, kinds, runs)))


# --------------------------------------------------------------------------- GPS time


def gps_to_utc(week: int, seconds: float) -> datetime:
    """UTC of a GPS time (week, seconds of week): GPS epoch + week + seconds − 18 s (µs resolution)."""
    return GPS_EPOCH + timedelta(weeks=int(week), seconds=float(seconds) - GPS_MINUS_UTC_S)


def utc_to_gps(stamp: datetime) -> tuple[int, float]:
    """GPS (week, seconds of week) of a UTC time (the inverse of :func:`gps_to_utc`)."""
    us = (stamp.astimezone(UTC) - GPS_EPOCH + timedelta(seconds=GPS_MINUS_UTC_S)) // timedelta(microseconds=1)
    week, rest = divmod(us, _WEEK_US)
    return int(week), rest / 1e6


# --------------------------------------------------------------------------- reading


def read_mscip_bin(path: str | Path, sample_rate_hz: float | None = None, acc_unit: str = "g",
                   device: str | None = None) -> Recording:
    """Read a captured Memsense MSCIP byte stream (``mscip-bin``).

    Parameters
    ----------
    path
        The file.
    sample_rate_hz
        Nominal rate, Hz: the time base when the stream has no time sub-packets.
    acc_unit
        Unit of the accelerometer sub-packets: ``g``, ``mg`` or ``m/s2``.
    device
        Device id to attach.

    Returns
    -------
    Recording
        ``t`` in s from the first sample, ``acc`` in m/s² (× g0 for g); ``start_utc`` (and
        ``header["Start (UTC)"]``) the GPS time of the first sample − 18 s; gyro (deg/s) and
        temperature (°C) in ``extra`` under the mscip-csv column names when present. Skipped
        entries and ``line`` hold byte offsets instead of line numbers.

    Raises
    ------
    RawFormatError
        Unreadable file, no valid packet, no accelerometer data, or neither time sub-packets
        nor ``sample_rate_hz``.
    """
    path = Path(path)
    if acc_unit not in ACC_UNITS:
        raise ValueError(f"acc_unit: expected one of {', '.join(ACC_UNITS)}, found {acc_unit!r}")
    data = read_file_bytes(path, text=False)
    s = decode_mscip(data)
    bad = (f"{s.packets_bad_checksum} with a bad checksum, {s.packets_bad_layout} with a bad layout, "
           f"{s.packets_truncated} truncated")
    if s.packets_ok == 0:
        raise RawFormatError(path, "MSCIP packets (A5 A5 <type> <length> <sub-packets> <2-byte Fletcher "
                             "checksum>)", f"no valid packet in {len(data)} bytes ({bad})")
    if s.n == 0:
        raise RawFormatError(path, "IMU output packets (type 0xA2) with an accelerometer sub-packet (0x81)",
                             f"{s.packets_ok} valid packets, none with accelerometer data "
                             f"({s.packets_other_type} of another type, {s.packets_non_finite} with "
                             f"NaN, infinite or out-of-range values; {bad})")
    values: dict[str, np.ndarray] = {"ax": s.acc[:, 0], "ay": s.acc[:, 1], "az": s.acc[:, 2]}
    if s.gyro is not None:
        values.update({name: s.gyro[:, i] for i, name in enumerate(MSCIP_GYRO)})
    if s.temperature is not None:
        values[MSCIP_TEMP] = s.temperature
    body = Body(values, s.offset.copy(), s.packets_ok + len(s.skipped), list(s.skipped), path, 0)
    header: dict[str, str] = {}
    start_utc = None
    timed = np.isfinite(s.seconds) if s.seconds is not None else np.zeros(s.n, dtype=bool)
    if timed.any():
        assert s.seconds is not None and s.week is not None
        body.skipped += [SkippedLine(int(at), SKIP_NO_TIME, f"packet at byte {int(at)}: no time sub-packet "
                                     "in a stream whose other packets have one") for at in s.offset[~timed]]
        body.skipped.sort(key=lambda e: e.line)
        body.values = {k: v[timed] for k, v in values.items()} | {"_w": s.week[timed], "_s": s.seconds[timed]}
        body.lines = body.lines[timed]
        w, sec = body.values["_w"], body.values["_s"]
        t, _ = clean_times(body, (w - w[0]).astype(np.float64) * WEEK_S + (sec - sec[0]), MAX_STEP_S)
        t = t - t[0]
        week0, sec0 = int(body.values["_w"][0]), float(body.values["_s"][0])
        header["GPS Week"], header["GPS Seconds"] = str(week0), repr(sec0)
        if week0 > 0:  # week 0 (January 1980): the receiver has no GPS time yet
            start_utc = gps_to_utc(week0, sec0)
            header["Start (UTC)"] = start_utc.strftime("%Y-%m-%dT%H:%M:%S.%fZ")
    elif sample_rate_hz is None:
        raise RawFormatError(path, "time sub-packets (0x88) or a sample_rate_hz in the device's manifest "
                             "entry", f"{s.n} IMU packets without time (set sample_rate_hz in the "
                             "manifest)")
    else:
        t = np.arange(s.n, dtype=np.float64) / sample_rate_hz
    if sample_rate_hz is not None:
        header["Sample Rate (Hz)"] = f"{sample_rate_hz:g}"
    v = body.values
    acc = np.stack([v["ax"], v["ay"], v["az"]], axis=1) * ACC_UNITS[acc_unit]
    gaps = find_gaps(t, body.lines, 1.0 / sample_rate_hz if sample_rate_hz else None)
    diag = ReadDiagnostics(path, 0, body.lines_read, int(t.shape[0]), tuple(body.skipped), gaps)
    extra = {c: v[c] for c in (*MSCIP_GYRO, MSCIP_TEMP) if c in v}
    hdr = header | ({"device": device} if device else {})
    return Recording(path, "mscip-bin", t, acc, np.zeros(t.shape[0], dtype=bool), body.lines, start_utc,
                     sample_rate_hz, hdr, diag, extra)


# --------------------------------------------------------------------------- writing


def encode_mscip(
    t_s: np.ndarray,
    acc: np.ndarray,
    start_utc: str | datetime | None,
    *,
    gyro: np.ndarray | None = None,
    temperature: np.ndarray | None = None,
    flags: int = 0,
) -> bytes:
    """MSCIP byte stream of IMU output packets, one per sample (deterministic bytes).

    Each packet holds, in this order, accelerometer (0x81), gyroscope (0x82) and temperature
    (0x87) when given, and time (0x88) when ``start_utc`` is given.

    Parameters
    ----------
    t_s
        (N,) s after ``start_utc``.
    acc
        (N, 3) accelerometer values in the stream's unit (written as float32).
    start_utc
        UTC of ``t_s = 0`` (ISO 8601 string or aware datetime), or None for packets without time.
    gyro
        (N, 3) angular rate, deg/s, or None.
    temperature
        (N,) °C, or None.
    flags
        Flags word of the time sub-packets.

    Returns
    -------
    bytes
    """
    acc = np.asarray(acc, dtype=np.float64)
    n = acc.shape[0]
    fields: list[tuple[str, str] | tuple[str, str, tuple[int, ...]]] = [
        ("sync", ">u2"), ("type", "u1"), ("length", "u1")]
    subs = {CODE_ACC: acc, CODE_GYRO: gyro, CODE_TEMP: temperature}
    for code, values in subs.items():
        if values is not None:
            fields += [(f"c{code}", "u1"), (f"n{code}", "u1"), (f"v{code}", ">f4", (SUB_LENGTH[code] // 4,))]
    if start_utc is not None:
        fields += [(f"c{CODE_TIME}", "u1"), (f"n{CODE_TIME}", "u1"), ("sec", ">f8"), ("week", ">u2"),
                   ("flags", ">u2")]
    fields += [("check", "u1", (2,))]
    rec = np.zeros(n, dtype=np.dtype(fields))
    size = rec.dtype.itemsize
    rec["sync"], rec["type"], rec["length"] = 0xA5A5, TYPE_IMU_OUTPUT, size - 6
    for code, values in subs.items():
        if values is not None:
            rec[f"c{code}"], rec[f"n{code}"] = code, SUB_LENGTH[code]
            rec[f"v{code}"] = np.asarray(values, dtype=np.float64).reshape(n, -1)
    if start_utc is not None:
        stamp = start_utc if isinstance(start_utc, datetime) else parse_utc(start_utc)
        if stamp is None:
            raise ValueError(f"start_utc: expected an ISO 8601 UTC time, found {start_utc!r}")
        week0, sec0 = utc_to_gps(stamp)
        sec = sec0 + np.asarray(t_s, dtype=np.float64)
        roll = np.floor(sec / WEEK_S)
        rec[f"c{CODE_TIME}"], rec[f"n{CODE_TIME}"] = CODE_TIME, SUB_LENGTH[CODE_TIME]
        rec["sec"], rec["week"], rec["flags"] = sec - roll * WEEK_S, week0 + roll.astype(np.int64), flags
    raw = rec.view(np.uint8).reshape(n, size)
    weights = np.arange(size - 2, 0, -1, dtype=np.float64)  # c2 = Σ (L − i)·byte_i
    for lo in range(0, n, _CHUNK):
        block = raw[lo:lo + _CHUNK, :-2].astype(np.float64)  # exact: sums stay far below 2^53
        raw[lo:lo + _CHUNK, -2] = block.sum(axis=1).astype(np.int64) % 256
        raw[lo:lo + _CHUNK, -1] = (block @ weights).astype(np.int64) % 256
    return raw.tobytes()


def write_mscip_bin(
    path: str | Path,
    t_s: np.ndarray,
    acc_mps2: np.ndarray,
    start_utc: str | datetime | None,
    *,
    gyro: np.ndarray | None = None,
    temperature: np.ndarray | None = None,
    unit: str = "g",
) -> None:
    """Write an MSCIP byte stream (atomically) that :func:`read_mscip_bin` reads back.

    Parameters
    ----------
    path
        Target file.
    t_s
        (N,) s after ``start_utc``.
    acc_mps2
        (N, 3) specific force, m/s²; written in ``unit`` as float32.
    start_utc
        UTC of ``t_s = 0``, or None to write no time sub-packets.
    gyro
        (N, 3) deg/s, or None.
    temperature
        (N,) °C, or None.
    unit
        ``g``, ``mg`` or ``m/s2``.
    """
    if unit not in ACC_UNITS:
        raise ValueError(f"unit: expected one of {', '.join(ACC_UNITS)}, found {unit!r}")
    acc = np.asarray(acc_mps2, dtype=np.float64) / ACC_UNITS[unit]
    write_bytes_atomic(path, encode_mscip(t_s, acc, start_utc, gyro=gyro, temperature=temperature))


def _read(path: Path, device: DeviceSpec) -> Recording:
    opts = device.bin if device.bin is not None else BinOptions()
    return read_mscip_bin(path, opts.sample_rate_hz, opts.acc_unit, device.id)


# init: a binary file with A5 A5 sync
register_format(Format(name="mscip-bin", reader=_read, reference=True, order=30))
