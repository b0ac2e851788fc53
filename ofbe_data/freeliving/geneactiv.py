"""GENEActiv ``.bin`` files, page by page, in numpy.

The format (Activinsights' "Decoding .bin files"; read here as actfast's reader,
childmindresearch/actfast ``src/geneactiv``, MIT, and GGIRread's ``GENEActivReader.cpp``,
wadpac/GGIRread, Apache-2.0, read it; written anew) is text, lines ending in CR LF:

- a header of ``Category`` lines and ``key:value`` lines (59 lines as written by the devices;
  here: everything before the first ``Recorded Data`` line), among them ``Calibration Data``:
  ``x gain``, ``x offset``, … (integers) and ``Configuration Info``: ``Measurement Frequency``;
- then pages of 10 lines: ``Recorded Data``, then ``key:value`` lines (``Device Unique Serial
  Code``, ``Sequence Number``, ``Page Time`` ``YYYY-MM-DD hh:mm:ss:mmm``, ``Unassigned``,
  ``Temperature`` (°C), ``Battery voltage``, ``Device Status``, ``Measurement Frequency`` (Hz)),
  then one line of hexadecimal digits: 12 per sample (300 samples a page), 48 bits each, most
  significant first: x, y, z (12-bit two's complement), light (10 bits), button (1), one unused.

Samples are calibrated with the header's gain and offset as both readers do,
``(raw · 100 − offset) / gain``, in float32 (actfast computes in float32; GGIRread computes in
double and stores float32: the same numbers, since a double quotient rounded to float32 is the
float32 quotient). Sample ``i`` of a page lies at ``page time + i · ⌊10⁹ / f⌋`` ns, ``f`` the
page's frequency as a float32 and the quotient taken in float32 (actfast), and carries the
page's temperature (GGIRread: per page, float32).

Damage is named, never read as numbers: a page whose hex line holds a non-hexadecimal character
is skipped (:class:`~ofbe_data.freeliving.blocks.BadBlock`, reason ``not hexadecimal``); a page
with fewer samples than the first page (the file cut inside its hex line, as the GGIRread test
file is) keeps its whole samples, as both readers do, and is named (``truncated``/``short``); a
page whose lines are not in the page layout stops the reading with a
:class:`~ofbe_data.freeliving.blocks.RawFileError` naming the page and its byte offset.

Memory: :data:`BLOCK_BYTES` of text at a time (about 2 000 pages, 650 000 samples).
"""

from __future__ import annotations

import binascii
import re
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO

import numpy as np

from ofbe_data.freeliving.blocks import BadBlock, RawFileError

BLOCK_BYTES = 1 << 23
"""Bytes of the file parsed at a time."""
HEADER_MAX_BYTES = 1 << 16
"""The header must end (a ``Recorded Data`` line) within this many bytes."""
PAGE_LINES = 10
"""Lines of one page: ``Recorded Data``, eight ``key:value`` lines, the hex line."""
HEX_PER_SAMPLE = 12
"""Hexadecimal digits per sample (48 bits)."""
PAGE_START = b"Recorded Data"
_FIELDS = {b"Page Time:": 3, b"Temperature:": 5, b"Measurement Frequency:": 8}
"""The page lines read, at their usual positions (1–8) in a page."""
_DATETIME_CHARS = 19
"""``YYYY-MM-DD hh:mm:ss``."""


@dataclass(frozen=True)
class BinHeader:
    """What the header of a ``.bin`` file says.

    Attributes
    ----------
    metadata
        ``{category: {key: value}}``, the header's lines (each stripped, split at its first
        colon; a line without a colon starts a category), as actfast hands them on.
    gain, offset
        Calibration, per axis x, y, z (``Calibration Data``).
    n_lines
        Lines of the header.
    data_offset
        Byte offset of the first page.
    """

    metadata: dict[str, dict[str, str]]
    gain: tuple[int, int, int]
    offset: tuple[int, int, int]
    n_lines: int
    data_offset: int


@dataclass(frozen=True, eq=False)
class BinChunk:
    """Consecutive samples of whole pages.

    Attributes
    ----------
    time_ns
        Shape (n,), int64: device clock, ns since 1970 read as UTC.
    acc_g
        Shape (3, n), float32: calibrated acceleration, g.
    temperature_c
        Shape (n,), float32: the temperature of each sample's page, °C.
    """

    time_ns: np.ndarray
    acc_g: np.ndarray
    temperature_c: np.ndarray


