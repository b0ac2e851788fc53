"""Writing a free-living campaign (``kind: free-living``): epoch csv files, raw sample sessions, truth.

Layout of ``raw/<campaign>/`` for N files named ``<session_prefix>-001`` … (``output`` says which
of the first two are written)::

    epochs/<file>.csv                     one row per epoch: meanx,meany,meanz,sdx,sdy,sdz,temperature
    <file>/session.yaml                   a session of one recording, generic csv (raw-formats.md)
    <file>/rec-01/<file>.csv              t (Unix s), ax, ay, az (g), temperature (°C)
    _truth/<file>.json                    the device's truth (in three conventions), scenario, epoch counts
    _truth/<file>.segments.csv            the wearer's spells: state, epochs, gravity direction
    _truth/simulation.yaml                seed and resolved configuration

With ``output: both`` the epoch file holds the epochs of the raw file (computed in integers from
the written samples); with ``epochs`` they are drawn directly from their distributions
(:func:`~ofbe_data.simulator.freeliving.draw_epochs`). The device and the plan are the same in every
mode.

The truth of a device in three conventions: ``sensor``, the sensor model of docs/sensor-model.md
(readings in g are m/s² ÷ g0, raw-formats.md, of a specific force of g_local, so an ideal device
at rest reads g_local/g0, 0.99885 g at the default site); ``autocal``, the convention of
``ofbe-autocal``'s summary (``a_xx`` …, ``ofbe_offset_*``, ``ofbe_temp_slope_*``), whose unit is
local gravity: a calibration from still epochs alone knows no site and makes the reading 1 at
rest, so its A is g_local/g0 · the sensor's A, its offset and slope the sensor's; and ``ggir``,
GGIR's coefficients, which carry the same factor. Compare a summary with ``autocal`` or ``ggir``.
The last files may be QC scenarios (``free_living.scenarios``,
:data:`~ofbe_data.simulator.wearconfig.SCENARIOS`): the truth names the file's ``scenario`` and the
signed axes its still epochs never point within 45° of (``unseen_faces``).

Seeding follows the bench campaigns': file i (0-based) draws from the child ``spawn_key = (i + 1,)``
of ``SeedSequence(seed)``, split into ``(i + 1, 0)`` for the device, ``(i + 1, 1)`` for the plan and
``(i + 1, 2)`` for the epochs or samples. A file's bytes therefore depend on the seed, its index and
the configuration only, never on ``--jobs`` or the order of writing.
"""

from __future__ import annotations

import io
import json
import math
import os
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import yaml

from ofbe_data.core.atomic import atomic_directory, write_bytes_atomic
from ofbe_data.core.parallel import map_progress
from ofbe_data.core.precision import UNIT_DECIMALS, round_floats
from ofbe_data.io.device_options import CsvMapping
from ofbe_data.io.formats.writing import fixed_point
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import DeviceSpec, RecordingSpec, SessionManifest, Site, write_manifest
from ofbe_data.simulator.campaign import TRUTH_DECIMALS, TRUTH_FORMAT, truth_config
from ofbe_data.simulator.config import SimConfig
from ofbe_data.simulator.freeliving import (
    RAW_ACC_DECIMALS,
    RAW_TEMP_DECIMALS,
    EpochStats,
    WearSensor,
    already_calibrated,
    draw_epochs,
    draw_sensor,
    epoch_stats,
    ggir_coefficients,
    raw_samples,
)
from ofbe_data.simulator.wear import NO_STILL_MOTION_G, WearPlan, draw_plan
from ofbe_data.simulator.wearconfig import FREE_LIVING, FreeLivingConfig, scenario_of

EPOCH_HEADER = "meanx,meany,meanz,sdx,sdy,sdz,temperature"
"""The epoch csv's columns: GGIR's ``spheredata`` layout."""
EPOCH_DECIMALS = 6
"""Decimals of epoch means and sds, g (1 µg; more would make pyarrow write a small value as 5E-7)."""
EPOCH_TEMP_DECIMALS = 4
"""Decimals of epoch temperatures, °C."""
RAW_COLUMNS = ("t", "ax", "ay", "az", "temperature")
"""The raw csv's columns."""
TIME_DECIMALS = 6
"""Decimals of raw times, s."""
DEVICE_MODEL = "ADXL345"
"""The devices' model in the manifests (ADXL345-class noise by default)."""
RECORDING = "rec-01"
"""The one recording of each raw session."""


