"""Axivity ``.cwa`` data as GGIR sees it: GGIRread's ``readAxivity``, block by block, in numpy.

GGIR's ``g.calibrate`` reads ``.cwa`` files through GGIRread (wadpac/GGIRread, R/readAxivity.R
and src/resample.cpp; Apache-2.0), which puts every block's samples on a time axis and resamples
them, by linear interpolation, onto a regular grid at the header's sample rate. This module
follows that code step by step (written anew; the steps are named as GGIRread names them):

1. **First valid block** (``readHeader``): block 0 onwards, skipping up to 20 bad blocks.
2. **End of the grid**: reading to the end of the file, the last valid block (going back over
   up to 20 bad ones) gives ``endTimestamp = start + L·step + 2·L·step`` (``L``: samples in the
   first valid block; ``step``: 1 / the header's rate); reading up to block ``end`` (GGIRread's
   ``end``), the start of the first valid block from ``end`` on.
3. **Start**: the first valid block from ``start`` on (up to 20 bad ones skipped, logged); the
   grid is ``t_i = t_start + i·step`` for ``i < n``, ``n = ⌊(endTimestamp − t_start) / step +
   1e-10⌋`` (R's ``seq``, last point dropped).
4. **Each next valid block** (bad ones skipped and logged; 21 in a row stop the reading): the
   previous block's ``L`` samples sit at ``seq(prevStart, thisStart, length.out = L + 1)``
   (the last point unused), after a carry-over point: the last grid point already filled and
   its value (for the first block: its start − 10 µs and its first sample).
5. **Integrity**: the pair is *imputed* when the sequence numbers are not consecutive (the new
   one not 0) or the observed rate ``(L + 1) / (t_{L−1} − t_carry)`` is more than 10 % off the
   block rate; imputed grid points (those before ``t_{L−1}``) get the carry-over value scaled
   to 1 g when its norm is within 0.8–1.2 g, else (0, 0, 1) — for six-axis data GGIRread
   computes this from the gyroscope columns and leaves the accelerometer at 0. Otherwise the
   grid points up to ``t_{L−1}`` are interpolated linearly (``resample``: the first sample time
   at or after the point is the right end of the interval; an interval fraction outside [0, 1]
   counts as 0). At most ``200 + ⌊(t_{L−1} − t_{pos+200})·rate⌋`` points per block.
6. **Last block of the file**: resampled on ``seq(startOfTheBlockBefore, extrapolated end,
   length.out = L + 1)`` — GGIRread's own time axis for it, reproduced as it is.
7. Each grid point gets the temperature of the block it was resampled from.

GGIRread reads the device clock in the user's time zone; here it is read as UTC (the seconds
are the same unless that zone changes to or from summer time during the recording).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ofbe_data.freeliving.blocks import (
    BLOCK_BYTES,
    HEADER_BYTES,
    BadBlock,
    CwaBlocks,
    CwaHeader,
    CwaParams,
    RawFileError,
    bad_reason,
    block_params,
    block_status,
    decode_blocks,
    read_header,
)
from ofbe_data.freeliving.hashing import HashingReader

MAX_CORRUPT_BLOCKS = 20
"""GGIRread's ``maxAllowedCorruptBlocks``."""
FREQUENCY_TOL = 0.1
"""GGIRread's ``frequency_tol``: a block whose observed rate is further off is imputed."""
CARRY_DT_S = 0.00001
"""The first block's carry-over point lies this long before its start, s (GGIRread)."""
WINDOW = 200
"""Grid points GGIRread looks at per block, before its time-jump extension."""
CHUNK_BLOCKS = 2048
"""Data blocks decoded at a time (about 250 000 samples at 120 per block): bounds the memory."""


@dataclass(frozen=True)
class QcEntry:
    """One row of GGIRread's ``QClog``.

    Attributes
    ----------
    checksum_pass
        False for a bad block skipped; True for a block pair that was imputed (or whose rate was
        more than 5 % off).
    block_current, block_next
        For a bad block: its number and the next; otherwise the sequence numbers of the block
        resampled and of the block after it.
    start_s, end_s
        Start times of those two blocks, s (0 for a bad block).
    frequency_observed
        ``(L + 1) / (t_{L−1} − t_carry)``, Hz (0 for a bad block).
    imputed
        Whether the block's grid points were imputed.
    """

    checksum_pass: bool
    block_current: int
    block_next: int
    start_s: float
    end_s: float
    frequency_observed: float
    imputed: bool


