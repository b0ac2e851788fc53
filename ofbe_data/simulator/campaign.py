"""Generation of simulated campaigns: campaign-level draws, sessions, files and truth.

Every random quantity is drawn from a :class:`numpy.random.SeedSequence` tree rooted at
the seed: child 0 holds the campaign-level draws (devices, tilt plan), child i+1 session
i. A session's data therefore does not depend on how many processes write the campaign
or in which order.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np

import ofbe_data.simulator.continuous as continuous  # the module, so tests can watch its use
from ofbe_data.core.errors import ConfigError
from ofbe_data.core.geometry import mul3, norm3, roll_pitch
from ofbe_data.io.formats.common import WRAP_US, format_utc
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import (
    BinOptions,
    DeviceSpec,
    RecordingSpec,
    SessionManifest,
    Site,
)
from ofbe_data.simulator.config import SimConfig, config_to_dict
from ofbe_data.simulator.continuous import Motion
from ofbe_data.simulator.physics import (
    MG,
    axis_vector,
    gauss_markov,
    level_nominal,
    plate_direction,
    random_unit_vectors,
    sensor_matrix,
    small_rotation,
    tap_signal,
)

TRUTH_FORMAT = "ofbe-truth/1"
SIMULATION_FORMAT = "ofbe-simulation/1"
SESSION_SPACING_S = 3600.0
"""Time between power-ons of consecutive sessions (chosen: one per hour)."""
WARMUP_WAIT_S = 30.0
"""Time from power-on to the first recording of a session (chosen)."""
REPOSITION_S = 60.0
"""Time between the end of one recording and the start of the next (chosen)."""
BOOT_POOL = (
    "ets Jun  8 2016 00:22:57",
    "rst:0x1 (POWERON_RESET),boot:0x13 (SPI_FAST_FLASH_BOOT)",
    "configsip: 0, SPIWP:0xee",
    "clk_drv:0x00,q_drv:0x00,d_drv:0x00,cs0_drv:0x00,hd_drv:0x00,wp_drv:0x00",
    "mode:DIO, clock div:1",
    "load:0x3fff0030,len:1184",
    "entry 0x400805e4",
)
GARBLE_BYTES = (b"\xff", b"\xfe", b"?", b"#", b"\x1b", b"@", b"\x00")


# --------------------------------------------------------------------------- draws


@dataclass(frozen=True)
class DeviceDraw:
    """Campaign-level truth of one device under test.

    Attributes
    ----------
    id
        Device id.
    A
        (3, 3) the sensor's own map I + scale + non-orthogonality.
    misalignment
        (3, 3) rotation from the nominal sensor frame to the true one (mount
        misalignment relative to the reference, or the level tilt).
    nominal
        (3, 3) nominal reference→sensor rotation (``reference_to_sensor``).
    offset_device
        (3,) fixed zero-g offset of the device, m/s².
    clock_ppm
        Rate error of the logger's crystal relative to the reference, ppm.
    """

    id: str
    A: np.ndarray
    misalignment: np.ndarray
    nominal: np.ndarray
    offset_device: np.ndarray
    clock_ppm: float

    @property
    def A_effective(self) -> np.ndarray:
        """Map from the *nominal* direction to the reading: A·misalignment."""
        return mul3(self.A, self.misalignment)

    @property
    def mount_rotation(self) -> np.ndarray:
        """True reference→sensor rotation: misalignment·nominal."""
        return mul3(self.misalignment, self.nominal)


@dataclass(frozen=True)
class Setting:
    """One recording's orientation: nominal tripod setting and the true plate direction."""

    nominal_roll_deg: float
    nominal_pitch_deg: float
    u_plate: np.ndarray


@dataclass(frozen=True)
class CampaignDraw:
    """Everything drawn once per campaign (``poses``: per session and recording, the (K, 3)
    pose directions of continuous recordings, whose ``settings`` hold the first pose)."""

    devices: dict[str, DeviceDraw]
    reference_A: np.ndarray | None
    settings: list[list[Setting]]
    g_local: float
    site: Site
    poses: list[list[np.ndarray]] | None = None


