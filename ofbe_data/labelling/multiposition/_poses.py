"""The static poses inside one continuous multi-position recording (methods.md §Labelling 8).

A multi-position calibration is usually one file: static poses separated by handling. The
poses are found as imu_tk (Tedaldi et al., ICRA 2014) finds them, its threshold taken from
the data:

1. **Moving statistics.** Over every window of ``window_s``: the mean, and the variance of
   each axis summed over the three axes (the trace of the covariance). The trace does not
   depend on how the sensor is oriented, so a motion counts the same along any axis (the
   largest axis' variance would not), and it sees a rotation that keeps |f| ≈ g, which the
   variance of the norm |f| would not.
2. **Noise floor.** The median moving variance over the first ``init_quiet_s`` when that
   stretch is quiet (imu_tk's initial rest: its median at most ``init_accept_ratio`` times the
   quietest stretch's), otherwise over the quietest stretch of that length; then the median
   over every window at most ``init_accept_ratio`` times that (one stretch scatters, and the
   quietest of many is biased low). A quantised output whose noise is below one step shows no
   variance there at all: the floor is at least what the output step implies
   (:func:`quantisation_floor`, the step read from the data's value grid).
3. **Static intervals** for a threshold ``k · floor``. A window is quiet when its variance is
   at most the threshold and its mean agrees with the means of the windows one window length
   before and after it (:func:`quiet_windows`: slow motion moves the mean long before it
   raises the variance). A sample is static when a quiet window holds it: imu_tk's
   centred-window test with each run widened by half a window, so that a run ends where the
   motion begins, and noise must push a whole window length of consecutive windows over the
   threshold to split a pose. A run must last ``min_pose_s`` (in samples, or in its time stamps:
   samples a link dropped do not shorten a pose, :func:`run_lasts`); it then loses ``margin_s``
   at both ends.
4. **Multiplier.** For each candidate ``k`` (imu_tk scans 2 … 10) the pose means are fitted
   with the norm-constrained least squares of ``_fit``; the
   smallest ``k`` whose residual is tied with the smallest residual wins
   (:func:`choose_multiplier`). A threshold that lets handling into a pose moves its mean off
   |A⁻¹(m − b)| = g and raises the residual. A candidate with fewer poses than the fit needs,
   or poses that do not determine it, is not eligible.
5. **Missed periods.** A still period that the chosen threshold saw as loud throughout (its
   median variance above it) while a larger multiplier finds it is added, when the fit with it
   still ties (:func:`_search.missed_periods`): a rig vibrating at a
   level a quiet sensor resolves keeps its poses. Leaving a pose out does not raise the
   residual, so step 4 alone would drop them.

Everything is plain numpy (cumulative sums, medians, means) and ``fit_poses``, whose start is
rounded so that its result is the same on every machine: same input, same poses, same bytes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np

from ofbe_data.core.errors import ConfigError, OfbeError
from ofbe_data.io.gravity import G0
from ofbe_data.io.recording import median, output_steps
from ofbe_data.labelling.multiposition._fit import BASE_MODELS, MODELS, PoseFit, fit_poses, min_poses

FLOOR_INITIAL = "initial quiet stretch"  #: ``floor_source``: the first ``init_quiet_s`` set the floor
FLOOR_QUIETEST = "quietest part"  #: ``floor_source``: the quietest stretch set it
FLOOR_QUANTISATION = "quantisation step"  #: ``floor_source``: the output step set it (quantisation_floor)
AUTO = "auto"  #: ``PoseParams.model``: ``scale-offset`` where a candidate has poses enough
MIN_WINDOW = 3  #: fewest samples in a moving window
MG = G0 / 1000.0  #: 1 mg in m/s² (for messages)
BLOCK = 1 << 16  #: windows taken at a time by the moving statistics (bounded temporaries)


class PoseParamError(ConfigError, ValueError):
    """A :class:`PoseParams` field is out of range (a :class:`ConfigError` and a ValueError)."""

    def __init__(self, key: str, expected: str, found: object) -> None:
        super().__init__("PoseParams", key, expected, repr(found))


class NoPosesError(OfbeError, ValueError):
    """No threshold multiplier yields static poses that the pose fit can use.

    Attributes ``noise_floor_var`` ((m/s²)², NaN when not measured), ``floor_source``,
    ``counts`` (multiplier → poses found) and ``needed`` (poses the fit needs) hold what the
    message says; ``poses`` holds, per recording, the poses the multiplier finding the most
    found (empty when none), for advice on which poses to add.
    """

    def __init__(self, message: str, noise_floor_var: float, floor_source: str,
                 counts: dict[float, int], needed: int, poses: tuple[tuple[Pose, ...], ...] = ()) -> None:
        super().__init__(message)
        self.noise_floor_var = noise_floor_var
        self.floor_source = floor_source
        self.counts = counts
        self.needed = needed
        self.poses = poses


@dataclass(frozen=True)
class PoseParams:
    """Parameters of the pose detector (a ``from_plain``-friendly record: numbers and a list).

    Attributes
    ----------
    window_s
        Moving window, s. Longer windows scatter less and see slower rotations (one at ω rad/s
        adds about (g·ω·window_s)²/12 to the variance); the window does not shorten a pose
        (step 3 of the module's description). 0.5 s is 25 samples at 50 Hz, enough that noise
        alone does not split a pose at multiplier 2 (at 0.25 s it did, at 50 Hz); imu_tk uses
        101 samples, 1 s at 100 Hz.
    min_pose_s
        Shortest pose kept, s, after the margins are trimmed (methods.md §8: 1 s).
    margin_s
        Trimmed from both ends of every static run, s. A device set down rings, and a hand
        starts a rotation gently: the windows at a run's ends can hold a few tenths of a second
        that differ from rest by less than the noise of a window mean. 0.25 s takes a quarter
        of a 2-s pose and leaves its mean as exact as the noise allows.
    multipliers
        Candidate thresholds in units of the noise floor, strictly increasing (imu_tk: 2 … 10).
    init_quiet_s
        Length of the stretch that sets the noise floor, s.
    init_accept_ratio
        The initial stretch sets the floor when its median moving variance is at most this
        many times the quietest stretch's; windows up to this many times the stretch's floor
        then refine it.
    drift_factor
        Two windows one window apart disagree when their means differ by more than
        sqrt(2 · drift_factor · threshold / window) (static: the difference scatters with
        variance 2 · floor / window). With 4, noise alone exceeds it with probability 3e-5
        at multiplier 2 (a χ² with 3 degrees of freedom above 24).
    min_noise_mps2, max_noise_mps2
        Bounds of the noise floor as a standard deviation per axis, m/s². Below 5e-3 (0.5 mg)
        the floor is raised to it: a pose on a table is not stiller than that (building
        vibration, a jig settling, drift within a second), so a quiet sensor's own noise
        (an ADXL355 at 0.2 mg) would put every threshold below what its still poses do and
        split or drop them, while a noisy one's (an ADXL345 at 3.5 mg) is far above it. Handling
        moves the reading by tens of mg, far beyond the raised threshold; a noise-free signal
        works too, and a coarsely quantised one through :func:`quantisation_floor`. A rig that
        vibrates above the raised floor in some poses keeps them through step 5. Above 0.3
        (30 mg, the stationarity check's ceiling) even the quietest part moves, and there is
        no pose.
    tie_sigmas
        Residuals within this many standard errors (1/sqrt(2ν) relative, ν degrees of freedom)
        of the smallest are tied; the smallest tied multiplier wins. Past the handling, a higher
        threshold adds samples at the poses' edges and lowers the residual by noise alone; one
        that lets handling in raises it far more.
    model
        Fit that scores a candidate: ``offset``, ``scale-offset``, ``full`` or ``auto`` (``scale-offset``
        from ``scale_min_poses`` poses, else ``offset``, as methods.md §8 fits sessions). Scale
        errors of 1–3 % leave an offset-only fit 0.1–0.3 m/s² of residual that would hide what
        the detection did.
    scale_min_poses
        Fewest poses for which ``auto`` scores with ``scale-offset`` (methods.md §8: 9).
    max_condition
        Largest condition number of an eligible candidate's fit (``fit_poses``' default:
        degenerate pose sets only; the labeller judges a session's spread itself).
    """

    window_s: float = 0.5
    min_pose_s: float = 1.0
    margin_s: float = 0.25
    multipliers: tuple[float, ...] = (2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0)
    init_quiet_s: float = 1.0
    init_accept_ratio: float = 3.0
    drift_factor: float = 4.0
    min_noise_mps2: float = 5e-3
    max_noise_mps2: float = 0.3
    tie_sigmas: float = 2.0
    model: str = AUTO
    scale_min_poses: int = 9
    max_condition: float = 1e6

    def __post_init__(self) -> None:
        for f in fields(self):
            if f.name not in ("multipliers", "model", "scale_min_poses"):
                _check_number(f.name, getattr(self, f.name), f.name in _MAY_BE_ZERO)
        _check_multipliers(self.multipliers)
        if self.model not in (AUTO, *BASE_MODELS):
            raise PoseParamError("model", " or ".join((AUTO, *BASE_MODELS)), self.model)
        least = min_poses("scale-offset")
        if not is_number(self.scale_min_poses) or int(self.scale_min_poses) != self.scale_min_poses \
                or self.scale_min_poses < least:
            raise PoseParamError("scale_min_poses", f"an integer ≥ {least}", self.scale_min_poses)
        if not self.init_accept_ratio >= 1:
            raise PoseParamError("init_accept_ratio", "a number ≥ 1", self.init_accept_ratio)
        if not self.max_noise_mps2 > self.min_noise_mps2:
            raise PoseParamError("max_noise_mps2", f"a number > min_noise_mps2 = {self.min_noise_mps2}",
                                 self.max_noise_mps2)


_MAY_BE_ZERO = frozenset({"margin_s", "tie_sigmas"})


def is_number(value: object) -> bool:
    return isinstance(value, int | float | np.floating | np.integer) and not isinstance(value, bool)


def _check_number(key: str, value: object, may_be_zero: bool) -> None:
    expected = "a finite number ≥ 0" if may_be_zero else "a finite number > 0"
    if not is_number(value) or not math.isfinite(value) or value < 0 or (value == 0 and not may_be_zero):
        raise PoseParamError(key, expected, value)


def _check_multipliers(value: object) -> None:
    expected = "a non-empty, strictly increasing list of finite numbers > 0"
    if not isinstance(value, tuple) or not value:
        raise PoseParamError("multipliers", expected, value)
    for i, k in enumerate(value):
        _check_number(f"multipliers[{i}]", k, False)
    if any(b <= a for a, b in zip(value, value[1:], strict=False)):
        raise PoseParamError("multipliers", expected, value)


@dataclass(frozen=True)
class Pose:
    """One static pose of a recording.

    Attributes
    ----------
    index
        Position in time, from 0.
    start, stop
        Sample range [start, stop) of the recording, margins already trimmed.
    start_s, end_s
        s, the recording's times ``t[start]`` and ``t[stop − 1]`` (first and last sample).
    mean
        (3,) m/s², mean specific force over the interval (read-only; not compared).
    """

    index: int
    start: int
    stop: int
    start_s: float
    end_s: float
    mean: np.ndarray = field(compare=False)


def window_samples(fs_hz: float, params: PoseParams) -> int:
    """Moving window in samples: ``round(window_s · fs_hz)``, at least :data:`MIN_WINDOW`."""
    if not is_number(fs_hz) or not math.isfinite(fs_hz) or not fs_hz > 0:
        raise ValueError(f"fs_hz must be a positive finite number, got {fs_hz!r}")
    return max(MIN_WINDOW, int(round(params.window_s * fs_hz)))


def check_acc(acc: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(acc, dtype=np.float64)  # one summation order whatever the layout
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"acc must have shape (N, 3), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError("acc must be finite")
    return a


def moving_stats(acc: np.ndarray, window: int) -> tuple[np.ndarray, np.ndarray]:
    """Mean and variance (summed over the axes) of ``acc`` in a sliding window.

    Parameters
    ----------
    acc
        (N, 3) m/s², specific force.
    window
        Window, samples (2 ≤ window ≤ N).

    Returns
    -------
    means
        (N − window + 1, 3) m/s²; row j covers samples j … j + window − 1.
    var
        (N − window + 1,) (m/s²)², the sum over the axes of the (ddof = 1) variances.
    """
    x = np.asarray(acc, dtype=np.float64)
    centre = x.mean(axis=0)  # taken out: keeps the cumulative sums well conditioned
    m = max(x.shape[0] - window + 1, 0)
    means, var = np.empty((m, 3)), np.empty(m)
    carry = np.zeros((2, 1, 3))  # the cumulative sums of x and x² before the block's first sample
    for a in range(0, m, BLOCK):  # in blocks: the same additions in the same order, bounded memory
        b = min(m, a + BLOCK)
        d = x[a:b + window - 1] - centre
        sums = np.stack((d, d * d))
        if a:  # numpy's running sum adds each element to the one before: carry it in the same way
            sums[:, 0] += carry[:, 0]
        c = np.concatenate((carry, np.cumsum(sums, axis=1)), axis=1)
        carry = c[:, b - a:b - a + 1]
        s1, s2 = c[0, window:] - c[0, :b - a], c[1, window:] - c[1, :b - a]
        var[a:b] = np.maximum((s2 - s1 * s1 / window) / (window - 1), 0.0).sum(axis=1)
        means[a:b] = s1 / window + centre
    return means, var


def noise_floor(var: np.ndarray, window: int, fs_hz: float, params: PoseParams) -> tuple[float, str]:
    """Noise floor of a recording from its moving variance (step 2 of the module's description).

    Parameters
    ----------
    var
        (M,) (m/s²)², the moving variance (:func:`moving_stats`).
    window
        Its window, samples.
    fs_hz
        Sample rate, Hz.
    params
        Detector parameters.

    Returns
    -------
    floor, source
        (m/s²)², at least ``3 · min_noise_mps2²``; :data:`FLOOR_INITIAL` or :data:`FLOOR_QUIETEST`.
    """
    length = int(np.clip(round(params.init_quiet_s * fs_hz) - window + 1, 1, var.shape[0]))
    sums = np.zeros(var.shape[0] + 1)
    np.cumsum(var, out=sums[1:])
    quietest = int(np.argmin(sums[length:] - sums[:-length]))
    lowest = 3.0 * params.min_noise_mps2**2
    floor_quietest = max(median(var[quietest:quietest + length]), lowest)
    floor_initial = median(var[:length])
    if floor_initial <= params.init_accept_ratio * floor_quietest:
        first, source = max(floor_initial, lowest), FLOOR_INITIAL
    else:
        first, source = floor_quietest, FLOOR_QUIETEST
    floor = median(var[var <= params.init_accept_ratio * first])
    return max(floor, lowest), source


def quantisation_floor(acc: np.ndarray) -> float:
    """The noise floor that a recording's output step implies, (m/s²)²: Σ_a q_a²/4.

    A quantised reading is known to within its step q only. When the noise spans several steps,
    rounding adds q²/12 per axis to the noise's variance and the quietest stretch measures both.
    When the noise is below one step, a still output sits on one grid value (variance 0: the
    quietest stretch shows nothing at all) or toggles between two neighbouring ones, and a
    toggle at even odds has a variance of q²/4 per axis, the most that a still two-level output
    shows (a short window: up to q²·n/(4(n − 1)), 0.3·q² in five samples). The floor is
    therefore at least Σ_a q_a²/4, with the steps inferred from the data's value grid
    (:func:`~ofbe_data.io.recording.output_steps`), so that a pose whose readings sit on one or
    two grid values per axis is still at every multiplier the search scans. The bound exceeds
    the measured floor only where the noise is below about 0.4·q (3·(σ² + q²/12) < 3·q²/4);
    readings that are not quantised give a negligible one.

    Parameters
    ----------
    acc
        (N, 3) m/s², a recording's readings.

    Returns
    -------
    float
        (m/s²)², the sum over the axes of step²/4.
    """
    steps = output_steps(acc)
    return float(np.sum(steps * steps)) / 4.0


def quiet_windows(means: np.ndarray, var: np.ndarray, window: int, threshold_var: float,
                  drift_factor: float) -> np.ndarray:
    """Windows that are quiet: small variance, and a mean that agrees with the windows beside it.

    Window j is quiet when its variance is at most ``threshold_var`` and its mean differs from
    the means of windows j − window and j + window by at most sqrt(2 · drift_factor ·
    threshold_var / window), where those exist and are not loud themselves (a loud window's
    mean says nothing about drift).

    Parameters
    ----------
    means, var
        (M, 3) m/s² and (M,) (m/s²)², from :func:`moving_stats`.
    window
        Window, samples.
    threshold_var
        (m/s²)², the variance threshold.
    drift_factor
        See :class:`PoseParams`.

    Returns
    -------
    np.ndarray
        (M,) bool.
    """
    low = var <= threshold_var
    limit = 2.0 * drift_factor * threshold_var / window
    steady = ~low[window:] | ~low[:-window]  # entry j: window j + window against window j
    for a in range(0, steady.shape[0], BLOCK):
        e = min(a + BLOCK, steady.shape[0])
        d = means[a + window:e + window] - means[a:e]
        steady[a:e] |= np.sum(d * d, axis=1) <= limit
    pad = np.ones(min(window, var.shape[0]), dtype=bool)
    after = np.concatenate((steady, pad))[:var.shape[0]]
    before = np.concatenate((pad, steady))[:var.shape[0]]
    return low & after & before


def static_runs(quiet: np.ndarray, window: int) -> np.ndarray:
    """Runs of samples that lie in at least one quiet window.

    Parameters
    ----------
    quiet
        (M,) bool; entry j covers samples j … j + window − 1 (M + window − 1 samples).
    window
        Window, samples.

    Returns
    -------
    np.ndarray
        (R, 2) int64, half-open sample ranges [start, stop), in time order.
    """
    pad = np.zeros(1, dtype=np.int8)
    runs = np.flatnonzero(np.diff(np.concatenate((pad, quiet.astype(np.int8), pad)))).reshape(-1, 2)
    if not runs.size:
        return runs.astype(np.int64)
    # quiet windows p … q − 1 hold samples p … q + window − 2; runs that touch or overlap are one
    first, stop = runs[:, 0], runs[:, 1] + (window - 1)
    new = np.concatenate(([True], first[1:] > stop[:-1]))
    return np.stack((first[new], stop[np.append(new[1:], True)]), axis=1).astype(np.int64)


def run_lasts(runs: np.ndarray, t: np.ndarray, fs_hz: float) -> np.ndarray:
    """How long each run of samples lasts in time, s: from its first sample's time to its last
    one's, plus one sample period (1/``fs_hz``), as its sample count over the rate gives it
    without gaps.

    Parameters
    ----------
    runs
        (R, 2) int64 half-open sample ranges, each non-empty.
    t
        (N,) s, the sample times.
    fs_hz
        Sample rate, Hz (kept and missing samples over the span).

    Returns
    -------
    np.ndarray
        (R,) s.
    """
    if runs.shape[0] == 0:
        return np.zeros(0)
    return t[runs[:, 1] - 1] - t[runs[:, 0]] + 1.0 / fs_hz


def _trim_runs(runs: np.ndarray, fs_hz: float, params: PoseParams,
               t: np.ndarray | None = None) -> list[tuple[int, int]]:
    """Keep the (R, 2) runs that stay still ``min_pose_s`` long, and trim ``margin_s`` from both
    ends of each (at least a quarter of the run is kept).

    The minimum is the length of the still run, as a person timing the pose would measure it
    (methods.md §8: a minimum pose length, and a margin trimmed at both ends); the margin only
    keeps the settling after set-down and the start of the next turn out of the mean. A run
    lasts ``min_pose_s`` when it holds that many seconds of samples or, with the sample times
    ``t``, when its time stamps span it (:func:`run_lasts`): samples a logger dropped inside a
    still pose (a radio link's gaps) do not shorten the pose.

    Returns half-open sample ranges, in the order given.
    """
    shortest = max(1, int(math.ceil(params.min_pose_s * fs_hz - 1e-9)))
    length = runs[:, 1] - runs[:, 0]
    margin = np.minimum(int(round(params.margin_s * fs_hz)), (length * 3) // 8)
    starts, stops = runs[:, 0] + margin, runs[:, 1] - margin
    keep = length >= shortest
    if t is not None and not keep.all():
        keep |= (length >= 2) & (run_lasts(runs, t, fs_hz) >= params.min_pose_s)
    return [(int(a), int(b)) for a, b in zip(starts[keep], stops[keep], strict=True)]


def intervals(means: np.ndarray, var: np.ndarray, window: int, threshold_var: float, fs_hz: float,
              params: PoseParams, t: np.ndarray | None = None) -> list[tuple[int, int]]:
    """Static intervals for one threshold from the moving statistics (:func:`detect_static`'s
    steps; ``t``, s, lets a pose's time span count, :func:`_trim_runs`)."""
    quiet = quiet_windows(means, var, window, threshold_var, params.drift_factor)
    return _trim_runs(static_runs(quiet, window), fs_hz, params, t)


def detect_static(acc: np.ndarray, fs_hz: float, threshold_var: float,
                  params: PoseParams = PoseParams()) -> list[tuple[int, int]]:
    """Static intervals of a recording for one variance threshold (step 3 of the description).

    Parameters
    ----------
    acc
        (N, 3) m/s², specific force.
    fs_hz
        Sample rate, Hz.
    threshold_var
        (m/s²)², largest moving variance (summed over the axes) of a quiet window.
    params
        Detector parameters (window, drift factor, margin, shortest pose).

    Returns
    -------
    list of (start, stop)
        Half-open sample ranges in time order, margins trimmed, each at least ``min_pose_s``
        long; empty when the recording is shorter than one window.

    Raises
    ------
    ValueError
        If ``acc`` is not a finite (N, 3) array, ``fs_hz`` not a positive finite number or
        ``threshold_var`` not a finite number ≥ 0.
    """
    a = check_acc(acc)
    window = window_samples(fs_hz, params)
    if not is_number(threshold_var) or not math.isfinite(threshold_var) or threshold_var < 0:
        raise ValueError(f"threshold_var must be a finite number ≥ 0, got {threshold_var!r}")
    if a.shape[0] < window:
        return []
    means, var = moving_stats(a, window)
    return intervals(means, var, window, float(threshold_var), fs_hz, params)


def make_poses(t: np.ndarray, acc: np.ndarray, intervals: list[tuple[int, int]]) -> tuple[Pose, ...]:
    """Poses from half-open intervals in time order: numbered, timed (``t``, s), and their mean
    specific force (``acc``, (N, 3) m/s²)."""
    out = []
    for k, (a, b) in enumerate(intervals):
        mean = acc[a:b].mean(axis=0)
        mean.setflags(write=False)
        out.append(Pose(k, a, b, float(t[a]), float(t[b - 1]), mean))
    return tuple(out)


def pose_scoring_model(n_poses: int, params: PoseParams) -> str:
    """Fit model that scores a candidate with ``n_poses`` poses (``params.model``, or for
    ``auto``: ``scale-offset`` from ``scale_min_poses`` poses on, else ``offset``)."""
    if params.model != AUTO:
        return params.model
    return "scale-offset" if n_poses >= params.scale_min_poses else "offset"


def score(means: np.ndarray, g_local: float, params: PoseParams) -> tuple[float, int, PoseFit | None]:
    """Residual of the pose fit over a candidate's pose means, per degree of freedom.

    Parameters
    ----------
    means
        (K, 3) m/s², the candidate's pose means.
    g_local
        m/s², local gravity magnitude.
    params
        Detector parameters (model, largest condition number).

    Returns
    -------
    residual, dof, fit
        sqrt(Σ_k r_k² / ν) in m/s², with r_k = |A⁻¹(m_k − b)| − g and ν = K − P the degrees of
        freedom the model's P unknowns leave (the RMS over the poses would favour a candidate
        that lost poses); ν; the fit (None below the model's fewest poses). The residual is NaN
        and ν 0 when the candidate has too few poses or the fit is not determined.
    """
    model = pose_scoring_model(means.shape[0], params)
    k = means.shape[0]
    if k < min_poses(model):
        return math.nan, 0, None
    fit = fit_poses(means, g_local, model, params.max_condition)
    if not fit.determined:
        return math.nan, 0, fit
    dof = k - MODELS[model]
    return fit.residual_rms * math.sqrt(k / dof), dof, fit


def choose_multiplier(residuals: dict[float, float], dofs: dict[float, int],
                      tie_sigmas: float) -> float | None:
    """Smallest multiplier whose residual is tied with the smallest one.

    A residual from ν degrees of freedom has a relative standard error of about 1/sqrt(2ν);
    residuals up to ``tie_sigmas`` of the best candidate's standard errors above it are tied.

    Parameters
    ----------
    residuals
        Multiplier → residual, m/s² (NaN: not eligible).
    dofs
        Multiplier → degrees of freedom of its residual.
    tie_sigmas
        Width of a tie, in standard errors.

    Returns
    -------
    float or None
        None when no multiplier is eligible.
    """
    valid = {k: r for k, r in residuals.items() if math.isfinite(r)}
    if not valid:
        return None
    limit = tie_limit(residuals, dofs, tie_sigmas)
    return min(k for k, r in valid.items() if r <= limit)


def tie_limit(residuals: dict[float, float], dofs: dict[float, int], tie_sigmas: float) -> float:
    """The largest residual that ties with the smallest finite one (:func:`choose_multiplier`).

    Parameters
    ----------
    residuals, dofs, tie_sigmas
        As :func:`choose_multiplier` takes them.

    Returns
    -------
    float
        m/s², the smallest residual times (1 + ``tie_sigmas``/sqrt(2ν)); NaN when none is finite.
    """
    valid = {k: r for k, r in residuals.items() if math.isfinite(r)}
    if not valid:
        return math.nan
    best = min(valid, key=lambda k: (valid[k], k))
    return valid[best] * (1.0 + tie_sigmas / math.sqrt(2.0 * dofs[best]))