def settings(cfg: SimConfig) -> FreeLivingConfig:
    """The configuration's ``free_living`` section (its defaults when absent)."""
    return cfg.free_living or FreeLivingConfig()


def file_name(cfg: SimConfig, index: int) -> str:
    """Name of file ``index`` (0-based): ``<session_prefix>-<NNN>``; also its session and device id."""
    return f"{cfg.session_prefix}-{index + 1:03d}"


def file_seeds(seed: int, index: int) -> tuple[np.random.SeedSequence, np.random.SeedSequence,
                                                np.random.SeedSequence]:
    """The device, plan and data seed sequences of file ``index`` (module docstring)."""
    return tuple(np.random.SeedSequence(seed, spawn_key=(index + 1, k)) for k in range(3))  # type: ignore[return-value]


def site_of(cfg: SimConfig) -> Site:
    """The configuration's site (gravity override, or latitude and height)."""
    s = cfg.site
    if "gravity_mps2" in s:
        return Site(gravity_mps2=float(s["gravity_mps2"]))
    return Site(latitude_deg=float(s["latitude_deg"]), height_m=float(s.get("height_m", 0.0)))


def start_of(cfg: SimConfig) -> tuple[datetime, float]:
    """``start_utc`` and its hour of the day (taken as the wearer's local time), h."""
    start = datetime.fromisoformat(cfg.start_utc.replace("Z", "+00:00"))
    return start, start.hour + start.minute / 60.0 + (start.second + start.microsecond * 1e-6) / 3600.0


@dataclass(frozen=True, eq=False)
class WearFile:
    """One simulated file before its samples: name, device truth, plan and scenario (None: ordinary)."""

    name: str
    sensor: WearSensor
    plan: WearPlan
    g_local: float
    scenario: str | None = None


def simulate_wear_file(cfg: SimConfig, index: int, seed: int | None = None) -> WearFile:
    """Draw file ``index``'s device and plan (no samples, no files): for writing, statistics and tests.

    Parameters
    ----------
    cfg
        A free-living configuration.
    index
        0-based file index.
    seed
        Seed (defaults to ``cfg.seed``).

    Returns
    -------
    WearFile
    """
    fl = settings(cfg)
    scenario = scenario_of(fl, cfg.sessions, index)
    dev_seq, plan_seq, _ = file_seeds(cfg.seed if seed is None else seed, index)
    g_local = site_of(cfg).g_local
    sensor = draw_sensor(cfg.dut_model, fl, g_local / G0, np.random.default_rng(dev_seq))
    if scenario == "already-calibrated":
        sensor = already_calibrated(sensor)
    placement, idle, per_day, night, tremor = (fl.placement, fl.idle_sleep, fl.nonwear_per_day,
                                               fl.nonwear_night_prob, 0.0)
    if scenario in ("no-still", "poor-coverage"):  # worn day and night, never taken off
        per_day, night = 0.0, 0.0
    if scenario == "no-still":
        tremor = NO_STILL_MOTION_G
    elif scenario == "poor-coverage":
        placement = "hip"
    elif scenario == "idle-sleep":
        idle = True
    plan = draw_plan(placement, fl.n_epochs, fl.epoch_s, start_of(cfg)[1], idle_sleep=idle,
                     nonwear_per_day=per_day, nonwear_night_prob=night, tremor_g=tremor,
                     rng=np.random.default_rng(plan_seq))
    return WearFile(file_name(cfg, index), sensor, plan, g_local, scenario)


COVERAGE_COS = math.cos(math.radians(45.0))
"""A signed axis is seen when a still epoch's gravity direction is within 45° of it (ofbe-autocal's
coverage rule, docs/free-living.md)."""


