"""The threshold multiplier that finds a session's poses, chosen by the pose fit's residual.

``_poses`` finds static intervals for a given threshold; this module
chooses the threshold (methods.md §8). Each recording has its own noise floor; for every
candidate multiplier ``k`` each recording's static intervals at ``k · floor`` become poses,
and the poses of **all** the session's recordings of one device are fitted together (they
share one power cycle, hence one offset). The smallest multiplier whose residual ties with
the smallest residual wins. So a session of one continuous file with forty poses and a
session of six files with one pose each are treated alike. A still period that the winning
threshold saw as loud throughout, and a larger multiplier finds, is added to its poses when the
fit with it still ties (:func:`missed_periods`): leaving a pose out
does not raise the residual, so the smallest multiplier alone would drop the still periods of
a quiet sensor on a rig that vibrates above its own noise.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ofbe_data.io.recording import median
from ofbe_data.labelling.multiposition._fit import PoseFit, min_poses
from ofbe_data.labelling.multiposition._poses import (
    FLOOR_QUANTISATION,
    MG,
    NoPosesError,
    Pose,
    PoseParams,
    check_acc,
    choose_multiplier,
    intervals,
    is_number,
    make_poses,
    moving_stats,
    noise_floor,
    quantisation_floor,
    score,
    tie_limit,
    window_samples,
)
from ofbe_data.labelling.multiposition._poses import pose_scoring_model as scoring_model


@dataclass(frozen=True)
class PoseDetection:
    """Result of :func:`find_session_poses` (and :func:`find_poses`, one recording).

    Attributes
    ----------
    poses
        Per recording, its poses at the chosen multiplier, in time order, numbered from 0.
    multiplier
        The chosen threshold multiplier; a recording's threshold is ``multiplier`` times its
        noise floor.
    noise_floor_var
        Per recording, (m/s²)², its noise floor: a quiet window's variance summed over the axes.
    floor_source
        Per recording, where its floor came from (:data:`_poses.FLOOR_INITIAL`,
        :data:`_poses.FLOOR_QUIETEST`, or
        :data:`_poses.FLOOR_QUANTISATION` where the output step implies more).
    residuals
        Multiplier → residual of its pose fit per degree of freedom (m/s²; NaN: not eligible).
    counts
        Multiplier → poses found with it over all recordings.
    fit
        The pose fit of the chosen candidate (its model: ``fit.model``).
    window
        Per recording, the moving window in samples.
    pose_multipliers
        Per recording, per pose, the multiplier whose threshold found it: ``multiplier``, or a
        larger one for a still period that the chosen threshold saw as loud throughout
        (:func:`missed_periods`).
    """

    poses: tuple[tuple[Pose, ...], ...]
    multiplier: float
    noise_floor_var: tuple[float, ...]
    floor_source: tuple[str, ...]
    residuals: dict[float, float]
    counts: dict[float, int]
    fit: PoseFit
    window: tuple[int, ...]
    pose_multipliers: tuple[tuple[float, ...], ...] = ()

    @property
    def all_poses(self) -> tuple[Pose, ...]:
        """Every recording's poses, recording after recording."""
        return tuple(p for poses in self.poses for p in poses)


def _no_poses_message(floors: Sequence[float], sources: Sequence[str], counts: dict[float, int],
                      fits: dict[float, PoseFit | None], needed: int, params: PoseParams) -> str:
    found = ", ".join(f"×{k:g}: {n}" + (f" ({fits[k].reason})" if fits[k] is not None else "")
                      for k, n in counts.items())
    floor = max(floors) if floors else math.nan
    where = f"from the {sources[0]}" if len(set(sources)) == 1 else "per recording"
    return (f"no threshold multiplier gives static poses that determine the pose fit ({needed} "
            f"at least; static intervals of {params.min_pose_s:g} s or more per multiplier: "
            f"{found}); noise floor {floor:.3g} (m/s²)² "
            f"({math.sqrt(floor / 3.0) / MG:.2f} mg per axis) {where}")


