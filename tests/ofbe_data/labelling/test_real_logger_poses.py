"""Still poses on real loggers' files (issue 33, item 3): found, and not refused as saturated.

Each shape is a small continuous multi-position file written here, labelled through
``label_session`` as a lab's session would be, and held to the truth it was built from:

- **Coarse quantisation** (a): a logger printing g with two decimals (10 mg steps), noise below
  one step so that the output rarely changes, 9.5 Hz, six faces 15–20 s apart. The quietest
  part of such a file shows no variance at all; the noise floor is what the output step
  implies (:func:`~ofbe_data.labelling.multiposition._poses.quantisation_floor`).
- **Short poses on a fine grid** (b): one-second poses at 1/256 g (counts) on a ±2 g sensor,
  one of them with 9 of its 41 samples at its lowest value, −0.668 g; and ten minutes of
  30 Hz poses on a 0.001 g grid. A pile-up well inside the range is never saturation
  (:func:`~ofbe_data.io.recording.full_scale`); a sensor that really clips still is.
- **A quiet and a noisy sensor in one BLE file** (c): an ADXL355-class and a BMI160-class
  triad side by side in one semicolon file with epoch-microsecond host stamps (30 % step
  jitter, 35 dropped stretches), forty poses, some on a rig that vibrates at about 1 mg (someone
  walking by: invisible under the noisy sensor's noise, above the quiet one's). Both devices
  share their still periods, so both must find every one
  (:func:`~ofbe_data.labelling.multiposition._search.missed_periods`), and a short pose whose samples the link
  partly dropped still lasts its time (:func:`~ofbe_data.labelling.multiposition._poses.run_lasts`).

A pose is "found" when exactly one detected pose overlaps its rest, and no detected pose lies
outside every rest (widened by what the sensor cannot resolve of the handling's slow ends).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from ofbe_data.io.formats import read_device_file
from ofbe_data.io.manifest import load_manifest
from ofbe_data.io.recording import full_scale, output_steps
from ofbe_data.labelling.checks import clipped_samples
from ofbe_data.labelling.labels import SessionLabels, label_session
from ofbe_data.labelling.multiposition._poses import (
    FLOOR_QUANTISATION,
    PoseParams,
    quantisation_floor,
    run_lasts,
)
from ofbe_data.labelling.multiposition._search import (
    angle_deg,
    find_session_poses,
    louder_than,
    missed_periods,
)

G0 = 9.80665
MG = G0 / 1000.0


# --------------------------------------------------------------------------- motion of the rig


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _rotate(axes: np.ndarray, angles: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Rotate each vector (M, 3) about its unit axis (M, 3) by its angle (M,), rad (Rodrigues)."""
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    dot = np.sum(axes * vectors, axis=1, keepdims=True)
    return vectors * c + np.cross(axes, vectors) * s + axes * dot * (1.0 - c)


def _faces(rng: np.random.Generator) -> np.ndarray:
    """The six faces in random order, each tilted by up to 0.4° (a board turned on a table)."""
    faces = np.vstack([np.eye(3), -np.eye(3)])[rng.permutation(6)]
    return _rotate(_unit(rng.normal(size=(6, 3))), np.radians(0.4) * rng.uniform(size=6), faces)


def _sphere(rng: np.random.Generator, k: int) -> np.ndarray:
    """(k, 3) directions spread over the sphere (Fibonacci), in random order."""
    i = np.arange(k) + 0.5
    z = 1.0 - 2.0 * i / k
    phi = np.pi * (1.0 + 5.0**0.5) * i
    pts = np.column_stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z])
    return pts[rng.permutation(k)]


def _rests(rng: np.random.Generator, k: int, rest_s: tuple[float, float],
           handling_s: tuple[float, float]) -> np.ndarray:
    """(k, 2) s, rest intervals separated by handling, the first from 0."""
    out, at = [], 0.0
    for _ in range(k):
        r = rng.uniform(*rest_s)
        out.append((at, at + r))
        at += r + rng.uniform(*handling_s)
    return np.array(out)