def unseen_faces(plan: WearPlan) -> list[str]:
    """Signed axes (``+x`` … ``-z``, in that order) that no still, non-idle epoch of the plan points
    within 45° of: what ``ofbe-autocal``'s coverage rule should name."""
    u = plan.u[plan.still & ~plan.idle]
    out = []
    for k, axis in enumerate("xyz"):
        for sign, word in ((1.0, "+"), (-1.0, "-")):
            if not (u.shape[0] and float(np.max(sign * u[:, k])) > COVERAGE_COS):
                out.append(word + axis)
    return out


def simulate_wear_epochs(cfg: SimConfig, wear: WearFile, index: int, seed: int | None = None) -> EpochStats:
    """The epoch writer's epochs of file ``index`` (``output: epochs``), in memory."""
    _, _, data_seq = file_seeds(cfg.seed if seed is None else seed, index)
    rng = np.random.default_rng(data_seq)
    return draw_epochs(wear.sensor, wear.plan, settings(cfg).samples_per_epoch, rng)


def _decimal(ints: np.ndarray, decimals: int) -> pa.Array:
    """A pyarrow decimal array printing the integers ``ints`` · 10^−decimals exactly."""
    ints = np.ascontiguousarray(ints, dtype=np.int64)
    words = np.empty((ints.shape[0], 2), dtype=np.int64)
    words[:, 0] = ints
    words[:, 1] = np.where(ints < 0, -1, 0)
    buffers = [None, pa.py_buffer(words.tobytes())]
    return pa.Array.from_buffers(pa.decimal128(38, decimals), ints.shape[0], buffers)


def _csv_lines(columns: list[pa.Array]) -> bytes:
    """Data lines of equal-length columns, no header."""
    table = pa.table(columns, names=[f"c{i}" for i in range(len(columns))])
    buf = io.BytesIO()
    pacsv.write_csv(table, buf, pacsv.WriteOptions(include_header=False, quoting_style="none"))
    return buf.getvalue()


def epoch_csv(stats: EpochStats) -> bytes:
    """The bytes of an epoch csv (header :data:`EPOCH_HEADER`), values rounded as written."""
    cols = [fixed_point(stats.mean_g[:, k], EPOCH_DECIMALS) for k in range(3)]
    cols += [fixed_point(stats.sd_g[:, k], EPOCH_DECIMALS) for k in range(3)]
    cols.append(fixed_point(stats.temperature_c, EPOCH_TEMP_DECIMALS))
    return (EPOCH_HEADER + "\n").encode() + _csv_lines(cols)


def raw_mapping(rate_hz: float) -> CsvMapping:
    """How ofbe's generic csv reader reads the raw files."""
    return CsvMapping(columns={c: c for c in RAW_COLUMNS}, time_unit="s", acc_unit="g",
                      sample_rate_hz=rate_hz)


def _write_raw(cfg: SimConfig, wear: WearFile, data_seq: np.random.SeedSequence, path: Path,
               start_us: int) -> EpochStats:
    """Write the raw csv chunk by chunk; return the epochs of the samples written."""
    fl = settings(cfg)
    big_n = fl.samples_per_epoch
    means, sds, temps = [], [], []
    with open(path, "wb") as fh:
        fh.write((",".join(RAW_COLUMNS) + "\n").encode())
        for chunk in raw_samples(wear.sensor, wear.plan, fl.rate_hz, np.random.default_rng(data_seq)):
            ne = chunk.counts.shape[0]
            index = np.arange(chunk.first_epoch * big_n, (chunk.first_epoch + ne) * big_n)
            t_us = start_us + np.rint(index / fl.rate_hz * 1e6).astype(np.int64)
            flat = chunk.counts.reshape(-1, 3)
            cols = [_decimal(t_us, TIME_DECIMALS)]
            cols += [_decimal(flat[:, k], RAW_ACC_DECIMALS) for k in range(3)]
            cols.append(_decimal(chunk.temp_centi.reshape(-1), RAW_TEMP_DECIMALS))
            fh.write(_csv_lines(cols))
            stats = epoch_stats(chunk.counts, chunk.temp_centi)
            means.append(stats.mean_g)
            sds.append(stats.sd_g)
            temps.append(stats.temperature_c)
    return EpochStats(np.concatenate(means), np.concatenate(sds), np.concatenate(temps))