def find_session_poses(recordings: Sequence[tuple[np.ndarray, np.ndarray, float]], g_local: float,
                       params: PoseParams | None = None) -> PoseDetection:
    """Find the static poses of a device's recordings of one power cycle.

    Parameters
    ----------
    recordings
        Per recording ``(t, acc, fs_hz)``: (N,) s, (N, 3) m/s² in the sensor frame, Hz.
    g_local
        m/s², local gravity magnitude, for the pose fit that scores each multiplier.
    params
        Detector parameters (default :class:`PoseParams`).

    Returns
    -------
    PoseDetection
        The poses at the chosen multiplier.

    Raises
    ------
    NoPosesError
        When a recording is shorter than a window or even its quietest part is noisier than
        ``max_noise_mps2``, or when no multiplier gives poses that determine the fit; the
        message gives the poses found per multiplier and the noise floor.
    ValueError
        If an array is not finite or of shapes (N,) and (N, 3), or ``fs_hz`` or ``g_local``
        is not a positive finite number.
    """
    params = params or PoseParams()
    if not is_number(g_local) or not math.isfinite(g_local) or not g_local > 0:
        raise ValueError(f"g_local must be a positive finite number, got {g_local!r}")
    needed = min_poses(scoring_model(0, params))
    data, floors, sources, windows = [], [], [], []
    for t, acc, fs_hz in recordings:
        a = check_acc(acc)
        times = np.asarray(t, dtype=np.float64)
        if times.shape != (a.shape[0],):
            raise ValueError(f"t must have shape ({a.shape[0]},) like acc, got {times.shape}")
        window = window_samples(fs_hz, params)
        if a.shape[0] < window:
            raise NoPosesError(f"the recording holds {a.shape[0]} samples, fewer than one "
                               f"{window}-sample window", math.nan, "", {}, needed)
        means, var = moving_stats(a, window)
        floor, source = noise_floor(var, window, fs_hz, params)
        coarse = quantisation_floor(a)
        if coarse > floor:  # a coarse output step: the quietest part shows its grid, not the noise
            floor, source = coarse, FLOOR_QUANTISATION
        if floor > 3.0 * params.max_noise_mps2**2:
            std = math.sqrt(floor / 3.0)
            raise NoPosesError(f"no static part: the noise floor (from the {source}) is {std:.3g} m/s² "
                               f"per axis ({std / MG:.1f} mg), above max_noise_mps2 = "
                               f"{params.max_noise_mps2:g} m/s²", floor, source, {}, needed)
        data.append((times, a, means, var, fs_hz))
        floors.append(floor)
        sources.append(source)
        windows.append(window)
    poses: dict[float, tuple[tuple[Pose, ...], ...]] = {}
    fits: dict[float, PoseFit | None] = {}
    residuals: dict[float, float] = {}
    dofs: dict[float, int] = {}
    for k in map(float, params.multipliers):
        poses[k] = tuple(make_poses(times, a, intervals(means, var, w, k * f, fs, params, times))
                         for (times, a, means, var, fs), f, w in zip(data, floors, windows, strict=True))
        pose_means = np.array([p.mean for rec in poses[k] for p in rec]).reshape(-1, 3)
        residuals[k], dofs[k], fits[k] = score(pose_means, g_local, params)
    counts = {k: sum(len(r) for r in p) for k, p in poses.items()}
    chosen = choose_multiplier(residuals, dofs, params.tie_sigmas)
    fit = fits[chosen] if chosen is not None else None
    if chosen is None or fit is None:
        most = max(counts, key=lambda k: counts[k]) if counts else None  # the first of equal counts
        raise NoPosesError(_no_poses_message(floors, sources, counts, fits, needed, params),
                           max(floors) if floors else math.nan, sources[0] if sources else "", counts,
                           needed, poses[most] if most is not None else ())
    found, fit, multipliers = _with_missed_periods(poses, chosen, fit, data, floors, windows, residuals, dofs,
                                                   g_local, params)
    return PoseDetection(found, chosen, tuple(floors), tuple(sources), residuals, counts, fit,
                         tuple(windows), multipliers)