def rig_force(rng: np.random.Generator, t: np.ndarray, u: np.ndarray, rests: np.ndarray) -> np.ndarray:
    """(N, 3) m/s², noise-free specific force of a rig resting at g·u_k over each rest and handled
    in between: a minimum-jerk turn to the next direction with a 5–20° wobble, a lift and a hand
    tremor (3–10 Hz), all fading in and out with the handling; at rest after the last pose."""
    f = np.tile(G0 * u[-1], (t.size, 1))
    for k in range(len(u)):
        a, b = rests[k]
        f[(t >= a) & (t <= b)] = G0 * u[k]
        if k + 1 == len(u):
            break
        h0, h1 = b, rests[k + 1][0]
        m = (t > h0) & (t < h1)
        if not m.any():
            continue
        s = (t[m] - h0) / (h1 - h0)
        n = int(m.sum())
        cross = np.cross(u[k], u[k + 1])
        axis = _unit(cross) if np.linalg.norm(cross) > 1e-6 else _unit(np.cross(u[k], rng.normal(size=3)))
        angle = math.atan2(float(np.linalg.norm(cross)), float(np.dot(u[k], u[k + 1])))
        v = _rotate(np.tile(axis, (n, 1)), angle * (10 * s**3 - 15 * s**4 + 6 * s**5), np.tile(u[k], (n, 1)))
        v = _rotate(np.tile(_unit(rng.normal(size=3)), (n, 1)),
                    np.radians(rng.uniform(5.0, 20.0)) * np.sin(np.pi * s) ** 2, v)
        envelope = np.sin(np.pi * s)[:, None] ** 2
        lift = rng.uniform(0.2, 1.0) * np.sin(2 * np.pi * s)[:, None] * _unit(rng.normal(size=3))
        tremor = sum(rng.uniform(0.02, 0.08)
                     * np.sin(2 * np.pi * rng.uniform(3, 10) * t[m] + rng.uniform(0, 7))[:, None]
                     * _unit(rng.normal(size=3)) for _ in range(4))
        f[m] = G0 * v + (lift + tremor) * envelope
    return f


def vibration(rng: np.random.Generator, t: np.ndarray, rests: np.ndarray, share: float,
              rms_mg: tuple[float, float]) -> np.ndarray:
    """(N, 3) m/s²: in a ``share`` of the rests, the rig vibrates (2–15 Hz, ``rms_mg`` rms per
    axis) throughout the rest: a building's floor as someone walks by."""
    out = np.zeros((t.size, 3))
    for a, b in rests:
        if rng.random() < share:
            m = (t >= a) & (t <= b)
            rms = rng.uniform(*rms_mg) * MG
            phase, freq = rng.uniform(0, 7, (4, 3)), rng.uniform(2, 15, (4, 3))
            waves = np.sin(2 * np.pi * freq * t[m, None, None] + phase)
            out[m] = rms * np.sum(waves, axis=1) / math.sqrt(2.0)
    return out


def sensor(rng: np.random.Generator, f: np.ndarray, noise_mps2: float, cross: float = 0.005,
           scale: float = 0.01, offset_mg: float = 30.0) -> np.ndarray:
    """(N, 3) m/s², what a sensor with a full 3×3 map (scales, cross-axis terms), an offset and
    white noise reads of the specific force ``f``."""
    a = np.diag(1 + rng.uniform(-scale, scale, 3)) + rng.uniform(-cross, cross, (3, 3)) * (1 - np.eye(3))
    return f @ a.T + rng.uniform(-offset_mg, offset_mg, 3) * MG + rng.normal(size=f.shape) * noise_mps2


# --------------------------------------------------------------------------- sessions


MANIFEST = """format: ofbe-session/1
campaign: real-loggers
session: {session}
kind: multi-position
site: {{gravity_mps2: {g}}}
power_cycle: 1
devices:
{devices}recordings:
  - id: rec-01
    files: {{{files}}}
"""