def _site(cfg: SimConfig) -> Site:
    s = cfg.site
    if "gravity_mps2" in s:
        return Site(gravity_mps2=float(s["gravity_mps2"]))
    return Site(latitude_deg=float(s["latitude_deg"]), height_m=float(s.get("height_m", 0.0)))


def _rotated_settings(cfg: SimConfig, rng: np.random.Generator) -> list[list[Setting]]:
    """Distinct tripod settings: a third roll-only, a third pitch-only, a third combined.

    Angles are stratified over their ranges (one uniform draw per equal-width stratum),
    so every campaign covers the whole pitch and roll ranges, then rounded to the
    tripod's ``setting_step_deg``; zero or repeated settings move by one step.
    """
    t = cfg.tilts
    n = cfg.sessions * cfg.recordings_per_session
    step = t.setting_step_deg
    counts = [len(range(k, n, 3)) for k in range(3)]

    def strata(lo: float, hi: float, m: int) -> np.ndarray:
        return rng.permutation(lo + (hi - lo) * (np.arange(m) + rng.uniform(0.0, 1.0, m)) / m)

    raw = [(r, 0.0) for r in strata(*t.roll_deg, counts[0])]
    raw += [(0.0, p) for p in strata(*t.pitch_deg, counts[1])]
    raw += list(zip(strata(*t.roll_deg, counts[2]), strata(*t.pitch_deg, counts[2]), strict=True))
    seen: set[tuple[float, float]] = set()
    chosen: list[tuple[float, float]] = []
    for roll0, pitch0 in raw:
        roll_axis, pitch_axis = roll0 != 0.0, pitch0 != 0.0
        for shift in range(1000):
            sgn = 1 if shift % 2 else -1
            roll = float(np.clip(step * (np.round(roll0 / step) + sgn * (shift // 2) * roll_axis),
                                 *t.roll_deg))
            # pitch moves for pitch-only settings, and for combined ones whose pitch rounds to 0
            move_pitch = pitch_axis and (not roll_axis or np.round(pitch0 / step) == 0)
            pitch = float(np.clip(step * (np.round(pitch0 / step) + sgn * (shift // 2) * move_pitch),
                                  *t.pitch_deg))
            roll = 180.0 if roll == -180.0 else roll + 0.0  # one name per orientation
            pitch += 0.0
            if (roll_axis and roll == 0.0) or (pitch_axis and pitch == 0.0):
                continue
            if (roll, pitch) not in seen:
                break
        else:
            raise ConfigError("tilts", "setting_step_deg", f"a grid with {n} distinct settings",
                              "too few within the pitch and roll ranges")
        seen.add((roll, pitch))
        chosen.append((roll, pitch))
    order = rng.permutation(n)
    err = rng.normal(0.0, t.setting_error_deg, (n, 2))
    flat = [Setting(chosen[k][0], chosen[k][1],
                    plate_direction(chosen[k][0] + err[k, 0], chosen[k][1] + err[k, 1]))
            for k in order]
    r = cfg.recordings_per_session
    return [flat[i * r:(i + 1) * r] for i in range(cfg.sessions)]


def _multi_position_settings(cfg: SimConfig, rng: np.random.Generator) -> list[list[Setting]]:
    """Per session: the six faces (within ``face_error_deg``), then random directions."""
    faces = [axis_vector(a) for a in ("+z", "-z", "+x", "-x", "+y", "-y")]
    out = []
    for _ in range(cfg.sessions):
        row = []
        r = cfg.recordings_per_session
        extra = random_unit_vectors(max(0, r - 6), rng)
        for k in range(r):
            if k < 6:
                tilt = small_rotation(rng.normal(0.0, np.radians(cfg.tilts.face_error_deg), 3))
                u = mul3(tilt, faces[k])
                nominal = roll_pitch(faces[k])
            else:
                u = extra[k - 6]
                nominal = tuple(float(np.round(v)) for v in roll_pitch(u))
            row.append(Setting(nominal[0], nominal[1], u / norm3(u)))
        out.append(row)
    return out


def draw_campaign(cfg: SimConfig, seed_seq: np.random.SeedSequence) -> CampaignDraw:
    """Draw the campaign-level truth: device errors and the orientation plan.

    Parameters
    ----------
    cfg
        Configuration.
    seed_seq
        The campaign's child seed sequence.

    Returns
    -------
    CampaignDraw
    """
    rng = np.random.default_rng(seed_seq)
    m = cfg.dut_model
    devices: dict[str, DeviceDraw] = {}
    for d in cfg.duts:
        scale = rng.normal(0.0, m.scale_sigma, 3)
        nonorth = rng.normal(0.0, np.radians(m.cross_axis_sigma_deg), 3)
        if cfg.tilts.mode == "level":
            tilt = rng.normal(0.0, np.radians(cfg.tilts.level_sigma_deg), 3)
            misalignment = small_rotation(tilt)
        else:
            rotvec = rng.normal(0.0, np.radians(m.mount_sigma_deg) / np.sqrt(3.0), 3)
            misalignment = small_rotation(rotvec)
        offset = rng.normal(0.0, 1.0, 3) * np.asarray(m.offset_sigma_mg) * MG
        ppm = float(rng.uniform(-m.clock_ppm, m.clock_ppm))
        nominal = np.asarray(d.reference_to_sensor, dtype=float)
        if cfg.tilts.mode == "level":
            nominal = level_nominal(d.up_axis)
        devices[d.id] = DeviceDraw(d.id, sensor_matrix(scale, nonorth), misalignment, nominal,
                                   offset, ppm)
    ref_a = None
    if cfg.reference is not None:
        rm = cfg.reference_model
        ref_a = sensor_matrix(rng.normal(0.0, rm.scale_sigma, 3),
                              rng.normal(0.0, np.radians(rm.cross_axis_sigma_deg), 3))
    plans = None
    if cfg.tilts.mode == "rotated":
        settings = _rotated_settings(cfg, rng)
    elif cfg.continuous is not None:
        plans = continuous.draw_pose_plans(cfg, rng)
        settings = [[Setting(0.0, 0.0, p[0]) for p in row] for row in plans]
    elif cfg.tilts.mode == "multi-position":
        settings = _multi_position_settings(cfg, rng)
    else:
        level = Setting(0.0, 0.0, np.array([0.0, 0.0, 1.0]))
        settings = [[level] * cfg.recordings_per_session for _ in range(cfg.sessions)]
    site = _site(cfg)
    return CampaignDraw(devices, ref_a, settings, site.g_local, site, plans)


# --------------------------------------------------------------------------- sessions


@dataclass
class DutFile:
    """One simulated ``ofbe-logger`` file before writing."""

    device: str
    t_us: np.ndarray
    counts: np.ndarray
    header: dict[str, str]
    boot_lines: list[str]
    truth: dict[str, Any]


@dataclass
class RefFile:
    """One simulated reference file (``mscip-csv`` or ``mscip-bin``) before writing."""

    t_s: np.ndarray
    acc_g: np.ndarray
    gyro_dps: np.ndarray
    temperature_c: np.ndarray
    start_utc: str
    serial: str
    rate_hz: float
    truth: dict[str, Any]


@dataclass
class SessionData:
    """A simulated session in memory: manifest, files and truth."""

    manifest: SessionManifest
    dut_files: dict[tuple[str, str], DutFile]
    ref_files: dict[str, RefFile]
    truth: dict[str, Any]


def session_name(cfg: SimConfig, index: int) -> str:
    """Id of session ``index`` (0-based): ``<session_prefix>-pc<NNN>``, NNN = power cycle."""
    return f"{cfg.session_prefix}-pc{index + 1:03d}"


def _utc(base: datetime, seconds: float) -> datetime:
    return base + timedelta(seconds=seconds)


TRUTH_DECIMALS = 12
"""Decimal places of every float in a truth JSON (docs/formats.md)."""


def _as_list(a: np.ndarray) -> Any:
    return np.asarray(a, dtype=float).tolist()


@dataclass(frozen=True)
class _Timeline:
    """Times of one recording, s after its start (the reference's Time (s) origin)."""

    total: float
    taps: tuple[float, ...]
    stationary: tuple[float, float]
    dut_window: dict[str, tuple[float, float]]


def _timeline(cfg: SimConfig, rng: np.random.Generator) -> _Timeline:
    tc = cfg.taps
    duration = float(rng.uniform(*cfg.stationary_s))
    if not tc.enabled:
        return _Timeline(duration, (), (0.0, duration),
                         {d.id: (0.0, duration) for d in cfg.duts})
    lead = float(rng.uniform(*tc.lead_s))
    tail = float(rng.uniform(*tc.tail_s))
    tap1 = lead
    tap2 = lead + duration + 2 * tc.margin_s
    total = tap2 + tail
    stagger = min(tc.start_stagger_s, 0.5 * min(lead, tail))
    windows = {d.id: (float(rng.uniform(0.0, stagger)), total - float(rng.uniform(0.0, stagger)))
               for d in cfg.duts}
    return _Timeline(total, (tap1, tap2), (tap1 + tc.margin_s, tap2 - tc.margin_s), windows)


def _continuous_timeline(cfg: SimConfig, motion: Motion, rng: np.random.Generator) -> _Timeline:
    """A continuous recording's times: no taps, its first pose as the stationary part."""
    stagger = min(cfg.taps.start_stagger_s, 0.5 * min(motion.lead, motion.tail))
    windows = {d.id: (float(rng.uniform(0.0, stagger)), motion.total - float(rng.uniform(0.0, stagger)))
               for d in cfg.duts}
    return _Timeline(motion.total, (), (float(motion.rests[0, 0]), float(motion.rests[0, 1])), windows)


def _taps(cfg: SimConfig, timeline: _Timeline, rng: np.random.Generator) -> list[dict[str, Any]]:
    tc = cfg.taps
    return [{"t": t, "amplitude": float(rng.uniform(*tc.amplitude_g)) * G0,
             "frequency": float(rng.uniform(*tc.frequency_hz)),
             "direction": random_unit_vectors(1, rng)[0]} for t in timeline.taps]


def _tap_sum(t: np.ndarray, taps: list[dict[str, Any]], rotation: np.ndarray, decay: float,
             ) -> np.ndarray:
    out = np.zeros((t.shape[0], 3))
    for tap in taps:
        out += tap_signal(t, tap["t"], tap["amplitude"], tap["frequency"], decay,
                          mul3(rotation, tap["direction"]))
    return out


def _simulate_dut(cfg: SimConfig, draw: CampaignDraw, dev: DeviceDraw, setting: Setting,
                  timeline: _Timeline, taps: list[dict[str, Any]], t_rec: float,
                  t_power: float, uptime0: float, ppm: float, b_on: np.ndarray,
                  rng: np.random.Generator, base_utc: datetime, motion: Motion | None = None,
                  ) -> DutFile:
    """One DUT file: polls on the logger's clock, the error model, quantisation (``motion``: a
    continuous recording's, else the device rests in ``setting`` between the taps)."""
    m = cfg.dut_model
    rate = 1.0 + ppm * 1e-6
    start, end = timeline.dut_window[dev.id]
    clock_start = uptime0 + (t_rec + start - t_power) * rate
    if cfg.taps.enabled:
        n = int(np.floor((end - start) * rate * m.rate_hz)) + 1
    else:
        n = int(round((end - start) * m.rate_hz))
    k = np.arange(n)
    clock = clock_start + k / m.rate_hz + rng.uniform(-m.jitter_s, m.jitter_s, n)
    keep = rng.random(n) >= m.drop_prob
    keep[0] = keep[-1] = True
    dropped = int(n - keep.sum())
    clock = clock[keep]
    t_local = (clock - uptime0) / rate + t_power - t_rec  # s after the recording start
    n = clock.shape[0]
    u_nominal = mul3(dev.nominal, setting.u_plate)
    u_sensor = mul3(dev.misalignment, u_nominal)
    drift = np.stack([gauss_markov(n, 1.0 / m.rate_hz, m.drift_sigma_mg * MG, m.drift_tau_s, rng)
                      for _ in range(3)], axis=1)
    since_power = t_local + t_rec - t_power
    warm = np.exp(-since_power / m.warmup_tau_s)[:, None] * (np.asarray(m.warmup_mg) * MG)
    bias = dev.offset_device + b_on + drift + warm
    if motion is None:
        specific = draw.g_local * u_sensor[None, :] + _tap_sum(t_local, taps, dev.mount_rotation,
                                                                cfg.taps.decay_s)
    else:
        specific = continuous.specific_force(motion, t_local, dev.nominal, dev.misalignment,
                                             dev.mount_rotation, draw.g_local)
    noise = rng.standard_normal((n, 3)) * (np.asarray(m.noise_mg) * MG)
    f = mul3(specific, dev.A.T) + bias + noise
    limit = int(round(m.range_g * m.lsb_per_g))
    counts = np.clip(np.rint(f / G0 * m.lsb_per_g), -limit, limit - 1).astype(np.int64)
    t_us = np.floor(clock * 1e6).astype(np.int64)
    s0, s1 = timeline.stationary
    stat = (t_local >= s0) & (t_local <= s1)
    offset = bias[stat].mean(axis=0)
    apparent = mul3(dev.A, u_sensor) * draw.g_local + offset - draw.g_local * u_nominal
    wraps_before = int(t_us[0] // WRAP_US)
    clock_offset = uptime0 + (t_rec - t_power) * rate - wraps_before * WRAP_US * 1e-6
    host = _utc(base_utc, t_rec + t_local[0] + rng.uniform(-m.host_latency_s, m.host_latency_s))
    header = {"fw": m.firmware, "board": "sparkfun-thing-plus-esp32", "chip": "ADXL345",
              "device": dev.id, "odr_hz": f"{m.rate_hz:g}", "range_g": f"{m.range_g:d}",
              "full_res": "1", "lsb_per_g": f"{m.lsb_per_g:g}", "host_start_utc": format_utc(host)}
    lo, hi = m.boot_lines
    boot = list(BOOT_POOL[: int(rng.integers(lo, hi + 1))])
    roll, pitch = roll_pitch(u_sensor)
    truth = {
        "offset": _as_list(offset),
        "apparent_bias": _as_list(apparent),
        "u_sensor": _as_list(u_sensor),
        "u_nominal": _as_list(u_nominal),
        "roll_deg": roll,
        "pitch_deg": pitch,
        "clock_offset_s": float(clock_offset),
        "clock_drift_ppm": float(ppm),
        "taps_t_device": [float(clock_offset + rate * tap["t"]) for tap in taps],
        "stationary_t_device": [float(clock_offset + rate * s0), float(clock_offset + rate * s1)],
        "stationary_samples": int(stat.sum()),
        "samples_written": int(n),
        "dropped_samples": dropped,
        "wraps": int(t_us[-1] // WRAP_US - wraps_before),
        "boot_lines": len(boot),
        "saturated_samples": int(((counts == -limit) | (counts == limit - 1)).any(axis=1).sum()),
    }
    if motion is not None:  # the legacy keys above hold the first pose
        truth["poses"] = continuous.pose_truth(motion, t_local, bias, dev.nominal, dev.misalignment,
                                               dev.A, draw.g_local, clock_offset, rate)
    return DutFile(dev.id, t_us, counts, header, boot, truth)


def _simulate_reference(cfg: SimConfig, draw: CampaignDraw, setting: Setting,
                        timeline: _Timeline, taps: list[dict[str, Any]], b_ref: np.ndarray,
                        rng: np.random.Generator, start_utc: str) -> RefFile:
    rm = cfg.reference_model
    n = int(np.floor(timeline.total * rm.rate_hz)) + 1
    t = np.arange(n) / rm.rate_hz
    assert draw.reference_A is not None
    specific = draw.g_local * setting.u_plate[None, :] + _tap_sum(t, taps, np.eye(3),
                                                                   cfg.taps.decay_s)
    f = mul3(specific, draw.reference_A.T) + b_ref + rng.standard_normal((n, 3)) * rm.noise_mg * MG
    gyro = rng.standard_normal((n, 3)) * rm.gyro_noise_dps
    for tap in taps:
        gyro += tap_signal(t, tap["t"], 20.0, tap["frequency"], cfg.taps.decay_s,
                           np.cross(tap["direction"], [0.0, 0.0, 1.0]))
    temp = rm.temperature_c + 0.002 * t + rng.normal(0.0, 0.02, n)
    s0, s1 = timeline.stationary
    truth = {"bias": _as_list(b_ref), "u_plate": _as_list(setting.u_plate),
             "stationary_t": [s0, s1], "samples_written": n}
    assert cfg.reference is not None
    return RefFile(t, f / G0, gyro, temp, start_utc, cfg.reference.serial, rm.rate_hz, truth)


def simulate_session(cfg: SimConfig, draw: CampaignDraw, index: int, campaign: str,
                     seed_seq: np.random.SeedSequence, folder: Path) -> SessionData:
    """Simulate one session (power cycle) in memory.

    Parameters
    ----------
    cfg
        Configuration.
    draw
        Campaign-level draws.
    index
        0-based session index (power cycle = index + 1).
    campaign
        Campaign id written to the manifest.
    seed_seq
        The session's child seed sequence.
    folder
        Session folder the manifest will describe.

    Returns
    -------
    SessionData
    """
    rng = np.random.default_rng(seed_seq)
    m = cfg.dut_model
    base_utc = datetime.fromisoformat(cfg.start_utc.replace("Z", "+00:00"))
    name = session_name(cfg, index)
    t_power = index * SESSION_SPACING_S
    b_on = {d.id: rng.normal(0.0, 1.0, 3) * np.asarray(m.turn_on_sigma_mg) * MG for d in cfg.duts}
    uptime0 = {d.id: float(rng.uniform(*m.uptime_s)) for d in cfg.duts}
    ppm = {d.id: draw.devices[d.id].clock_ppm + float(rng.normal(0.0, 0.5)) for d in cfg.duts}
    b_ref = (rng.normal(0.0, cfg.reference_model.bias_sigma_mg * MG, 3)
             if cfg.reference is not None else np.zeros(3))
    devices: dict[str, DeviceSpec] = {}
    for d in cfg.duts:
        r2s = None if cfg.kind == "gravity-aligned" else np.asarray(d.reference_to_sensor, float)
        devices[d.id] = DeviceSpec(d.id, "ADXL345", "dut", "ofbe-logger", r2s)
    if cfg.reference is not None:
        binary = cfg.reference_format == "mscip-bin"
        devices[cfg.reference.id] = DeviceSpec(cfg.reference.id, "MS-IMU3025", "reference",
                                               cfg.reference_format,
                                               bin=BinOptions() if binary else None)
    dut_files: dict[tuple[str, str], DutFile] = {}
    ref_files: dict[str, RefFile] = {}
    recordings: list[RecordingSpec] = []
    rec_truth: dict[str, Any] = {}
    t_rec = t_power + WARMUP_WAIT_S
    for r, setting in enumerate(draw.settings[index]):
        rid = f"rec-{r + 1:02d}"
        t_rec = float(np.round(t_rec, 3))
        motion = None if draw.poses is None else continuous.draw_motion(cfg, draw.poses[index][r], rng)
        if motion is None:
            timeline = _timeline(cfg, rng)
            taps = _taps(cfg, timeline, rng) if cfg.taps.enabled else []
            nominal = {"roll_deg": setting.nominal_roll_deg, "pitch_deg": setting.nominal_pitch_deg}
        else:  # many poses, no tripod setting to name
            timeline, taps, nominal = _continuous_timeline(cfg, motion, rng), [], {}
        files = {dev: f"{rid}/{dev}.{'bin' if devices[dev].format == 'mscip-bin' else 'csv'}"
                 for dev in devices}
        recordings.append(RecordingSpec(rid, files, nominal))
        dev_truth: dict[str, Any] = {}
        for d in cfg.duts:
            f = _simulate_dut(cfg, draw, draw.devices[d.id], setting, timeline, taps, t_rec,
                              t_power, uptime0[d.id], ppm[d.id], b_on[d.id], rng, base_utc, motion)
            dut_files[(rid, d.id)] = f
            dev_truth[d.id] = f.truth
        if cfg.reference is not None:
            start = format_utc(_utc(base_utc, t_rec))
            ref = _simulate_reference(cfg, draw, setting, timeline, taps, b_ref, rng, start)
            ref_files[rid] = ref
            dev_truth[cfg.reference.id] = ref.truth
        roll, pitch = roll_pitch(setting.u_plate)
        rec_truth[rid] = {
            "plate_roll_deg": roll, "plate_pitch_deg": pitch,
            "u_plate": _as_list(setting.u_plate),
            "nominal": nominal,
            "start_utc": format_utc(_utc(base_utc, t_rec)),
            "duration_s": timeline.total,
            "taps_t_ref": list(timeline.taps),
            "stationary_t_ref": list(timeline.stationary),
            "devices": dev_truth,
            **(continuous.recording_truth(motion) if motion is not None else {}),
        }
        t_rec += timeline.total + REPOSITION_S
    manifest = SessionManifest(folder, campaign, name, cfg.kind, draw.site, index + 1, devices,
                               tuple(recordings))
    dev_info: dict[str, Any] = {}
    for d in cfg.duts:
        dd = draw.devices[d.id]
        dev_info[d.id] = {
            "role": "dut", "model": "ADXL345",
            "A": _as_list(dd.A), "A_effective": _as_list(dd.A_effective),
            "misalignment": _as_list(dd.misalignment),
            "mount_rotation": _as_list(dd.mount_rotation),
            "reference_to_sensor": _as_list(dd.nominal),
            "offset_device": _as_list(dd.offset_device),
            "offset_turn_on": _as_list(b_on[d.id]),
            "offset_sigma": _as_list(np.asarray(m.offset_sigma_mg) * MG),
            "turn_on_sigma": _as_list(np.asarray(m.turn_on_sigma_mg) * MG),
            "noise_rms": _as_list(np.asarray(m.noise_mg) * MG),
            "drift_sigma": m.drift_sigma_mg * MG,
            "clock_drift_ppm": ppm[d.id],
            "uptime_at_power_on_s": uptime0[d.id],
        }
    if cfg.reference is not None:
        rm = cfg.reference_model
        assert draw.reference_A is not None
        dev_info[cfg.reference.id] = {"role": "reference", "model": "MS-IMU3025",
                                      "A": _as_list(draw.reference_A), "bias": _as_list(b_ref),
                                      "noise_rms": rm.noise_mg * MG}
    truth = {
        "format": TRUTH_FORMAT, "campaign": campaign, "session": name, "kind": cfg.kind,
        "power_cycle": index + 1, "g_local": draw.g_local,
        "clock_model": "t_device = clock_offset_s + (1 + clock_drift_ppm*1e-6) * t_ref, "
                       "t_device as the reader returns it (s, wraps undone from the first "
                       "sample), t_ref = reference Time (s) (recording start when none)",
        "offset_model": "mean reading over the stationary part = A_effective . u_nominal . "
                        "g_local + offset; apparent_bias = that mean - g_local . u_nominal",
        "devices": dev_info, "recordings": rec_truth,
    }
    return SessionData(manifest, dut_files, ref_files, truth)


def truth_config(cfg: SimConfig, seed: int, campaign: str) -> dict[str, Any]:
    """The resolved configuration recorded beside the truth files."""
    return {"format": SIMULATION_FORMAT, "campaign": campaign,
            "seed": seed, "config": config_to_dict(cfg)}
