"""What a wearer does, epoch by epoch: the behaviour behind a simulated free-living recording.

A file of ``days`` days is cut into epochs (10 s); every epoch gets a state, whether the device is
still, the direction of gravity in the device frame, the motion on top of it, and the device's
temperature. :func:`draw_plan` builds the plan from one random generator; the sensor model that turns
it into numbers is :mod:`ofbe_data.simulator.freeliving`. Every boundary falls on an epoch
boundary. All the constants below are chosen, not measured; docs/sensor-model.md, "Free-living
recordings", gives the reasoning.

- **Day and night.** Each night the wearer sleeps from ~N(23:00, 45 min) (clipped to 21:00–01:30)
  to ~N(07:00, 45 min) (05:00–09:30); the clock is ``start_utc``'s, taken as local time.
- **Waking hours** are bouts: active (5–60 min), sitting (10–120 min), standing (2–20 min), the
  next bout's kind drawn from :data:`NEXT_BOUT`. An active bout is moving epochs only. A sitting or
  standing bout alternates moving epochs (shifting posture, fidgeting: 1–10 sitting, 1–6 standing)
  with a still spell (sitting 0.3–5 min, standing 0.3–3 min) in one orientation drawn from the
  posture's clusters.
- **Sleep** is the same with lying clusters: still spells of 5–90 min separated by 1–3 epochs of
  turning over.
- **Non-wear**: per waking interval a Poisson number of periods (``nonwear_per_day`` per 16 h awake)
  of 10–120 min, and with probability ``nonwear_night_prob`` a whole night: the device is taken
  off (one moving epoch), lies on a table in one fixed orientation, and is put back on (one moving
  epoch).
- **Idle sleep** (``idle_sleep``, ActiGraph's mode): every still epoch after the first of its
  spell is idle (the device repeats its last sample).
- **Temperature**: a target per epoch, ambient 18–22 °C (a daily cosine, coldest at 04:00) off the
  body, skin temperature on it (sleep 33.5, sitting 32, standing 31.5, active 31 °C, plus a tenth of
  the ambient's swing), followed by the device with a first-order lag of 15 min, so that the
  temperature lags activity and wear.

Gravity directions (the unit specific force, "up", in the device frame) of still epochs come from
a mixture of von Mises–Fisher clusters per placement and posture (:data:`POSTURES`, :data:`TABLE`).
Wrist device (left wrist, watch style): +x along the forearm towards the hand, +y towards the thumb,
+z out of the watch face. Hip device (clip on the right hip): +x up along the trunk, +y forwards,
+z away from the body. A cluster's concentration κ spreads its directions by about √(2/κ) rad.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.signal import lfilter

from ofbe_data.core.geometry import dot3, norm3, unit

Vec3 = tuple[float, float, float]

STATES = ("active", "sit", "stand", "sleep", "nonwear")
"""Names of the states, indexed by their codes."""
ACTIVE, SIT, STAND, SLEEP, NONWEAR = range(5)


@dataclass(frozen=True)
class Cluster:
    """One von Mises–Fisher cluster of gravity directions in the device frame.

    Attributes
    ----------
    weight
        Share of the posture's spells drawn from it (a posture's weights sum to 1).
    direction
        Mean direction (any length; normalised when drawn).
    kappa
        Concentration (dimensionless); the directions spread by about √(2/κ) rad.
    """

    weight: float
    direction: Vec3
    kappa: float


POSTURES: dict[str, dict[int, tuple[Cluster, ...]]] = {
    "wrist": {
        STAND: (Cluster(0.55, (-1.0, 0.0, 0.0), 15.0),    # arm hanging, palm to the thigh
                Cluster(0.25, (-0.3, 0.0, 1.0), 8.0),     # hands in front, face up
                Cluster(0.20, (0.5, 0.0, 0.85), 10.0)),   # forearm raised: phone, watch
        SIT: (Cluster(0.40, (0.0, 0.0, 1.0), 10.0),       # forearm on desk or lap, typing
              Cluster(0.20, (0.0, 1.0, 0.0), 8.0),        # hand on lap, thumb up
              Cluster(0.10, (0.0, 0.0, -1.0), 8.0),       # palm up on the armrest
              Cluster(0.15, (0.6, 0.0, 0.8), 8.0),        # holding a phone, hand above elbow
              Cluster(0.15, (-1.0, 0.0, 0.0), 10.0)),     # arm hanging beside the chair
        SLEEP: (Cluster(0.25, (0.0, 0.0, 1.0), 4.0), Cluster(0.20, (0.0, 0.0, -1.0), 4.0),
                Cluster(0.20, (0.0, 1.0, 0.0), 4.0), Cluster(0.10, (0.0, -1.0, 0.0), 4.0),
                Cluster(0.15, (1.0, 0.0, 0.0), 4.0),      # hand under the pillow or above the head
                Cluster(0.10, (-1.0, 0.0, 0.0), 4.0)),    # arm along the body
    },
    "hip": {
        STAND: (Cluster(1.0, (1.0, 0.0, 0.0), 80.0),),
        SIT: (Cluster(0.7, (0.8, -0.5, 0.0), 25.0),       # reclined trunk
              Cluster(0.3, (0.95, 0.3, 0.0), 25.0)),      # leaning forwards
        SLEEP: (Cluster(0.45, (0.0, 1.0, 0.0), 15.0),     # on the back
                Cluster(0.25, (0.0, 0.0, 1.0), 15.0),     # on the left side
                Cluster(0.15, (0.0, 0.0, -1.0), 15.0),    # on the right side
                Cluster(0.15, (0.0, -1.0, 0.0), 15.0)),   # prone
    },
}
"""Still-epoch gravity directions per placement and posture."""
TABLE = (Cluster(0.60, (0.0, 0.0, 1.0), 400.0), Cluster(0.10, (0.0, 0.0, -1.0), 400.0),
         Cluster(0.10, (0.0, 1.0, 0.0), 200.0), Cluster(0.10, (0.0, -1.0, 0.0), 200.0),
         Cluster(0.05, (1.0, 0.0, 0.0), 200.0), Cluster(0.05, (-1.0, 0.0, 0.0), 200.0))
"""A device off the body, on a table: mostly face up, within a few degrees of a face."""

BOUT_MIN = {ACTIVE: (5.0, 60.0), SIT: (10.0, 120.0), STAND: (2.0, 20.0)}
"""Length of a waking bout, minutes (uniform)."""
SPELL_MIN = {SIT: (0.3, 5.0), STAND: (0.3, 3.0), SLEEP: (5.0, 90.0)}
"""Length of one still spell within a bout, minutes (uniform)."""
SHIFT_EPOCHS = {SIT: (1, 10), STAND: (1, 6), SLEEP: (1, 3)}
"""Moving epochs between two still spells of a bout, fewest and most (uniform integers)."""
NEXT_BOUT = {ACTIVE: ((SIT, 0.6), (STAND, 0.4)), SIT: ((ACTIVE, 0.6), (STAND, 0.4)),
             STAND: ((ACTIVE, 0.5), (SIT, 0.5))}
"""The next waking bout's kind and its probability."""
FIRST_BOUT = ((SIT, 0.5), (ACTIVE, 0.3), (STAND, 0.2))
"""The first bout of a waking interval."""
NONWEAR_MIN = (10.0, 120.0)
"""Length of a non-wear period in waking hours, minutes (uniform)."""
AWAKE_H = 16.0
"""Hours awake per day that ``nonwear_per_day`` refers to."""
SLEEP_ONSET_H = (23.0, 0.75, 21.0, 25.5)
"""Sleep onset: mean, standard deviation, earliest and latest, hours of the day."""
WAKE_H = (7.0, 0.75, 5.0, 9.5)
"""Waking: mean, standard deviation, earliest and latest, hours of the next day."""
MICRO_MOTION_G = {SIT: 0.003, STAND: 0.004, SLEEP: 0.002, NONWEAR: 0.0}
"""Motion of a still epoch, g rms per axis (breathing, pulse, tremor); none off the body."""
MIN_MOTION_G = 0.025
NO_STILL_MOTION_G = 0.02
"""Least motion of every epoch on the body in a device that never rests (``tremor_g`` of
:func:`draw_plan`, the ``no-still`` scenario), g rms per axis: an epoch's standard deviation stays
above GGIR's 13 mg (by more than 10 of its own standard errors at 300 samples)."""
"""Least motion of a moving epoch, g rms per axis: its sd stays well above GGIR's 13 mg."""
SHIFT_MOTION_G = (0.03, 0.15)
"""Motion of an epoch of posture shifting, turning over or taking the device off, g (uniform)."""
SHIFT_RHO = (0.6, 1.0)
"""Such an epoch's mean is gravity shrunk by this factor (orientations averaged; uniform)."""
ACTIVE_MOTION_G = (0.2, 0.5)
"""An active bout's motion level: log-normal, median (g) and σ of its logarithm; each epoch
0.7–1.3 times it."""
ACTIVE_RHO = (0.8, 1.0)
"""Shrinking of an active epoch's mean gravity (uniform)."""
AMBIENT_C = (18.0, 4.0, 4.0)
"""Ambient temperature: minimum and daily swing, °C, and the hour of the minimum."""
SKIN_C = {ACTIVE: 31.0, SIT: 32.0, STAND: 31.5, SLEEP: 33.5}
"""Skin temperature under the device per state, °C, before a tenth of the ambient's swing."""
THERMAL_TAU_S = 900.0
"""Time constant of the device's temperature, s."""


