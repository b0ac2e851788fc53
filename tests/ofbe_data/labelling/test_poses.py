"""Pose detection in continuous multi-position recordings: synthetic truth and a real session.

The synthetic recordings are built here, with their truth: K static poses of 2–10 s separated
by 1–4 s of handling (a minimum-jerk rotation between the orientations with a wobble about a
random axis, a lift and hand tremor; a jolt as the hand takes the device and a ringing as it
sets it down, or, for gentle handling, none), a known zero-g offset and diagonal scale, noise
like an ADXL345's (4 mg rms per axis at 100 Hz, growing as √fs), output quantised to its
3.9 mg step. A pose's true static interval ("still") is where the noise-free specific force is
within 1 mg of the pose's: its rest, plus the ends of the handling that differ from rest by
less than a quarter of one sample's noise.

The offset fitted to the detected poses must match the truth within five standard deviations
of what the pose means' noise alone gives (σ/√n per pose, propagated through the fit at the
truth), plus what the fitted model cannot represent (see ``_offset_tolerance``).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np
import pytest

from ofbe_data.core.errors import ConfigError, OfbeError
from ofbe_data.labelling.multiposition._fit import fit_poses
from ofbe_data.labelling.multiposition._poses import (
    FLOOR_INITIAL,
    FLOOR_QUIETEST,
    NoPosesError,
    Pose,
    PoseParamError,
    PoseParams,
    detect_static,
    moving_stats,
)
from ofbe_data.labelling.multiposition._search import find_poses
from tests.helpers.paths import ROOT, TESTS

G = 9.80665
MG = G / 1000.0
ADXL345_NOISE_MG = 4.0
"""Noise per axis at 100 Hz, mg rms."""
ADXL345_LSB_MG = 3.9
"""Output step in full resolution, mg."""
STILL_MG = 1.0
"""A sample is still when its noise-free specific force is within this of its pose's, mg (a
quarter of the noise of one sample: invisible)."""
DATA = TESTS / "data" / "imucal-ferraris"
FERRARIS_CSV = (ROOT / "raw" / "examples" / "imucal-ferraris"
                / "ferraris-continuous" / "rec-01" / "imu2.csv")
"""imucal's example_ferraris_session.csv, unchanged, as the example session holds it."""
FERRARIS_FS = 102.4


