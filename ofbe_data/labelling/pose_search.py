"""The threshold multiplier that finds a session's poses, chosen by the pose fit's residual.

:mod:`ofbe_data.labelling.poses` finds static intervals for a given threshold; this module
chooses the threshold (methods.md §8). Each recording has its own noise floor; for every
candidate multiplier ``k`` each recording's static intervals at ``k · floor`` become poses,
and the poses of **all** the session's recordings of one device are fitted together (they
share one power cycle, hence one offset). The smallest multiplier whose residual ties with
the smallest residual wins. So a session of one continuous file with forty poses and a
session of six files with one pose each are treated alike.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ofbe_data.labelling.multiposition import PoseFit, min_poses
from ofbe_data.labelling.poses import (
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
    score,
    window_samples,
)
from ofbe_data.labelling.poses import _scoring_model as scoring_model


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
        Per recording, where its floor came from (:data:`~ofbe_data.labelling.poses.FLOOR_INITIAL`
        or :data:`~ofbe_data.labelling.poses.FLOOR_QUIETEST`).
    residuals
        Multiplier → residual of its pose fit per degree of freedom (m/s²; NaN: not eligible).
    counts
        Multiplier → poses found with it over all recordings.
    fit
        The pose fit of the chosen candidate (its model: ``fit.model``).
    window
        Per recording, the moving window in samples.
    """

    poses: tuple[tuple[Pose, ...], ...]
    multiplier: float
    noise_floor_var: tuple[float, ...]
    floor_source: tuple[str, ...]
    residuals: dict[float, float]
    counts: dict[float, int]
    fit: PoseFit
    window: tuple[int, ...]

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
        poses[k] = tuple(make_poses(times, a, intervals(means, var, w, k * f, fs, params))
                         for (times, a, means, var, fs), f, w in zip(data, floors, windows, strict=True))
        pose_means = np.array([p.mean for rec in poses[k] for p in rec]).reshape(-1, 3)
        residuals[k], dofs[k], fits[k] = score(pose_means, g_local, params)
    counts = {k: sum(len(r) for r in p) for k, p in poses.items()}
    chosen = choose_multiplier(residuals, dofs, params.tie_sigmas)
    fit = fits[chosen] if chosen is not None else None
    if chosen is None or fit is None:
        raise NoPosesError(_no_poses_message(floors, sources, counts, fits, needed, params),
                           max(floors) if floors else math.nan, sources[0] if sources else "", counts,
                           needed)
    return PoseDetection(poses[chosen], chosen, tuple(floors), tuple(sources), residuals, counts, fit,
                         tuple(windows))


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
    for i, u in enumerate(units):
        for group in groups:
            if float(np.sum(u * units[group[0]])) >= cos_tol:
                group.append(i)
                break
        else:
            groups.append([i])
    return groups


def distinct_directions(means: np.ndarray, tolerance_deg: float = 10.0) -> int:
    """Number of distinct directions among pose means, (K, 3) m/s² (:func:`direction_groups`)."""
    return len(direction_groups(means, tolerance_deg))