@functools.lru_cache(maxsize=32)
def _table(clusters: tuple[Cluster, ...]) -> tuple[np.ndarray, np.ndarray, list[float]]:
    """A mixture's cumulative weights but the last (K − 1,), unit mean directions (K, 3), concentrations."""
    directions = np.array([unit(np.asarray(c.direction, dtype=np.float64)) for c in clusters])
    return np.cumsum([c.weight for c in clusters])[:-1], directions, [c.kappa for c in clusters]


def sample_mixture(clusters: tuple[Cluster, ...], m: int, rng: np.random.Generator) -> np.ndarray:
    """``m`` directions from a mixture of von Mises–Fisher clusters on the sphere (3-D, exact).

    Each direction's cluster is drawn by weight; its cosine to the cluster's mean is
    w = 1 + ln(ξ + (1 − ξ)·e^(−2κ))/κ with ξ uniform in (0, 1] (the inverse of its distribution
    function in 3-D, no rejection), and its tangent direction is uniform. The logarithms are
    scalar ``math`` calls, so that no vectorised transcendental differs between processors.

    Parameters
    ----------
    clusters
        The mixture (weights summing to 1).
    m
        Number of directions.
    rng
        Random generator: m uniforms (the clusters), m uniforms (ξ), (m, 3) normals.

    Returns
    -------
    ndarray, shape (m, 3)
        Unit vectors.
    """
    bounds, directions, kappas = _table(clusters)
    k = np.searchsorted(bounds, rng.random(m), side="right")
    xi = 1.0 - rng.random(m)
    g = rng.standard_normal((m, 3))
    mu = directions[k]
    w = np.array([min(1.0, max(-1.0, 1.0 + math.log(x + (1.0 - x) * math.exp(-2.0 * kappas[j])) / kappas[j]))
                  for x, j in zip(xi.tolist(), k.tolist(), strict=True)])
    tangent = g - dot3(g, mu)[:, None] * mu
    tangent /= norm3(tangent)[:, None]
    return w[:, None] * mu + np.sqrt(1.0 - w * w)[:, None] * tangent