@dataclass(frozen=True, eq=False)
class SampleChunk:
    """Consecutive rows of the resampled stream.

    Attributes
    ----------
    first
        Row number of the first row (0-based, in the whole stream).
    time_s
        Shape (n,): grid times, s on the device clock.
    values
        Shape (n_axes, n): accelerometer in g (after the gyroscope in °/s for six axes).
    temperature_c
        Shape (n,): temperature of the block each row came from, °C.
    """

    first: int
    time_s: np.ndarray
    values: np.ndarray
    temperature_c: np.ndarray


@dataclass
class _Block:
    """One valid block kept between chunks (the previous block of the next pair)."""

    index: int
    sequence: int
    start_s: float
    count: int
    temperature_c: float
    samples: np.ndarray  # (n_axes, capacity)


@dataclass
class _State:
    rows: int = 0  # grid points filled so far (GGIRread's pos - 1)
    carry_t: float = math.nan
    carry_v: np.ndarray = field(default_factory=lambda: np.zeros(0))
    first_pair: bool = True
    prev: _Block | None = None
    before_prev: tuple[float, int] | None = None  # start and length of the block before ``prev``
    corrupt_run: int = 0


@dataclass(frozen=True, eq=False)
class _Pairs:
    """Block pairs to resample: the previous block of each (its samples at ``base`` in ``samples``)."""

    frm: np.ndarray  # (p,) previous block start, s
    to: np.ndarray  # (p,) next block start (or the extrapolated end), s
    length: np.ndarray  # (p,) samples in the previous block
    base: np.ndarray  # (p,) column of its first sample in ``samples``
    samples: np.ndarray  # (n_axes, columns)
    temperature_c: np.ndarray  # (p,)
    sequence: np.ndarray  # (p,) previous block's sequence number
    next_sequence: np.ndarray  # (p,)
    next_start: np.ndarray  # (p,) for the QC log
    seq_jump: np.ndarray  # (p,) bool


def _grid_count(t0: float, step: float, n: int, u: np.ndarray, strict: bool) -> np.ndarray:
    """Number of grid points ``t0 + i·step`` (``i < n``) at or before ``u`` (before, if strict)."""
    k = np.clip(np.floor((u - t0) / step) + 1.0, 0, n).astype(np.int64)
    for _ in range(2):  # correct the division's rounding with the grid's own arithmetic
        t_k = t0 + k * step
        over = (k < n) & ((t_k < u) if strict else (t_k <= u))
        k = k + over
        t_km1 = t0 + (k - 1) * step
        under = (k > 0) & ((t_km1 >= u) if strict else (t_km1 > u))
        k = k - under
    return k


def _imputed_values(carry: np.ndarray) -> np.ndarray:
    """GGIRread's imputation (shape (n_axes, n)) from carry-over values (same shape): the first three
    columns scaled to 1 g when their norm is within 0.8–1.2, else (0, 0, 1); the others 0."""
    v = carry[:3]
    norm = np.sqrt(np.sum(v**2, axis=0))
    ok = (norm > 0.8) & (norm < 1.2)
    out = np.zeros_like(carry)
    with np.errstate(divide="ignore", invalid="ignore"):
        out[:3] = np.where(ok[None, :], v / norm, np.array([[0.0], [0.0], [1.0]]))
    return out


