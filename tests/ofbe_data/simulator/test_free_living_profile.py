"""The ``free-living`` simulator profiles (docs/sensor-model.md, "Free-living recordings"): wearables
worn for days, written as GGIR-style epoch csv files and raw sample sessions, with their truth."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from ofbe_data.cli.simulate import main as simulate_main
from ofbe_data.core.errors import ConfigError
from ofbe_data.freeliving import EpochTable, GgirSettings, apply_ggir, ggir_calibrate, read_epoch_csv
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.gravity import G0
from ofbe_data.io.manifest import load_manifest
from ofbe_data.io.recording import TEMPERATURE
from ofbe_data.simulator import builtin_profiles, load_config, simulate_campaign
from ofbe_data.simulator.freeliving import epoch_sigma, expected_means
from ofbe_data.simulator.physics import sensor_matrix
from ofbe_data.simulator.wear import STATES
from ofbe_data.simulator.wearconfig import SCENARIOS
from ofbe_data.simulator.wearfiles import simulate_wear_epochs, simulate_wear_file, unseen_faces

TINY = "tiny-free-living"
NO_SCENARIOS = {name: 0 for name in SCENARIOS}
NAMES = ["wear-001", "wear-002", "wear-003"]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tiny campaign, written by the command with one job."""
    out = tmp_path_factory.mktemp("fl") / "tiny"
    assert simulate_main([TINY, "--out", str(out), "--jobs", "1", "--quiet"]) == 0
    return out


