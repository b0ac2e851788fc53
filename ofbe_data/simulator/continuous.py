"""Continuous multi-position recordings: many poses in one file, handling between them.

A real multi-position calibration (imu_tk, imucal's Ferraris) is usually one file: the device
rests in a pose, is turned by hand, rests in the next pose, and so on. With the configuration's
``continuous`` section (:class:`~ofbe_data.simulator.config.ContinuousConfig`) each recording
of a multi-position campaign is such a file:

- **Plan** (campaign draws, :func:`draw_pose_plans`): per recording K poses, K uniform in
  ``poses``, their specific-force directions spread over the sphere
  (:func:`~ofbe_data.simulator.physics.spread_directions`) in random order.
- **Motion** (session draws, :func:`draw_motion`): the recording starts at rest in its first
  pose (``quiet_s`` of quiet stretch before that pose's own rest) or with the device being
  handled into it from a random orientation; then the poses, each resting ``pose_s``, with
  ``handling_s`` of handling between them; it ends with the device picked up (``handling_s``).
- **Handling** (:class:`Handling`): a minimum-jerk rotation the shortest way from one
  direction to the next, a 5–20° wobble about a random axis, a lift of 0.2–1 m/s² and hand
  tremor (0.05–0.2 m/s² rms, 3–12 Hz), all faded in and out (sin²); a jolt as the hand takes
  the device (a 1–3 m/s² pulse of 0.05–0.15 s and a 8–20 Hz ringing) and another as it sets it
  down 0.15–0.3 s before the next rest, faded out by the rest's start.

The specific force (plate frame) is evaluated at each logger's own sample times
(:meth:`Motion.evaluate`); each device sees it through its true mount, and the sensor model
applies as everywhere (scale, cross-axis, bias with in-run drift, noise, quantisation). The
truth of every pose (:func:`pose_truth`) is its rest interval, its direction and the zero-g
offset over the rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ofbe_data.core.geometry import dot3, mul3, norm3, roll_pitch
from ofbe_data.simulator.config import SimConfig
from ofbe_data.simulator.physics import (
    jolt_signal,
    minimum_jerk,
    random_unit_vectors,
    rotate_about,
    spread_directions,
)

TREMOR_SINES = 3
"""Sinusoids per axis that make the hand tremor."""


def draw_pose_plans(cfg: SimConfig, rng: np.random.Generator) -> list[list[np.ndarray]]:
    """Per session, per recording: the (K, 3) unit directions of its poses (plate frame).

    Parameters
    ----------
    cfg
        Configuration with a ``continuous`` section.
    rng
        The campaign's random generator.

    Returns
    -------
    list of list of ndarray
        ``plans[session][recording]``, shape (K, 3), in time order.
    """
    assert cfg.continuous is not None
    lo, hi = cfg.continuous.poses
    return [[spread_directions(int(rng.integers(lo, hi + 1)), rng)
             for _ in range(cfg.recordings_per_session)] for _ in range(cfg.sessions)]


@dataclass(frozen=True)
class Handling:
    """One handling motion, from rest (or the hand) to rest (or the hand).

    Attributes
    ----------
    t0, t1
        s (recording time, t_ref): start and end.
    u_from, u_to
        (3,) unit directions before and after.
    axis, angle
        (3,) unit axis and angle (rad) of the shortest rotation from ``u_from`` to ``u_to``.
    put_down
        s after ``t0``: the rotation ends (the set-down jolt starts).
    wobble_axis, wobble
        (3,) unit axis and peak angle (rad) of the wobble.
    lift_dir, lift
        (3,) unit direction and amplitude (m/s²) of the lift.
    tremor_hz, tremor_phase, tremor_amp
        (3, TREMOR_SINES) frequencies (Hz), phases (rad) and amplitudes (m/s²) per axis.
    jolts
        The take and set-down jolts (:func:`~ofbe_data.simulator.physics.jolt_signal`).
    """

    t0: float
    t1: float
    u_from: np.ndarray
    u_to: np.ndarray
    axis: np.ndarray
    angle: float
    put_down: float
    wobble_axis: np.ndarray
    wobble: float
    lift_dir: np.ndarray
    lift: float
    tremor_hz: np.ndarray
    tremor_phase: np.ndarray
    tremor_amp: np.ndarray
    jolts: tuple[dict[str, Any], dict[str, Any]]

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Direction (N, 3) and linear acceleration (N, 3, m/s²) at times ``t`` (s, t_ref)."""
        tau = t - self.t0
        s = np.clip(tau / self.put_down, 0.0, 1.0)
        u = rotate_about(self.axis, self.angle * minimum_jerk(s), self.u_from)
        bump = np.sin(np.pi * s) ** 2
        u = rotate_about(self.wobble_axis, self.wobble * bump, u)
        phase = 2.0 * np.pi * self.tremor_hz[None, :, :] * tau[:, None, None] + self.tremor_phase[None]
        tremor = np.sum(self.tremor_amp[None] * np.sin(phase), axis=2)
        lin = (self.lift * np.sin(2.0 * np.pi * s) * bump)[:, None] * self.lift_dir + tremor * bump[:, None]
        lin = lin + jolt_signal(tau, self.jolts[0], self.put_down)
        lin = lin + jolt_signal(tau - self.put_down, self.jolts[1], self.t1 - self.t0 - self.put_down)
        return u, lin