def _with_missed_periods(poses: dict[float, tuple[tuple[Pose, ...], ...]], chosen: float, fit: PoseFit,
                         data: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]],
                         floors: list[float], windows: list[int], residuals: dict[float, float],
                         dofs: dict[float, int], g_local: float, params: PoseParams,
                         ) -> tuple[tuple[tuple[Pose, ...], ...], PoseFit, tuple[tuple[float, ...], ...]]:
    """The chosen multiplier's poses, with the still periods that its threshold saw as loud
    throughout and a larger multiplier found (:func:`missed_periods`), kept when the pose fit
    with them still ties with the smallest residual of the candidates: all of them when the fit
    with all ties, else each in time order that keeps the fit tied.

    Returns
    -------
    poses, fit, multipliers
        Per recording its poses in time order (those of ``chosen`` when nothing was missed), their
        fit, and per pose the multiplier whose threshold found it.
    """
    larger = [k for k in sorted(poses) if k > chosen]
    base = poses[chosen]
    missed = []
    for r, ((_, a, _, var, _), floor, window) in enumerate(zip(data, floors, windows, strict=True)):
        own = [(p.start, p.stop) for p in base[r]]
        ranges = [[(p.start, p.stop) for p in poses[k][r]] for k in larger]
        missed.append(missed_periods(own, ranges, var, window, chosen * floor, a))
    if not any(missed):
        return base, fit, tuple((chosen,) * len(rec) for rec in base)
    limit = tie_limit(residuals, dofs, params.tie_sigmas)
    kept: list[list[tuple[int, int, float, np.ndarray]]] = [[(p.start, p.stop, chosen, p.mean) for p in rec]
                                                            for rec in base]
    extra = [[(s, e, larger[j], d[1][s:e].mean(axis=0)) for s, e, j in m]
             for m, d in zip(missed, data, strict=True)]

    def tied(sets: list[list[tuple[int, int, float, np.ndarray]]]) -> PoseFit | None:
        means = np.array([m for rec in sets for *_, m in sorted(rec, key=lambda x: x[0])]).reshape(-1, 3)
        residual, _, trial = score(means, g_local, params)
        return trial if trial is not None and residual <= limit else None  # NaN (not determined) never ties

    every = [[*rec, *more] for rec, more in zip(kept, extra, strict=True)]
    trial = tied(every)
    if trial is not None:
        kept, fit = every, trial
    else:
        for r, more in enumerate(extra):
            for item in more:
                with_it = [*kept[:r], [*kept[r], item], *kept[r + 1:]]
                trial = tied(with_it)
                if trial is not None:
                    kept, fit = with_it, trial
    ordered = [sorted(rec, key=lambda x: x[0]) for rec in kept]
    found = tuple(make_poses(d[0], d[1], [(s, e) for s, e, _, _ in rec])
                  for d, rec in zip(data, ordered, strict=True))
    return found, fit, tuple(tuple(k for _, _, k, _ in rec) for rec in ordered)


def find_poses(t: np.ndarray, acc: np.ndarray, fs_hz: float, g_local: float,
               params: PoseParams | None = None) -> PoseDetection:
    """Find the static poses of one continuous recording (:func:`find_session_poses` of one).

    Parameters
    ----------
    t
        (N,) s, sample times (only reported: ``Pose.start_s``, ``Pose.end_s``).
    acc
        (N, 3) m/s², specific force in the sensor frame.
    fs_hz
        Sample rate, Hz (sets the window, margin and shortest pose in samples).
    g_local
        m/s², local gravity magnitude.
    params
        Detector parameters.

    Returns
    -------
    PoseDetection
        With one recording: ``poses[0]`` are its poses.
    """
    return find_session_poses([(t, acc, fs_hz)], g_local, params)


SAME_POSE_DEG = 10.0
"""A still period within this angle of the chosen pose next to it in time is that pose,
interrupted (:func:`missed_periods`; :func:`direction_groups` takes a face recorded twice as one
direction at the same angle)."""


def overlaps(a: tuple[int, int], b: tuple[int, int]) -> bool:
    """Whether two half-open sample ranges share a sample."""
    return a[0] < b[1] and b[0] < a[1]


def louder_than(var: np.ndarray, window: int, start: int, stop: int, threshold_var: float) -> bool:
    """Whether most windows centred in samples [start, stop) are above ``threshold_var``.

    Parameters
    ----------
    var
        (M,) (m/s²)², the moving variance (:func:`_poses.moving_stats`);
        window j covers samples j … j + window − 1, its centre is j + (window − 1) // 2.
    window
        Its window, samples.
    start, stop
        Half-open sample range.
    threshold_var
        (m/s²)².

    Returns
    -------
    bool
        The median variance of those windows exceeds the threshold (False when there is none).
    """
    half = (window - 1) // 2
    lo, hi = max(start - half, 0), min(stop - half, var.shape[0])
    return hi > lo and median(var[lo:hi]) > threshold_var


def angle_deg(u: np.ndarray, v: np.ndarray) -> float:
    """Angle between two (3,) vectors, degrees (0 when either is zero)."""
    nu, nv = float(np.linalg.norm(u)), float(np.linalg.norm(v))
    if nu == 0.0 or nv == 0.0:
        return 0.0
    return math.degrees(math.acos(min(1.0, max(-1.0, float(np.dot(u, v)) / (nu * nv)))))