def _rotate(axes: np.ndarray, angles: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Rotate each vector (M, 3) about its unit axis (M, 3) by its angle (M,), rad (Rodrigues)."""
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    dot = np.sum(axes * vectors, axis=1, keepdims=True)
    return vectors * c + np.cross(axes, vectors) * s + axes * dot * (1.0 - c)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _directions(rng: np.random.Generator, k: int) -> np.ndarray:
    """(k, 3) pose directions in time order: the six faces tilted by ≤ 2°, or a spread set."""
    if k == 6:
        faces = np.vstack([np.eye(3), -np.eye(3)])[rng.permutation(6)]
        tilt = np.radians(2.0) * rng.uniform(size=6)
        return _rotate(_unit(rng.normal(size=(6, 3))), tilt, faces)
    i = np.arange(k) + 0.5  # Fibonacci sphere: evenly spread, then shuffled and rotated
    z = 1.0 - 2.0 * i / k
    phi = np.pi * (1.0 + 5.0**0.5) * i
    pts = np.column_stack([np.sqrt(1.0 - z * z) * np.cos(phi), np.sqrt(1.0 - z * z) * np.sin(phi), z])
    pts = _rotate(np.tile(_unit(rng.normal(size=3)), (k, 1)), np.full(k, rng.uniform(0, np.pi)), pts)
    return pts[rng.permutation(k)]


def _smooth_noise(rng: np.random.Generator, n: int, fs: float, rms: float) -> np.ndarray:
    """(n, 3) band-limited noise (moving mean of 0.05 s), m/s²."""
    w = max(1, int(0.05 * fs))
    white = rng.normal(size=(n + w, 3))
    c = np.cumsum(white, axis=0)
    x = (c[w:] - c[:-w]) / np.sqrt(w)
    return x * rms


def _jolt(rng: np.random.Generator, tau: np.ndarray, end: float) -> np.ndarray:
    """(n, 3) m/s², a hand's jolt from tau = 0 (zero before): a pulse of 1–3 m/s² lasting
    0.05–0.15 s and a ringing, faded out (cosine taper over 0.05 s) by ``end``."""
    length = rng.uniform(0.05, 0.15)
    on = (tau >= 0) & (tau <= length)
    pulse = np.where(on, rng.uniform(1.0, 3.0) * np.sin(np.pi * np.clip(tau, 0, length) / length), 0.0)
    f, decay = rng.uniform(8.0, 20.0), rng.uniform(0.02, 0.05)
    ring = np.where(tau >= 0, rng.uniform(0.3, 1.0) * np.exp(-np.maximum(tau, 0) / decay)
                    * np.sin(2 * np.pi * f * tau), 0.0)
    taper = 0.5 - 0.5 * np.cos(np.pi * np.clip((end - tau) / 0.05, 0.0, 1.0))
    return (pulse[:, None] * _unit(rng.normal(size=3)) + ring[:, None] * _unit(rng.normal(size=3))) \
        * taper[:, None]


def _handling(rng: np.random.Generator, u_a: np.ndarray, u_b: np.ndarray, n: int, fs: float,
              jolts: bool = True) -> np.ndarray:
    """(n, 3) specific force, m/s², of n samples of handling that turn u_a into u_b.

    A minimum-jerk rotation (the shortest way, plus a 5–20° wobble about a random axis), a
    lift and hand tremor. With ``jolts`` the hand jolts the device as it takes it (at the
    start) and the device rings as it is set down (the last 0.15–0.3 s, after the rotation);
    without, the handling starts and ends as gently as the rotation does.
    """
    tau = np.arange(1, n + 1) / fs
    d = (n + 1) / fs
    put_down = d - rng.uniform(0.15, 0.3) if jolts else d
    s = np.clip(tau / put_down, 0.0, 1.0)
    minjerk = 10 * s**3 - 15 * s**4 + 6 * s**5
    cross = np.cross(u_a, u_b)
    axis = _unit(cross) if np.linalg.norm(cross) > 1e-6 else _unit(np.cross(u_a, rng.normal(size=3)))
    angle = math.atan2(float(np.linalg.norm(cross)), float(np.dot(u_a, u_b)))
    u = _rotate(np.tile(axis, (n, 1)), angle * minjerk, np.tile(u_a, (n, 1)))
    wobble = np.radians(rng.uniform(5.0, 20.0)) * np.sin(np.pi * s) ** 2
    u = _rotate(np.tile(_unit(rng.normal(size=3)), (n, 1)), wobble, u)
    envelope = np.sin(np.pi * s)[:, None] ** 2
    lift = rng.uniform(0.2, 1.0) * np.sin(2 * np.pi * s)[:, None] * _unit(rng.normal(size=3))
    tremor = _smooth_noise(rng, n, fs, rng.uniform(0.05, 0.2)) * envelope
    out = G * u + lift * envelope + tremor
    if jolts:
        out += _jolt(rng, tau - 1.0 / fs, put_down) + _jolt(rng, tau - put_down, d)
    return out


@dataclass(frozen=True)
class Synthetic:
    """A synthetic continuous recording and its truth.

    Attributes
    ----------
    t
        (N,) s.
    acc
        (N, 3) m/s², measured specific force.
    fs
        Hz.
    static
        (K, 2) sample ranges [start, stop) in which the device rests in each pose (time order).
    still
        (K, 2) those ranges widened while the noise-free specific force stays within
        :data:`STILL_MG` of the pose's: what no detector can tell from rest. The true static
        intervals the tests hold detections to.
    directions
        (K, 3) true unit specific-force directions.
    offset, scale
        (3,) true zero-g offset (m/s²) and diagonal scale.
    noise_std
        m/s², per-axis noise rms, quantisation included.
    """

    t: np.ndarray
    acc: np.ndarray
    fs: float
    static: np.ndarray
    still: np.ndarray
    directions: np.ndarray
    offset: np.ndarray
    scale: np.ndarray
    noise_std: float


def synthetic_recording(k: int, fs: float, seed: int, start_with_motion: bool = False,
                        jolts: bool = True) -> Synthetic:
    """A continuous recording of k static poses (2–10 s) separated by 1–4 s of handling.

    Parameters
    ----------
    k
        Number of poses (6: the six faces, tilted by up to 2°; otherwise spread over the sphere).
    fs
        Sample rate, Hz.
    seed
        Random seed.
    start_with_motion
        Begin with 1–4 s of handling instead of the first pose.
    jolts
        Whether the hand jolts the device when it takes it and sets it down (without, the
        handling starts and ends as gently as a minimum-jerk rotation).

    Returns
    -------
    Synthetic
    """
    rng = np.random.default_rng(seed)
    u = _directions(rng, k)
    lengths = (rng.uniform(2.0, 10.0, size=k) * fs).astype(int)
    gaps = (rng.uniform(1.0, 4.0, size=k + 1) * fs).astype(int)
    pieces, static, at = [], [], 0
    if start_with_motion:
        first = _handling(rng, _unit(rng.normal(size=3)), u[0], int(gaps[k]), fs, jolts)
        pieces.append(first)
        at += first.shape[0]
    for i in range(k):
        pieces.append(np.tile(G * u[i], (lengths[i], 1)))
        static.append((at, at + lengths[i]))
        at += lengths[i]
        if i + 1 < k:
            pieces.append(_handling(rng, u[i], u[i + 1], int(gaps[i]), fs, jolts))
            at += gaps[i]
    # picked up at the end
    pieces.append(_handling(rng, u[-1], _unit(rng.normal(size=3)), int(fs), fs, jolts))
    truth = np.vstack(pieces)
    still = _still(truth, np.array(static), u)
    offset = rng.uniform(-0.5, 0.5, size=3)
    scale = 1.0 + rng.uniform(-0.03, 0.03, size=3)
    sigma = ADXL345_NOISE_MG * MG * math.sqrt(fs / 100.0)
    lsb = ADXL345_LSB_MG * MG
    acc = np.round((truth * scale + offset + rng.normal(size=truth.shape) * sigma) / lsb) * lsb
    t = np.arange(acc.shape[0]) / fs
    return Synthetic(t, acc, fs, np.array(static), still, u, offset, scale,
                     math.sqrt(sigma**2 + lsb**2 / 12))


def _still(truth: np.ndarray, static: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(K, 2) each static range widened while |truth − g·u_k| stays within STILL_MG."""
    out = []
    for (a, b), uk in zip(static, u, strict=True):
        near = np.linalg.norm(truth - G * uk, axis=1) <= STILL_MG * MG
        lo, hi = int(a), int(b)
        while lo > 0 and near[lo - 1]:
            lo -= 1
        while hi < truth.shape[0] and near[hi]:
            hi += 1
        out.append((lo, hi))
    return np.array(out)


# --- the detector's parts --------------------------------------------------------------------------


@pytest.mark.parametrize("kwargs, key, expected", [
    ({"window_s": float("nan")}, "window_s", "a finite number > 0"),
    ({"window_s": 0.0}, "window_s", "a finite number > 0"),
    ({"min_pose_s": -1.0}, "min_pose_s", "a finite number > 0"),
    ({"margin_s": -0.1}, "margin_s", "a finite number ≥ 0"),
    ({"init_quiet_s": float("inf")}, "init_quiet_s", "a finite number > 0"),
    ({"drift_factor": True}, "drift_factor", "a finite number > 0"),
    ({"multipliers": ()}, "multipliers", "a non-empty, strictly increasing list"),
    ({"multipliers": (3.0, 2.0)}, "multipliers", "a non-empty, strictly increasing list"),
    ({"multipliers": (2.0, float("nan"))}, "multipliers[1]", "a finite number > 0"),
    ({"init_accept_ratio": 0.5}, "init_accept_ratio", "a number ≥ 1"),
    ({"max_noise_mps2": 1e-5}, "max_noise_mps2", "a number > min_noise_mps2"),
    ({"model": "affine"}, "model", "auto or offset or scale-offset"),
    ({"scale_min_poses": 6}, "scale_min_poses", "an integer ≥ 7"),
])
def test_bad_parameters_are_refused_with_the_field_named(kwargs: dict, key: str, expected: str) -> None:
    with pytest.raises(PoseParamError) as info:
        PoseParams(**kwargs)
    assert isinstance(info.value, ValueError | ConfigError | OfbeError)
    assert isinstance(info.value, ValueError) and isinstance(info.value, ConfigError)
    assert str(info.value).startswith(f"PoseParams: {key}: expected {expected}")


def test_moving_stats_match_a_direct_computation() -> None:
    rng = np.random.default_rng(1)
    x = rng.normal(size=(300, 3)) * 0.05 + np.array([0.1, -0.2, 9.8])
    means, var = moving_stats(x, 40)
    direct_var = np.array([x[j:j + 40].var(axis=0, ddof=1).sum() for j in range(261)])
    direct_mean = np.array([x[j:j + 40].mean(axis=0) for j in range(261)])
    np.testing.assert_allclose(var, direct_var, rtol=1e-9)
    np.testing.assert_allclose(means, direct_mean, rtol=0, atol=1e-12)


def _two_poses(fs: float, rest_s: float, move_s: float) -> np.ndarray:
    """Noise-free: rest along +z, a 90° turn (sine velocity), rest along +x."""
    n_rest, n_move = int(rest_s * fs), int(move_s * fs)
    angle = np.pi / 2 * (1 - np.cos(np.pi * np.arange(1, n_move + 1) / (n_move + 1))) / 2
    turn = G * np.column_stack([np.sin(angle), np.zeros(n_move), np.cos(angle)])
    return np.vstack([np.tile([0.0, 0.0, G], (n_rest, 1)), turn, np.tile([G, 0.0, 0.0], (n_rest, 1))])


def test_noise_free_poses_end_where_the_motion_begins_less_the_margins() -> None:
    acc = _two_poses(100.0, 3.0, 1.0)
    assert detect_static(acc, 100.0, 1e-9, PoseParams(margin_s=0.0)) == [(0, 300), (400, 700)]
    assert detect_static(acc, 100.0, 1e-9) == [(25, 275), (425, 675)]
    # min_pose_s is the still run's own length: a 1.4-s rest is a pose (trimmed by the margins),
    # a 0.9-s one is not
    assert detect_static(_two_poses(100.0, 1.4, 1.0), 100.0, 1e-9) == [(25, 115), (265, 355)]
    assert detect_static(_two_poses(100.0, 0.9, 1.0), 100.0, 1e-9) == []
    assert detect_static(acc[:40], 100.0, 1e-9) == []  # shorter than one window


@pytest.mark.parametrize("rate_deg_s", [2.0, 5.0, 20.0])
def test_a_slow_rotation_about_one_axis_is_not_static(rate_deg_s: float) -> None:
    """|f| stays g while its direction turns slowly; the variance alone barely moves (at 2°/s
    it adds 0.4 % of the noise floor), the window means do: no static interval inside the turn."""
    fs, rng = 100.0, np.random.default_rng(7)
    turn_s = 90.0 / rate_deg_s
    n_rest, n_turn = 500, int(turn_s * fs)
    angle = np.radians(rate_deg_s) * np.arange(1, n_turn + 1) / fs
    f = np.vstack([np.tile([0.0, 0.0, G], (n_rest, 1)),
                   G * np.column_stack([np.sin(angle), np.zeros(n_turn), np.cos(angle)]),
                   np.tile([G, 0.0, 0.0], (n_rest, 1))])
    acc = f + rng.normal(size=f.shape) * ADXL345_NOISE_MG * MG
    floor = 3 * (ADXL345_NOISE_MG * MG) ** 2
    found = detect_static(acc, fs, 10.0 * floor)  # the loosest default multiplier
    inside = [(a, b) for a, b in found if b > n_rest + fs and a < n_rest + n_turn - fs]
    assert inside == []
    assert len(found) == 2


def test_find_poses_refuses_bad_arrays() -> None:
    acc = np.zeros((100, 3))
    with pytest.raises(ValueError, match=r"acc must have shape \(N, 3\)"):
        find_poses(np.arange(100.0), np.zeros((100, 2)), 100.0, G)
    with pytest.raises(ValueError, match=r"t must have shape \(100,\)"):
        find_poses(np.arange(99.0), acc, 100.0, G)
    with pytest.raises(ValueError, match="fs_hz must be a positive finite number"):
        find_poses(np.arange(100.0), acc, float("nan"), G)
    with pytest.raises(ValueError, match="g_local must be a positive finite number"):
        find_poses(np.arange(100.0), acc, 100.0, 0.0)
    bad = acc.copy()
    bad[3, 1] = np.nan
    with pytest.raises(ValueError, match="acc must be finite"):
        find_poses(np.arange(100.0), bad, 100.0, G)


# --- synthetic recordings with known truth ----------------------------------------------------------


def _matches(detected: tuple[Pose, ...], synth: Synthetic) -> list[Pose]:
    """The one detected pose in each true still interval (asserts that there is exactly one)."""
    out = []
    for k, (a, b) in enumerate(synth.still):
        hits = [p for p in detected if p.start < b and p.stop > a]
        assert len(hits) == 1, f"pose {k} ({a}–{b}) found {len(hits)} times"
        out.append(hits[0])
    assert len(detected) == len(synth.still), "a pose outside every still interval"
    return out


def _coverage(pose: Pose, a: int, b: int, margin: int) -> float:
    """Fraction of the still interval less its margins, [a + margin, b − margin), that the pose covers."""
    return (min(pose.stop, b - margin) - max(pose.start, a + margin)) / (b - a - 2 * margin)


def _offset_tolerance(synth: Synthetic, poses: list[Pose], model: str) -> np.ndarray:
    """(3,) m/s²: what the fit's offset may miss the truth by, per axis.

    Five standard deviations of the offset that the pose means' noise alone produces (σ/√n per
    mean, propagated through the fit's Jacobian at the truth), plus what the model cannot
    represent (the offset the same fit finds on noise-free means: the truth for scale-offset, a
    little off it for an offset-only fit of tilted faces with scale errors).
    """
    u, s = synth.directions, synth.scale
    jac = -u / s
    if model == "scale-offset":
        jac = np.hstack([jac, -G * u * u / s])
    sigma2 = np.array([synth.noise_std**2 / (p.stop - p.start) for p in poses])
    inv = np.linalg.inv(jac.T @ jac)
    cov = inv @ jac.T @ (jac * sigma2[:, None]) @ inv
    exact = fit_poses(G * u * s + synth.offset, G, model).offset
    return np.abs(exact - synth.offset) + 5.0 * np.sqrt(np.diag(cov)[:3])


def _check_offset(synth: Synthetic, poses: list[Pose]) -> tuple[np.ndarray, np.ndarray]:
    model = "scale-offset" if len(poses) >= 9 else "offset"
    fit = fit_poses(np.array([p.mean for p in poses]), G, model)
    error, tol = np.abs(fit.offset - synth.offset), _offset_tolerance(synth, poses, model)
    assert np.all(error <= tol), (error, tol)
    return error, tol


GRID = [(6, 50.0, False), (6, 100.0, True), (6, 400.0, False), (9, 50.0, True), (9, 100.0, False),
        (9, 400.0, True), (18, 50.0, False), (18, 100.0, True), (18, 400.0, False), (40, 50.0, True),
        (40, 100.0, False), (40, 400.0, True)]


@pytest.mark.parametrize("k, fs, start_with_motion", GRID)
def test_every_pose_is_found_once_inside_its_still_interval(k: int, fs: float,
                                                             start_with_motion: bool) -> None:
    synth = synthetic_recording(k, fs, seed=1000 * k + int(fs), start_with_motion=start_with_motion)
    det = find_poses(synth.t, synth.acc, fs, G)
    poses = _matches(det.poses[0], synth)
    margin = int(round(PoseParams().margin_s * fs))
    for pose, (a, b) in zip(poses, synth.still, strict=True):
        assert a <= pose.start and pose.stop <= b
        assert _coverage(pose, a, b, margin) >= 0.8
        assert pose.start_s == synth.t[pose.start] and pose.end_s == synth.t[pose.stop - 1]
    assert [p.index for p in det.poses[0]] == list(range(k))
    assert all(p.stop <= q.start for p, q in zip(det.poses[0], det.poses[0][1:], strict=False))
    if not start_with_motion:
        assert det.floor_source[0] == FLOOR_INITIAL
    assert abs(det.noise_floor_var[0] / (3 * synth.noise_std**2) - 1) < 0.1
    _check_offset(synth, poses)


@pytest.mark.parametrize("k, fs, start_with_motion", [(18, 50.0, True), (18, 100.0, False),
                                                      (18, 400.0, True)])
def test_gentle_handling_is_trimmed_to_within_half_a_second(k: int, fs: float,
                                                            start_with_motion: bool) -> None:
    """Without the hand's jolts the handling starts and ends like a minimum-jerk rotation: its
    first and last few tenths of a second differ from rest by less than the noise of a window
    mean, and a pose may keep some of them (0.40 s at most over 120 such recordings)."""
    synth = synthetic_recording(k, fs, seed=2000 * k + int(fs), start_with_motion=start_with_motion,
                                jolts=False)
    det = find_poses(synth.t, synth.acc, fs, G)
    poses = _matches(det.poses[0], synth)
    margin = int(round(PoseParams().margin_s * fs))
    for pose, (a, b) in zip(poses, synth.still, strict=True):
        assert a - 0.5 * fs <= pose.start and pose.stop <= b + 0.5 * fs
        assert _coverage(pose, a, b, margin) >= 0.8
    _check_offset(synth, poses)


def test_a_recording_that_starts_moving_takes_its_floor_from_the_quietest_part() -> None:
    synth = synthetic_recording(9, 100.0, seed=11)
    rng = np.random.default_rng(12)
    shaking = synth.acc[0] + _smooth_noise(rng, 300, 100.0, 2.0)  # 3 s of vigorous handling first
    acc = np.vstack([shaking, synth.acc])
    det = find_poses(np.arange(acc.shape[0]) / 100.0, acc, 100.0, G)
    assert det.floor_source[0] == FLOOR_QUIETEST
    assert [(p.start - 300, p.stop - 300) for p in det.poses[0]] == \
        [(p.start, p.stop) for p in find_poses(synth.t, synth.acc, 100.0, G).poses[0]]


def _turning(rate_deg_s: float, seconds: float = 30.0, fs: float = 100.0) -> np.ndarray:
    """(n, 3) m/s²: a device turning about its x axis at a constant rate, with ADXL345 noise."""
    angle = np.radians(rate_deg_s) * np.arange(int(seconds * fs)) / fs
    f = G * np.column_stack([np.zeros_like(angle), np.sin(angle), np.cos(angle)])
    return f + np.random.default_rng(3).normal(size=f.shape) * ADXL345_NOISE_MG * MG


def test_a_recording_with_no_static_part_is_refused_with_the_reason() -> None:
    t = np.arange(3000) / 100.0
    with pytest.raises(NoPosesError) as info:
        find_poses(t, _turning(90.0), 100.0, G)
    assert str(info.value) == ("no static part: the noise floor (from the initial quiet stretch) is "
                               "1.28 m/s² per axis (130.9 mg), above max_noise_mps2 = 0.3 m/s²")
    with pytest.raises(NoPosesError) as info:
        find_poses(t, _turning(10.0), 100.0, G)  # slow enough to pass the noise ceiling
    assert str(info.value) == (
        "no threshold multiplier gives static poses that determine the pose fit (4 at least; static "
        "intervals of 1 s or more per multiplier: ×2: 0, ×3: 0, ×4: 0, ×5: 0, ×6: 0, ×7: 0, ×8: 0, "
        "×9: 0, ×10: 0); noise floor 0.0669 (m/s²)² (15.23 mg per axis) from the initial quiet stretch")
    assert info.value.counts == {float(k): 0 for k in range(2, 11)}


def test_too_few_poses_are_refused_with_the_count_per_multiplier() -> None:
    synth = synthetic_recording(3, 100.0, seed=5)
    with pytest.raises(NoPosesError) as info:
        find_poses(synth.t, synth.acc, 100.0, G)
    assert str(info.value) == (
        "no threshold multiplier gives static poses that determine the pose fit (4 at least; static "
        "intervals of 1 s or more per multiplier: ×2: 3, ×3: 3, ×4: 3, ×5: 3, ×6: 3, ×7: 3, ×8: 3, "
        "×9: 3, ×10: 3); noise floor 0.00506 (m/s²)² (4.19 mg per axis) from the initial quiet stretch")
    assert info.value.needed == 4 and set(info.value.counts.values()) == {3}


def test_the_result_does_not_depend_on_the_array_layout() -> None:
    synth = synthetic_recording(9, 100.0, seed=21)
    one = find_poses(synth.t, synth.acc, 100.0, G)
    two = find_poses(synth.t.copy(), np.asfortranarray(synth.acc), 100.0, G)
    assert one.poses == two.poses and one.multiplier == two.multiplier
    assert b"".join(p.mean.tobytes() for p in one.all_poses) == \
        b"".join(p.mean.tobytes() for p in two.all_poses)
    assert one.residuals == two.residuals and one.noise_floor_var == two.noise_floor_var


def test_poses_that_do_not_determine_the_fit_are_refused_with_the_fit_s_reason() -> None:
    """Five noise-free poses in one plane (turns about x): enough poses, no offset normal to the plane."""
    fs, pieces = 100.0, []
    for k in range(5):
        a0, a1 = np.radians(72.0 * k), np.radians(72.0 * (k + 1))
        pieces.append(np.tile([0.0, G * np.sin(a0), G * np.cos(a0)], (300, 1)))
        ramp = a0 + (a1 - a0) * (1 - np.cos(np.pi * np.arange(1, 101) / 101)) / 2
        pieces.append(G * np.column_stack([np.zeros(100), np.sin(ramp), np.cos(ramp)]))
    acc = np.vstack(pieces[:-1])
    with pytest.raises(NoPosesError) as info:
        find_poses(np.arange(acc.shape[0]) / fs, acc, fs, G)
    assert "×2: 5 (poses do not span three dimensions (condition" in str(info.value)


# --- a real session: imucal's Ferraris example (MIT licence, see tests/data/imucal-ferraris) -------


def _ferraris() -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, tuple[int, int]]]:
    """t (s), acc (m/s²), gyr (deg/s) and imucal's annotation (name → [start, end) samples)."""
    data = np.loadtxt(FERRARIS_CSV, delimiter=",", skiprows=1)
    assert np.array_equal(data[:, 0], np.arange(data.shape[0]))  # n_samples: a sample index
    annotation = json.loads((DATA / "example_ferraris_session_list.json").read_text())
    parts = {name: (int(v["start"]), int(v["end"])) for name, v in annotation.items()}
    return data[:, 0] / FERRARIS_FS, data[:, 4:7], data[:, 1:4], parts