def _jolt(rng: np.random.Generator) -> dict[str, Any]:
    return {"length": float(rng.uniform(0.05, 0.15)), "pulse": float(rng.uniform(1.0, 3.0)),
            "pulse_dir": random_unit_vectors(1, rng)[0], "ring": float(rng.uniform(0.3, 1.0)),
            "ring_dir": random_unit_vectors(1, rng)[0], "ring_hz": float(rng.uniform(8.0, 20.0)),
            "decay_s": float(rng.uniform(0.02, 0.05))}


def _handling(t0: float, t1: float, u_from: np.ndarray, u_to: np.ndarray,
              rng: np.random.Generator) -> Handling:
    """Draw the shape of one handling motion from ``u_from`` (at t0) to ``u_to`` (at t1)."""
    d = t1 - t0
    put_down = d - min(float(rng.uniform(0.15, 0.3)), 0.3 * d)
    cross = np.cross(u_from, u_to)
    sin_angle, cos_angle = float(norm3(cross)), float(dot3(u_from, u_to))
    if sin_angle > 1e-9:
        axis = cross / sin_angle
    else:  # parallel or opposite: any axis normal to u_from
        other = np.cross(u_from, random_unit_vectors(1, rng)[0])
        axis = other / float(norm3(other))
    rms = float(rng.uniform(0.05, 0.2))
    return Handling(
        t0, t1, u_from, u_to, axis, math.atan2(sin_angle, cos_angle), put_down,
        random_unit_vectors(1, rng)[0], math.radians(float(rng.uniform(5.0, 20.0))),
        random_unit_vectors(1, rng)[0], float(rng.uniform(0.2, 1.0)),
        rng.uniform(3.0, 12.0, (3, TREMOR_SINES)), rng.uniform(0.0, 2.0 * np.pi, (3, TREMOR_SINES)),
        np.full((3, TREMOR_SINES), rms * math.sqrt(2.0 / TREMOR_SINES)), (_jolt(rng), _jolt(rng)))


