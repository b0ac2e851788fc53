"""Faster formulations inside labelling compute the very numbers of the plain ones they replace.

Each test keeps the plain formulation (the code as it was before) as the reference and compares
bits: NaN, ±inf and −0.0 included where the data can hold them.
"""

from __future__ import annotations

import io

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from ofbe_data.core.geometry import mul3
from ofbe_data.io.recording import median
from ofbe_data.labelling.checks import clipped_samples, without_repeats
from ofbe_data.labelling.stationarity import centred_sums, column_mean, moving_variance_norm, running_sums
from ofbe_data.labelling.store import _parquet_bytes
from ofbe_data.labelling.sync import _lag_at, _window


def _bits(x: np.ndarray) -> bytes:
    return np.ascontiguousarray(x).tobytes()


def _arrays(rng: np.random.Generator) -> list[np.ndarray]:
    specials = np.array([np.nan, np.inf, -np.inf, -0.0, 0.0, 1e308, -1e308, 5e-324])
    out = []
    for n in (1, 2, 3, 7, 100, 8191, 8193, 40_001):
        x = rng.normal(size=(n, 3)) * 10.0 ** rng.integers(-5, 5)
        out.append(x)
        y = x.copy()
        mask = rng.random(y.shape) < 0.01
        y[mask] = rng.choice(specials, size=int(mask.sum()))
        out.append(y)
    out.append(np.full((50, 3), -0.0))
    out.append(np.rint(rng.normal(0.0, 2.0, size=(5000, 3))) / 256.0 * 9.80665)
    return out


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_running_sums_have_the_bits_of_cumsum() -> None:
    rng = np.random.default_rng(11)
    for x in _arrays(rng):
        expected = _bits(np.cumsum(x, axis=0))
        assert _bits(running_sums(x)) == expected
        out = np.empty((x.shape[0] + 1, 3))
        assert running_sums(x, out[1:]) is not None and _bits(out[1:]) == expected
        assert _bits(column_mean(x)) == _bits(x.mean(axis=0))
    # other layouts and shapes are numpy's own
    x = rng.normal(size=(300, 6))
    assert _bits(running_sums(x[:, ::2])) == _bits(np.cumsum(x[:, ::2], axis=0))
    assert _bits(running_sums(x)) == _bits(np.cumsum(x, axis=0))
    y = rng.normal(size=(300, 3))
    expected = _bits(np.cumsum(y, axis=0))
    assert _bits(running_sums(y, y)) == expected  # in place


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_moving_variance_norm_has_the_bits_of_the_textbook_expressions() -> None:
    rng = np.random.default_rng(12)
    for x in _arrays(rng):
        n, window = x.shape[0], max(2, min(150, x.shape[0]))
        if n < 2:
            continue
        mean = x.mean(axis=0)
        d = x - mean
        c1 = np.concatenate((np.zeros((1, 3)), np.cumsum(d, axis=0)))
        c2 = np.concatenate((np.zeros((1, 3)), np.cumsum(d * d, axis=0)))
        s1, s2 = c1[window:] - c1[:-window], c2[window:] - c2[:-window]
        var = np.maximum((s2 - s1 * s1 / window) / (window - 1), 0.0)
        expected = _bits(var.sum(axis=1))
        assert _bits(moving_variance_norm(x, window)) == expected
        assert _bits(moving_variance_norm(x, window, *centred_sums(x))) == expected