def test_the_six_faces_of_a_real_ferraris_session_are_found_unaided() -> None:
    """Detected vs imucal's annotation (s), 102.4 Hz: x_p 3.92–13.31 vs 5.27–12.41, x_a
    14.88–24.34 vs 15.82–23.06, y_p 25.57–33.89 vs 27.48–32.21, y_a 35.49–41.68 vs 36.52–40.55,
    z_p 42.89–49.88 vs 44.16–48.58, z_a 51.54–59.42 vs 52.50–58.43: each detected pose holds the
    whole annotated interval (imucal's hand-drawn intervals keep 0.9–1.9 s from the handling),
    and the gyroscope, which the detector never sees, is still (≤ 0.31 °/s) over all of it."""
    t, acc, gyr, parts = _ferraris()
    det = find_poses(t, acc, FERRARIS_FS, 9.81)
    faces = {n: ab for n, ab in parts.items() if not n.endswith("_rot")}
    rotations = {n: ab for n, ab in parts.items() if n.endswith("_rot")}
    found = {}
    for name, (a, b) in faces.items():
        hits = [p for p in det.poses[0] if p.start < b and p.stop > a]
        assert len(hits) == 1, name
        found[name] = hits[0]
        assert (min(hits[0].stop, b) - max(hits[0].start, a)) / (b - a) >= 0.8, name
    for name, (a, b) in rotations.items():
        assert [p.index for p in det.poses[0] if p.start < b and p.stop > a] == [], name
    # the other poses rest on the same faces, before and after each rotation
    face_means = np.array([p.mean for p in found.values()])
    for p in det.poses[0]:
        assert np.min(np.linalg.norm(face_means - p.mean, axis=1)) < 0.05
    # the gyroscope agrees that every detected pose is still
    bias = np.median(np.vstack([gyr[a:b] for a, b in faces.values()]), axis=0)
    for p in det.poses[0]:
        assert np.max(np.linalg.norm(gyr[p.start:p.stop] - bias, axis=1)) < 0.5, p.index
    # the offset from the detected faces is the offset from imucal's annotated faces
    detected = fit_poses(face_means, 9.81, "offset").offset
    annotated = fit_poses(np.array([acc[a:b].mean(axis=0) for a, b in faces.values()]), 9.81,
                          "offset").offset
    np.testing.assert_allclose(detected, annotated, rtol=0, atol=1e-3)