def _files(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def _z_and_ratio(mean: np.ndarray, sd: np.ndarray, mu: np.ndarray, sigma: np.ndarray, n: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Epoch means as z-scores against the model, and sd² / σ² (χ²_{n−1}/(n − 1) under the model)."""
    return ((mean - mu) / (sigma / np.sqrt(n))).ravel(), ((sd / sigma) ** 2).ravel()


def test_the_profiles_and_their_checks() -> None:
    assert {"free-living", "tiny-free-living"} <= set(builtin_profiles())
    full, tiny = load_config("free-living"), load_config(TINY)
    assert full.kind == tiny.kind == "free-living" and full.reference is None
    assert full.free_living is not None and tiny.free_living is not None
    assert full.sessions >= 50 and full.free_living.days == 7.0 and full.free_living.output == "epochs"
    assert full.free_living.scenarios == {name: 2 for name in SCENARIOS}  # the last 8 of 58 files
    assert full.sessions - sum(full.free_living.scenarios.values()) == 50
    assert sum(tiny.free_living.scenarios.values()) == 0
    assert full.free_living.placement == "wrist" and full.free_living.n_epochs == 7 * 8640
    assert tiny.sessions == 3 and tiny.free_living.output == "both" and tiny.free_living.rate_hz == 30.0
    assert tiny.free_living.samples_per_epoch == 300
    assert tiny.free_living.noise_density_ug == (290.0, 290.0, 430.0)
    with pytest.raises(ConfigError) as info:
        load_config(TINY, {"free_living": {"output": "csv"}})
    assert str(info.value) == ("tiny-free-living: free_living.output: expected one of epochs, raw, both, "
                               "found 'csv'")
    with pytest.raises(ConfigError) as info:
        load_config(TINY, {"free_living": {"rate_hz": 33.33}})
    assert str(info.value) == ("tiny-free-living: free_living.rate_hz: expected epoch_s × rate_hz a whole "
                               "number of samples in 2..6000, found 10 s × 33.33 Hz = 333.3")
    with pytest.raises(ConfigError) as info:
        load_config(TINY, {"free_living": {"rate": 30}})
    assert str(info.value).startswith("tiny-free-living: free_living.rate: expected one of days, epoch_s, ")
    assert str(info.value).endswith("found an unknown key (did you mean rate_hz?)")
    with pytest.raises(ConfigError) as info:
        load_config("rotated", {"free_living": {"days": 1.0}})
    assert str(info.value) == ("rotated: free_living: expected no free_living section for kind rotated, "
                               "found one")


def test_files_and_truth_match_what_was_simulated(tiny: Path) -> None:
    cfg = load_config(TINY)
    assert (tiny / "_truth" / "simulation.yaml").is_file()
    for i, name in enumerate(NAMES):
        wear = simulate_wear_file(cfg, i)
        truth = json.loads((tiny / "_truth" / f"{name}.json").read_text())
        s = truth["sensor"]
        assert truth["kind"] == "free-living" and truth["epochs"] == wear.plan.n == 432
        assert np.allclose(s["offset_mg"], wear.sensor.offset_g * 1e3, rtol=0, atol=1e-9)
        assert np.allclose(s["temp_coeff_mg_per_c"], wear.sensor.temp_coeff_g_per_c * 1e3, rtol=0, atol=1e-9)
        assert np.allclose(s["A"], sensor_matrix(np.array(s["scale"]), np.array(s["nonorthogonality_rad"])),
                           rtol=0, atol=1e-11)
        assert np.allclose(s["noise_rms_mg"], np.array([290.0, 290.0, 430.0]) * 1e-3 * np.sqrt(15.0), rtol=0,
                           atol=1e-9)
        assert {k: truth[k] for k in wear.plan.counts()} == wear.plan.counts()
        # the spells in the segments file rebuild the plan's states and still epochs
        lines = (tiny / "_truth" / f"{name}.segments.csv").read_text().splitlines()[1:]
        state, still = np.full(wear.plan.n, -1), np.zeros(wear.plan.n, dtype=bool)
        for line in lines:
            cells = line.split(",")
            first, count = int(cells[1]), int(cells[2])
            state[first:first + count] = STATES.index(cells[0])
            still[first:first + count] = cells[3] == "true"
            if cells[3] == "true":
                assert np.allclose([float(c) for c in cells[5:8]], wear.plan.u[first], rtol=0, atol=1e-9)
        assert np.array_equal(state, wear.plan.state) and np.array_equal(still, wear.plan.still)
        epochs = read_epoch_csv(tiny / "epochs" / f"{name}.csv")
        assert epochs.n == 432 and epochs.temperature_c is not None
        assert (tiny / name / "rec-01" / f"{name}.csv").is_file()
    states = {e for i in range(3) for e in simulate_wear_file(cfg, i).plan.state.tolist()}
    assert states >= {STATES.index("sit"), STATES.index("sleep")}


def test_jobs_give_the_same_bytes(tiny: Path, tmp_path: Path) -> None:
    simulate_campaign(TINY, tmp_path / "tiny", jobs=2, progress=False)
    assert _files(tmp_path / "tiny") == _files(tiny)


def test_raw_samples_agree_with_the_epoch_model(tiny: Path) -> None:
    """Epochs computed here (floats, numpy) from the raw samples that ofbe's generic csv reader reads
    have the model's distribution, as do the epoch writer's epochs of the same plans; and the epoch csv
    of ``output: both`` holds the raw file's epochs."""
    cfg = load_config(TINY)
    n = 300
    raw_z, raw_r, drawn_z, drawn_r = [], [], [], []
    for i, name in enumerate(NAMES):
        wear = simulate_wear_file(cfg, i)
        m = load_manifest(tiny / name)
        rec = read_device_file(tiny / name / m.recordings[0].files[name], m.devices[name])
        assert rec.acc.shape == (432 * n, 3) and rec.diagnostics.samples == 432 * n
        acc = (rec.acc / G0).reshape(432, n, 3)
        mean, sd = acc.mean(axis=1), acc.std(axis=1, ddof=1)
        temp = rec.extra[TEMPERATURE].reshape(432, n).mean(axis=1)
        written = read_epoch_csv(tiny / "epochs" / f"{name}.csv")
        assert np.allclose(written.mean_g, mean, rtol=0, atol=6e-7)  # 6 decimals
        assert np.allclose(written.sd_g, sd, rtol=0, atol=6e-7)
        assert np.allclose(written.temperature_c, temp, rtol=0, atol=6e-5)
        assert np.abs(temp - wear.plan.temperature_c).max() < 0.01
        mu, sigma = expected_means(wear.sensor, wear.plan), epoch_sigma(wear.sensor, wear.plan)
        z, r = _z_and_ratio(mean, sd, mu, sigma, n)
        raw_z.append(z)
        raw_r.append(r)
        drawn = simulate_wear_epochs(cfg, wear, i)
        z, r = _z_and_ratio(drawn.mean_g, drawn.sd_g, mu, sigma, n)
        drawn_z.append(z)
        drawn_r.append(r)
    pooled = [(np.concatenate(z), np.concatenate(r)) for z, r in ((raw_z, raw_r), (drawn_z, drawn_r))]
    for z, r in pooled:
        k = z.size  # 3888: bounds at about 5 standard errors
        assert abs(z.mean()) < 5 / np.sqrt(k) and abs(z.std() - 1.0) < 5 / np.sqrt(2 * k)
        assert abs(r.mean() - 1.0) < 5 * np.sqrt(2 / (n - 1)) / np.sqrt(k)
        assert abs(r.std() - np.sqrt(2 / (n - 1))) < 0.1 * np.sqrt(2 / (n - 1))


def test_idle_sleep_repeats_samples_exactly(tmp_path: Path) -> None:
    cfg = load_config(TINY, {"sessions": 2, "free_living": {"idle_sleep": True}})
    simulate_campaign(cfg, tmp_path / "idle", progress=False)
    for i, name in enumerate(NAMES[:2]):
        wear = simulate_wear_file(cfg, i)
        idle = wear.plan.idle
        assert idle.sum() > 100 and not (idle & ~wear.plan.still).any()
        lines = (tmp_path / "idle" / name / "rec-01" / f"{name}.csv").read_bytes().splitlines()[1:]
        acc = np.array([line.split(b",")[1:4] for line in lines]).reshape(432, 300, 3)
        for k in np.flatnonzero(idle):  # each sample of an idle epoch: the last one before it, to the byte
            assert (acc[k] == acc[k - 1, -1]).all()
        written = read_epoch_csv(tmp_path / "idle" / "epochs" / f"{name}.csv")
        drawn = simulate_wear_epochs(cfg, wear, i)
        for mean, sd in ((written.mean_g, written.sd_g), (drawn.mean_g, drawn.sd_g)):
            assert np.array_equal(sd == 0.0, np.repeat(idle[:, None], 3, axis=1))
            repeat = idle[1:] & idle[:-1]
            assert np.array_equal(mean[1:][repeat], mean[:-1][repeat])
        rows = (tmp_path / "idle" / "epochs" / f"{name}.csv").read_text().splitlines()[1:]
        k = int(np.flatnonzero(idle[1:] & idle[:-1])[0]) + 1
        assert rows[k].split(",")[:6] == rows[k - 1].split(",")[:6] and rows[k].split(",")[3] == "0.000000"


def test_a_wrist_week_is_mostly_still_and_covers_the_sphere() -> None:
    cfg = load_config("free-living")
    for i in range(2):
        wear = simulate_wear_file(cfg, i)
        plan = wear.plan
        assert set(np.unique(plan.state).tolist()) == set(range(len(STATES)))
        assert 0.55 < plan.still.mean() < 0.8  # sleep, sedentary spells and non-wear
        assert 18.0 <= plan.temperature_c.min() < 22.0 and 32.0 < plan.temperature_c.max() <= 34.0
        epochs = simulate_wear_epochs(cfg, wear, i)
        table = EpochTable("week", epochs.mean_g, epochs.sd_g, epochs.temperature_c)
        ggir_still = np.all(table.sd_g < GgirSettings().still_sd_g, axis=1)
        assert np.array_equal(ggir_still, plan.still)  # the moving epochs' sd stays above 13 mg
        x = table.mean_g[ggir_still]
        assert (x.min(axis=0) < -0.3).all() and (x.max(axis=0) > 0.3).all()  # GGIR's sphere rule, every axis
        assert (np.abs(x) > 0.3).mean(axis=0).min() > 0.1


def _ggir_to_convergence(table: EpochTable) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """GGIR's model fitted by ``ggir_calibrate`` restarted on its own calibrated epochs until it stops
    moving, the coefficients composed: offset = o₁ + o₂/s₁, scale = s₁·s₂, temp_offset = τ₁·s₂ + τ₂."""
    offset, scale, temp_offset = np.zeros(3), np.ones(3), np.zeros(3)
    means, temp_mean = table.mean_g, 0.0
    for _ in range(300):
        r = ggir_calibrate(EpochTable(table.path, means, table.sd_g, table.temperature_c))
        assert r.calibrated and r.temp_mean_c is not None
        temp_mean = r.temp_mean_c
        offset, scale = offset + r.offset / scale, scale * r.scale
        temp_offset = temp_offset * r.scale + r.temp_offset
        means = apply_ggir(table.mean_g, table.temperature_c, scale, offset, temp_offset, temp_mean)
        if np.abs(r.offset).max() < 1e-6 and np.abs(r.scale - 1.0).max() < 1e-6:
            break
    return offset, scale, temp_offset, temp_mean


def test_ggir_recovers_the_truth_of_a_file_without_misalignment(tmp_path: Path) -> None:
    """The truth in GGIR's convention (``ggir`` in the truth file): scale = 1/(g_local/g0 · A_kk),
    temp_offset = −temp_coeff · scale, offset = −(offset + temp_coeff · (T̄ − temp_ref_c))."""
    cfg = load_config("free-living", {"sessions": 1, "dut_model": {"cross_axis_sigma_deg": 0.0},
                                      "free_living": {"days": 1.5, "scenarios": NO_SCENARIOS}})
    simulate_campaign(cfg, tmp_path / "week", progress=False)
    truth = json.loads((tmp_path / "week" / "_truth" / "wear-001.json").read_text())
    assert truth["sensor"]["nonorthogonality_rad"] == [0.0, 0.0, 0.0]
    table = read_epoch_csv(tmp_path / "week" / "epochs" / "wear-001.csv")
    offset, scale, temp_offset, temp_mean = _ggir_to_convergence(table)
    s, ggir = truth["sensor"], truth["ggir"]
    coeff = np.array(s["temp_coeff_mg_per_c"]) * 1e-3
    expected = -(np.array(s["offset_mg"]) * 1e-3 + coeff * (temp_mean - s["temp_ref_c"]))
    assert np.abs(offset - expected).max() < 1e-3  # 1 mg
    assert np.abs(scale - np.array(ggir["scale"])).max() < 1e-3
    assert np.abs(temp_offset - np.array(ggir["temp_offset_g_per_c"])).max() < 5e-5  # 0.05 mg/°C
    diagonal = 1.0 + np.array(s["scale"])
    assert np.allclose(ggir["scale"], 1.0 / (truth["g_local_in_g0"] * diagonal), rtol=0, atol=1e-11)
    assert np.allclose(ggir["offset_at_temp_ref_g"], -np.array(s["offset_mg"]) * 1e-3, rtol=0, atol=1e-11)


def test_the_profiles_scenario_files_are_what_they_say() -> None:
    """wear-051 … wear-058: 2 files of each scenario, after the 50 ordinary ones (plans and devices only)."""
    cfg = load_config("free-living")
    assert simulate_wear_file(cfg, 49).scenario is None
    for k, name in enumerate(SCENARIOS):
        for i in (50 + 2 * k, 51 + 2 * k):
            wear = simulate_wear_file(cfg, i)
            plan, sensor = wear.plan, wear.sensor
            assert wear.scenario == name and wear.name == f"wear-{i + 1:03d}"
            if name == "no-still":
                assert not plan.still.any() and plan.motion_g.min() >= 0.02
                assert not (plan.state == STATES.index("nonwear")).any()
            elif name == "poor-coverage":
                assert plan.placement == "hip" and plan.still.mean() > 0.5
                assert unseen_faces(plan) == ["-x"]
            elif name == "idle-sleep":
                assert plan.idle.sum() > 0.5 * plan.still.sum() and unseen_faces(plan) == []
            else:
                assert np.allclose(sensor.g_ratio * sensor.A, np.eye(3), rtol=0, atol=1e-15)
                assert not sensor.offset_g.any() and not sensor.temp_coeff_g_per_c.any()
                assert unseen_faces(plan) == []