@dataclass(frozen=True, eq=False)
class WearPlan:
    """The behaviour of one file, one row per epoch.

    Attributes
    ----------
    placement
        ``wrist`` or ``hip``.
    epoch_s
        Epoch length, s.
    start_hour
        Hour of the day at the start of the first epoch (``start_utc``), h.
    state
        (n,) int8 codes into :data:`STATES`.
    still
        (n,) True where the device is still (only noise and micro-motion).
    u
        (n, 3) unit direction of gravity in the device frame (of the epoch's mean when moving).
    rho
        (n,) the epoch's mean specific force is ``rho · g · u`` (1 when still, < 1 when moving).
    motion_g
        (n,) motion per axis, g rms, isotropic in the device frame before the sensor's errors.
    spell
        (n,) id of the spell each epoch belongs to (one still orientation, or one stretch of moving
        epochs drawn together).
    idle
        (n,) True where the device repeats its last sample (idle sleep).
    temperature_c
        (n,) the device's temperature at the epoch's centre, °C.
    """

    placement: str
    epoch_s: float
    start_hour: float
    state: np.ndarray
    still: np.ndarray
    u: np.ndarray
    rho: np.ndarray
    motion_g: np.ndarray
    spell: np.ndarray
    idle: np.ndarray
    temperature_c: np.ndarray

    @property
    def n(self) -> int:
        """Number of epochs."""
        return int(self.state.shape[0])

    def segments(self) -> list[dict[str, Any]]:
        """Runs of epochs of one spell, in time order: ``state``, ``first_epoch`` (0-based),
        ``epochs``, ``still``, and for still runs ``u`` (the gravity direction) and ``idle_epochs``."""
        starts = np.flatnonzero(np.r_[True, self.spell[1:] != self.spell[:-1]])
        ends = np.r_[starts[1:], self.n]
        out: list[dict[str, Any]] = []
        for s, e in zip(starts.tolist(), ends.tolist(), strict=True):
            seg: dict[str, Any] = {"state": STATES[int(self.state[s])], "first_epoch": s, "epochs": e - s,
                                   "still": bool(self.still[s])}
            if seg["still"]:
                seg["u"] = self.u[s].tolist()
                seg["idle_epochs"] = int(self.idle[s:e].sum())
            out.append(seg)
        return out

    def counts(self) -> dict[str, int]:
        """Epochs per state, still epochs and idle epochs."""
        out = {f"{name}_epochs": int(np.sum(self.state == k)) for k, name in enumerate(STATES)}
        out["still_epochs"] = int(self.still.sum())
        out["idle_epochs"] = int(self.idle.sum())
        return out