def _write_session(cfg: SimConfig, wear: WearFile, campaign: str, folder: Path) -> None:
    """The raw session's manifest: one device, one recording, generic csv."""
    fl = settings(cfg)
    spec = DeviceSpec(wear.name, DEVICE_MODEL, "dut", "csv", None, csv=raw_mapping(fl.rate_hz))
    rec = RecordingSpec(RECORDING, {wear.name: f"{RECORDING}/{wear.name}.csv"})
    manifest = SessionManifest(folder, campaign, wear.name, "multi-position", site_of(cfg), 1,
                               {wear.name: spec}, (rec,))
    write_manifest(manifest, folder / "session.yaml")


def truth_of(cfg: SimConfig, wear: WearFile, campaign: str) -> dict[str, Any]:
    """The truth JSON of one file (before rounding).

    GGIR's ``offset_at_temp_ref`` is its offset for T̄ = ``temp_ref_c``; for another T̄ add
    −temp_coeff·(T̄ − temp_ref_c) (:func:`~ofbe_data.simulator.freeliving.ggir_coefficients`).
    """
    fl = settings(cfg)
    s = wear.sensor
    offset, scale, temp_offset = ggir_coefficients(s, s.temp_ref_c)
    outputs = {"epochs": None if fl.output == "raw" else f"epochs/{wear.name}.csv",
               "raw": None if fl.output == "epochs" else f"{wear.name}/{RECORDING}/{wear.name}.csv",
               "segments": f"_truth/{wear.name}.segments.csv"}
    return {
        "format": TRUTH_FORMAT, "campaign": campaign, "file": wear.name, "kind": FREE_LIVING,
        "scenario": wear.scenario, "unseen_faces": unseen_faces(wear.plan),
        "device": wear.name, "placement": wear.plan.placement, "start_utc": cfg.start_utc, "days": fl.days,
        "epoch_s": fl.epoch_s, "epochs": wear.plan.n, "rate_hz": fl.rate_hz,
        "samples_per_epoch": fl.samples_per_epoch,
        "idle_sleep": fl.idle_sleep or wear.scenario == "idle-sleep", "outputs": outputs,
        "g_local": wear.g_local, "g_local_in_g0": s.g_ratio,
        "sensor_model": "reading (g) = A . (g_local/g0 . rho . u + motion) + offset + temp_coeff . "
                        "(T - temp_ref_c) + noise; A = (I + diag(scale)) . T(nonorthogonality_rad), "
                        "imu_tk's convention (docs/sensor-model.md)",
        "sensor": {
            "offset_mg": (s.offset_g * 1e3).tolist(), "scale": s.scale.tolist(),
            "nonorthogonality_rad": s.nonorth_rad.tolist(), "A": s.A.tolist(),
            "temp_coeff_mg_per_c": (s.temp_coeff_g_per_c * 1e3).tolist(), "temp_ref_c": s.temp_ref_c,
            "noise_density_ug": s.noise_density_ug.tolist(), "noise_rms_mg": (s.noise_g * 1e3).tolist(),
        },
        "autocal": {
            "model": "raw = A . u + b + c . (T - temp_mean_c), |u| = 1 at rest (ofbe-autocal's summary: "
                     "a_xx..a_zz, ofbe_offset_*, ofbe_temp_slope_*); 1 = local gravity, so A = "
                     "g_local/g0 . sensor.A",
            "A": (s.g_ratio * s.A).tolist(), "offset_at_temp_ref_g": s.offset_g.tolist(),
            "temp_slope_g_per_c": s.temp_coeff_g_per_c.tolist(),
            "offset_rule": "b = offset_at_temp_ref_g + temp_slope_g_per_c . (temp_mean_c - temp_ref_c)",
        },
        "ggir": {
            "model": "calibrated = (raw + offset) . scale + (T - temp_mean_c) . temp_offset",
            "scale": scale.tolist(), "temp_offset_g_per_c": temp_offset.tolist(),
            "offset_at_temp_ref_g": offset.tolist(),
            "offset_rule": "offset = -(offset_mg/1000 + temp_coeff_mg_per_c/1000 . "
                           "(temp_mean_c - temp_ref_c)); exact when A is diagonal",
        },
        "temperature_c": [float(wear.plan.temperature_c.min()), float(wear.plan.temperature_c.max())],
        **wear.plan.counts(),
    }