def _lag_at_plain(t_dut: np.ndarray, x_dut: np.ndarray, t_ref: np.ndarray, x_ref: np.ndarray,
                  centre_dut: float, to_ref: float, lags: np.ndarray, window_s: float,
                  ref_map: np.ndarray | None = None) -> tuple[float, float]:
    """The lag search as it was written before the interpolation ran over transposed queries."""
    a, b = _window(t_dut, centre_dut, window_s)
    if b - a < 5:
        return float("nan"), float("nan")
    td, xd = t_dut[a:b], np.ascontiguousarray(x_dut[a:b])
    xd = xd - xd.mean(axis=0)
    tq = (td - to_ref)[None, :] - lags[:, None]
    lo = max(int(np.searchsorted(t_ref, min(tq[0, 0], tq[-1, 0]))) - 1, 0)
    hi = int(np.searchsorted(t_ref, max(tq[0, -1], tq[-1, -1]))) + 1
    tr = t_ref[lo:hi]
    xs = x_ref[lo:hi] if ref_map is None else mul3(x_ref[lo:hi], ref_map)
    score = np.zeros(lags.size)
    energy_r = np.zeros(lags.size)
    product = np.empty_like(tq)
    for c in range(xd.shape[1]):
        xr = np.interp(tq, tr, xs[:, c]) if tr.size else np.zeros_like(tq)
        xr -= xr.mean(axis=1, keepdims=True)
        score += np.sum(np.multiply(xr, xd[:, c], out=product), axis=1)
        energy_r += np.sum(np.multiply(xr, xr, out=product), axis=1)
    score = score / np.sqrt(energy_r * float(np.sum(xd * xd)) + 1e-30)
    k = int(np.argmax(score))
    lag = float(lags[k])
    if 0 < k < lags.size - 1:
        y0, y1, y2 = score[k - 1], score[k], score[k + 1]
        den = y0 - 2 * y1 + y2
        if den < 0:
            lag += 0.5 * (y0 - y2) / den * float(lags[1] - lags[0])
    return lag, float(score[k])


def _same(a: tuple[float, float], b: tuple[float, float]) -> bool:
    return np.array(a).tobytes() == np.array(b).tobytes()


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@pytest.mark.parametrize("seed", range(6))
def test_lag_search_has_the_bits_of_the_plain_search(seed: int) -> None:
    rng = np.random.default_rng(seed)
    t_ref = np.cumsum(rng.uniform(0.0049, 0.0051, 4000))
    x_ref = rng.normal(size=(t_ref.size, 3))
    x_ref[1500:1520] += rng.normal(0.0, 20.0, size=(20, 3))  # a tap
    if seed == 3:
        x_ref[rng.random(x_ref.shape) < 0.001] = np.nan
    t_dut = 0.37 + np.cumsum(rng.uniform(0.0066, 0.0067, 3000))
    x_dut = rng.normal(size=(t_dut.size, 3))
    rot = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    coarse = np.arange(-0.5, 0.5 + 0.002, 0.004)
    fine = np.arange(-0.012, 0.012 + 0.0001, 0.0002)
    for centre in (t_ref[1510] + 0.37, 0.4, t_dut[-1] - 0.1, t_dut[-1] + 5.0, t_ref[-1] + 0.3):
        for to_ref in (0.37, 0.2, -3.0):
            args = (t_dut, x_dut, t_ref, x_ref, centre, to_ref)
            assert _same(_lag_at(*args, fine, 0.75, rot.T), _lag_at_plain(*args, fine, 0.75, rot.T))
            env_d, env_r = np.abs(x_dut[:, :1]), np.abs(x_ref[:, :1])
            args = (t_dut, env_d, t_ref, env_r, centre, to_ref)
            assert _same(_lag_at(*args, coarse, 0.75), _lag_at_plain(*args, coarse, 0.75))
    # a reference with no sample in reach
    args = (t_dut, x_dut, t_ref[:1], x_ref[:1], 1.0, 0.0, fine, 0.75)
    assert _same(_lag_at(*args), _lag_at_plain(*args))


def _without_repeats_plain(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=np.float64)
    if x.shape[0] < 2:
        return x
    keep = np.ones(x.shape[0], dtype=bool)
    keep[1:] = np.any(x[1:] != x[:-1], axis=1)
    return x if keep.all() else x[keep]


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_clipping_check_without_repeats_is_unchanged() -> None:
    from ofbe_data.labelling import checks

    rng = np.random.default_rng(13)
    for trial in range(600):
        n = int(rng.integers(0, 400))
        k = 3 if trial % 9 else int(rng.integers(0, 5))
        x = np.rint(rng.normal(0.0, rng.choice([0.1, 0.6, 3.0, 50.0]), size=(n, k)))
        if trial % 3 == 0 and n:
            x = np.repeat(x, rng.integers(1, 4), axis=0)
        if trial % 7 == 0 and x.size:
            x[rng.random(x.shape) < 0.05] = rng.choice([np.nan, np.inf, -0.0, 0.0])
        if trial % 11 == 0 and x.size:
            x[x > 1] = 2.0
        expected = _without_repeats_plain(x)
        got = without_repeats(x)
        assert got.shape == expected.shape and _bits(got) == _bits(expected)
        original = checks.without_repeats
        try:  # the check over the plain row-wise repeats, against the check over columns
            checks.without_repeats = _without_repeats_plain
            plain = _clipped_samples_plain(x)
        finally:
            checks.without_repeats = original
        assert repr(clipped_samples(x)) == repr(plain)