def write_session(folder: Path, data: str, devices: dict[str, str], name: str = "log.csv") -> Path:
    """A multi-position session of one file ``name`` holding ``data``, read by each device through
    its manifest keys (``devices``: id → the lines of its ``csv`` entry after ``format``)."""
    (folder / "rec-01").mkdir(parents=True)
    (folder / "rec-01" / name).write_text(data, encoding="utf-8")
    entries = "".join(f"  {d}:\n    model: X\n    role: dut\n    format: csv\n{keys}"
                      for d, keys in devices.items())
    files = ", ".join(f"{d}: rec-01/{name}" for d in devices)
    text = MANIFEST.format(session=folder.name, g=G0, devices=entries, files=files)
    (folder / "session.yaml").write_text(text, encoding="utf-8")
    return folder


@dataclass(frozen=True)
class Found:
    """Detected poses of one device against the true rests."""

    rows: list[dict]
    hits: list[int]
    """Per true rest, how many detected poses overlap it."""
    outside: list[tuple[float, float]]
    """Detected poses that lie outside every (widened) rest."""


def match(labels: SessionLabels, device: str, rests: np.ndarray, t0: float, widen_s: float) -> Found:
    rows = [r for r in labels.rows if r["device"] == device]
    spans = [(r["segment_start_s"] - t0, r["segment_end_s"] - t0) for r in rows]
    hits = [sum(1 for s, e in spans if s < b and e > a) for a, b in rests]
    outside = [(s, e) for s, e in spans if not any(a - widen_s <= s and e <= b + widen_s for a, b in rests)]
    return Found(rows, hits, outside)


# --------------------------------------------------------------------------- (a) coarse quantisation


def test_the_output_step_is_the_grid_the_readings_sit_on() -> None:
    rng = np.random.default_rng(1)
    g2 = np.round(rng.normal(0.0, 0.004, (500, 3)) + [0.0, 0.5, 1.0], 2) * G0  # g, two decimals
    np.testing.assert_allclose(output_steps(g2), 0.01 * G0, rtol=1e-9)
    counts = (np.rint(rng.normal(100.0, 2.0, (500, 3))) - 0.0) / 256.0 * G0
    np.testing.assert_allclose(output_steps(counts), G0 / 256.0, rtol=1e-9)
    floats = rng.normal(0.0, 1e-3, (500, 3))
    assert np.all(output_steps(floats) < 1e-7)
    one_value = np.full((10, 3), 9.81)
    assert np.all(output_steps(one_value) == 0.0) and quantisation_floor(one_value) == 0.0
    assert quantisation_floor(g2) == pytest.approx(3 * (0.01 * G0) ** 2 / 4, rel=1e-9)


def coarse_logger(seed: int, noise_mg: float, log_the_turns: bool = True) -> tuple[str, np.ndarray]:
    """A 9.5-Hz logger printing g with two decimals: six faces of 10–16 s, 15–20 s apart. Without
    ``log_the_turns`` the logger pauses while the board is turned (a 3–6 s gap in its stamps)."""
    rng = np.random.default_rng(seed)
    rests = _rests(rng, 6, (10.0, 16.0), (3.0, 6.0))
    t = np.arange(0.0, rests[-1, 1] + 1.0, 1 / 9.5)
    t = t + rng.uniform(-0.004, 0.004, t.size)  # a host clock
    f = rig_force(rng, t, _faces(rng), rests)
    g = np.round(sensor(rng, f, noise_mg * MG, scale=0.02) / G0, 2)
    keep = np.ones(t.size, dtype=bool)
    if not log_the_turns:
        keep = np.any([(t >= a - 0.3) & (t <= b + 0.3) for a, b in rests], axis=0)
    body = "".join(f"{ti:.3f},{x:.2f},{y:.2f},{z:.2f}\n"
                   for ti, (x, y, z) in zip(t[keep], g[keep], strict=True))
    return "time_s,ax_g,ay_g,az_g\n" + body.replace("-0.00", "0.00"), rests


COARSE = "    columns: {t: time_s, ax: ax_g, ay: ay_g, az: az_g}\n    acc_unit: g\n"


@pytest.mark.parametrize("seed, noise_mg, log_the_turns", [(1, 1.0, True), (2, 2.0, True), (3, 3.0, True),
                                                            (4, 2.0, False)])
