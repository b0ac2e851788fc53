"""The wearable's sensor model in free-living recordings: its truth, epoch statistics and raw samples.

Per sample (g, device frame, per axis k)::

    reading = A · (g_r · rho · u + m) + offset + temp_coeff · (T − temp_ref_c) + n

- ``A = (I + diag(scale)) · T`` with the non-orthogonality T of imu_tk
  (:func:`~ofbe_data.simulator.physics.sensor_matrix`, the bench simulator's convention);
- ``g_r = g_local / g0``: gravity in units of standard gravity (the readings are in g);
- ``u``, ``rho``: the epoch's gravity direction and its shrinking (1 when still; the plan,
  :mod:`ofbe_data.simulator.wear`); ``m ~ N(0, motion² I)``, the epoch's motion, drawn anew per sample;
- ``offset`` (g) is the zero-g reading at ``temp_ref_c``; ``temp_coeff`` (g/°C) its slope; T the
  device's temperature;
- ``n ~ N(0, diag(σ²))`` with σ = noise density · √(rate / 2) (white noise over the bandwidth).

Samples are iid within an epoch, so the statistics of an epoch of N samples have exact
distributions, which :func:`draw_epochs` draws directly (a week of epochs costs milliseconds):

- mean ~ N(μ, Σ / N) with μ = A·g_r·rho·u + offset + temp_coeff·(T − temp_ref_c) and
  Σ = motion²·A·Aᵀ + diag(σ²), drawn as μ + (motion/√N)·A·z₁ + (σ/√N)∘z₂;
- sd per axis (N − 1 in the denominator, as R's ``sd`` in GGIR) = √Σ_kk · √(χ²_{N−1} / (N − 1)),
  independent of the mean (the cross-axis dependence of the three sds, through A's off-diagonal
  terms, is not drawn);
- an idle epoch (ActiGraph's idle sleep) repeats the last sample of the spell's first epoch: its
  mean is that sample (drawn from the sample's own distribution), its sd exactly 0.

:func:`raw_samples` draws the samples themselves, in chunks of epochs, rounded to 1e-5 g;
:func:`epoch_stats` computes an epoch's statistics from them in integers, exactly.

GGIR's model (``calibrated = (raw + offset_G)·scale_G + (T − T̄)·temp_offset_G``) maps the readings of
a device with a diagonal A onto the unit sphere with (:func:`ggir_coefficients`)::

    scale_G       = 1 / (g_r · A_kk)             A_kk = 1 + scale_k
    temp_offset_G = −temp_coeff · scale_G        g/°C
    offset_G      = −(offset + temp_coeff · (T̄ − temp_ref_c))   g

where T̄ is GGIR's ``meantempcal`` (the mean temperature of its still epochs). ofbe-autocal's own map
(``raw = A'·u + b + c·(T − T̄)``, |u| = 1 at rest) is likewise A' = g_r·A: a calibration from still
epochs takes local gravity as its unit. Put the first two into
the model and the terms in T cancel; what is left is u. With non-orthogonality (A not diagonal) GGIR's
model is only a first-order approximation.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from ofbe_data.core.geometry import mul3
from ofbe_data.simulator.config import DutModel
from ofbe_data.simulator.physics import sensor_matrix
from ofbe_data.simulator.wear import WearPlan
from ofbe_data.simulator.wearconfig import FreeLivingConfig

RAW_ACC_DECIMALS = 5
"""Decimals of raw accelerations in g (10 µg: rounding adds 2.9 µg rms to σ of a few mg)."""
RAW_TEMP_DECIMALS = 2
"""Decimals of raw temperatures in °C."""
CHUNK_SAMPLES = 200_000
"""Raw samples drawn at a time (whole epochs): memory stays bounded for week-long files."""


@dataclass(frozen=True, eq=False)
class WearSensor:
    """The truth of one wearable device.

    Attributes
    ----------
    scale
        (3,) scale errors (dimensionless): A's diagonal is 1 + scale.
    nonorth_rad
        (3,) non-orthogonality α_yz, α_zy, α_zx, rad (imu_tk's convention).
    A
        (3, 3) the sensor's map, ``sensor_matrix(scale, nonorth_rad)``.
    offset_g
        (3,) zero-g reading at ``temp_ref_c``, g.
    temp_coeff_g_per_c
        (3,) slope of the offset with temperature, g/°C.
    temp_ref_c
        °C.
    noise_density_ug
        (3,) µg/√Hz.
    noise_g
        (3,) white noise of one sample, g rms.
    g_ratio
        g_local / g0.
    """

    scale: np.ndarray
    nonorth_rad: np.ndarray
    A: np.ndarray
    offset_g: np.ndarray
    temp_coeff_g_per_c: np.ndarray
    temp_ref_c: float
    noise_density_ug: np.ndarray
    noise_g: np.ndarray
    g_ratio: float


def noise_rms_g(noise_density_ug: tuple[float, float, float] | np.ndarray, rate_hz: float) -> np.ndarray:
    """White noise of one sample, g rms: density (µg/√Hz) · √(rate / 2), shape (3,)."""
    return np.asarray(noise_density_ug, dtype=np.float64) * 1e-6 * math.sqrt(rate_hz / 2.0)


def draw_sensor(model: DutModel, fl: FreeLivingConfig, g_ratio: float,
                rng: np.random.Generator) -> WearSensor:
    """Draw one device's errors: scale, non-orthogonality, offset, temperature coefficient (in that order).

    Parameters
    ----------
    model
        ``scale_sigma``, ``cross_axis_sigma_deg`` and ``offset_sigma_mg`` apply.
    fl
        ``temp_coeff_sigma_mg_per_c``, ``temp_ref_c``, ``noise_density_ug`` and ``rate_hz`` apply.
    g_ratio
        g_local / g0.
    rng
        Random generator.

    Returns
    -------
    WearSensor
    """
    scale = rng.standard_normal(3) * model.scale_sigma
    nonorth = rng.standard_normal(3) * math.radians(model.cross_axis_sigma_deg)
    offset = rng.standard_normal(3) * np.asarray(model.offset_sigma_mg) * 1e-3
    coeff = rng.standard_normal(3) * np.asarray(fl.temp_coeff_sigma_mg_per_c) * 1e-3
    density = np.asarray(fl.noise_density_ug, dtype=np.float64)
    return WearSensor(scale, nonorth, sensor_matrix(scale, nonorth), offset, coeff, fl.temp_ref_c, density,
                      noise_rms_g(density, fl.rate_hz), g_ratio)


def already_calibrated(sensor: WearSensor) -> WearSensor:
    """The device of the ``already-calibrated`` scenario: its readings were calibrated before.

    A = I / g_r (scale = 1/g_r − 1, no non-orthogonality), so that it reads exactly 1 at rest,
    the unit of a still-epoch calibration (local gravity); no offset, no temperature slope. The
    noise is ``sensor``'s.
    """
    scale = np.full(3, 1.0 / sensor.g_ratio - 1.0)
    zero = np.zeros(3)
    return WearSensor(scale, zero, sensor_matrix(scale, zero), zero.copy(), zero.copy(), sensor.temp_ref_c,
                      sensor.noise_density_ug, sensor.noise_g, sensor.g_ratio)


def expected_means(sensor: WearSensor, plan: WearPlan) -> np.ndarray:
    """μ per epoch: A·g_r·rho·u + offset + temp_coeff·(T − temp_ref_c), g, shape (n, 3)."""
    gravity = (sensor.g_ratio * plan.rho)[:, None] * plan.u
    drift = sensor.temp_coeff_g_per_c * (plan.temperature_c - sensor.temp_ref_c)[:, None]
    return mul3(gravity, sensor.A.T) + sensor.offset_g + drift


def epoch_sigma(sensor: WearSensor, plan: WearPlan) -> np.ndarray:
    """Standard deviation of one sample per epoch and axis, √(motion²·Σ_j A_kj² + σ_k²), g, shape (n, 3)."""
    a = sensor.A
    rows = a[:, 0] * a[:, 0] + a[:, 1] * a[:, 1] + a[:, 2] * a[:, 2]
    return np.sqrt((plan.motion_g * plan.motion_g)[:, None] * rows + sensor.noise_g * sensor.noise_g)


def _idle_source(idle: np.ndarray) -> np.ndarray:
    """For each epoch, the last non-idle epoch at or before it (−1 when none), shape (n,)."""
    return np.maximum.accumulate(np.where(idle, -1, np.arange(idle.shape[0])))


@dataclass(frozen=True, eq=False)
class EpochStats:
    """Epoch statistics of one file: ``mean_g`` and ``sd_g`` (n, 3), g; ``temperature_c`` (n,), °C."""

    mean_g: np.ndarray
    sd_g: np.ndarray
    temperature_c: np.ndarray


def draw_epochs(sensor: WearSensor, plan: WearPlan, samples_per_epoch: int,
                rng: np.random.Generator) -> EpochStats:
    """Draw every epoch's mean and sd from their exact distributions (module docstring).

    Parameters
    ----------
    sensor, plan
        The device and what its wearer does.
    samples_per_epoch
        N, the samples each epoch stands for.
    rng
        Random generator: z₁, z₂, χ², then the two normals of each epoch's last sample, (n, 3) each.

    Returns
    -------
    EpochStats
        The temperature is the plan's.
    """
    n, big_n = plan.n, samples_per_epoch
    z_motion, z_noise = rng.standard_normal((n, 3)), rng.standard_normal((n, 3))
    chi2 = rng.chisquare(big_n - 1, (n, 3))
    last_motion, last_noise = rng.standard_normal((n, 3)), rng.standard_normal((n, 3))
    mu = expected_means(sensor, plan)
    motion = plan.motion_g[:, None]
    root = math.sqrt(big_n)
    mean = mu + (motion / root) * mul3(z_motion, sensor.A.T) + (sensor.noise_g / root) * z_noise
    sd = epoch_sigma(sensor, plan) * np.sqrt(chi2 / (big_n - 1))
    if plan.idle.any():
        last = mu + motion * mul3(last_motion, sensor.A.T) + sensor.noise_g * last_noise
        idle = plan.idle
        mean[idle] = last[_idle_source(idle)[idle]]
        sd[idle] = 0.0
    return EpochStats(mean, sd, plan.temperature_c.copy())


@dataclass(frozen=True, eq=False)
class RawChunk:
    """Raw samples of whole epochs.

    Attributes
    ----------
    first_epoch
        Index of the chunk's first epoch.
    counts
        (epochs, N, 3) int64 readings in units of 1e-5 g.
    temp_centi
        (epochs, N) int64 temperatures in units of 0.01 °C.
    """

    first_epoch: int
    counts: np.ndarray
    temp_centi: np.ndarray


def raw_samples(sensor: WearSensor, plan: WearPlan, rate_hz: float, rng: np.random.Generator,
                chunk_samples: int = CHUNK_SAMPLES) -> Iterator[RawChunk]:
    """Draw the samples of a file, chunk by chunk of whole epochs.

    Sample j of epoch k is at t = (k·N + j) / rate_hz s from the start; its temperature is the
    plan's epoch temperatures interpolated linearly between epoch centres. In an idle epoch every
    sample repeats the last sample before it exactly (the drawn ones are discarded, so that the
    draws do not depend on the idle pattern).

    Parameters
    ----------
    sensor, plan
        The device and what its wearer does.
    rate_hz
        Sample rate, Hz (``plan.epoch_s · rate_hz`` samples per epoch).
    rng
        Random generator: per chunk, the motion normals then the noise normals, (samples, 3) each.
    chunk_samples
        Samples per chunk at most (at least one epoch).

    Yields
    ------
    RawChunk
    """
    big_n = int(round(plan.epoch_s * rate_hz))
    per_chunk = max(1, chunk_samples // big_n)
    centres = (np.arange(plan.n) + 0.5) * plan.epoch_s
    carry = np.zeros(3, dtype=np.int64)
    for e0 in range(0, plan.n, per_chunk):
        e1 = min(plan.n, e0 + per_chunk)
        ne = e1 - e0
        t = np.arange(e0 * big_n, e1 * big_n) / rate_hz
        temp = np.interp(t, centres, plan.temperature_c)
        ep = np.repeat(np.arange(e0, e1), big_n)
        z_motion, z_noise = rng.standard_normal((ne * big_n, 3)), rng.standard_normal((ne * big_n, 3))
        true = (sensor.g_ratio * plan.rho[ep])[:, None] * plan.u[ep] + plan.motion_g[ep][:, None] * z_motion
        drift = sensor.temp_coeff_g_per_c * (temp - sensor.temp_ref_c)[:, None]
        f = mul3(true, sensor.A.T) + sensor.offset_g + drift + sensor.noise_g * z_noise
        counts = np.rint(f * 10.0**RAW_ACC_DECIMALS).astype(np.int64).reshape(ne, big_n, 3)
        idle = plan.idle[e0:e1]
        if idle.any():
            src = _idle_source(idle)
            fill = np.where((src >= 0)[:, None], counts[np.maximum(src, 0), -1, :], carry)
            counts[idle] = fill[idle][:, None, :]
        carry = counts[-1, -1, :].copy()
        temp_centi = np.rint(temp * 10.0**RAW_TEMP_DECIMALS).astype(np.int64).reshape(ne, big_n)
        yield RawChunk(e0, counts, temp_centi)


def epoch_stats(counts: np.ndarray, temp_centi: np.ndarray) -> EpochStats:
    """Epoch means and sds (N − 1 in the denominator) of raw samples, exact in integers.

    Parameters
    ----------
    counts
        (epochs, N, 3) int64 readings, 1e-5 g.
    temp_centi
        (epochs, N) int64 temperatures, 0.01 °C.

    Returns
    -------
    EpochStats
        The same on every machine: integer sums, then one division and one square root.
    """
    big_n = counts.shape[1]
    total = counts.sum(axis=1)
    centred = counts - (total // big_n)[:, None, :]
    s = centred.sum(axis=1)
    q = (centred * centred).sum(axis=1)
    scale = 10.0**RAW_ACC_DECIMALS
    mean = total / (big_n * scale)
    sd = np.sqrt((big_n * q - s * s) / float(big_n * (big_n - 1))) / scale
    temp = temp_centi.sum(axis=1) / (big_n * 10.0**RAW_TEMP_DECIMALS)
    return EpochStats(mean, sd, temp)


def ggir_coefficients(sensor: WearSensor, temp_mean_c: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """GGIR's coefficients that calibrate this device exactly when A is diagonal (module docstring).

    Parameters
    ----------
    sensor
        The device.
    temp_mean_c
        GGIR's ``meantempcal``, °C: the mean temperature of the still epochs it fitted.

    Returns
    -------
    offset, scale, temp_offset
        Shapes (3,): g (GGIR's sign, added before scaling), dimensionless, g/°C.
    """
    scale = 1.0 / (sensor.g_ratio * np.diag(sensor.A))
    temp_offset = -sensor.temp_coeff_g_per_c * scale
    offset = -(sensor.offset_g + sensor.temp_coeff_g_per_c * (temp_mean_c - sensor.temp_ref_c))
    return offset, scale, temp_offset
