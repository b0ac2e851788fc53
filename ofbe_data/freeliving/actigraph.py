"""ActiGraph ``.gt3x`` files, record by record, in numpy.

The format (ActiGraph's GT3X-File-Format documentation; read here as GGIR's reader,
THLfi/read.gt3x ``src/parseGT3X.cpp`` (its behaviour followed, none of its code), and actfast,
childmindresearch/actfast ``src/actigraph``, MIT, read it; written anew) is a zip archive with
``info.txt`` (``key: value`` lines: ``Sample Rate``, ``Acceleration Scale``, ``Serial Number``,
``TimeZone``…) and ``log.bin``, a sequence of records:

====== ======== ================================================================================
offset type     field
====== ======== ================================================================================
0      u8       separator 0x1E
1      u8       type: 0x00 ``ACTIVITY`` (one second of samples, 12-bit two's complement packed
                most significant first, in the order y, x, z), 0x1A ``ACTIVITY2`` (int16
                little-endian, x, y, z), 0x15 ``PARAMETERS`` (8-byte address/key/value entries),
                others (battery, lux, events, metadata…) not read here
2      u32      time stamp: seconds since 1970 on the device clock
6      u16      payload size ``s``
8      …        payload; then one checksum byte: the one's complement of the XOR of all
                bytes before it (separator included)
====== ======== ================================================================================

What the readers do, and this reader too: an ``ACTIVITY`` record of ``s`` bytes holds
``⌊8s / 36⌋`` samples, an ``ACTIVITY2`` record ``⌊s / 6⌋``; sample ``i`` lies at
``t + i · ⌊10⁹ / rate⌋`` ns (actfast); values are ``count / scale`` rounded to 1 mg, halves
away from zero (read.gt3x's ``round(x / scale · 1000) / 1000``), ``scale`` and ``rate`` from
``info.txt`` (read.gt3x; a ``PARAMETERS`` record's accelerometer scale, address 0 key 55, when
``info.txt`` has none, as actfast). Seconds the device did not write (idle sleep, an empty
``ACTIVITY`` record) are missing samples: the samples either side become neighbours.

Damage is named: a record whose checksum fails is skipped
(:class:`~ofbe_data.freeliving.blocks.BadBlock` with its record number and byte offset in
``log.bin``; neither read.gt3x nor actfast checks it), a ``log.bin`` that ends inside a record
keeps the records before (``truncated``), a missing separator, a zip without its central
directory (a truncated file) or a member failing its CRC-32 stop the reading with a
:class:`~ofbe_data.freeliving.blocks.RawFileError`. Older "NHANES" files (``activity.bin``
instead of ``log.bin``) are refused with that reason.

Memory: ``log.bin`` is read through the zip member (:meth:`zipfile.ZipFile.open`) a block of
:data:`READ_BYTES` at a time.
"""

from __future__ import annotations

import struct
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import numpy as np

from ofbe_data.freeliving.blocks import BadBlock, RawFileError

INFO_NAME = "info.txt"
LOG_NAME = "log.bin"
OLD_NAME = "activity.bin"
"""The samples of an older (NHANES-style) ``.gt3x`` file."""
SEPARATOR = 0x1E
ACTIVITY, ACTIVITY2, PARAMETERS = 0x00, 0x1A, 0x15
RECORD_HEADER = 8
"""Separator, type, time stamp and size, bytes."""
READ_BYTES = 1 << 22
"""Bytes of ``log.bin`` parsed at a time."""
DECIMALS = 3
"""read.gt3x rounds samples to 1 mg."""
_HEAD = struct.Struct("<BIH")


def round_half_away(x: np.ndarray, decimals: int) -> np.ndarray:
    """Round to ``decimals`` places, halves away from zero (C's ``round``, as ``read.gt3x``)."""
    scale = 10.0**decimals
    return np.sign(x) * np.floor(np.abs(x) * scale + 0.5) / scale