def test_a_two_decimal_logger_s_six_faces_are_found(tmp_path: Path, seed: int, noise_mg: float,
                                                   log_the_turns: bool) -> None:
    """Issue 33 3a: refused before (seeds 2 and 4; seed 1 split the six faces into 23 poses): the
    quietest part shows no variance, the floor was the 0.5-mg minimum, and a one-step toggle in
    a five-sample window (0.2·q²) is 26 times that, so every toggle split a pose. At 3 mg of
    noise the output changes often enough for the measured floor (seed 3, found before too)."""
    text, rests = coarse_logger(seed, noise_mg, log_the_turns)
    folder = write_session(tmp_path / f"coarse-{seed}", text, {"logger": COARSE})
    labels = label_session(folder)
    assert labels.rejections == []
    found = match(labels, "logger", rests, 0.0, widen_s=1.0)
    assert found.hits == [1] * 6 and found.outside == []
    assert {r["fit_model"] for r in found.rows} <= {"offset", "scale-offset"}
    m = load_manifest(folder)
    rec = read_device_file(m.file_path(m.recordings[0], "logger"), m.devices["logger"])
    det = find_session_poses([(rec.t, rec.acc, rec.fs_hz)], G0)
    assert det.floor_source == (FLOOR_QUANTISATION,)
    assert det.noise_floor_var[0] == pytest.approx(3 * (0.01 * G0) ** 2 / 4, rel=1e-9)


# --------------------------------------------------------------------------- (b) false saturation