def segments_csv(plan: WearPlan) -> bytes:
    """The bytes of ``_truth/<file>.segments.csv``: one line per spell (u empty when moving)."""
    lines = ["state,first_epoch,epochs,still,idle_epochs,ux,uy,uz"]
    for seg in plan.segments():
        u = ",,"
        if seg["still"]:
            u = ",".join(f"{round(v, UNIT_DECIMALS) + 0.0:.{UNIT_DECIMALS}f}" for v in seg["u"])
        lines.append(f"{seg['state']},{seg['first_epoch']},{seg['epochs']},{str(seg['still']).lower()},"
                     f"{seg.get('idle_epochs', 0)},{u}")
    return ("\n".join(lines) + "\n").encode()


def _write_one(args: tuple[SimConfig, int, int, str, Path]) -> tuple[int, int]:
    """Simulate and write file ``index``; (files written, bytes written)."""
    cfg, seed, index, campaign, tmp = args
    fl = settings(cfg)
    wear = simulate_wear_file(cfg, index, seed)
    paths: list[Path] = []
    if fl.output != "epochs":
        folder = tmp / wear.name
        (folder / RECORDING).mkdir(parents=True)
        start_us = (start_of(cfg)[0] - datetime(1970, 1, 1, tzinfo=UTC)) // timedelta(microseconds=1)
        raw = folder / RECORDING / f"{wear.name}.csv"
        stats = _write_raw(cfg, wear, file_seeds(seed, index)[2], raw, start_us)
        _write_session(cfg, wear, campaign, folder)
        paths += [raw, folder / "session.yaml"]
    else:
        stats = simulate_wear_epochs(cfg, wear, index, seed)
    if fl.output != "raw":
        paths.append(tmp / "epochs" / f"{wear.name}.csv")
        write_bytes_atomic(paths[-1], epoch_csv(stats))
    truth = round_floats(truth_of(cfg, wear, campaign), TRUTH_DECIMALS)
    paths += [tmp / "_truth" / f"{wear.name}.json", tmp / "_truth" / f"{wear.name}.segments.csv"]
    write_bytes_atomic(paths[-2], (json.dumps(truth, indent=1) + "\n").encode())
    write_bytes_atomic(paths[-1], segments_csv(wear.plan))
    return len(paths), sum(p.stat().st_size for p in paths)


def write_free_living(cfg: SimConfig, out: Path, seed: int, campaign: str, *, jobs: int = 1,
                      force: bool = False, progress: bool = True, scheduler: str = "processes",
                      ) -> tuple[int, int]:
    """Write a free-living campaign into ``out`` (built beside it, renamed when complete).

    Parameters
    ----------
    cfg
        A free-living configuration (``cfg.sessions`` files).
    out
        Campaign folder.
    seed
        Seed.
    campaign
        Campaign id (manifests, truth).
    jobs, progress, scheduler
        As :func:`~ofbe_data.core.parallel.map_progress`.
    force
        Replace an existing ``out``.

    Returns
    -------
    files, bytes
        Files written (truth included) and their size.
    """
    scenario_of(settings(cfg), cfg.sessions, 0)  # too many scenario files: a ConfigError before any work
    with atomic_directory(out, replace=force) as tmp:
        (tmp / "_truth").mkdir()
        if settings(cfg).output != "raw":
            (tmp / "epochs").mkdir()
        tasks = [(cfg, seed, i, campaign, tmp) for i in range(cfg.sessions)]
        written = map_progress(_write_one, tasks, jobs=min(jobs, os.cpu_count() or 1),
                               desc=f"simulate {campaign}", unit="file", progress=progress,
                               scheduler=scheduler, name=lambda t: f"file {file_name(cfg, t[2])}")
        text = yaml.safe_dump(truth_config(cfg, seed, campaign), sort_keys=False)
        write_bytes_atomic(tmp / "_truth" / "simulation.yaml", text.encode())
    return sum(f for f, _ in written) + 1, sum(s for _, s in written) + len(text.encode())