@dataclass(frozen=True)
class Motion:
    """The motion of one continuous recording, in the plate frame.

    Attributes
    ----------
    directions
        (K, 3) unit specific-force directions of the poses.
    rests
        (K, 2) s (t_ref), each pose's rest [start, end].
    handlings
        Every handling motion, in time order (before the first pose when the recording starts
        moving, between the poses, after the last).
    quiet_start
        Whether the recording starts at rest in its first pose.
    lead, tail
        s, the quiet stretch or the handling before the first pose's ``pose_s``; the handling
        after the last pose.
    total
        s, the recording's length.
    """

    directions: np.ndarray
    rests: np.ndarray
    handlings: tuple[Handling, ...]
    quiet_start: bool
    lead: float
    tail: float
    total: float

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Specific-force direction (N, 3) and linear acceleration (N, 3, m/s²) at ``t`` (s, t_ref).

        Times outside [0, total] take the value at the nearer end.
        """
        t = np.clip(np.asarray(t, dtype=np.float64), 0.0, self.total)
        u = np.zeros((t.shape[0], 3))
        lin = np.zeros((t.shape[0], 3))
        for h in self.handlings:
            m = (t >= h.t0) & (t <= h.t1)
            if m.any():
                u[m], lin[m] = h.evaluate(t[m])
        for direction, (r0, r1) in zip(self.directions, self.rests, strict=True):
            m = (t >= r0) & (t <= r1)
            u[m] = direction
            lin[m] = 0.0
        return u, lin


def draw_motion(cfg: SimConfig, directions: np.ndarray, rng: np.random.Generator) -> Motion:
    """Draw the timeline and handling of one continuous recording.

    Parameters
    ----------
    cfg
        Configuration with a ``continuous`` section.
    directions
        (K, 3) the recording's pose directions (:func:`draw_pose_plans`).
    rng
        The session's random generator.

    Returns
    -------
    Motion
    """
    c = cfg.continuous
    assert c is not None
    k = directions.shape[0]
    quiet = bool(rng.random() < c.quiet_start_prob)
    lead = float(rng.uniform(*(c.quiet_s if quiet else c.handling_s)))
    start_dir = random_unit_vectors(1, rng)[0]
    rest_s = rng.uniform(*c.pose_s, k)
    gaps = rng.uniform(*c.handling_s, k)  # after each pose; the last one: picked up
    end_dir = random_unit_vectors(1, rng)[0]
    handlings = []
    if not quiet:
        handlings.append(_handling(0.0, lead, start_dir, directions[0], rng))
    at = lead
    rests = []
    for i in range(k):
        r0 = 0.0 if (quiet and i == 0) else at
        r1 = at + float(rest_s[i])
        rests.append((r0, r1))
        nxt = directions[i + 1] if i + 1 < k else end_dir
        handlings.append(_handling(r1, r1 + float(gaps[i]), directions[i], nxt, rng))
        at = r1 + float(gaps[i])
    return Motion(directions, np.array(rests), tuple(handlings), quiet, lead, float(gaps[-1]), at)


def specific_force(motion: Motion, t: np.ndarray, nominal: np.ndarray, misalignment: np.ndarray,
                   mount: np.ndarray, g: float) -> np.ndarray:
    """(N, 3) m/s², the true specific force in a sensor frame at times ``t`` (s, t_ref).

    g·u through the nominal mount then the misalignment (as a resting device's direction), plus
    the linear acceleration through the true mount rotation (as a tap's).
    """
    u_plate, lin = motion.evaluate(t)
    u_sensor = mul3(mul3(u_plate, nominal.T), misalignment.T)
    return g * u_sensor + mul3(lin, mount.T)


def pose_truth(motion: Motion, t_local: np.ndarray, bias: np.ndarray, nominal: np.ndarray,
               misalignment: np.ndarray, A: np.ndarray, g: float, clock_offset: float, rate: float,
               ) -> list[dict[str, Any]]:
    """Each pose's truth for one device: interval, samples, direction, offsets.

    Parameters
    ----------
    motion
        The recording's motion.
    t_local
        (N,) s (t_ref), the device's sample times.
    bias
        (N, 3) m/s², its true zero-g offset at each sample (in-run drift included).
    nominal, misalignment, A
        (3, 3) its nominal mount, mount misalignment and own map.
    g
        m/s², local gravity.
    clock_offset, rate
        Its clock: t_device = clock_offset + rate · t_ref.

    Returns
    -------
    list of dict
        Per pose: ``t_device`` (s, its first and last sample at rest on the device clock),
        ``samples``, ``offset`` (mean bias over them), ``apparent_bias``, ``u_sensor``,
        ``u_nominal``, ``roll_deg``, ``pitch_deg``.
    """
    out = []
    for direction, (r0, r1) in zip(motion.directions, motion.rests, strict=True):
        idx = np.flatnonzero((t_local >= r0) & (t_local <= r1))
        if idx.size == 0:  # pragma: no cover - the loggers' stagger leaves every pose samples
            raise AssertionError(f"a pose ({r0:.3f}-{r1:.3f} s) without samples")
        u_nominal = mul3(nominal, direction)
        u_sensor = mul3(misalignment, u_nominal)
        offset = bias[idx].mean(axis=0)
        apparent = mul3(A, u_sensor) * g + offset - g * u_nominal
        roll, pitch = roll_pitch(u_sensor)
        out.append({
            "t_device": [float(clock_offset + rate * t_local[idx[0]]),
                         float(clock_offset + rate * t_local[idx[-1]])],
            "samples": int(idx.size), "offset": offset.tolist(), "apparent_bias": apparent.tolist(),
            "u_sensor": u_sensor.tolist(), "u_nominal": u_nominal.tolist(),
            "roll_deg": roll, "pitch_deg": pitch})
    return out


def recording_truth(motion: Motion) -> dict[str, Any]:
    """The recording-level truth of a continuous recording (extra keys of its truth entry)."""
    poses = []
    for direction, (r0, r1) in zip(motion.directions, motion.rests, strict=True):
        roll, pitch = roll_pitch(direction)
        poses.append({"t_ref": [float(r0), float(r1)], "u_plate": direction.tolist(),
                      "plate_roll_deg": roll, "plate_pitch_deg": pitch})
    return {"start": "quiet" if motion.quiet_start else "motion", "poses": poses,
            "handling_t_ref": [[h.t0, h.t1] for h in motion.handlings]}