def _epochs(minutes: float, per_min: float) -> int:
    """A duration in whole epochs, at least one."""
    return max(1, int(round(minutes * per_min)))


def _pick(options: tuple[tuple[int, float], ...], rng: np.random.Generator) -> int:
    """One of ``options`` (value, probability)."""
    return options[int(rng.choice(len(options), p=[p for _, p in options]))][0]


class _Builder:
    """Fills the per-epoch arrays of a plan, spell by spell."""

    def __init__(self, n: int, placement: str, epoch_s: float, rng: np.random.Generator) -> None:
        self.rng = rng
        self.clusters = POSTURES[placement]
        self.per_min = 60.0 / epoch_s
        self.state = np.zeros(n, dtype=np.int8)
        self.still = np.zeros(n, dtype=bool)
        self.u = np.tile([0.0, 0.0, 1.0], (n, 1))
        self.rho = np.ones(n)
        self.motion = np.zeros(n)
        self.spell = np.zeros(n, dtype=np.int64)
        self.spells = 0

    def _mark(self, a: int, b: int, state: int, still: bool) -> None:
        self.spells += 1
        self.state[a:b], self.still[a:b], self.spell[a:b] = state, still, self.spells

    def still_spell(self, a: int, b: int, state: int, u: np.ndarray) -> None:
        """Epochs [a, b) still in direction ``u``."""
        self._mark(a, b, state, True)
        self.u[a:b], self.rho[a:b], self.motion[a:b] = u, 1.0, MICRO_MOTION_G[state]

    def moving(self, a: int, b: int, state: int, clusters: tuple[Cluster, ...], rho: tuple[float, float],
               motion: np.ndarray) -> None:
        """Epochs [a, b) moving: each its own mean direction from ``clusters``, shrinking and motion."""
        self._mark(a, b, state, False)
        self.u[a:b] = sample_mixture(clusters, b - a, self.rng)
        self.rho[a:b] = self.rng.uniform(*rho, b - a)
        self.motion[a:b] = np.maximum(motion, MIN_MOTION_G)

    def shift(self, a: int, b: int, state: int, clusters: tuple[Cluster, ...]) -> None:
        """Epochs [a, b) of shifting posture (or handling the device)."""
        self.moving(a, b, state, clusters, SHIFT_RHO, self.rng.uniform(*SHIFT_MOTION_G, b - a))

    def active(self, a: int, b: int) -> None:
        """An active bout: moving epochs around the standing orientations."""
        median, sigma = ACTIVE_MOTION_G
        level = math.exp(math.log(median) + sigma * float(self.rng.standard_normal()))
        self.moving(a, b, ACTIVE, self.clusters[STAND], ACTIVE_RHO, level * self.rng.uniform(0.7, 1.3, b - a))

    def posture_bout(self, a: int, b: int, state: int) -> None:
        """Sitting, standing or sleep: a few shifting epochs, a still spell, and again."""
        k = a
        while k < b:
            lo, hi = SHIFT_EPOCHS[state]
            stop = min(b, k + int(self.rng.integers(lo, hi + 1)))
            self.shift(k, stop, state, self.clusters[state])
            k = stop
            if k >= b:
                break
            stop = min(b, k + _epochs(float(self.rng.uniform(*SPELL_MIN[state])), self.per_min))
            self.still_spell(k, stop, state, sample_mixture(self.clusters[state], 1, self.rng)[0])
            k = stop

    def wake(self, a: int, b: int) -> None:
        """Waking hours [a, b): bouts of activity, sitting and standing."""
        state = _pick(FIRST_BOUT, self.rng)
        k = a
        while k < b:
            stop = min(b, k + _epochs(float(self.rng.uniform(*BOUT_MIN[state])), self.per_min))
            if state == ACTIVE:
                self.active(k, stop)
            else:
                self.posture_bout(k, stop, state)
            k = stop
            state = _pick(NEXT_BOUT[state], self.rng)

    def nonwear(self, a: int, b: int) -> None:
        """Epochs [a, b) off the body: taken off, one orientation on a table, put back on."""
        if b - a < 3:
            self.shift(a, b, NONWEAR, TABLE)
            return
        self.shift(a, a + 1, NONWEAR, TABLE)
        self.still_spell(a + 1, b - 1, NONWEAR, sample_mixture(TABLE, 1, self.rng)[0])
        self.shift(b - 1, b, NONWEAR, TABLE)