def short_poses_in_counts(seed: int) -> tuple[str, np.ndarray, float]:
    """40 Hz, counts at 256 per g, 24 poses of 1.6–1.8 s (one second each once the margins are
    trimmed); in the pose whose x axis reads −0.658 g (−168.5 counts), 9 of the 41 middle samples
    sit at −171 counts (−0.668 g) and 3 at −170, its lowest values. Returns the file, the rests
    and the time of the first of those 41 samples."""
    rng = np.random.default_rng(seed)
    u = _sphere(rng, 24)
    u[5] = _unit(np.array([-168.5 / 256, 0.55, 0.5264]))
    rests = _rests(rng, 24, (1.6, 1.8), (1.0, 2.0))
    t = np.arange(0.0, rests[-1, 1] + 0.5, 1 / 40.0)
    read = sensor(rng, rig_force(rng, t, u, rests), 1.2 / 256 * G0) / G0 * 256
    a, b = rests[5]
    rest = np.flatnonzero((t >= a) & (t <= b))
    middle = rest[(rest.size - 41) // 2:][:41]
    read[:, 0] += -168.5 - np.median(read[middle, 0])  # x's offset puts that pose at −168.5 counts
    counts = np.rint(read)
    counts[rest, 0] = np.clip(counts[rest, 0], -169, None)
    x = counts[middle, 0]
    x[[0, 4, 8, 12, 20, 24, 28, 32, 36]] = -171  # nine at the lowest value ...
    x[[2, 18, 30]] = -170  # ... three times as many as at the next one
    counts[middle, 0] = x
    body = "".join(f"{ti:.4f},{int(p)},{int(q)},{int(r)}\n" for ti, (p, q, r) in zip(t, counts, strict=True))
    return "t,ax,ay,az\n" + body, rests, float(t[middle[0]])


COUNTS = "    columns: {t: t, ax: ax, ay: ay, az: az}\n    acc_unit: counts\n    lsb_per_g: 256\n"


@pytest.mark.parametrize("declared", [True, False])
def test_a_pile_up_at_minus_0_668_g_on_a_2_g_sensor_is_not_saturation(tmp_path: Path, declared: bool) -> None:
    """Issue 33 3b: 9 of 41 samples at −0.668 g, the pose's lowest value, rejected the pose as
    ``saturated``. Judged against the declared ±2 g, or against the file's own full scale (it
    reads beyond ±0.97 g on every axis elsewhere), it is noise."""
    text, rests, at = short_poses_in_counts(7)
    keys = COUNTS + ("    range_g: 2\n" if declared else "")
    folder = write_session(tmp_path / f"counts-{declared}", text, {"imu": keys})
    m = load_manifest(folder)
    rec = read_device_file(m.file_path(m.recordings[0], "imu"), m.devices["imu"])
    pose = rec.acc[(rec.t >= at - 1e-6) & (rec.t < at + 40.5 / 40.0)]
    assert clipped_samples(pose) == (9, 0, -171 / 256 * G0, False)  # the segment alone: a pile-up
    assert clipped_samples(pose, bounds=(rec.full_scale.low, rec.full_scale.high)) is None
    assert rec.full_scale.source == ("declared" if declared else "inferred")
    labels = label_session(folder)
    assert [r.reason for r in labels.rejections] == []
    found = match(labels, "imu", rests, 0.0, widen_s=0.5)
    assert found.hits == [1] * 24 and found.outside == []


def thirty_hz_on_a_milli_g_grid(seed: int, minutes: float) -> tuple[str, np.ndarray]:
    """30 Hz, g with three decimals, noise 1.5 mg: poses of 1.3–2.5 s, 1–2 s of handling."""
    rng = np.random.default_rng(seed)
    k = int(minutes * 60 / 3.4)
    rests = _rests(rng, k, (1.3, 2.5), (1.0, 2.0))
    t = np.arange(0.0, rests[-1, 1] + 0.5, 1 / 30.0)
    g = np.round(sensor(rng, rig_force(rng, t, _unit(rng.normal(size=(k, 3))), rests), 1.5 * MG) / G0, 3)
    body = "".join(f"{ti:.4f},{x:.3f},{y:.3f},{z:.3f}\n" for ti, (x, y, z) in zip(t, g, strict=True))
    return "t,x,y,z\n" + body, rests


def test_short_poses_on_a_milli_g_grid_are_not_saturated(tmp_path: Path) -> None:
    """Issue 33 3b: a 20-hour 30-Hz recording on a 0.001 g grid had 48 poses rejected as
    ``saturated``; ten minutes of this one had two (seeds 0 and 1: one and none)."""
    text, rests = thirty_hz_on_a_milli_g_grid(2, 10.0)
    folder = write_session(tmp_path / "milli-g", text, {"imu": "    columns: {t: t, ax: x, ay: y, az: z}\n"
                                                               "    acc_unit: g\n"})
    labels = label_session(folder)
    assert Counter(r.reason for r in labels.rejections) == Counter()
    found = match(labels, "imu", rests, 0.0, widen_s=0.5)
    assert found.hits == [1] * len(rests) and found.outside == []


def test_a_sensor_that_clips_at_its_range_is_still_saturated(tmp_path: Path) -> None:
    """A ±1 g tilt sensor (no range declared) clips every axis at ±1 g: the poses whose axis
    reads beyond it pile up at the file's largest magnitude and are rejected, the others kept."""
    rng = np.random.default_rng(3)
    u = _sphere(rng, 12)
    u[3], u[8] = [0.0, 0.0, 1.0], _unit(np.array([0.15, 0.1, 0.984]))  # z up, and z nearly up
    rests = _rests(rng, 12, (2.0, 3.0), (1.0, 2.0))
    t = np.arange(0.0, rests[-1, 1] + 0.5, 1 / 50.0)
    read = sensor(rng, rig_force(rng, t, u, rests), 2.0 * MG)
    read[:, 2] += 0.06 * G0  # z reads 60 mg high: the poses with z (nearly) up read beyond 1 g
    g = np.clip(np.round(read / G0, 3), -1.0, 1.0)
    body = "".join(f"{ti:.3f},{x:.3f},{y:.3f},{z:.3f}\n" for ti, (x, y, z) in zip(t, g, strict=True))
    folder = write_session(tmp_path / "tilt", "t,x,y,z\n" + body,
                           {"tilt": "    columns: {t: t, ax: x, ay: y, az: z}\n    acc_unit: g\n"})
    m = load_manifest(folder)
    rec = read_device_file(m.file_path(m.recordings[0], "tilt"), m.devices["tilt"])
    assert rec.full_scale.high[2] == pytest.approx(G0) and rec.full_scale.source == "inferred"
    labels = label_session(folder)
    saturated = [r for r in labels.rejections if r.reason == "saturated"]
    assert all(" z " in r.detail and "9.8066 m/s²" in r.detail for r in saturated), saturated
    assert [int(r.detail.split()[1]) for r in saturated] == [3, 8]  # the poses that read beyond 1 g
    assert len(labels.rows) == 10


def test_full_scale_from_a_declared_range_an_inferred_one_and_a_stuck_axis() -> None:
    acc = np.array([[0.1, -9.7, 9.9], [0.2, 9.5, 9.8], [0.1, 0.0, -9.6], [0.3, 0.0, 9.9]])
    declared = full_scale(acc, 2 * G0, 0.99)
    np.testing.assert_allclose(declared.high, 0.99 * 2 * G0)
    np.testing.assert_allclose(declared.low, -0.99 * 2 * G0)
    inferred = full_scale(acc)  # largest magnitude 9.9 (z): within 5 % of it count
    assert inferred.high.tolist() == [np.inf, 9.5, 9.9] and inferred.low.tolist() == [-np.inf, -9.7, -9.6]
    stuck = full_scale(np.column_stack([np.full(4, 0.4), acc[:, 1:]]))
    assert stuck.high[0] == stuck.low[0] == 0.4


# --------------------------------------------------------------------------- (c) one BLE file, two sensors


def ble_file(seed: int, k: int = 40) -> tuple[str, np.ndarray, float, tuple[float, float]]:
    """Two triads (``ax1…az1``: ADXL355-class, 25 µg/√Hz; ``ax2…az2``: BMI160-class, 180 µg/√Hz,
    mounted turned) in one semicolon file at 50 Hz, stamped by the host in epoch microseconds
    when each line arrives (step jitter 30 %), with 35 stretches of lines lost; ``k`` poses of
    2–6 s, 30 % of them on a rig vibrating at 0.6–1.2 mg rms per axis; and one pose of 1.2 s
    with 0.55 s of it lost. Returns the file, the rests (s from the first stamp), the first
    stamp (s) and the short pose's rest."""
    rng = np.random.default_rng(seed)
    fs = 50.0
    rests = _rests(rng, k, (2.0, 6.0), (1.5, 3.5))
    short = 17
    shift = 1.2 - (rests[short, 1] - rests[short, 0])
    rests[short, 1] += shift
    rests[short + 1:] += shift
    n = int((rests[-1, 1] + 1.0) * fs)
    t = np.arange(n) / fs
    rests[-1, 1] = t[-1]  # the last pose lasts to the end of the file
    f = rig_force(rng, t, _sphere(rng, k), rests) + vibration(rng, t, np.delete(rests, short, axis=0), 0.3,
                                                             (0.6, 1.2))
    quiet = sensor(rng, f, 25e-6 * G0 * math.sqrt(fs / 2), cross=0.005, scale=0.005, offset_mg=20.0)
    turned = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
    noisy = sensor(rng, f @ turned.T, 180e-6 * G0 * math.sqrt(fs / 2), cross=0.01, scale=0.02, offset_mg=50.0)
    t0 = 1.7e9
    stamps = np.round((t0 + t + rng.uniform(0.0, 0.3 * math.sqrt(6.0) / fs, n)) * 1e6).astype(np.int64)
    keep = np.ones(n, dtype=bool)
    a, b = rests[short]
    keep[(t > a + 0.35) & (t < a + 0.9)] = False  # 0.55 s of the short pose lost
    elsewhere = ((t < a - 1.0) | (t > b + 1.0)) & (t > 1.0) & (t < t[-1] - 1.0)
    for start in rng.choice(np.flatnonzero(elsewhere), 34, replace=False):
        keep[start:start + rng.integers(2, 15)] = False
    q, z = quiet[keep] / G0, noisy[keep] / G0
    lines = [f"{s};{q[i, 0]:.6f};{q[i, 1]:.6f};{q[i, 2]:.6f};{z[i, 0]:.5f};{z[i, 1]:.5f};{z[i, 2]:.5f}"
             for i, s in enumerate(stamps[keep])]
    text = "timestamp_us;ax1;ay1;az1;ax2;ay2;az2\n" + "\n".join(lines) + "\n"
    return text, rests, float(stamps[0]) * 1e-6, (float(a), float(b))


def triad(i: int) -> str:
    return (f"    columns: {{t: timestamp_us, ax: ax{i}, ay: ay{i}, az: az{i}}}\n    time_unit: us\n"
            "    acc_unit: g\n    delimiter: ';'\n")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_quiet_and_a_noisy_sensor_in_one_ble_file_find_the_same_poses(tmp_path: Path, seed: int) -> None:
    """Issue 33 3c: the noisier sensor found 39 poses, the quiet one 28. The quiet sensor's floor
    is its own noise (raised to 0.5 mg), and the vibrating rests are louder than the thresholds
    up to ×3–×6 of it, while the noisy sensor's noise hides the vibration; the pose fit's
    residual does not rise when a pose is left out, so the smallest multiplier won and the
    vibrating rests were lost. Before, seeds 0–2 found 33, 28, 32 of the 40 rests (quiet) and 36,
    40, 40 (noisy). The short pose lost 0.55 of its 1.2 s to the link: fewer samples than a
    second's 50, though it lasted longer (seed 0: both sensors dropped it before)."""
    text, rests, t0, short = ble_file(seed)
    folder = write_session(tmp_path / f"ble-{seed}", text, {"quiet": triad(1), "noisy": triad(2)}, "ble.csv")
    labels = label_session(folder)
    assert labels.rejections == []
    for device in ("quiet", "noisy"):
        found = match(labels, device, rests, t0, widen_s=0.5)
        assert min(found.hits) >= 1, (device, found.hits)
        assert found.outside == [], device
        assert sum(h > 1 for h in found.hits) <= 3, (device, found.hits)  # a vibrating rest may split
        spans = [(r["segment_start_s"] - t0, r["segment_end_s"] - t0) for r in found.rows]
        assert [s for s in spans if s[0] < short[1] and s[1] > short[0]], device


def test_a_period_the_chosen_threshold_saw_as_loud_is_taken_from_a_larger_multiplier() -> None:
    """Four still periods: one quiet, one vibrating (louder than the chosen threshold throughout),
    one quiet but cut short (a tap's ringing), and one vibrating but on the face of the pose
    right after it (the same pose, interrupted): only the vibrating one on a face of its own is
    taken."""
    window = 5
    var = np.full(600, 10.0)  # handling
    var[0:100] = 1.0  # a still period the chosen threshold found
    var[150:250] = 3.0  # a vibrating still period: louder than the chosen threshold (2)
    var[300:315] = 5.0  # the ringing of a tap ...
    var[315:360] = 1.0  # ... then quiet, too short at the chosen threshold
    var[400:450] = 3.0  # vibrating, then knocked, then the same face again, quiet
    var[470:600] = 1.0
    acc = np.zeros((604, 3))
    acc[:, 2] = G0
    acc[150:250] = [G0, 0.0, 0.0]  # the vibrating pose is on another face
    found = [(10, 95), (475, 595)]
    larger = [[(10, 100), (475, 596)], [(5, 100), (155, 248), (402, 451), (475, 597)],
              [(5, 101), (150, 250), (302, 360), (401, 452), (470, 598)]]
    assert missed_periods(found, larger, var, window, 2.0, acc) == [(155, 248, 1)]
    assert louder_than(var, window, 150, 250, 2.0) and not louder_than(var, window, 300, 362, 2.0)
    assert missed_periods(found, [], var, window, 2.0, acc) == []
    assert angle_deg(np.array([1.0, 0, 0]), np.array([0, 2.0, 0])) == pytest.approx(90.0)


def test_a_run_lasts_its_time_stamps() -> None:
    t = np.concatenate([np.arange(0, 30) / 50.0, 1.0 + np.arange(0, 10) / 50.0])  # 40 samples, 0.4 s lost
    runs = np.array([[0, 40], [0, 30]])
    np.testing.assert_allclose(run_lasts(runs, t, 50.0), [1.2, 0.6])
    assert PoseParams().min_pose_s == 1.0
