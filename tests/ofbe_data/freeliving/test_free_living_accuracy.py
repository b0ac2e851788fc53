"""``ofbe-autocal --mode ofbe`` against the ``free-living`` simulator's truth, on short files.

The acceptance (issue 35, docs/free-living.md "Accuracy on simulated wear") is measured on 58 week-long
files by ``benchmarks/freeliving_accuracy.py``; here the same checks run on one-day files of the same
profile (fixed seed): the tolerances scaled by √7 for a seventh of the data, the normalised errors
(error / the summary's standard error), and the QC outcome of each scenario file.
"""

from __future__ import annotations

import csv
import json
import math
import re
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from ofbe_data.cli.autocal import main as autocal
from ofbe_data.core.errors import ConfigError
from ofbe_data.simulator import load_config, simulate_campaign
from ofbe_data.simulator.wearconfig import SCENARIOS

DAYS = 1.0
SCALE = math.sqrt(7.0 / DAYS)
"""Errors shrink as 1/√(still epochs): a day has a seventh of a week's."""
OFFSET_MG, SCALE_TOL, SLOPE_MG_PER_C = 1.0 * SCALE, 1e-3 * SCALE, 0.2 * SCALE
ONE_EACH = {name: 1 for name in SCENARIOS}


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, dict[str, str]]]:
    """Three ordinary one-day files and one file of each scenario, calibrated by the command."""
    root = tmp_path_factory.mktemp("fl-accuracy")
    cfg = load_config("free-living", {"sessions": 3 + len(SCENARIOS), "seed": 11,
                                      "free_living": {"days": DAYS, "scenarios": ONE_EACH}})
    simulate_campaign(cfg, root / "campaign", progress=False)
    args = [str(root / "campaign" / "epochs"), "--out", str(root / "out"), "--jobs", "1", "--quiet"]
    assert autocal(args) == 0
    with open(root / "out" / "summary.csv", newline="") as fh:
        rows = {Path(r["file"]).stem: r for r in csv.DictReader(fh)}
    return root / "campaign", rows


def _truth(campaign: Path, name: str) -> dict:
    return json.loads((campaign / "_truth" / f"{name}.json").read_text())


@pytest.mark.slow  # the fixture: 7 one-day files simulated and calibrated, 10 s of CPU
def test_the_truth_is_written_in_the_summarys_convention(calibrated) -> None:
    """``autocal``: A relative to local gravity (the sensor's A times g_local/g0), as the fit's
    unit-sphere reading makes it; the offset and slope as the sensor's."""
    campaign, rows = calibrated
    for name in rows:
        truth = _truth(campaign, name)
        s, auto = truth["sensor"], truth["autocal"]
        assert np.allclose(auto["A"], truth["g_local_in_g0"] * np.array(s["A"]), rtol=0, atol=1e-11)
        assert np.allclose(auto["offset_at_temp_ref_g"], np.array(s["offset_mg"]) * 1e-3, rtol=0, atol=1e-11)
        assert np.allclose(auto["temp_slope_g_per_c"], np.array(s["temp_coeff_mg_per_c"]) * 1e-3, rtol=0,
                           atol=1e-11)
        assert abs(truth["g_local_in_g0"] - 1.0) > 1e-3  # the default site: dropping it would show


