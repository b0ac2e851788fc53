"""Synchronising a DUT's clock to the reference's from the header stamps and the taps.

Clock model: ``t_dut = offset + (1 + drift) · t_ref``, with ``t_dut`` the DUT time stamps as
the reader returns them (s, counter wraps undone) and ``t_ref`` the reference's ``Time (s)``.

1. Coarse offset from the header UTC stamps: the DUT's first sample arrived at the host at
   ``host_start_utc`` (± ~0.1 s serial latency), the reference's ``Time (s) = 0`` is its
   ``Start (UTC)``.
2. Taps: a tap is a sharp transient in the high-passed specific force. The detector runs on
   the *tap envelope* ``e(t) = ‖f(t) − moving_mean(f)(t)‖``: the norm of the high-passed vector
   is the same in any frame, so no knowledge of the mount is needed.
3. Fine offset: around each tap the reference envelope, interpolated at the DUT's (mapped)
   time stamps, is cross-correlated with the DUT envelope over a grid of lags; a parabola
   through the peak gives a sub-sample lag. Two taps give the offset and the drift; more
   taps are fitted by least squares.
4. Residual: after the fit, each tap's lag is measured again; the rms of those lags is the
   residual (the fit's own consistency, a fraction of a sample when all is well).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ofbe_data.core.geometry import mul3
from ofbe_data.io.recording import Recording, median
from ofbe_data.labelling.stationarity import centred_sums, row_sum


@dataclass(frozen=True)
class SyncParams:
    """Parameters of tap detection and alignment.

    Attributes
    ----------
    highpass_s
        Length of the moving mean removed before the envelope, s.
    tap_threshold_mps2
        Absolute envelope level above which a sample belongs to a tap, m/s² (0.1 g: far
        above sensor noise, far below a tap).
    tap_noise_factor
        The threshold is at least this many times the envelope's median.
    tap_merge_s
        Tap samples closer than this belong to one tap, s.
    search_s
        Largest lag searched around the coarse (or first-tap) alignment, s.
    coarse_step_s
        Grid step of the envelope lag search, s.
    fine_range_s
        Half-range of the signed search around the envelope lag, s (under half a tap
        period, so the search cannot slip by a cycle).
    lag_step_s
        Grid step of the signed lag search, s (refined by a parabola).
    min_signed_correlation
        Below this normalised correlation the signed alignment is not trusted.
    window_s
        Half-length of the correlation window around each tap, s.
    max_drift_ppm
        A fitted drift beyond this means a mismatched tap; the taps are then not trusted.
    """

    highpass_s: float = 0.25
    tap_threshold_mps2: float = 0.98
    tap_noise_factor: float = 8.0
    tap_merge_s: float = 1.0
    search_s: float = 0.5
    coarse_step_s: float = 0.004
    fine_range_s: float = 0.012
    lag_step_s: float = 0.0002
    min_signed_correlation: float = 0.5
    window_s: float = 0.75
    max_drift_ppm: float = 500.0


@dataclass(frozen=True)
class SyncResult:
    """How a DUT clock maps onto the reference clock.

    Attributes
    ----------
    offset_s
        DUT time at reference time 0, s.
    drift_ppm
        DUT clock rate error relative to the reference, ppm.
    residual_s
        rms lag left at the taps after the fit, s; NaN without taps.
    method
        ``taps`` or ``utc`` (header stamps only; drift assumed 0).
    taps_ref_s
        Tap times on the reference clock, s.
    coarse_offset_s
        The header-stamp offset, s (NaN when a stamp is missing).
    warning
        Why the taps were not used, when they were not.
    """

    offset_s: float
    drift_ppm: float
    residual_s: float
    method: str
    taps_ref_s: tuple[float, ...]
    coarse_offset_s: float
    warning: str = ""

    def to_device(self, t_ref: np.ndarray | float) -> np.ndarray:
        """Reference time → DUT time, s."""
        return self.offset_s + (1.0 + self.drift_ppm * 1e-6) * np.asarray(t_ref, dtype=np.float64)

    def to_reference(self, t_dut: np.ndarray | float) -> np.ndarray:
        """DUT time → reference time, s."""
        return (np.asarray(t_dut, dtype=np.float64) - self.offset_s) / (1.0 + self.drift_ppm * 1e-6)


class SyncError(ValueError):
    """Neither the taps nor the header stamps can align two recordings."""


def highpass(t: np.ndarray, acc: np.ndarray, highpass_s: float,
             centred: tuple[np.ndarray, np.ndarray] | None = None, median_step: float | None = None,
             ) -> np.ndarray:
    """Specific force minus its centred moving mean (a zero-phase high-pass).

    Parameters
    ----------
    t
        (N,) s.
    acc
        (N, 3) m/s².
    highpass_s
        Length of the centred moving mean, s (rounded to an odd number of samples, so the
        filter has no delay at any sample rate).
    centred
        ``centred_sums(acc)`` (:func:`~ofbe_data.labelling.stationarity.centred_sums`) when
        the caller has it (read only).
    median_step
        ``np.median(np.diff(t))`` when the caller has it.

    Returns
    -------
    ndarray, shape (N, 3)
        m/s².
    """
    n = acc.shape[0]
    acc = np.asarray(acc, dtype=np.float64)
    mean, c = centred_sums(acc) if centred is None else centred
    x = acc - mean
    if n < 3:
        return x
    dt = median(np.diff(t)) if median_step is None else median_step
    w = int(max(3, round(highpass_s / dt)) | 1)
    w = min(w, n if n % 2 else n - 1)
    half = w // 2
    # sample i takes the mean of x over lo … hi − 1, hi = min(i + half + 1, n) and
    # lo = max(i − half, 0), that is (c[hi] − c[lo]) / (hi − lo): the operations of a gather
    # over those indices, done by slices, the interior in place
    head = np.arange(half + 1, w, dtype=np.int64)  # hi of samples 0 … half − 1 (lo = 0)
    tail = np.arange(w - 1, half, -1, dtype=np.int64)  # hi − lo of samples n − half … n − 1
    x[:half] -= (c[half + 1:w] - c[0]) / head[:, None]
    x[n - half:] -= (c[n] - c[n - w + 1:n - half]) / tail[:, None]
    inner = c[w:] - c[:-w]
    inner /= float(w)
    x[half:n - half] -= inner
    return x


def detect_taps(t: np.ndarray, envelope: np.ndarray, params: SyncParams) -> np.ndarray:
    """Times of the taps in one recording.

    Parameters
    ----------
    t
        (N,) s.
    envelope
        (N,) tap envelope, m/s² (:attr:`TapSignals.envelope`).
    params
        Threshold and merging parameters.

    Returns
    -------
    ndarray, shape (K,)
        Time of the envelope peak of each tap, s, in time order.
    """
    if envelope.size == 0:
        return np.zeros(0)
    threshold = max(params.tap_threshold_mps2, params.tap_noise_factor * _median_at_most(
        envelope, params.tap_threshold_mps2 / params.tap_noise_factor, params.tap_noise_factor,
        params.tap_threshold_mps2))
    hot = np.flatnonzero(envelope > threshold)
    if hot.size == 0:
        return np.zeros(0)
    breaks = np.flatnonzero(np.diff(t[hot]) > params.tap_merge_s)
    groups = np.split(hot, breaks + 1)
    return np.array([t[g[np.argmax(envelope[g])]] for g in groups])


def _median_at_most(x: np.ndarray, bound: float, factor: float, ceiling: float) -> float:
    """``np.median(x)``, or ``bound`` when the median is known to be at most ``bound`` and
    ``factor · median`` therefore cannot exceed ``ceiling`` (the only use of the value).

    The median takes the sorted elements at n // 2 (and n // 2 − 1): when fewer than
    n − n // 2 elements exceed ``bound``, both are at most ``bound``, and so is their mean. A
    count is one pass; the partition a median needs costs several.
    """
    n = x.size
    if factor > 0 and factor * bound <= ceiling and int(np.count_nonzero(x > bound)) < n - n // 2:
        return bound
    return median(x)


@dataclass(frozen=True)
class TapSignals:
    """One recording's tap-related signals, computed once and shared by every pairing.

    Attributes
    ----------
    highpassed
        (N, 3) high-passed specific force, m/s², the recording's own frame.
    envelope
        (N,) tap envelope ``‖highpassed‖``, m/s² (the same in every frame, so taps are
        found without knowing the mount).
    taps
        (K,) tap times on the recording's clock, s.
    """

    highpassed: np.ndarray
    envelope: np.ndarray
    taps: np.ndarray


def tap_signals(rec: Recording, params: SyncParams,
                centred: tuple[np.ndarray, np.ndarray] | None = None) -> TapSignals:
    """High-pass a recording, take its tap envelope and find its taps (``centred``: see
    :func:`highpass`)."""
    hp = highpass(rec.t, rec.acc, params.highpass_s, centred, rec.median_step_s)
    # ‖hp‖ per row as np.linalg.norm(hp, axis=1) computes it: the squares summed by
    # x.sum(axis=1), then the root
    envelope = np.sqrt(row_sum(hp * hp))
    return TapSignals(hp, envelope, detect_taps(rec.t, envelope, params))


def _window(t: np.ndarray, centre: float, half: float) -> tuple[int, int]:
    """Samples [a, b) of increasing times ``t`` with ``|t − centre| ≤ half`` (exactly that
    test, on a slice found by bisection: ``t − centre`` never decreases, so they are one run)."""
    slack = 1e-6 * (1.0 + abs(centre) + half)
    a0 = int(np.searchsorted(t, centre - half - slack, side="left"))
    b0 = int(np.searchsorted(t, centre + half + slack, side="right"))
    inside = np.flatnonzero(np.abs(t[a0:b0] - centre) <= half)
    if inside.size == 0:
        return 0, 0
    return a0 + int(inside[0]), a0 + int(inside[-1]) + 1


def _lag_at(t_dut: np.ndarray, x_dut: np.ndarray, t_ref: np.ndarray, x_ref: np.ndarray,
            centre_dut: float, to_ref: float, lags: np.ndarray, window_s: float,
            ref_map: np.ndarray | None = None) -> tuple[float, float]:
    """Lag that best aligns DUT and reference signals around one tap.

    The DUT samples within ``window_s`` of ``centre_dut`` are compared with the reference
    signal (linearly interpolated) at ``t_dut − to_ref − lag`` for each candidate lag; the
    normalised correlation is summed over channels, and a parabola through the best grid
    point refines the lag.

    Parameters
    ----------
    t_dut, x_dut
        (N,) s and (N, C) DUT signal.
    t_ref, x_ref
        (M,) s and (M, C) reference signal, channels matching the DUT's.
    centre_dut
        DUT time of the tap, s.
    to_ref
        Current offset: reference time ≈ DUT time − to_ref, s.
    lags
        (L,) candidate lags, s, evenly spaced.
    window_s
        Half-length of the comparison window, s.
    ref_map
        (C, C) matrix the reference's rows are multiplied by (``x_ref @ ref_map``, the
        products of :func:`~ofbe_data.core.geometry.mul3`) before the comparison: applied to
        the samples the search reaches only, with the same bits as mapping them all first.

    Returns
    -------
    lag
        Best lag, s (NaN when the window holds too few samples).
    peak
        Normalised correlation at the best lag (1 for identical shapes).
    """
    a, b = _window(t_dut, centre_dut, window_s)
    if b - a < 5:
        return float("nan"), float("nan")
    td, xd = t_dut[a:b], np.ascontiguousarray(x_dut[a:b])
    xd = xd - xd.mean(axis=0)
    xd_cols = np.ascontiguousarray(xd.T)  # each channel's values side by side for the products
    # the query times tq[lag, sample] = (td − to_ref) − lag, built transposed: np.interp finds each
    # query's interval starting from the previous one's, and one sample's lags lie within an
    # interval or two of each other where one lag's samples do not (a third faster); each value
    # depends only on its own query, so the transpose back holds the same numbers
    tq_t = (td - to_ref)[:, None] - lags[None, :]
    # only the reference samples the search can reach are interpolated; td and lags increase,
    # so the extremes of tq are two of its corners
    lo = max(int(np.searchsorted(t_ref, min(tq_t[0, 0], tq_t[0, -1]))) - 1, 0)
    hi = int(np.searchsorted(t_ref, max(tq_t[-1, 0], tq_t[-1, -1]))) + 1
    tr = t_ref[lo:hi]
    xs = x_ref[lo:hi] if ref_map is None else mul3(x_ref[lo:hi], ref_map)
    score = np.zeros(lags.size)
    energy_r = np.zeros(lags.size)
    product = np.empty((lags.size, td.size))
    xr = np.zeros_like(product)
    for c in range(xd.shape[1]):
        # outside the reference's span np.interp repeats its edge value: a constant, which the
        # mean removal turns into zero correlation
        if tr.size:
            xr[...] = np.interp(tq_t, tr, xs[:, c]).T
        xr -= xr.mean(axis=1, keepdims=True)
        # elementwise products and numpy's own sums, not BLAS: the same last bits on every machine
        score += np.sum(np.multiply(xr, xd_cols[c], out=product), axis=1)
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


def fit_line(x: np.ndarray, y: np.ndarray) -> tuple[float, float]:
    """Least-squares line ``y ≈ intercept + slope·x`` in closed form about the mean of x.

    Written out instead of ``np.linalg.lstsq`` so that the result (which is written into
    every label) does not depend on the machine's BLAS kernel, and centred so that large
    times do not cost precision.

    Parameters
    ----------
    x, y
        (K,) points, K ≥ 2 with at least two distinct x.

    Returns
    -------
    intercept, slope
    """
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    xm, ym = float(np.mean(x)), float(np.mean(y))
    dx = x - xm
    slope = float(np.sum(dx * (y - ym)) / np.sum(dx * dx))
    return ym - slope * xm, slope


def _grid(half_range: float, step: float) -> np.ndarray:
    return np.arange(-half_range, half_range + step / 2, step)


def coarse_offset(dut: Recording, ref: Recording) -> float:
    """DUT time at reference time 0 from the header UTC stamps, s (NaN when one is missing)."""
    if dut.start_utc is None or ref.start_utc is None or dut.n == 0:
        return float("nan")
    return float(dut.t[0] - (dut.start_utc - ref.start_utc).total_seconds())


def synchronise(dut: Recording, ref: Recording, reference_to_sensor: np.ndarray | None = None,
                params: SyncParams = SyncParams(), ref_signals: TapSignals | None = None,
                ) -> SyncResult:
    """Fit the DUT clock to the reference clock (coarse stamps, then taps).

    Each tap is aligned in two stages: the tap envelopes (frame-free, robust) to within a
    few ms, then the signed high-passed signals, the reference's brought into the DUT frame
    through the nominal mount, within ± half a tap period of that (sub-millisecond). When
    the signed signals do not match (a wrong mount in the manifest), the envelope lag is
    kept and a warning says so.

    Parameters
    ----------
    dut, ref
        The two recordings of one recording id.
    reference_to_sensor
        (3, 3) nominal rotation from the reference frame to the DUT frame (identity if None).
    params
        Detection and search parameters.
    ref_signals
        The reference's :func:`tap_signals` when already computed (one reference serves
        every DUT of a recording).

    Returns
    -------
    SyncResult
        ``method == "taps"`` when taps were matched; otherwise the header-stamp offset with
        zero drift and a warning saying why.

    Raises
    ------
    SyncError
        When there are neither matching taps nor header stamps.
    """
    N = np.eye(3) if reference_to_sensor is None else np.asarray(reference_to_sensor, float)
    coarse = coarse_offset(dut, ref)
    ref_sig = tap_signals(ref, params) if ref_signals is None else ref_signals
    dut_sig = tap_signals(dut, params)
    hp_ref, to_dut = ref_sig.highpassed, N.T  # the reference's signed signal in DUT axes: hp_ref @ N.T
    hp_dut = dut_sig.highpassed
    e_ref = ref_sig.envelope[:, None]
    e_dut = dut_sig.envelope[:, None]
    taps_ref, taps_dut = ref_sig.taps, dut_sig.taps

    def fallback(why: str) -> SyncResult:
        if not np.isfinite(coarse):
            raise SyncError(f"cannot align {dut.path} with {ref.path}: {why}, and a header "
                            "UTC stamp is missing")
        return SyncResult(coarse, 0.0, float("nan"), "utc", tuple(map(float, taps_ref)), coarse,
                          f"{why}; aligned by header UTC stamps only (±0.1 s, drift unknown)")

    if taps_ref.size < 2:
        return fallback(f"{taps_ref.size} tap(s) found in the reference, 2 needed")
    if taps_dut.size < 1:
        return fallback("no tap found in the DUT")
    # initial offset: the header stamps, or else the first DUT tap against the first reference tap
    start = coarse if np.isfinite(coarse) else float(taps_dut[0] - taps_ref[0])
    coarse_lags = _grid(params.search_s, params.coarse_step_s)
    fine_lags = _grid(params.fine_range_s, params.lag_step_s)
    lags, weak = [], []
    for tr in taps_ref:
        lag, _ = _lag_at(dut.t, e_dut, ref.t, e_ref, start + tr, start, coarse_lags, params.window_s)
        if not np.isfinite(lag) or abs(lag) > params.search_s - 2 * params.coarse_step_s:
            lags.append(float("nan"))
            continue
        fine, peak = _lag_at(dut.t, hp_dut, ref.t, hp_ref, start + lag + tr, start + lag, fine_lags,
                             params.window_s, to_dut)
        if np.isfinite(fine) and peak >= params.min_signed_correlation:
            lag += fine
        else:
            weak.append(f"{tr:.2f} s (correlation {peak:.2f})")
        lags.append(lag)
    lag_arr = np.asarray(lags)
    ok = np.isfinite(lag_arr)
    if ok.sum() < 2:
        return fallback(f"only {int(ok.sum())} tap(s) matched between DUT and reference")
    # each matched tap gives a point (t_ref, t_dut) on the clock line t_dut = offset + slope·t_ref
    x = taps_ref[ok]
    y = start + lag_arr[ok] + x
    offset, slope = fit_line(x, y)
    drift = float(slope - 1.0)
    if abs(drift) * 1e6 > params.max_drift_ppm:
        return fallback(f"tap fit gave an implausible drift of {drift * 1e6:.0f} ppm")
    # residual: re-measure each tap's lag under the fitted clock map
    again = []
    for tr in x:
        centre = float(offset + slope * tr)
        again.append(_lag_at(dut.t, hp_dut, ref.t, hp_ref, centre, centre - tr, fine_lags,
                             params.window_s, to_dut)[0])
    residual = float(np.sqrt(np.nanmean(np.square(again))))
    warning = ("signed tap signals did not match through the nominal mount at "
               + ", ".join(weak) + "; envelope alignment used there (check reference_to_sensor)"
               if weak else "")
    return SyncResult(float(offset), drift * 1e6, residual, "taps", tuple(map(float, taps_ref)),
                      coarse, warning)