def _int(path: Path, meta: dict[str, dict[str, str]], key: str) -> int:
    text = meta.get("Calibration Data", {}).get(key)
    m = re.fullmatch(r"\s*([-+]?\d+)\s*", text or "")
    if m is None:
        raise RawFileError(path, f"an integer '{key}' under 'Calibration Data' in the header",
                           "none" if text is None else repr(text))
    return int(m.group(1))


def parse_header(path: str | Path, head: bytes) -> BinHeader:
    """Parse the header from the first bytes of a file (``head``: at least up to the first page).

    Raises
    ------
    RawFileError
        Not a GENEActiv file (the first line is not ``Device Identity``), no ``Recorded Data``
        line within :data:`HEADER_MAX_BYTES`, or no calibration (or a gain of 0) in the header.
    """
    p = Path(path)
    if not head.lstrip(b"\xef\xbb\xbf").startswith(b"Device Identity"):
        raise RawFileError(p, "a GENEActiv .bin file (first line 'Device Identity')", repr(head[:20]), 0)
    m = re.search(rb"(?:^|\n)" + PAGE_START, head)
    if m is None:
        raise RawFileError(p, f"a page ('{PAGE_START.decode()}') after the header, within "
                              f"{HEADER_MAX_BYTES} bytes", "none", 0)
    data_offset = m.start() + (1 if head[m.start():m.start() + 1] == b"\n" else 0)
    lines = head[:data_offset].decode("latin-1").split("\n")[:-1]
    meta: dict[str, dict[str, str]] = {}
    category = ""
    for raw in lines:
        line = raw.strip()
        if not line:
            continue
        colon = line.find(":")
        if colon < 0:
            category = line
            meta.setdefault(category, {})
            continue
        meta.setdefault(category, {})[line[:colon]] = line[colon + 1:]
    gain = tuple(_int(p, meta, f"{a} gain") for a in "xyz")
    offset = tuple(_int(p, meta, f"{a} offset") for a in "xyz")
    if 0 in gain:
        raise RawFileError(p, "non-zero gains under 'Calibration Data'", f"x, y, z gain = {gain}")
    return BinHeader(meta, gain, offset, len(lines), data_offset)  # type: ignore[arg-type]


def decode_samples(raw: np.ndarray, header: BinHeader) -> np.ndarray:
    """Calibrated samples (shape (3, n), float32, g) from ``raw`` (shape (n, 6), uint8: 48 bits each)."""
    b0, b1, b2, b3, b4 = (raw[:, k].astype(np.int16) for k in range(5))  # 12-bit counts fit int16
    counts = np.empty((3, len(raw)), dtype=np.int16)
    counts[0] = (b0 << 4) | (b1 >> 4)
    counts[1] = ((b1 & 0x0F) << 8) | b2
    counts[2] = (b3 << 4) | (b4 >> 4)
    counts -= (counts & 0x800) << 1  # 12-bit two's complement
    out = counts.astype(np.float32)
    out *= np.float32(100.0)
    out -= np.array(header.offset, dtype=np.float32)[:, None]
    out /= np.array(header.gain, dtype=np.float32)[:, None]
    return out


def _page_ns(stamps: list[bytes]) -> np.ndarray | None:
    """``YYYY-MM-DD hh:mm:ss:mmm`` (stripped) → ns since 1970 as UTC; None when one has another shape."""
    arr = np.array(stamps)
    if arr.dtype.itemsize != _DATETIME_CHARS + 4 or len(arr) == 0:
        return None
    u8 = arr.view(np.uint8).reshape(len(arr), -1)
    digits = u8[:, 20:23].astype(np.int64) - 48
    if not (np.all(u8[:, 19] == ord(":")) and np.all((digits >= 0) & (digits <= 9))):
        return None
    try:
        seconds = arr.astype(f"S{_DATETIME_CHARS}").astype(f"U{_DATETIME_CHARS}").astype("datetime64[s]")
    except ValueError:
        return None
    ms = digits[:, 0] * 100 + digits[:, 1] * 10 + digits[:, 2]
    return seconds.astype(np.int64) * 1_000_000_000 + ms * 1_000_000


def _one_page_ns(text: bytes) -> int | None:
    """One page time, ``YYYY-MM-DD hh:mm:ss:f…`` (any number of fraction digits), or None."""
    m = re.fullmatch(rb"(\d{4}-\d{2}-\d{2} \d{2}:\d{2}:\d{2}):(\d+)", text)
    if m is None:
        return None
    try:
        seconds = int(np.datetime64(m.group(1).decode(), "s").astype(np.int64))
    except ValueError:
        return None
    frac = m.group(2)
    return seconds * 1_000_000_000 + int(frac) * 10 ** (9 - len(frac)) if len(frac) <= 9 else None