def sleep_windows(n: int, start_hour: float, epoch_s: float,
                  rng: np.random.Generator) -> list[tuple[int, int]]:
    """The nights of a file: epoch intervals [onset, wake) within [0, n), in time order.

    One onset and one wake time are drawn for every night from the one before the start to the
    one after the end (so the number of draws depends on ``n`` and ``start_hour`` only).
    """
    per_h = 3600.0 / epoch_s
    out: list[tuple[int, int]] = []
    for day in range(-1, int(math.ceil((start_hour + n / per_h) / 24.0)) + 1):
        mean, sd, lo, hi = SLEEP_ONSET_H
        onset = 24.0 * day + min(hi, max(lo, mean + sd * float(rng.standard_normal())))
        mean, sd, lo, hi = WAKE_H
        wake = 24.0 * (day + 1) + min(hi, max(lo, mean + sd * float(rng.standard_normal())))
        a = min(n, max(0, int(round((onset - start_hour) * per_h))))
        b = min(n, max(0, int(round((wake - start_hour) * per_h))))
        if a < b:
            out.append((a, b))
    return out


def temperature(state: np.ndarray, epoch_s: float, start_hour: float) -> np.ndarray:
    """The device's temperature per epoch, °C: the state's target followed with a lag.

    Parameters
    ----------
    state
        (n,) state codes.
    epoch_s
        Epoch length, s.
    start_hour
        Hour of the day at the start, h.

    Returns
    -------
    ndarray, shape (n,)
        °C, starting at the first epoch's target.
    """
    low, swing, coldest = AMBIENT_C
    hours = start_hour + (np.arange(state.shape[0]) + 0.5) * (epoch_s / 3600.0)
    cosine = np.array([math.cos(2.0 * math.pi * (h - coldest) / 24.0) for h in hours.tolist()])
    ambient = low + swing * (1.0 - cosine) / 2.0
    skin_c = np.array([SKIN_C.get(s, 0.0) for s in range(len(STATES))])
    skin = skin_c[state] + 0.1 * (ambient - (low + swing / 2))
    target = np.where(state == NONWEAR, ambient, skin)
    a = math.exp(-epoch_s / THERMAL_TAU_S)
    return lfilter([1.0 - a], [1.0, -a], target, zi=[a * target[0]])[0]