class AxivityStream:
    """GGIRread's ``readAxivity(filename, start, end)`` as a stream of :class:`SampleChunk`.

    Iterate it once; afterwards :attr:`qc_log`, :attr:`bad_blocks`, :attr:`rows` and
    :attr:`imputed_rows` hold what the reading found, and :attr:`sha256` the file's SHA-256 (hex),
    computed from the blocks as they are read (:class:`~ofbe_data.freeliving.hashing.HashingReader`;
    None when nothing was read). Memory: :data:`CHUNK_BLOCKS` blocks at a time.

    Parameters
    ----------
    path
        The ``.cwa`` file.
    start, end
        GGIRread's block range (``end`` None: to the end of the file).
    max_corrupt
        Bad blocks in a row that stop the reading (GGIRread's ``maxAllowedCorruptBlocks``).
    chunk_blocks
        Blocks decoded at a time.

    Raises
    ------
    RawFileError
        (On iteration) not a ``.cwa`` file, too many bad blocks in a row, all requested blocks
        bad, or fewer than two valid blocks to resample between.
    """

    def __init__(self, path: str | Path, start: int = 0, end: int | None = None,
                 max_corrupt: int = MAX_CORRUPT_BLOCKS, chunk_blocks: int = CHUNK_BLOCKS) -> None:
        self.path = Path(path)
        self.start, self.end = start, end
        self.max_corrupt = max_corrupt
        self.chunk_blocks = max(2, int(chunk_blocks))
        size = self.path.stat().st_size
        with open(self.path, "rb") as fh:
            self.header: CwaHeader = read_header(self.path, fh.read(HEADER_BYTES), size)
        self.qc_log: list[QcEntry] = []
        self._bad: dict[int, BadBlock] = {}
        self.rows = 0
        self.imputed_rows = 0
        self.sha256: str | None = None
        self.params: CwaParams | None = None
        if (size - HEADER_BYTES) % BLOCK_BYTES and size > HEADER_BYTES:
            n = self.header.n_blocks
            self._bad[n] = BadBlock(n, HEADER_BYTES + BLOCK_BYTES * n, "truncated")

    @property
    def bad_blocks(self) -> tuple[BadBlock, ...]:
        """Every bad block met, by number."""
        return tuple(self._bad[k] for k in sorted(self._bad))

    # ----------------------------------------------------------------- file access

    def _sectors(self, fh: HashingReader, first: int, count: int) -> np.ndarray:
        fh.seek(HEADER_BYTES + BLOCK_BYTES * first)
        data = fh.read(BLOCK_BYTES * count)
        return np.frombuffer(data, dtype=np.uint8).reshape(-1, BLOCK_BYTES)

    def _note_bad(self, sectors: np.ndarray, first: int, ok: np.ndarray) -> None:
        for k in np.flatnonzero(~ok):
            i = first + int(k)
            self._bad.setdefault(i, BadBlock(i, HEADER_BYTES + BLOCK_BYTES * i, bad_reason(sectors[k])))

    def _one(self, fh: HashingReader, i: int) -> tuple[bool, np.ndarray]:
        sec = self._sectors(fh, i, 1)
        ok = bool(block_status(sec)[0])
        self._note_bad(sec, i, np.array([ok]))
        return ok, sec[0]

    def _fail(self, expected: str, found: str, block: int | None = None) -> RawFileError:
        offset = None if block is None else HEADER_BYTES + BLOCK_BYTES * block
        return RawFileError(self.path, expected, found, offset)

    # ----------------------------------------------------------------- GGIRread's phases

    def _first_block_length(self, fh: HashingReader, n: int) -> int:
        """``readHeader``: samples in the first valid block from block 0."""
        for i in range(min(n - 1, self.max_corrupt) + 1):
            ok, sec = self._one(fh, i)
            if ok:
                return int(decode_blocks(sec[None, :], i, block_params(sec)).count[0])
        raise self._fail(f"a valid data block among the first {min(n, self.max_corrupt + 1)}", "none", 0)

    def _end_time(self, fh: HashingReader, n: int, start: int, end: int, length: int) -> tuple[int, float]:
        """The grid's end (GGIRread's ``endTimestamp``) and the possibly moved ``end``."""
        step = 1.0 / self.header.sample_rate_hz
        if end < n:
            for i in range(end, min(n - 1, end + self.max_corrupt) + 1):
                ok, sec = self._one(fh, i)
                if ok:
                    return end, float(decode_blocks(sec[None, :], i, block_params(sec)).start_s[0])
                end += 1
            if end < n:
                raise self._fail("a valid block after the requested range", "only bad blocks", end)
        lo = max(start, end - self.max_corrupt - 1)
        for i in range(end - 1, lo - 1, -1):
            ok, sec = self._one(fh, i)
            if ok:
                last = float(decode_blocks(sec[None, :], i, block_params(sec)).start_s[0])
                return end, (last + length * step) + 2 * length * step
            end -= 1
        if start == end:
            raise self._fail("a valid block among those requested", "all requested blocks bad", start)
        raise self._fail(f"a valid block among the last {self.max_corrupt + 1}", "all bad", end)

    def _first_valid(self, fh: HashingReader, start: int, end: int) -> tuple[int, np.ndarray]:
        """The first valid block from ``start`` (bad ones logged), and its sector."""
        for _ in range(min(end - start, self.max_corrupt + 1)):
            ok, sec = self._one(fh, start)
            if ok:
                return start, sec
            self.qc_log.append(QcEntry(False, start, start + 1, 0.0, 0.0, 0.0, False))
            start += 1
        if start == end:
            raise self._fail("a valid block among those requested", "all requested blocks bad", start)
        raise self._fail(f"a valid block among the first {self.max_corrupt + 1} requested", "all bad", start)

    # ----------------------------------------------------------------- iteration

    def __iter__(self) -> Iterator[SampleChunk]:
        n = self.header.n_blocks
        start = max(self.start, 0)
        end = n if self.end is None else min(self.end, n)
        if end <= start or n == 0:
            return
        with open(self.path, "rb") as raw:
            fh = HashingReader(raw)
            length = self._first_block_length(fh, n)
            end, t_end = self._end_time(fh, n, start, end, length)
            start, sec = self._first_valid(fh, start, end)
            self.params = params = block_params(sec)
            first = decode_blocks(sec[None, :], start, params)
            self.t0 = float(first.start_s[0])
            step = 1.0 / self.header.sample_rate_hz
            span = (t_end - self.t0) / step
            dd = abs(t_end - self.t0) / max(abs(t_end), abs(self.t0))
            self.n_grid = 0 if dd < 100 * np.finfo(float).eps else max(0, int(span + 1e-10))
            state = _State(prev=_Block(start, int(first.sequence[0]), self.t0, int(first.count[0]),
                                       float(first.temperature_c[0]), first.samples[:, 0].copy()))
            last_read = min(end, n - 1)
            for lo in range(start + 1, last_read + 1, self.chunk_blocks):
                hi = min(lo + self.chunk_blocks, last_read + 1)
                sectors = self._sectors(fh, lo, hi - lo)
                blocks = decode_blocks(sectors, lo, params)
                self._note_bad(sectors, lo, blocks.valid)
                chunk = self._pairs(blocks, state, params, step)
                if chunk is not None:
                    yield chunk
            if end == n:
                chunk = self._last_block(state, params, step)
                if chunk is not None:
                    yield chunk
            self.sha256 = fh.hexdigest()
        self.rows = state.rows

    def _pairs(self, blocks: CwaBlocks, state: _State, params: CwaParams, step: float) -> SampleChunk | None:
        """Resample the previous block of every pair that ends in this chunk."""
        valid = np.flatnonzero(blocks.valid)
        bad = np.flatnonzero(~blocks.valid)
        if len(bad):
            before = np.searchsorted(valid, bad) - 1  # position in ``valid`` of the last valid before
            run = np.where(before >= 0, bad - valid[np.maximum(before, 0)], state.corrupt_run + bad + 1)
            for i, r in zip(blocks.index[bad], run, strict=True):
                self.qc_log.append(QcEntry(False, int(i), int(i) + 1, 0.0, 0.0, 0.0, False))
                if r > self.max_corrupt:
                    raise self._fail(f"at most {self.max_corrupt} bad blocks in a row",
                                     f"{r} (blocks {int(i) - r + 1}–{int(i)})", int(i))
            state.corrupt_run = int(run[-1]) if bad[-1] > (valid[-1] if len(valid) else -1) else 0
        elif len(valid):
            state.corrupt_run = 0
        if not len(valid):
            return None
        prev = state.prev
        assert prev is not None
        n_axes, m, cap = blocks.samples.shape
        width = max(cap, prev.samples.shape[1])
        samples = np.zeros((n_axes, m + 1, width))
        samples[:, 0, : prev.samples.shape[1]] = prev.samples
        samples[:, 1:, :cap] = blocks.samples
        rows = valid[:-1]
        nxt = blocks.sequence[valid]
        pseq = np.concatenate([[prev.sequence], blocks.sequence[rows]])
        pairs = _Pairs(
            frm=np.concatenate([[prev.start_s], blocks.start_s[rows]]),
            to=blocks.start_s[valid],
            length=np.concatenate([[prev.count], blocks.count[rows]]),
            base=np.concatenate([[0], rows + 1]) * width,
            samples=samples.reshape(n_axes, (m + 1) * width),
            temperature_c=np.concatenate([[prev.temperature_c], blocks.temperature_c[rows]]),
            sequence=pseq, next_sequence=nxt, next_start=blocks.start_s[valid],
            seq_jump=(nxt != 0) & (nxt - pseq != 1),
        )
        k = int(valid[-1])
        state.before_prev = (float(pairs.frm[-1]), int(pairs.length[-1]))
        state.prev = _Block(int(blocks.index[k]), int(blocks.sequence[k]), float(blocks.start_s[k]),
                            int(blocks.count[k]), float(blocks.temperature_c[k]), blocks.samples[:, k].copy())
        return self._resample(pairs, state, params, step)

    def _last_block(self, state: _State, params: CwaParams, step: float) -> SampleChunk | None:
        """GGIRread's pass for the file's last block (``ii == numDBlocks``): its samples on
        ``seq(startOfTheBlockBefore, extrapolated end, length.out = L + 1)``."""
        p, b = state.prev, state.before_prev
        if p is None or b is None:
            raise self._fail("at least two valid data blocks to resample between", "one",
                             p.index if p else None)
        b_start, b_count = b
        extrapolated = (p.start_s - b_start) / b_count * p.count + p.start_s
        one = np.array
        pairs = _Pairs(frm=one([b_start]), to=one([extrapolated]), length=one([p.count]), base=one([0]),
                       samples=p.samples, temperature_c=one([p.temperature_c]), sequence=one([p.sequence]),
                       next_sequence=one([p.sequence]), next_start=one([p.start_s]), seq_jump=one([False]))
        return self._resample(pairs, state, params, step, log_start=p.start_s)

    def _resample(self, pairs: _Pairs, state: _State, params: CwaParams, step: float,
                  log_start: float | None = None) -> SampleChunk | None:
        """Steps 4–5 for the given pairs: grid points per pair, then their values."""
        length = pairs.length
        by = (pairs.to - pairs.frm) / length
        u_end = np.where(length >= 2, pairs.frm + (length - 1) * by, pairs.frm)
        if state.first_pair:
            state.carry_t = float(pairs.frm[0]) - CARRY_DT_S
            state.carry_v = pairs.samples[:, pairs.base[0]].copy()
        counts, imputed, carry_rows, freq_obs = _counts(u_end, length, pairs.seq_jump, state, self.t0, step,
                                                        self.n_grid, params.frequency_hz)
        off = np.abs(freq_obs - params.frequency_hz) / params.frequency_hz > 0.05
        for j in np.flatnonzero(imputed | off):
            start_s = float(pairs.frm[j]) if log_start is None else log_start
            self.qc_log.append(QcEntry(True, int(pairs.sequence[j]), int(pairs.next_sequence[j]), start_s,
                                       float(pairs.next_start[j]), float(freq_obs[j]), bool(imputed[j])))
        total = int(counts.sum())
        self.imputed_rows += int(counts[imputed].sum())
        first_row = state.rows
        carry0_t, carry0_v = state.carry_t, state.carry_v
        state.first_pair = False
        if total == 0:
            return None
        t = self.t0 + (first_row + np.arange(total)) * step
        values = _interpolate(pairs, by, counts, t, imputed, carry_rows - first_row, carry0_t, carry0_v)
        state.rows = first_row + total
        state.carry_t, state.carry_v = float(t[-1]), values[:, -1].copy()
        return SampleChunk(first_row, t, values, np.repeat(pairs.temperature_c, counts))


