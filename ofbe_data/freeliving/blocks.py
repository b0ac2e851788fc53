"""Axivity ``.cwa`` files, sector by sector, in numpy: the header, the data blocks, their checksums.

The format (OpenMovement's ``cwa.h``; GGIRread's ``R/readAxivity.R``, which this follows field by
field) is a 1024-byte header (``MD``) and then 512-byte data blocks (``AX``), block ``i`` at byte
``1024 + 512 i``. A data block is valid when its 256 little-endian 16-bit words sum to 0 modulo
65536 (blocks whose sample-rate byte is 0, written by very old firmware, carry no checksum). Its
fields, by byte offset:

====== ======== ==============================================================================
offset type     field
====== ======== ==============================================================================
0      ``AX``   packet header; 2: u16 packet length (508)
4      u16      top bit set: a 15-bit fraction of a second for the time stamp
10     u32      sequence number (GGIRread's ``blockID``)
14     u32      time stamp, packed ``YYYYYYMM MMDDDDDh hhhhmmmm mmssssss`` (year − 2000)
18     u16      light (low 10 bits); accelerometer scale code (top 3 bits: 1/2^(8+n) g);
                gyroscope range code (bits 10–12: 8000/2^n °/s)
20     u16      temperature (low 10 bits): ``value · 75 / 256 − 50`` °C
24     u8       sample rate ``3200 / 2^(15 − (code & 15))`` Hz; range ``16 >> (code >> 6)`` g
25     u8       axes (top nibble: 3, 6 = gyroscope + accelerometer, 9) and packing (bottom
                nibble: 0 = three 10-bit values and a 2-bit exponent in a u32; 2 = int16)
26     s16      index of the sample at which the whole-second time stamp holds
28     u16      number of samples in the block
30     …        the samples; 510: u16 checksum
====== ======== ==============================================================================

Why ofbe reads ``.cwa`` itself instead of through actfast: GGIR resamples every block onto a
regular grid and imputes bad blocks and time jumps, which needs each block's time stamp and
sequence number (actfast hands on samples only, refuses a file with a bad block, and in its
lenient mode drops the block); and reading block by block bounds the memory of a week-long file
(actfast holds every sample at once: 2.35 GB for 7 days at 100 Hz, benchmarks/autocal_raw.py).
The resampling that GGIRread does on these blocks is :mod:`ofbe_data.freeliving.axivity`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ofbe_data.core.errors import OfbeError

HEADER_BYTES = 1024
"""The ``MD`` header, bytes."""
BLOCK_BYTES = 512
"""One data block, bytes."""
_HEADER_HW_AX6 = 0x64
"""Hardware type byte (offset 4) of an AX6; GGIRread calls every other value an AX3."""


class RawFileError(OfbeError):
    """A raw wearable file cannot be read.

    Parameters
    ----------
    path
        The file.
    expected, found
        What the format asks for and what the file holds.
    offset
        Byte offset of the problem in the file, when there is one.
    """

    def __init__(self, path: str | Path, expected: str, found: str, offset: int | None = None) -> None:
        self.path = Path(path)
        self.expected = expected
        self.found = found
        self.offset = offset
        where = f"{path} (byte {offset}): " if offset is not None else f"{path}: "
        super().__init__(f"{where}expected {expected}, found {found}")


@dataclass(frozen=True)
class BadBlock:
    """A data block that cannot be trusted and is skipped.

    Attributes
    ----------
    index
        Data block number (0: the block right after the header).
    byte_offset
        Where it starts in the file: ``1024 + 512 · index``.
    reason
        ``checksum`` (its words do not sum to 0), ``not AX`` (checksum good, but no ``AX``
        packet of 508 bytes), ``truncated`` (the file ends inside it).
    """

    index: int
    byte_offset: int
    reason: str


@dataclass(frozen=True)
class CwaHeader:
    """The ``MD`` header of a ``.cwa`` file.

    Attributes
    ----------
    hardware
        ``AX3`` or ``AX6`` (GGIRread's rule: byte 4 = 0x64 is an AX6).
    device_id
        Serial number (lower 16 bits at offset 5, upper at 11; 0xFFFF there means none).
    session_id
        Session number set when the device was configured.
    sample_rate_hz
        Configured rate, Hz (GGIRread's ``frequency_header``: every block is resampled to it).
    range_g
        Configured accelerometer range, ±g.
    firmware
        Firmware revision.
    time_zone_min
        The clock's offset from UTC, minutes, or None when the file says unknown (−1).
    annotation
        Metadata text written at configuration (offset 64, 448 bytes), trailing blanks removed.
    n_blocks
        Whole data blocks in the file.
    file_bytes
        Size of the file, bytes.
    """

    hardware: str
    device_id: int
    session_id: int
    sample_rate_hz: float
    range_g: float
    firmware: int
    time_zone_min: int | None
    annotation: str
    n_blocks: int
    file_bytes: int


@dataclass(frozen=True)
class CwaParams:
    """What GGIRread takes from the first valid data block and keeps for every block.

    Attributes
    ----------
    accel_scale
        g per count (``1 / 2^(8 + code)``).
    n_axes
        3 (accelerometer) or 6 (gyroscope, then accelerometer).
    frequency_hz
        Block sample rate, Hz (GGIRread's ``frequency_data``).
    fractional
        True when the time stamps carry a fraction of a second (GGIRread's ``format == 1``).
    """

    accel_scale: float
    n_axes: int
    frequency_hz: float
    fractional: bool


@dataclass(frozen=True, eq=False)
class CwaBlocks:
    """Decoded data blocks, one row each (struct of arrays).

    Attributes
    ----------
    index
        Shape (m,): data block numbers.
    valid
        Shape (m,): checksum good and an ``AX`` packet.
    sequence
        Shape (m,): sequence numbers (GGIRread's ``blockID``).
    start_s
        Shape (m,): time of the block's first sample on the device clock, s since 1970 read as
        UTC (GGIRread: ``timestamp + fraction / 65536 − shift / frequency``).
    temperature_c
        Shape (m,): block temperature, °C.
    count
        Shape (m,): samples in each block.
    samples
        Shape (n_axes, m, capacity): the samples, accelerometer in g (after the gyroscope in °/s
        for six axes); those past a block's ``count`` are 0.
    """

    index: np.ndarray
    valid: np.ndarray
    sequence: np.ndarray
    start_s: np.ndarray
    temperature_c: np.ndarray
    count: np.ndarray
    samples: np.ndarray


def _u16(b: np.ndarray, at: int) -> np.ndarray:
    return b[:, at].astype(np.int64) | (b[:, at + 1].astype(np.int64) << 8)


def _u32(b: np.ndarray, at: int) -> np.ndarray:
    return _u16(b, at) | (_u16(b, at + 2) << 16)


def _s16(b: np.ndarray, at: int) -> np.ndarray:
    v = _u16(b, at)
    return np.where(v >= 0x8000, v - 0x10000, v)


def _rate_hz(code: int | np.ndarray) -> np.ndarray:
    """``round(3200 / 2^(15 − (code & 15)))``, Hz (GGIRread's rounding)."""
    return np.round(3200.0 / np.left_shift(1, 15 - (np.asarray(code) & 15)).astype(np.float64))


def read_header(path: str | Path, head: bytes, file_bytes: int) -> CwaHeader:
    """Parse the ``MD`` header (the first 1024 bytes of the file).

    Raises
    ------
    RawFileError
        The file is shorter than a header or does not start with ``MD``.
    """
    if len(head) < HEADER_BYTES or head[:2] != b"MD":
        found = f"{len(head)} bytes" if len(head) < HEADER_BYTES else f"{head[:2]!r}"
        raise RawFileError(path, "an Axivity .cwa header ('MD', 1024 bytes)", found, 0)
    b = np.frombuffer(head[:HEADER_BYTES], dtype=np.uint8)[None, :]
    upper = int(_u16(b, 11)[0])
    rate = int(b[0, 36])
    zone = int(_s16(b, 42)[0])
    return CwaHeader(
        hardware="AX6" if int(b[0, 4]) == _HEADER_HW_AX6 else "AX3",
        device_id=((0 if upper == 0xFFFF else upper) << 16) | int(_u16(b, 5)[0]),
        session_id=int(_u32(b, 7)[0]),
        sample_rate_hz=float(_rate_hz(rate)),
        range_g=float(16 >> (rate >> 6)),
        firmware=int(b[0, 41]),
        time_zone_min=None if zone == -1 else zone,
        annotation=head[64:512].split(b"\0")[0].decode("latin-1").rstrip(" \xff"),
        n_blocks=max(0, (file_bytes - HEADER_BYTES) // BLOCK_BYTES),
        file_bytes=file_bytes,
    )


def block_status(sectors: np.ndarray) -> np.ndarray:
    """Which of ``sectors`` (shape (m, 512), uint8) are valid data blocks, shape (m,) bool.

    Valid: the 256 little-endian u16 words sum to 0 modulo 65536 (not checked when the
    sample-rate byte, offset 24, is 0, as GGIRread), and an ``AX`` packet of length 508.
    """
    words = np.ascontiguousarray(sectors).view("<u2")
    checksum_ok = (words.sum(axis=1, dtype=np.uint32) % 65536 == 0) | (sectors[:, 24] == 0)
    return checksum_ok & (sectors[:, 0] == ord("A")) & (sectors[:, 1] == ord("X")) & (_u16(sectors, 2) == 508)


def bad_reason(sector: np.ndarray) -> str:
    """Why one invalid sector (shape (512,)) is bad: ``checksum`` or ``not AX``."""
    words = np.ascontiguousarray(sector).view("<u2")
    if int(sector[24]) != 0 and int(words.sum(dtype=np.uint64)) % 65536 != 0:
        return "checksum"
    return "not AX"


def block_params(sector: np.ndarray) -> CwaParams:
    """GGIRread's per-file parameters from the first valid block (shape (512,))."""
    b = sector[None, :]
    rate = int(b[0, 24])
    frequency = float(_rate_hz(rate)) if rate != 0 else float(_s16(b, 26)[0])
    return CwaParams(accel_scale=1.0 / 2.0 ** (8 + (int(_u16(b, 18)[0]) >> 13)), n_axes=int(b[0, 25]) >> 4,
                     frequency_hz=frequency, fractional=rate != 0 and bool(int(_u16(b, 4)[0]) & 0x8000))


def _days_from_civil(y: np.ndarray, m: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Days since 1970-01-01 of proleptic Gregorian dates (integer arrays)."""
    y = y - (m <= 2)
    era = np.floor_divide(y, 400)
    yoe = y - era * 400
    doy = (153 * (m + np.where(m > 2, -3, 9)) + 2) // 5 + d - 1
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    return era * 146097 + doe - 719468


def packed_seconds(stamp: np.ndarray) -> np.ndarray:
    """Seconds since 1970 (read as UTC) of packed ``.cwa`` time stamps (int64 array).

    Bits: year − 2000 (31–26), month (25–22), day (21–17), hour (16–12), minute (11–6),
    second (5–0), as GGIRread's ``timestampDecoder``.
    """
    s = np.asarray(stamp, dtype=np.int64)
    days = _days_from_civil(((s >> 26) & 0x3F) + 2000, (s >> 22) & 0x0F, (s >> 17) & 0x1F)
    return days * 86400 + ((s >> 12) & 0x1F) * 3600 + ((s >> 6) & 0x3F) * 60 + (s & 0x3F)


def start_seconds(sectors: np.ndarray, params: CwaParams) -> np.ndarray:
    """Time of each block's first sample (shape (m,), s), as GGIRread's ``readDataBlock``.

    ``shift`` is the s16 at offset 26; with fractional time stamps the fraction is
    ``(u16@4 & 0x7FFF) << 1`` (a 16-bit fraction of a second) and ``shift`` grows by
    ``(fraction · frequency) >> 16`` whole samples; the start is
    ``(timestamp + fraction / 65536) + (−shift / frequency)``, evaluated in that order.
    """
    freq = params.frequency_hz
    if int(sectors[0, 24]) == 0 and not params.fractional:  # very old files: no shift
        shift = np.zeros(len(sectors), dtype=np.int64)
    else:
        shift = _s16(sectors, 26)
    fraction = np.zeros(len(sectors), dtype=np.int64)
    if params.fractional:
        fraction = (_u16(sectors, 4) & 0x7FFF) << 1
        shift = shift + ((fraction * int(freq)) >> 16)
    whole = packed_seconds(_u32(sectors, 14)).astype(np.float64)
    return (whole + fraction / 65536.0) + (-shift / freq)


def _unpack(sectors: np.ndarray, params: CwaParams) -> np.ndarray:
    """Samples of every block, shape (n_axes, m, capacity), raw counts as float64."""
    body = np.ascontiguousarray(sectors[:, 30:510])
    packed = (sectors[:, 25] & 0x0F) == 0
    n_axes = params.n_axes
    m = len(sectors)
    if n_axes == 3 and packed.any():
        words = body.view("<u4")  # (m, 120): eezzzzzz zzzzyyyy yyyyyyxx xxxxxxxx
        exp = words >> 30
        shifted = bool(exp.any())
        out = np.empty((3, m, 120))
        for k in range(3):
            v = ((words >> (10 * k)) & 0x3FF) ^ 0x200
            v -= 0x200  # 10-bit two's complement, in uint32 arithmetic (wraps)
            if shifted:
                v <<= exp
            out[k] = v.view(np.int32)
        if not packed.all():  # a mix of packed and unpacked blocks: unpacked ones read as int16
            plain = body.view("<i2")[:, : 80 * 3].reshape(m, 80, 3).transpose(2, 0, 1)
            out[:, ~packed, :80] = plain[:, ~packed]
            out[:, ~packed, 80:] = 0.0
        return out
    per = 240 // n_axes
    return body.view("<i2")[:, : per * n_axes].reshape(m, per, n_axes).transpose(2, 0, 1).astype(np.float64)


def decode_blocks(sectors: np.ndarray, first_index: int, params: CwaParams) -> CwaBlocks:
    """Decode consecutive data blocks.

    Parameters
    ----------
    sectors
        Shape (m, 512), uint8: blocks ``first_index … first_index + m − 1``.
    first_index
        Number of the first block.
    params
        From the file's first valid block (:func:`block_params`), as GGIRread keeps them.

    Returns
    -------
    CwaBlocks
        Every block decoded; invalid ones flagged (their other fields are meaningless).
    """
    m = len(sectors)
    valid = block_status(sectors)
    samples = _unpack(sectors, params)
    counts = np.minimum(_u16(sectors, 28), samples.shape[2])
    if params.n_axes == 3:
        samples *= params.accel_scale
    else:  # GGIRread: gyroscope (first three) in °/s from the block's range code, then accelerometer in g
        gyro_range = 8000.0 / 2.0 ** ((_u16(sectors, 18) >> 10) & 0x07)
        samples[:3] *= (gyro_range / 2.0**15)[None, :, None]
        samples[3:6] *= params.accel_scale
    beyond = np.arange(samples.shape[2])[None, :] >= counts[:, None]
    if beyond.any():
        samples[:, beyond] = 0.0
    return CwaBlocks(
        index=np.arange(first_index, first_index + m, dtype=np.int64),
        valid=valid,
        sequence=_u32(sectors, 10),
        start_s=start_seconds(sectors, params),
        temperature_c=(_u16(sectors, 20) & 0x03FF) * 75.0 / 256.0 - 50.0,
        count=counts,
        samples=samples,
    )


# --------------------------------------------------------------------------- writing (tests, benchmarks)


def encode_header(device_id: int, session_id: int = 0, rate_hz: float = 100.0, range_g: int = 8,
                  hardware: str = "AX3", annotation: str = "") -> bytes:
    """A 1024-byte ``MD`` header (the fields :func:`read_header` reads; the rest 0xFF as a device
    leaves them).

    Raises
    ------
    ValueError
        A rate that is not ``3200 / 2^k`` Hz or a range not in 2, 4, 8, 16 g.
    """
    code = 15 - round(math.log2(3200.0 / rate_hz))
    if not 0 <= code <= 15 or _rate_hz(code) != rate_hz or range_g not in (2, 4, 8, 16):
        raise ValueError("expected a rate of 3200/2^k Hz and a range of 2, 4, 8 or 16 g, found "
                         f"{rate_hz} Hz, {range_g} g")
    head = bytearray(b"\xff" * HEADER_BYTES)
    head[0:2], head[2:4] = b"MD", (HEADER_BYTES - 4).to_bytes(2, "little")
    head[4] = _HEADER_HW_AX6 if hardware == "AX6" else 0x17
    head[5:7] = (device_id & 0xFFFF).to_bytes(2, "little")
    head[7:11] = session_id.to_bytes(4, "little")
    head[11:13] = (device_id >> 16).to_bytes(2, "little")
    head[36] = code | ({16: 0, 8: 1, 4: 2, 2: 3}[range_g] << 6)
    head[41] = 0
    head[42:44] = (-1).to_bytes(2, "little", signed=True)
    text = annotation.encode("latin-1")[:448]
    head[64:64 + len(text)] = text
    head[64 + len(text):512] = b" " * (448 - len(text))
    return bytes(head)


def packed_timestamp(seconds: np.ndarray) -> np.ndarray:
    """Whole seconds since 1970 (read as UTC) → packed ``.cwa`` time stamps (inverse of
    :func:`packed_seconds`, years 2000–2063)."""
    s = np.asarray(seconds, dtype="datetime64[s]")
    year = s.astype("datetime64[Y]").astype(np.int64) + 1970
    month = s.astype("datetime64[M]").astype(np.int64) % 12 + 1
    day = (s.astype("datetime64[D]") - s.astype("datetime64[M]")).astype(np.int64) + 1
    sec_of_day = (s - s.astype("datetime64[D]")).astype(np.int64)
    return ((year - 2000) << 26) | (month << 22) | (day << 17) | ((sec_of_day // 3600) << 12) \
        | (((sec_of_day // 60) % 60) << 6) | (sec_of_day % 60)


def encode_blocks(counts: np.ndarray, start_s: np.ndarray, first_sequence: int = 0, session_id: int = 0,
                  temperature_c: np.ndarray | float = 25.0, rate_hz: float = 100.0,
                  range_g: int = 8) -> np.ndarray:
    """Packed three-axis ``AX`` blocks of 120 samples with valid checksums.

    Parameters
    ----------
    counts
        Shape (m, 120, 3), integers: samples in 1/256 g, within ±511 (±2 g; exponent 0).
    start_s
        Shape (m,): time of each block's first sample, s since 1970 read as UTC, on the
        ``1 / rate_hz`` grid of its second (written as the next whole second and the index of
        its sample, without a fraction).
    first_sequence
        Sequence number of the first block.
    session_id, rate_hz, range_g
        As the header says them.
    temperature_c
        Block temperatures, °C (shape (m,) or one value), to 75/256 °C.

    Returns
    -------
    np.ndarray
        Shape (m, 512), uint8.
    """
    c = np.asarray(counts, dtype=np.int64)
    m = len(c)
    if c.shape != (m, 120, 3) or np.abs(c).max(initial=0) > 511:
        raise ValueError(f"expected counts of shape (m, 120, 3) within ±511, found {c.shape}")
    out = np.zeros((m, BLOCK_BYTES), dtype=np.uint8)

    def put(at: int, values: np.ndarray | int, nbytes: int) -> None:
        v = np.broadcast_to(np.asarray(values, dtype=np.int64), (m,)) & ((1 << (8 * nbytes)) - 1)
        for k in range(nbytes):
            out[:, at + k] = (v >> (8 * k)) & 0xFF

    whole = np.ceil(np.asarray(start_s, dtype=np.float64))
    index = np.round((whole - start_s) * rate_hz).astype(np.int64)
    temp = np.round((np.broadcast_to(temperature_c, (m,)) + 50.0) * 256.0 / 75.0).astype(np.int64)
    out[:, 0], out[:, 1] = ord("A"), ord("X")
    put(2, 508, 2)
    put(4, 0x8000, 2)  # fractional time stamps, fraction 0
    put(6, session_id, 4)
    put(10, first_sequence + np.arange(m), 4)
    put(14, packed_timestamp(whole.astype(np.int64)), 4)
    put(18, 0, 2)  # light 0; accelerometer scale code 0: 1/256 g
    put(20, temp & 0x3FF, 2)
    out[:, 23] = 200
    out[:, 24] = (15 - round(math.log2(3200.0 / rate_hz))) | ({16: 0, 8: 1, 4: 2, 2: 3}[range_g] << 6)
    out[:, 25] = 0x30  # three axes, packed
    put(26, index, 2)
    put(28, 120, 2)
    words = (c[:, :, 0] & 0x3FF) | ((c[:, :, 1] & 0x3FF) << 10) | ((c[:, :, 2] & 0x3FF) << 20)
    out[:, 30:510] = words.astype("<u4").view(np.uint8).reshape(m, 480)
    partial = out[:, :510].view("<u2").sum(axis=1, dtype=np.uint64) % 65536
    put(510, (65536 - partial.astype(np.int64)) % 65536, 2)
    return out