def decode_ssp(value: int) -> float:
    """A ``PARAMETERS`` float (ActiGraph's "SSP" encoding: 8-bit exponent, 24-bit significand)."""
    if value == 0x007FFFFF:
        return float("inf")
    if value == 0x00800000:
        return float("-inf")
    exponent = (value >> 24) & 0xFF
    exponent -= 0x100 if exponent & 0x80 else 0
    significand = value & 0x00FFFFFF
    significand -= 0x1000000 if significand & 0x800000 else 0
    return significand / 8388608.0 * 2.0**exponent


@dataclass(frozen=True, eq=False)
class Gt3xChunk:
    """Consecutive samples of whole records.

    Attributes
    ----------
    time_ns
        Shape (n,), int64: device clock, ns since 1970 read as UTC.
    acc_g
        Shape (3, n), float64: acceleration, g, rounded to 1 mg.
    """

    time_ns: np.ndarray
    acc_g: np.ndarray


def _activity_counts(arr: np.ndarray, off: np.ndarray, size: int, kind: int) -> np.ndarray:
    """Counts of records of one type and payload size: shape (m, n, 3), x, y, z (int32)."""
    payload = arr[off[:, None] + RECORD_HEADER + np.arange(size)]  # (m, size)
    m = len(off)
    if kind == ACTIVITY2:
        n = size // 6
        return np.ascontiguousarray(payload[:, : 6 * n]).view("<i2").reshape(m, n, 3).astype(np.int32)
    n = size * 8 // 36
    cols = -(-size // 3) * 3
    padded = np.zeros((m, cols), dtype=np.int32)
    padded[:, :size] = payload
    t = padded.reshape(m, -1, 3)
    vals = np.empty((m, t.shape[1], 2), dtype=np.int32)
    vals[:, :, 0] = (t[:, :, 0] << 4) | (t[:, :, 1] >> 4)
    vals[:, :, 1] = ((t[:, :, 1] & 0x0F) << 8) | t[:, :, 2]
    v = vals.reshape(m, -1)[:, : 3 * n].reshape(m, n, 3)
    v = v - ((v & 0x800) << 1)
    return v[:, :, [1, 0, 2]]  # y, x, z → x, y, z


class Gt3xStream:
    """A ``.gt3x`` file's samples, a block of records at a time.

    Iterate it once; afterwards :attr:`bad_records` names the records skipped (or cut short).

    Parameters
    ----------
    path
        The file (named in errors).
    fh
        The file, open for binary reading, seekable (``zipfile`` reads its end first).
    read_bytes
        Bytes of ``log.bin`` parsed at a time.

    Attributes
    ----------
    info
        ``info.txt``'s ``key: value`` lines.
    sample_rate_hz
        ``Sample Rate``, Hz (a whole number).

    Raises
    ------
    RawFileError
        (On creation) not a zip archive (or one cut short), an older NHANES-style file, no
        ``info.txt`` or ``log.bin``, or no whole sample rate; (on iteration) a record without its
        separator, no accelerometer scale, or a member that fails its CRC-32.
    """

    def __init__(self, path: str | Path, fh: IO[bytes], read_bytes: int = READ_BYTES) -> None:
        self.path = Path(path)
        self.read_bytes = max(int(read_bytes), 1024)
        try:
            self._zip = zipfile.ZipFile(fh)
        except (zipfile.BadZipFile, EOFError, ValueError) as exc:
            raise RawFileError(self.path, "a .gt3x file: a zip archive ending in its central directory",
                               f"none ({exc}): a truncated or damaged file") from None
        names = set(self._zip.namelist())
        if LOG_NAME not in names:
            if OLD_NAME in names:
                raise RawFileError(self.path, f"a .gt3x file with {LOG_NAME} (ActiGraph's format since the "
                                              "GT3X+ firmware of 2014)",
                                   f"an older NHANES-style file ({OLD_NAME}), which ofbe does not read: "
                                   "export it to csv with ActiLife and read the csv")
            raise RawFileError(self.path, f"{LOG_NAME} in the .gt3x archive", f"only {sorted(names)}")
        if INFO_NAME not in names:
            raise RawFileError(self.path, f"{INFO_NAME} in the .gt3x archive", f"only {sorted(names)}")
        text = self._member_bytes(INFO_NAME).decode("utf-8-sig", errors="replace")
        self.info: dict[str, str] = {}
        for line in text.splitlines():
            key, sep, value = line.partition(": ")
            if sep:
                self.info[key.strip()] = value.strip()
        rate_text = self.info.get("Sample Rate", "")
        try:
            rate = float(rate_text.replace(",", "."))
        except ValueError:
            rate = float("nan")
        if not (rate > 0 and rate == int(rate)):
            raise RawFileError(self.path, f"a whole 'Sample Rate' in {INFO_NAME}", repr(rate_text) or "none")
        self.sample_rate_hz = int(rate)
        scale_text = self.info.get("Acceleration Scale")
        self.scale: float | None = None
        if scale_text is not None:
            try:
                self.scale = float(scale_text.replace(",", "."))
            except ValueError:
                raise RawFileError(self.path, f"a number for 'Acceleration Scale' in {INFO_NAME}",
                                   repr(scale_text)) from None
        self.bad_records: list[BadBlock] = []
        self.records = 0
        self._table: np.ndarray | None = None

    def _member_bytes(self, name: str) -> bytes:
        try:
            return self._zip.read(name)
        except (zipfile.BadZipFile, zlib.error, EOFError) as exc:
            raise RawFileError(self.path, f"a readable {name} in the zip archive", f"{exc}") from None

    def _fail(self, record: int, log_offset: int, expected: str, found: str) -> RawFileError:
        return RawFileError(self.path, f"{LOG_NAME} record {record} (byte {log_offset} of {LOG_NAME}): "
                                       f"{expected}", found)

    def __iter__(self) -> Iterator[Gt3xChunk]:
        buf = b""
        at = 0  # byte offset in log.bin of buf[0]
        try:
            with self._zip.open(LOG_NAME) as member:
                while True:
                    more = member.read(self.read_bytes)
                    buf = buf + more if buf else more
                    used, chunk = self._records(buf, at, eof=not more)
                    at += used
                    buf = buf[used:]
                    if chunk is not None:
                        yield chunk
                    if not more:
                        break
        except (zipfile.BadZipFile, zlib.error, EOFError) as exc:
            raise RawFileError(self.path, f"a readable {LOG_NAME} in the zip archive (its CRC-32 and "
                                          "compressed data intact)", f"{exc}: a damaged file") from None
        if buf:
            self.bad_records.append(BadBlock(self.records, at, f"truncated: {LOG_NAME} ends inside this "
                                                               "record, the records before it read"))

    def _records(self, buf: bytes, at: int, eof: bool) -> tuple[int, Gt3xChunk | None]:
        """Parse the whole records at the start of ``buf``: bytes used and their samples."""
        types: list[int] = []
        stamps: list[int] = []
        sizes: list[int] = []
        offsets: list[int] = []
        n = len(buf)
        pos = 0
        unpack = _HEAD.unpack_from
        first = self.records
        while pos + RECORD_HEADER <= n:
            if buf[pos] != SEPARATOR:
                raise self._fail(first + len(types), at + pos, f"the record separator 0x{SEPARATOR:02X}",
                                 f"0x{buf[pos]:02X}")
            kind, stamp, size = unpack(buf, pos + 1)
            end = pos + RECORD_HEADER + size + 1
            if end > n:
                break
            types.append(kind)
            stamps.append(stamp)
            sizes.append(size)
            offsets.append(pos)
            pos = end
        self.records += len(types)
        if not types:
            return pos, None
        arr = np.frombuffer(buf, dtype=np.uint8, count=pos)
        kind_a = np.array(types, dtype=np.int64)
        size_a = np.array(sizes, dtype=np.int64)
        off_a = np.array(offsets, dtype=np.int64)
        for k in np.flatnonzero(kind_a == PARAMETERS):
            self._parameters(buf, int(off_a[k]), int(size_a[k]), first + int(k), at)
        act = (kind_a == ACTIVITY) | (kind_a == ACTIVITY2)
        if act.any():
            self._check(arr, kind_a, size_a, off_a, act, first, at)
        counts = np.where(kind_a == ACTIVITY, size_a * 8 // 36, size_a // 6) * act
        total = int(counts.sum())
        if total == 0:
            return pos, None
        if self.scale is None:
            k = int(np.flatnonzero(counts)[0])
            raise self._fail(first + k, at + int(off_a[k]),
                             f"an accelerometer scale ('Acceleration Scale' in {INFO_NAME} or a PARAMETERS "
                             "record) before the first samples", "none")
        starts = np.cumsum(counts) - counts
        values = np.empty((3, total), dtype=np.int32)
        for kind in (ACTIVITY, ACTIVITY2):
            of_kind = act & (kind_a == kind) & (counts > 0)
            for size in np.unique(size_a[of_kind]):
                sel = np.flatnonzero(of_kind & (size_a == size))
                v = _activity_counts(arr, off_a[sel], int(size), kind)  # (m, n, 3)
                where = (starts[sel][:, None] + np.arange(v.shape[1])).ravel()
                values[:, where] = v.reshape(-1, 3).T
        table = self._lookup()
        acc = table[values + 32768]
        step = 1_000_000_000 // self.sample_rate_hz
        rec = np.repeat(np.arange(len(counts)), counts)
        within = np.arange(total) - starts[rec]
        t = np.array(stamps, dtype=np.int64)[rec] * 1_000_000_000 + step * within
        return pos, Gt3xChunk(t, acc)

    def _lookup(self) -> np.ndarray:
        """Rounded g of every int16 count (``count / scale``, 1 mg, halves away from zero)."""
        if self._table is None:
            assert self.scale is not None
            self._table = round_half_away(np.arange(-32768, 32768, dtype=np.float64) / self.scale, DECIMALS)
        return self._table

    def _check(self, arr: np.ndarray, kind: np.ndarray, size: np.ndarray, off: np.ndarray, act: np.ndarray,
               first: int, at: int) -> None:
        """Drop (from ``act``) the activity records whose checksum fails, naming them."""
        for s in np.unique(size[act]):
            sel = np.flatnonzero(act & (size == s))
            body = arr[off[sel][:, None] + np.arange(RECORD_HEADER + int(s))]
            xor = np.bitwise_xor.reduce(body, axis=1)
            bad = (~xor & 0xFF) != arr[off[sel] + RECORD_HEADER + int(s)]
            for k in sel[bad]:
                act[k] = False
                name = "ACTIVITY2" if kind[k] == ACTIVITY2 else "ACTIVITY"
                self.bad_records.append(BadBlock(first + int(k), at + int(off[k]),
                                                 f"checksum ({name} record of {LOG_NAME}, its byte offset in "
                                                 f"{LOG_NAME}): skipped"))

    def _parameters(self, buf: bytes, off: int, size: int, record: int, at: int) -> None:
        """Take the accelerometer scale from a ``PARAMETERS`` record when ``info.txt`` has none."""
        body = buf[off:off + RECORD_HEADER + size]
        xor = 0
        for b in body:
            xor ^= b
        if (~xor & 0xFF) != buf[off + RECORD_HEADER + size]:
            self.bad_records.append(BadBlock(record, at + off, f"checksum (PARAMETERS record of {LOG_NAME}, "
                                                                f"its byte offset in {LOG_NAME}): skipped"))
            return
        payload = body[RECORD_HEADER:]
        for k in range(0, len(payload) - 7, 8):
            address, key, value = struct.unpack_from("<HHI", payload, k)
            if address == 0 and key == 55 and self.scale is None:
                scale = decode_ssp(value)
                if np.isfinite(scale) and scale > 0:
                    self.scale = scale
                    self._table = None


# --------------------------------------------------------------------------- writing (tests, benchmarks)


def encode_record(kind: int, stamp: int, payload: bytes) -> bytes:
    """One ``log.bin`` record with its checksum."""
    head = _HEAD.pack(kind, stamp, len(payload))
    body = bytes([SEPARATOR]) + head + payload
    xor = 0
    for b in body:
        xor ^= b
    return body + bytes([~xor & 0xFF])


def encode_activity(counts: np.ndarray, stamps: np.ndarray, kind: int = ACTIVITY) -> bytes:
    """``ACTIVITY`` (12-bit, y x z) or ``ACTIVITY2`` (int16, x y z) records, one per second.

    Parameters
    ----------
    counts
        Shape (m, k, 3), integers (x, y, z; within ±2047 for ``ACTIVITY``): k samples in each of m
        seconds (k = the sample rate; fewer for a partial second).
    stamps
        Shape (m,): each record's time stamp, s since 1970 on the device clock.
    kind
        :data:`ACTIVITY` or :data:`ACTIVITY2`.
    """
    c = np.asarray(counts, dtype=np.int64)
    m, k = c.shape[:2]
    if kind == ACTIVITY2:
        payloads = c.astype("<i2").reshape(m, k * 3)
        body = payloads.view(np.uint8).reshape(m, -1)
    else:
        if np.abs(c).max(initial=0) > 2047:
            raise ValueError("ACTIVITY counts must lie within ±2047")
        v = (c[:, :, [1, 0, 2]] & 0xFFF).reshape(m, -1)  # y, x, z
        if v.shape[1] % 2:
            v = np.concatenate([v, np.zeros((m, 1), dtype=np.int64)], axis=1)
        pairs = v.reshape(m, -1, 2)
        trip = np.empty((m, pairs.shape[1], 3), dtype=np.uint8)
        trip[:, :, 0] = pairs[:, :, 0] >> 4
        trip[:, :, 1] = ((pairs[:, :, 0] & 0x0F) << 4) | (pairs[:, :, 1] >> 8)
        trip[:, :, 2] = pairs[:, :, 1] & 0xFF
        body = trip.reshape(m, -1)[:, : -(-36 * k // 8)]
    size = body.shape[1]
    head = np.zeros((m, RECORD_HEADER), dtype=np.uint8)
    head[:, 0] = SEPARATOR
    head[:, 1] = kind
    st = np.asarray(stamps, dtype=np.uint32)
    head[:, 2:6] = st.astype("<u4").view(np.uint8).reshape(m, 4)
    head[:, 6:8] = np.frombuffer(np.uint16(size).astype("<u2").tobytes(), dtype=np.uint8)
    rec = np.concatenate([head, body.astype(np.uint8)], axis=1)
    check = (~np.bitwise_xor.reduce(rec, axis=1)) & 0xFF
    return np.concatenate([rec, check[:, None].astype(np.uint8)], axis=1).tobytes()


def encode_parameters(scale: float = 256.0, rate: int = 30) -> bytes:
    """A ``PARAMETERS`` record: accelerometer scale (address 0, key 55) and sample rate (1, 10)."""
    exponent = 0
    significand = scale
    while abs(significand) >= 1.0:
        significand /= 2.0
        exponent += 1
    ssp = ((exponent & 0xFF) << 24) | (int(round(significand * 8388608.0)) & 0xFFFFFF)
    payload = struct.pack("<HHI", 0, 55, ssp) + struct.pack("<HHI", 1, 10, rate)
    return encode_record(PARAMETERS, 0, payload)


def info_text(rate: int, scale: float | None = 256.0, serial: str = "MOS2E39180594",
              device: str = "wGT3XBT") -> bytes:
    """An ``info.txt`` (without ``Acceleration Scale`` when ``scale`` is None)."""
    lines = [f"Serial Number: {serial}", f"Device Type: {device}", "Firmware: 1.9.2", f"Sample Rate: {rate}",
             "TimeZone: 00:00:00"]
    if scale is not None:
        lines.append(f"Acceleration Scale: {scale:.1f}")
    lines += ["Acceleration Min: -8.0", "Acceleration Max: 8.0"]
    return ("\r\n".join(lines) + "\r\n").encode("utf-8")