class BinStream:
    """A ``.bin`` file's samples, a block of pages at a time.

    Iterate it once; afterwards :attr:`bad_pages` names the pages skipped or cut short and
    :attr:`pages` counts the pages read.

    Parameters
    ----------
    path
        The file (named in errors).
    fh
        The file, open for binary reading at its start (read sequentially once).
    block_bytes
        Bytes parsed at a time.

    Raises
    ------
    RawFileError
        (On creation) not a GENEActiv file, or a header without calibration; (on iteration) a page
        out of the page layout, or without a readable time, temperature or frequency.
    """

    def __init__(self, path: str | Path, fh: IO[bytes], block_bytes: int = BLOCK_BYTES) -> None:
        self.path = Path(path)
        self._fh = fh
        self.block_bytes = max(int(block_bytes), 4096)
        head = fh.read(min(self.block_bytes, HEADER_MAX_BYTES))
        while PAGE_START not in head and len(head) < HEADER_MAX_BYTES:
            more = fh.read(min(self.block_bytes, HEADER_MAX_BYTES - len(head)))
            if not more:
                break
            head += more
        self.header = parse_header(self.path, head)
        self._rest = head[self.header.data_offset:]
        self.bad_pages: list[BadBlock] = []
        self.pages = 0
        self._full: int | None = None  # samples of a full page (the first page's)

    def _fail(self, page: int, offset: int, expected: str, found: str) -> RawFileError:
        return RawFileError(self.path, f"page {page}: {expected}", found, offset)

    def __iter__(self) -> Iterator[BinChunk]:
        buf, at = self._rest, self.header.data_offset  # ``at``: byte offset of buf[0]
        self._rest = b""
        eof = False
        while not eof:
            more = self._fh.read(self.block_bytes)
            eof = not more
            buf = buf + more if buf else more
            lines = buf.split(b"\n")
            complete = len(lines) - 1  # the last piece has no newline yet
            if eof:
                n_pages = complete // PAGE_LINES
                tail_lines = lines[n_pages * PAGE_LINES:]
                if tail_lines == [b""]:
                    tail_lines = []
            else:
                n_pages = complete // PAGE_LINES
                tail_lines = []
            if n_pages:
                used = n_pages * PAGE_LINES
                chunk = self._pages(lines[:used], at)
                consumed = sum(map(len, lines[:used])) + used
                at += consumed
                buf = buf[consumed:]
                if chunk is not None:
                    yield chunk
            if eof and tail_lines:
                chunk = self._last_page(tail_lines, at)
                if chunk is not None:
                    yield chunk

    # ------------------------------------------------------------------ pages

    def _offsets(self, lines: list[bytes], at: int) -> np.ndarray:
        """Byte offset of each page's first line (for messages)."""
        sizes = np.fromiter((len(s) + 1 for s in lines), dtype=np.int64, count=len(lines))
        starts = at + np.concatenate([[0], np.cumsum(sizes)[:-1]])
        return starts[::PAGE_LINES]

    def _pages(self, lines: list[bytes], at: int) -> BinChunk | None:
        """Whole pages (``lines``: 10 per page) starting at byte ``at``."""
        first = self.pages
        m = len(lines) // PAGE_LINES
        self.pages += m
        starts = lines[0::PAGE_LINES]
        if not all(s.startswith(PAGE_START) for s in starts):
            k = next(i for i, s in enumerate(starts) if not s.startswith(PAGE_START))
            raise self._fail(first + k, int(self._offsets(lines, at)[k]),
                             f"a line '{PAGE_START.decode()}' (pages of {PAGE_LINES} lines)",
                             repr(starts[k][:40]))
        fields = self._fields(lines, m, first, at)
        hex_lines = [s.rstrip() for s in lines[PAGE_LINES - 1::PAGE_LINES]]
        return self._decode(hex_lines, fields, first, lambda: self._offsets(lines, at))

    def _fields(self, lines: list[bytes], m: int, first: int, at: int
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Page time (ns), temperature (float32, °C) and frequency (float32, Hz) of ``m`` pages."""
        values: dict[bytes, list[bytes]] = {}
        for key, pos in _FIELDS.items():
            col = lines[pos::PAGE_LINES]
            if all(s.startswith(key) for s in col):
                values[key] = [s[len(key):].strip() for s in col]
            else:  # not at its usual place: look for it among the page's lines, as actfast does
                found = []
                for k in range(m):
                    page = lines[k * PAGE_LINES + 1:k * PAGE_LINES + PAGE_LINES - 1]
                    hit = next((s[len(key):].strip() for s in page if s.startswith(key)), None)
                    if hit is None:
                        raise self._fail(first + k, int(self._offsets(lines, at)[k]),
                                         f"a '{key.decode()}' line", "none")
                    found.append(hit)
                values[key] = found
        times = _page_ns(values[b"Page Time:"])
        if times is None:
            parsed = [_one_page_ns(s) for s in values[b"Page Time:"]]
            if None in parsed:
                k = parsed.index(None)
                raise self._fail(first + k, int(self._offsets(lines, at)[k]),
                                 "a 'Page Time' of the form YYYY-MM-DD hh:mm:ss:mmm",
                                 repr(values[b"Page Time:"][k]))
            times = np.array(parsed, dtype=np.int64)
        out = []
        for key in (b"Temperature:", b"Measurement Frequency:"):
            try:
                out.append(np.array(values[key]).astype(np.float32))
            except ValueError:
                k = next(i for i, s in enumerate(values[key]) if not _is_number(s))
                raise self._fail(first + k, int(self._offsets(lines, at)[k]),
                                 f"a number after '{key.decode()}'", repr(values[key][k])) from None
        freq = out[1]
        if not np.all(freq > 0):
            k = int(np.flatnonzero(~(freq > 0))[0])
            raise self._fail(first + k, int(self._offsets(lines, at)[k]),
                             "a positive 'Measurement Frequency'", repr(values[b"Measurement Frequency:"][k]))
        return times, out[0], freq

    def _decode(self, hex_lines: list[bytes], fields: tuple[np.ndarray, np.ndarray, np.ndarray],
                first: int, offsets: Callable[[], np.ndarray]) -> BinChunk | None:
        """Samples of pages whose hex lines (stripped) are ``hex_lines``."""
        times, temp, freq = fields
        counts = np.fromiter((len(s) // HEX_PER_SAMPLE for s in hex_lines), dtype=np.int64,
                             count=len(hex_lines))
        if self._full is None and len(counts):
            self._full = int(counts[0])
        full = self._full or 0
        digits = b"".join(s[: c * HEX_PER_SAMPLE] for s, c in zip(hex_lines, counts.tolist(), strict=True))
        try:
            raw = binascii.unhexlify(digits)
        except (binascii.Error, ValueError):
            keep = np.ones(len(hex_lines), dtype=bool)
            where = offsets()
            for k, (s, c) in enumerate(zip(hex_lines, counts.tolist(), strict=True)):
                bad = re.search(rb"[^0-9A-Fa-f]", s[: c * HEX_PER_SAMPLE])
                if bad is not None:
                    keep[k] = False
                    self.bad_pages.append(BadBlock(first + k, int(where[k]),
                                                   f"not hexadecimal (character {bad.start()} of its data "
                                                   "line): page skipped"))
            counts = np.where(keep, counts, 0)
            digits = b"".join(s[: c * HEX_PER_SAMPLE]
                              for s, c in zip(hex_lines, counts.tolist(), strict=True))
            raw = binascii.unhexlify(digits)
        short = np.flatnonzero((counts < full) & (counts > 0))
        if len(short):
            where = offsets()
            for k in short:
                self.bad_pages.append(BadBlock(first + int(k), int(where[k]),
                                               f"short: {int(counts[k])} of {full} samples read"))
        n = int(counts.sum())
        if n == 0:
            return None
        acc = decode_samples(np.frombuffer(raw, dtype=np.uint8).reshape(n, 6), self.header)
        step = (np.float32(1e9) / freq).astype(np.int64)  # actfast: (1e9 / f) as i64, in float32
        page_of = np.repeat(np.arange(len(counts)), counts)
        within = np.arange(n) - np.repeat(np.cumsum(counts) - counts, counts)
        t = times[page_of] + step[page_of] * within
        return BinChunk(t, acc, temp[page_of])

    def _last_page(self, lines: list[bytes], at: int) -> BinChunk | None:
        """The lines after the last whole page: a page cut short by the end of the file."""
        page = self.pages
        if not lines[0].startswith(PAGE_START):
            raise self._fail(page, at, f"a line '{PAGE_START.decode()}' (pages of {PAGE_LINES} lines)",
                             repr(lines[0][:40]))
        if len(lines) < PAGE_LINES:
            self.bad_pages.append(BadBlock(page, at, f"truncated: the file ends in line {len(lines)} of "
                                                     f"its {PAGE_LINES}, no samples"))
            return None
        self.pages += 1
        before = len(self.bad_pages)
        fields = self._fields(lines, 1, page, at)
        chunk = self._decode([lines[PAGE_LINES - 1].rstrip()], fields, page, lambda: np.array([at]))
        if len(self.bad_pages) > before and self.bad_pages[-1].reason.startswith("short"):
            read = self.bad_pages[-1].reason[len("short: "):]
            self.bad_pages[-1] = BadBlock(page, at, f"truncated: {read}")
        return chunk


def _is_number(text: bytes) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


# --------------------------------------------------------------------------- writing (tests, benchmarks)


def encode_header(rate_hz: float, gain: tuple[int, int, int] = (25875, 25734, 25538),
                  offset: tuple[int, int, int] = (439, -662, -3056), n_pages: int = 0,
                  start: str = "2024-03-04 09:00:00:000", serial: str = "012967") -> bytes:
    """A 59-line ``.bin`` header (CR LF), laid out as a GENEActiv device writes it."""
    lines = [
        "Device Identity", f"Device Unique Serial Code:{serial}", "Device Type:GENEActiv",
        "Device Model:1.1", "Device Firmware Version:Ver1.30 date 05Aug11",
        "Calibration Date:2012-04-03 11:08:52:000", "",
        "Device Capabilities", "Accelerometer Range:-8 to 8", "Accelerometer Resolution:0.0039",
        "Accelerometer Units:g", "Light Meter Range:0 to 5000", "Light Meter Resolution:5",
        "Light Meter Units:lux", "Temperature Sensor Range:0 to 70", "Temperature Sensor Resolution:0.1",
        "Temperature Sensor Units:deg. C", "",
        "Configuration Info", f"Measurement Frequency:{rate_hz:g} Hz", "Measurement Period:168 Hours",
        f"Start Time:{start}", "Time Zone:GMT +00:00", "",
        "Trial Info", "Study Centre:", "Study Code:", "Investigator ID:", "Exercise Type:",
        "Config Operator ID:", "Config Time:", "Config Notes:", "Extract Operator ID:", "Extract Time:",
        "Extract Notes:", "",
        "Subject Info", "Device Location Code:", "Subject Code:", "Date of Birth:", "Sex:", "Height:",
        "Weight:", "Handedness Code:", "Subject Notes:", "",
        "Calibration Data", f"x gain:{gain[0]}", f"x offset:{offset[0]}", f"y gain:{gain[1]}",
        f"y offset:{offset[1]}", f"z gain:{gain[2]}", f"z offset:{offset[2]}", "Volts:300", "Lux:800", "",
        "Memory Status", f"Number of Pages:{n_pages}", "",
    ]
    return ("\r\n".join(lines) + "\r\n").encode("latin-1")


def encode_pages(counts: np.ndarray, page_ms: np.ndarray, rate_hz: float,
                 temperature_c: np.ndarray | float = 25.0, first_sequence: int = 0,
                 serial: str = "012967") -> bytes:
    """Pages (CR LF lines) of raw 12-bit counts.

    Parameters
    ----------
    counts
        Shape (m, k, 3), integers within ±2047: k samples (x, y, z) of each of m pages.
    page_ms
        Shape (m,): time of each page's first sample, ms since 1970 read as UTC.
    rate_hz
        The pages' ``Measurement Frequency``.
    temperature_c
        Page temperatures, °C (shape (m,) or one value), written to 0.1 °C.
    first_sequence
        Sequence number of the first page.
    """
    c = np.asarray(counts, dtype=np.int64)
    m, k = c.shape[:2]
    if c.shape != (m, k, 3) or np.abs(c).max(initial=0) > 2047:
        raise ValueError(f"expected counts of shape (m, k, 3) within ±2047, found {c.shape}")
    u = c & 0xFFF
    word = (u[:, :, 0] << 36) | (u[:, :, 1] << 24) | (u[:, :, 2] << 12)  # light 0, button 0
    raw = np.empty((m, k, 6), dtype=np.uint8)
    for b in range(6):
        raw[:, :, b] = (word >> (8 * (5 - b))) & 0xFF
    hex_all = raw.tobytes().hex().upper()
    per = 12 * k
    temps = np.broadcast_to(np.asarray(temperature_c, dtype=np.float64), (m,))
    stamps = np.asarray(page_ms, dtype="datetime64[ms]")
    out = []
    for i in range(m):
        s = str(stamps[i]).replace("T", " ")
        out.append(f"Recorded Data\r\nDevice Unique Serial Code:{serial}\r\n"
                   f"Sequence Number:{first_sequence + i}\r\nPage Time:{s[:19]}:{s[20:23]}\r\nUnassigned:\r\n"
                   f"Temperature:{temps[i]:.1f}\r\nBattery voltage:4.1493\r\nDevice Status:Recording\r\n"
                   f"Measurement Frequency:{rate_hz:g}\r\n{hex_all[i * per:(i + 1) * per]}\r\n")
    return "".join(out).encode("latin-1")