@pytest.mark.slow  # the fixture: 7 one-day files simulated and calibrated, 10 s of CPU
def test_offsets_scales_and_slopes_are_within_the_tolerances_and_their_standard_errors(calibrated) -> None:
    campaign, rows = calibrated
    out = campaign.parent / "out"
    z: list[float] = []
    fitted = 0
    for name, row in rows.items():
        truth = _truth(campaign, name)
        if truth["scenario"] not in (None, "idle-sleep") or truth["unseen_faces"]:
            continue
        # a day of idle sleep keeps one epoch per spell: 241 here, spanning 2.3 °C, too little for a slope
        model = "ofbe full" if truth["scenario"] else "ofbe full+temperature"
        assert row["calibrated"] == "true" and row["model"] == model, row["qc"]
        fitted += 1
        auto = truth["autocal"]
        c = np.array(auto["temp_slope_g_per_c"])
        if row["temp_mean_c"]:
            temp = float(row["temp_mean_c"])
        else:  # b is then the offset at the mean temperature of the epochs fitted
            ep = pq.read_table(out / f"{name}.epochs.parquet").to_pydict()
            temp = float(np.mean([t for t, u in zip(ep["temperature_c"], ep["used"], strict=True) if u]))
        b = np.array(auto["offset_at_temp_ref_g"]) + c * (temp - truth["sensor"]["temp_ref_c"])
        a = np.array(auto["A"])
        for k, axis in enumerate("xyz"):
            for col, true, tol in ((f"ofbe_offset_{axis}", b[k], OFFSET_MG * 1e-3),
                                   (f"a_{axis}{axis}", a[k, k], SCALE_TOL),
                                   (f"ofbe_temp_slope_{axis}", c[k], SLOPE_MG_PER_C * 1e-3)):
                if not row[col]:
                    continue
                est = float(row[col])
                assert abs(est - true) < tol, (name, col, est, true)
                z.append((est - true) / float(row[f"{col}_se"]))
        for i, j in ((0, 1), (0, 2), (1, 2)):
            col = f"a_{'xyz'[i]}{'xyz'[j]}"
            z.append((float(row[col]) - a[i, j]) / float(row[f"{col}_se"]))
    assert fitted == 3  # 2 of the 3 ordinary days cover the sphere (test below), and the idle-sleep one
    z_arr = np.array(z)
    assert np.abs(z_arr).max() < 4.0
    assert len(z) == 2 * 12 + 9 and 0.7 <= z_arr.std(ddof=1) <= 1.4, z_arr.std(ddof=1)


@pytest.mark.slow  # the fixture: 7 one-day files simulated and calibrated, 10 s of CPU
def test_each_scenario_gets_its_qc_outcome(calibrated) -> None:
    campaign, rows = calibrated
    seen = set()
    for name, row in rows.items():
        truth = _truth(campaign, name)
        scenario, qc = truth["scenario"], row["qc"]
        seen.add(scenario)
        if scenario == "no-still":
            assert qc == ("recalibration not done because no still epochs (standard deviation below 13 mg on "
                          "every axis and |mean| below 2 g)") and row["n_still"] == "0"
        elif scenario == "poor-coverage" or truth["unseen_faces"]:
            named = re.fullmatch(r"recalibration not done because the sphere is not populated: "
                                 r"no still epoch within 45° of ([-+xyz, ]+)", qc)
            assert named is not None, qc
            assert set(named.group(1).split(", ")) == set(truth["unseen_faces"])
            assert scenario != "poor-coverage" or truth["unseen_faces"] == ["-x"]  # a hip never upside down
            seen.add("ordinary, a day without -y" if truth["unseen_faces"] == ["-y"] else scenario)
        elif scenario == "idle-sleep":
            assert qc.startswith("recalibration done: ")
            assert qc.endswith(f"; {truth['idle_epochs']} idle-sleep epochs left out (standard deviation 0, "
                               "zero or repeated means)") and truth["idle_epochs"] > 1000
        elif scenario == "already-calibrated":
            assert qc.startswith("recalibration not done because recalibration does not decrease error (")
            assert row["calibrated"] == "false" and row["scale_x"] == "1.0" and row["offset_z"] == "0.0"
        else:
            assert qc.startswith("recalibration done: ")
        if scenario != "no-still":
            assert row["n_still"] != "0"
    assert seen == {None, "ordinary, a day without -y", *SCENARIOS}


def test_scenarios_are_checked() -> None:
    with pytest.raises(ConfigError) as info:
        load_config("free-living", {"free_living": {"scenarios": {"no-sleep": 1}}})
    assert str(info.value) == ("free-living: free_living.scenarios: expected scenario names among no-still, "
                               "poor-coverage, idle-sleep, already-calibrated, found 'no-sleep'")
    with pytest.raises(ConfigError) as info:
        load_config("free-living", {"free_living": {"scenarios": {"no-still": -1}}})
    assert str(info.value) == ("free-living: free_living.scenarios.no-still: expected a number of files "
                               ">= 0, found -1")
    with pytest.raises(ConfigError) as info:
        simulate_campaign(load_config("free-living", {"sessions": 5}), Path("/nonexistent/never-written"),
                          progress=False)
    assert str(info.value) == ("<config>: free_living.scenarios: expected at most sessions = 5 files in all "
                               "(counts of 0 for none), found 8")