def _counts(u_end: np.ndarray, length: np.ndarray, seq_jump: np.ndarray, state: _State, t0: float,
            step: float, n_grid: int, freq: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Grid points filled per pair, whether imputed, the carry-over row of each pair, observed rates.

    A vectorised pass assumes no pair is imputed and no window is exceeded; when either is
    false the pairs are walked one by one, exactly as GGIRread's loop does.
    """
    le = _grid_count(t0, step, n_grid, u_end, strict=False)
    lt = _grid_count(t0, step, n_grid, u_end, strict=True)
    rows_after = np.maximum.accumulate(np.maximum(le, state.rows))
    rows_before = np.concatenate([[state.rows], rows_after[:-1]])
    carry_t = np.where(rows_before > state.rows, t0 + (rows_before - 1) * step, state.carry_t)
    freq_obs = (length + 1) / (u_end - carry_t)
    imputed = seq_jump | (np.abs(freq_obs - freq) / freq > FREQUENCY_TOL)
    window = _window(rows_before, u_end, t0, step, n_grid, freq)
    if not imputed.any() and not (le > window).any():
        carry_rows = rows_before - 1
        return rows_after - rows_before, imputed, carry_rows, freq_obs
    counts = np.zeros(len(u_end), dtype=np.int64)
    carry_rows = np.zeros(len(u_end), dtype=np.int64)
    rows, c_t = state.rows, state.carry_t
    for j in range(len(u_end)):
        fo = (length[j] + 1) / (u_end[j] - c_t)
        freq_obs[j] = fo
        imp = bool(seq_jump[j]) or abs(fo - freq) / freq > FREQUENCY_TOL
        imputed[j] = imp
        last = int(_window(np.array([rows]), u_end[j:j + 1], t0, step, n_grid, freq)[0])
        idx = int(lt[j] if imp else le[j])
        carry_rows[j] = rows - 1
        counts[j] = max(0, min(idx, last) - rows)
        rows += int(counts[j])
        if counts[j]:
            c_t = t0 + (rows - 1) * step
    return counts, imputed, carry_rows, freq_obs


def _window(rows_before: np.ndarray, u_end: np.ndarray, t0: float, step: float, n_grid: int,
            freq: float) -> np.ndarray:
    """GGIRread's ``last``: ``pos + 200`` (1-based), moved on by a time jump, capped at the grid."""
    last = np.minimum(rows_before + 1 + WINDOW, n_grid)
    t_last = t0 + (last - 1) * step
    jump = u_end > t_last
    extra = np.where(jump, np.floor((u_end - t_last) * freq), 0).astype(np.int64)
    return np.minimum(last + extra, n_grid)


def _interpolate(pairs: _Pairs, by: np.ndarray, counts: np.ndarray, t: np.ndarray, imputed: np.ndarray,
                 carry_local: np.ndarray, carry0_t: float, carry0_v: np.ndarray) -> np.ndarray:
    """Values of the grid points ``t`` (shape (n_axes, n)): GGIRread's ``resample`` (type 1) and
    its imputation; ``counts[j]`` consecutive points belong to pair ``j``.

    The right end of a point's interval is the first sample at or after it (sample ``k`` at
    ``frm + k·by``); its left end the sample before, or, for ``k = 0``, the carry-over point: the
    last grid point filled before the pair (``carry_local``: its row in ``t``, negative: the one
    before this call, ``carry0_t``/``carry0_v``).
    """
    f = np.repeat(pairs.frm, counts)
    b = np.repeat(np.where(by > 0, by, np.inf), counts)  # a pair going back in time: k = 0
    top = np.repeat(pairs.length - 1, counts)
    k = np.ceil((t - f) / b).astype(np.int64)
    np.minimum(k, top, out=k)
    np.maximum(k, 0, out=k)
    k += (f + k * b < t) & (k < top)  # correct the division's rounding: first sample at or after t
    k -= (k > 0) & (f + (k - 1) * b >= t)
    b = np.repeat(by, counts)
    right_t = f + k * b
    left_t = f + (k - 1) * b
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (t - left_t) / (right_t - left_t)
    u[~((u >= 0) & (u <= 1))] = 0.0  # outside [0, 1] (GGIRread) or NaN
    right = np.repeat(pairs.base, counts) + k
    left = right - (k > 0)
    s = pairs.samples
    values = np.empty((s.shape[0], len(t)))
    for a in range(s.shape[0]):
        lv = s[a].take(left)
        values[a] = u * (s[a].take(right) - lv) + lv
    pair = np.repeat(np.arange(len(counts)), counts)
    # points whose left end is the carry-over point, and imputed pairs: resolved in passes
    todo = np.flatnonzero((k == 0) | imputed[pair])
    known = np.ones(len(t), dtype=bool)
    known[todo] = False
    for _ in range(len(pairs.frm) + 1):
        if len(todo) == 0:
            break
        src = carry_local[pair[todo]]
        ready = (src < 0) | known[np.maximum(src, 0)]
        now, src = todo[ready], src[ready]
        c_v = np.where((src < 0)[None, :], carry0_v[:, None], values[:, np.maximum(src, 0)])
        c_t = np.where(src < 0, carry0_t, t[np.maximum(src, 0)])
        imp = imputed[pair[now]]
        values[:, now[imp]] = _imputed_values(c_v[:, imp])
        rest = np.flatnonzero(~imp)
        r = now[rest]
        with np.errstate(divide="ignore", invalid="ignore"):
            uu = (t[r] - c_t[rest]) / (right_t[r] - c_t[rest])
        uu[(uu < 0) | (uu > 1)] = 0.0
        rv = s[:, right[r]]
        values[:, r] = uu * (rv - c_v[:, rest]) + c_v[:, rest]
        known[now] = True
        todo = todo[~ready]
    return values