def draw_plan(placement: str, n: int, epoch_s: float, start_hour: float, *, idle_sleep: bool = False,
              nonwear_per_day: float = 1.0, nonwear_night_prob: float = 0.1, tremor_g: float = 0.0,
              rng: np.random.Generator) -> WearPlan:
    """Draw what the wearer does in each of ``n`` epochs.

    Parameters
    ----------
    placement
        ``wrist`` or ``hip``.
    n
        Number of epochs.
    epoch_s
        Epoch length, s.
    start_hour
        Hour of the day at the start, h (``start_utc`` taken as local time).
    idle_sleep
        Mark every still epoch after the first of its spell idle.
    nonwear_per_day
        Mean non-wear periods per 16 h awake.
    nonwear_night_prob
        Probability that a night is spent off the body.
    tremor_g
        When above 0, every epoch on the body moves with at least this motion (g rms per axis) and
        is not still (the ``no-still`` scenario); no draw depends on it.
    rng
        Random generator: the nights, then the days and nights in time order, then the non-wear
        periods of the waking intervals, then one draw per night.

    Returns
    -------
    WearPlan
    """
    b = _Builder(n, placement, epoch_s, rng)
    nights = sleep_windows(n, start_hour, epoch_s, rng)
    awake: list[tuple[int, int]] = []
    k = 0
    for lo, hi in [*nights, (n, n)]:
        if k < lo:
            b.wake(k, lo)
            awake.append((k, lo))
        if lo < hi:
            b.posture_bout(lo, hi, SLEEP)
        k = hi
    per_awake_day = AWAKE_H * 3600.0 / epoch_s
    for lo, hi in awake:
        for _ in range(int(rng.poisson(nonwear_per_day * (hi - lo) / per_awake_day))):
            length = _epochs(float(rng.uniform(*NONWEAR_MIN)), b.per_min)
            start = lo + int(rng.integers(0, max(1, hi - lo - length + 1)))
            b.nonwear(start, min(hi, start + length))
    for lo, hi in nights:
        if float(rng.random()) < nonwear_night_prob:
            b.nonwear(lo, hi)
    if tremor_g > 0.0:
        on_body = b.state != NONWEAR
        b.motion[on_body] = np.maximum(b.motion[on_body], tremor_g)
        b.still[on_body] = False
    idle = np.zeros(n, dtype=bool)
    if idle_sleep:
        idle[1:] = b.still[1:] & b.still[:-1] & (b.spell[1:] == b.spell[:-1])
    temp = temperature(b.state, epoch_s, start_hour)
    return WearPlan(placement, epoch_s, start_hour, b.state, b.still, b.u, b.rho, b.motion, b.spell, idle,
                    temp)