def missed_periods(found: list[tuple[int, int]], larger: Sequence[list[tuple[int, int]]], var: np.ndarray,
                   window: int, threshold_var: float, acc: np.ndarray,
                   same_pose_deg: float = SAME_POSE_DEG) -> list[tuple[int, int, int]]:
    """Still periods of one recording that the chosen threshold saw as loud throughout.

    A still period is a stretch that the larger multipliers' poses cover (a connected part of
    their union) and that overlaps no pose of the chosen one (``found``). It was missed, rather
    than cut short by motion at its ends, when the median moving variance over it is above the
    chosen threshold: the period is still but louder than the threshold as a whole, as when the
    rig vibrates at a level that a quiet sensor resolves and a noisier one does not. Left out
    are a period that the chosen threshold sees as quiet, only too short (a tap's ringing or the
    slow end of a turn cut it), and one whose direction is within ``same_pose_deg`` of the
    chosen pose just before or after it: that is the same pose, interrupted (a knock, a cable
    tugged), and the chosen threshold already keeps it. Each period is taken as the pose of the
    smallest larger multiplier that finds it in one piece covering at least half of it, else as
    its longest pose.

    Parameters
    ----------
    found
        The chosen multiplier's poses, half-open sample ranges in time order.
    larger
        For each larger multiplier, in increasing order, its poses.
    var, window
        The recording's moving variance (:func:`_poses.moving_stats`) and
        its window, samples.
    threshold_var
        (m/s²)², the chosen threshold (multiplier × noise floor).
    acc
        (N, 3) m/s², the recording's readings (for the poses' directions).
    same_pose_deg
        Largest angle between a period and a neighbouring chosen pose that makes them one pose.

    Returns
    -------
    list of (start, stop, index)
        The missed periods in time order, each with the index into ``larger`` of the multiplier
        whose pose it is.
    """
    spans: list[list[int]] = []
    for a, b in sorted(p for poses in larger for p in poses):
        if spans and a < spans[-1][1]:
            spans[-1][1] = max(spans[-1][1], b)
        else:
            spans.append([a, b])
    f_start, f_stop = [f[0] for f in found], [f[1] for f in found]
    bounds = [([p[0] for p in poses], [p[1] for p in poses]) for poses in larger]
    out: list[tuple[int, int, int]] = []
    for a, b in spans:
        i = bisect.bisect_right(f_stop, a)  # the first chosen pose that ends after a
        if i < len(found) and f_start[i] < b:
            continue
        inside = [larger[j][bisect.bisect_right(stops, a):bisect.bisect_left(starts, b)]
                  for j, (starts, stops) in enumerate(bounds)]
        whole = [j for j, hits in enumerate(inside)
                 if len(hits) == 1 and 2 * (hits[0][1] - hits[0][0]) >= b - a]
        if whole:
            j = whole[0]
            pose = inside[j][0]
        else:
            pose, j = max(((p, m) for m, hits in enumerate(inside) for p in hits),
                          key=lambda pm: (pm[0][1] - pm[0][0], -pm[1]))
        if not louder_than(var, window, pose[0], pose[1], threshold_var):
            continue
        # the chosen poses just before and after it (none overlaps it)
        before = found[max(i - 1, 0):i]
        after = found[i:i + 1]
        direction = acc[pose[0]:pose[1]].mean(axis=0)
        if any(angle_deg(direction, acc[f[0]:f[1]].mean(axis=0)) <= same_pose_deg for f in before + after):
            continue
        out.append((pose[0], pose[1], j))
    return out


def direction_groups(means: np.ndarray, tolerance_deg: float = 10.0) -> list[list[int]]:
    """Poses grouped by direction: a pose within ``tolerance_deg`` of a group's first pose joins
    it (a face recorded twice is one direction).

    Parameters
    ----------
    means
        (K, 3) m/s², pose means in time order.
    tolerance_deg
        Largest angle to a group's first pose, degrees.

    Returns
    -------
    list of list of int
        Pose indices per group, groups in order of their first pose.
    """
    m = np.asarray(means, dtype=np.float64).reshape(-1, 3)
    units = m / np.linalg.norm(m, axis=1, keepdims=True)
    cos_tol = math.cos(math.radians(tolerance_deg))
    groups: list[list[int]] = []
    firsts = np.empty_like(units)  # each group's first pose: one product per group and pose, as arrays
    for i, u in enumerate(units):
        joins = np.flatnonzero(np.sum(firsts[:len(groups)] * u, axis=1) >= cos_tol)
        if joins.size:
            groups[int(joins[0])].append(i)
        else:
            firsts[len(groups)] = u
            groups.append([i])
    return groups


def distinct_directions(means: np.ndarray, tolerance_deg: float = 10.0) -> int:
    """Number of distinct directions among pose means, (K, 3) m/s² (:func:`direction_groups`)."""
    return len(direction_groups(means, tolerance_deg))