def _clipped_samples_plain(x: np.ndarray) -> tuple[int, int, float, bool] | None:
    """clipped_samples as it was written: repeats dropped row-wise first, then the columns."""
    from ofbe_data.labelling import checks

    x = checks.without_repeats(x)
    n = x.shape[0]
    need = max(5, 0.01 * n)
    columns = np.ascontiguousarray(x.T)
    for k in range(x.shape[1]):
        col = columns[k]
        if col.size == 0:
            continue
        hi, lo = col.max(), col.min()
        if hi == lo and np.isfinite(hi) and n >= need:
            if checks._others_vary(columns, k):
                return n, k, float(hi), True
            continue
        if not (np.isfinite(hi) and np.isfinite(lo)) or hi == 0.0 or lo == 0.0:
            found = checks._clipped_by_unique(col, need)
        else:
            found = checks._clipped_at_ends(col, hi, lo, need)
        if found is None:
            continue
        mostly = found[0] >= checks.MOSTLY_CLIPPED * n and checks._others_vary(columns, k)
        if mostly or np.unique(col).size >= checks.MIN_CLIP_LEVELS:
            return found[0], k, found[1], False
    return None


def test_parquet_bytes_are_those_written_to_a_file_object() -> None:
    table = pa.table({"a": [1.0, None, 3.5], "b": ["x", "y", None], "c": [1, 2, 3]})
    table = table.replace_schema_metadata({b"ofbe": b'{"k": 1}'})
    buf = io.BytesIO()
    pq.write_table(table, buf, compression="zstd")
    assert _parquet_bytes(table) == buf.getvalue()


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_median_has_the_bits_of_numpy_median() -> None:
    rng = np.random.default_rng(14)
    for trial in range(1500):
        n = int(rng.integers(1, 3000)) if trial % 2 else int(rng.integers(1, 12))
        kind = trial % 7
        if kind == 0:
            x = rng.normal(size=n)
        elif kind == 1:  # logger time steps: µs counts over 1e6
            x = np.diff(np.cumsum(rng.integers(6600, 6700, n + 1)) / 1e6)
        elif kind == 2:
            x = rng.choice([0.005, 0.004999999999999005, 0.0050000001], size=n)
        elif kind == 3:
            x = rng.normal(size=n)
            x[rng.random(n) < 0.01] = np.nan
        elif kind == 4:
            x = rng.choice([-0.0, 0.0, 1.0, -1.0], size=n)
        elif kind == 5:
            x = np.abs(rng.standard_cauchy(n))
            x[rng.random(n) < 0.05] = np.inf
        else:
            x = rng.choice([-np.inf, np.inf, 1.0, -0.0], size=n)
        assert np.float64(median(x)).tobytes() == np.float64(np.median(x)).tobytes(), (kind, n)
    ints = np.arange(10)
    assert median(ints) == float(np.median(ints))
    square = rng.normal(size=(4, 4))
    assert median(square) == float(np.median(square))


def test_counter_times_without_wraps_are_their_running_sum() -> None:
    from ofbe_data.io.formats.common import WRAP_US, _clean_times_fast

    rng = np.random.default_rng(15)
    for trial in range(300):
        n = int(rng.integers(2, 3000))
        t = np.cumsum(rng.integers(1, 20_000, n)).astype(np.int64) + int(rng.integers(0, 2**32))
        if trial % 2:
            t %= WRAP_US  # some wrap
        got = _clean_times_fast(t, 1e6, WRAP_US)
        assert got is not None
        d = np.diff(t)
        back = d < 0
        expected = np.empty(n)
        expected[0] = t[0]
        expected[1:] = float(t[0]) + np.cumsum(d + back * WRAP_US, dtype=np.int64)
        assert got[0].tobytes() == expected.tobytes() and got[1] == int(back.sum())
