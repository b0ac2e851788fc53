"""``ofbe-autocal --params FILE``: settings from a YAML file's ``autocal:`` section, flags over
them, every refusal naming the file and the key, and the settings of a run written beside its
summary so that the run can be repeated.

The data: two simulated free-living recordings (the ``tiny-free-living`` profile, 0.4 days of
epochs each). With the defaults, ``--mode ofbe`` calibrates ``wear-002`` (``full`` model) and not
``wear-001``, whose still epochs never come within 45° of −x; ``--mode ggir`` calibrates both.
"""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np
import pytest
import yaml

from ofbe_data.cli.autocal import main
from ofbe_data.core.errors import ConfigError
from ofbe_data.freeliving import EpochTable, GgirSettings, OfbeSettings, ofbe_calibrate
from ofbe_data.freeliving.params import (
    PARAMS_NAME,
    AutocalParams,
    autocal_params_from,
    load_autocal_params,
    params_yaml,
    with_overrides,
)
from tests.helpers.paths import ROOT

EXAMPLE = ROOT / "examples" / "autocal.yaml"
KEYS = ("alpha, coverage_deg, epoch_s, exclude_idle, max_condition, min_load_hours, mode, model, rate_hz, "
        "sphere_check, sphere_crit_g, still_sd_g, unit")
SPHERE = "recalibration not done because the sphere is not populated: no still epoch within 45° of -x"


@pytest.fixture(scope="module")
def wear(short_free_living: Path) -> Path:
    """The epochs folder of two simulated recordings (the session's, conftest.py: read only)."""
    return short_free_living / "fl" / "epochs"


def _rows(out: Path) -> dict[str, dict[str, str]]:
    with open(out / "summary.csv", newline="") as fh:
        return {Path(r["file"]).stem: r for r in csv.DictReader(fh)}


def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def test_the_example_file_holds_every_key_at_its_default_and_round_trips() -> None:
    data = yaml.safe_load(EXAMPLE.read_text(encoding="utf-8"))
    assert sorted(data["autocal"]) == sorted(KEYS.split(", "))  # every key documented in the example
    params = load_autocal_params(EXAMPLE)
    assert params == AutocalParams()
    assert params.ggir_settings() == GgirSettings() and params.ofbe_settings() == OfbeSettings()
    changed = dataclasses.replace(params, mode="ggir", still_sd_g=0.015, model="full+temperature",
                                  rate_hz=30.0, unit="mg", exclude_idle=False)
    assert autocal_params_from(yaml.safe_load(params_yaml(changed))["autocal"], "x") == changed
    assert params_yaml(changed) == params_yaml(dataclasses.replace(changed))  # the same bytes
    assert params_yaml(changed).decode().splitlines()[1:4] == ["autocal:", "  mode: ggir", "  epoch_s: 10.0"]


def test_the_file_sets_the_run_and_flags_given_override_it(wear: Path, tmp_path: Path,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    params = _write(tmp_path / "p.yaml", "autocal:\n  mode: ggir\n  sphere_check: false\n"
                                         "  model: scale-offset\n  still_sd_g: 0.02\n")
    out = tmp_path / "a"
    # --mode ofbe overrides the file's ggir; the file's model and sphere_check stay
    assert main([str(wear), "--out", str(out), "--params", str(params), "--mode", "ofbe", "--quiet"]) == 0
    rows = _rows(out)
    assert [r["mode"] for r in rows.values()] == ["ofbe", "ofbe"]
    assert [r["model"] for r in rows.values()] == ["ofbe scale-offset", "ofbe scale-offset"]
    assert rows["wear-001"]["calibrated"] == "true"  # fitted: the sphere check is off
    assert "scale-offset: forced" in rows["wear-001"]["qc"]
    written = load_autocal_params(out / PARAMS_NAME)
    assert written == AutocalParams(mode="ofbe", sphere_check=False, model="scale-offset", still_sd_g=0.02)
    # --sphere-check overrides the file's false
    out_b = tmp_path / "b"
    assert main([str(wear), "--out", str(out_b), "--params", str(params), "--mode", "ofbe", "--sphere-check",
                 "--quiet"]) == 0
    assert _rows(out_b)["wear-001"]["qc"] == SPHERE and _rows(out_b)["wear-001"]["calibrated"] == "false"
    # the file alone: ggir mode
    assert main([str(wear), "--out", str(tmp_path / "c"), "--params", str(params), "--quiet"]) == 0
    assert {r["mode"] for r in _rows(tmp_path / "c").values()} == {"ggir"}
    # the written settings repeat the run to the byte
    again = tmp_path / "again"
    assert main([str(wear), "--out", str(again), "--params", str(out / PARAMS_NAME), "--quiet"]) == 0
    first = {p.name: p.read_bytes() for p in out.iterdir()}
    assert {p.name: p.read_bytes() for p in again.iterdir()} == first
    assert capsys.readouterr().err == ""


def test_without_a_file_the_defaults_are_written(wear: Path, tmp_path: Path) -> None:
    assert main([str(wear / "wear-002.csv"), "--out", str(tmp_path / "o"), "--quiet"]) == 0
    assert (tmp_path / "o" / PARAMS_NAME).read_bytes() == params_yaml(AutocalParams())
    assert _rows(tmp_path / "o")["wear-002"]["model"] == "ofbe full"


def test_an_unknown_key_is_refused_with_the_file_the_key_and_the_closest_key(
        wear: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    params = _write(tmp_path / "p.yaml", "autocal:\n  mode: ofbe\n  stil_sd_g: 0.02\n")
    assert main([str(wear), "--out", str(tmp_path / "o"), "--params", str(params)]) == 2
    assert capsys.readouterr().err == (f"ofbe-autocal: error: {params}: autocal.stil_sd_g: expected one of "
                                       f"{KEYS}, found an unknown key (did you mean still_sd_g?)\n")
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(("text", "message"), [
    ("autocal:\n  still_sd_g: abc\n", "autocal.still_sd_g: expected a number, found 'abc'"),
    ("autocal:\n  mode: fast\n", "autocal.mode: expected ofbe or ggir, found 'fast'"),
    ("autocal:\n  sphere_check: 1\n", "autocal.sphere_check: expected true or false, found 1"),
    ("autocal:\n  coverage_deg: 120\n",
     "autocal.coverage_deg: expected a number of degrees above 0 and at most 90, found 120.0"),
    ("autocal:\n  alpha: 1.5\n", "autocal.alpha: expected a number between 0 and 1, found 1.5"),
    ("autocal:\n  min_load_hours: -1\n", "autocal.min_load_hours: expected a positive number, found -1.0"),
    ("autocal:\n  model: fulll\n", "autocal.model: expected auto or one of offset, scale-offset, full, "
                                   "offset+temperature, scale-offset+temperature, full+temperature, "
                                   "found 'fulll'"),
    ("autocal:\n  unit: counts\n", "autocal.unit: expected g, mg, m/s2 or null, found 'counts'"),
    ("autocal: [1, 2]\n", "autocal: expected a mapping of autocal parameters, found list"),
])
def test_a_bad_value_is_refused_with_the_file_and_the_key(tmp_path: Path, text: str, message: str) -> None:
    path = _write(tmp_path / "p.yaml", text)
    with pytest.raises(ConfigError) as err:
        load_autocal_params(path)
    assert str(err.value) == f"{path}: {message}"


def test_a_bad_flag_names_the_command_line_and_a_broken_file_its_line(
        wear: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(wear), "--out", str(tmp_path / "o"), "--still-sd-g", "-1"]) == 2
    assert capsys.readouterr().err == ("ofbe-autocal: error: command line: still_sd_g: expected a positive "
                                       "number, found -1.0 (given by --still-sd-g)\n")
    assert main([str(wear), "--out", str(tmp_path / "o"), "--rate", "0"]) == 2
    assert ("command line: rate_hz: expected a positive sample rate, Hz, or null, found 0.0 (given by --rate)"
            in capsys.readouterr().err)
    broken = _write(tmp_path / "b.yaml", "autocal:\n  mode: ofbe\n  model: [\n")
    assert main([str(wear), "--out", str(tmp_path / "o"), "--params", str(broken)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"ofbe-autocal: error: {broken}:") and err.count("\n") == 1
    assert main([str(wear), "--out", str(tmp_path / "o"), "--params", str(tmp_path / "missing.yaml")]) == 2
    assert "missing.yaml" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
    with pytest.raises(ValueError, match="expected keys among mode"):
        with_overrides(AutocalParams(), model="full")  # a setting no flag sets


def test_the_ofbe_settings_a_file_adds_change_the_fit() -> None:
    """``exclude_idle``, ``alpha`` and ``max_condition`` reach the ladder: idle epochs kept or left
    out; a Wald level that an ideal sensor's parameters pass takes the richer model; a condition
    limit no fit meets fits nothing."""
    rng = np.random.default_rng(3)
    u = rng.normal(size=(40, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    means = np.repeat(u * np.array([1.01, 0.99, 1.0]) + np.array([0.02, -0.01, 0.03]), 8, axis=0)
    means += rng.normal(0.0, 3e-4, means.shape)
    means[:8] = means[0]  # a run of repeated means: idle sleep
    table = EpochTable("t", means, np.full(means.shape, 0.004), None)
    default = ofbe_calibrate(table)
    assert default.n_idle == 8 and default.model == "scale-offset"  # no angles: full not significant
    assert "full not used: its 3 more parameters are ideal within their errors" in default.reason
    kept = ofbe_calibrate(table, AutocalParams(exclude_idle=False).ofbe_settings())
    assert kept.n_idle == 0 and kept.n_still == default.n_still + 8
    loose = ofbe_calibrate(table, AutocalParams(alpha=0.999).ofbe_settings())
    assert loose.model == "full" and "< 0.999" in loose.reason
    tight = ofbe_calibrate(table, AutocalParams(max_condition=1.0).ofbe_settings())
    assert tight.model is None and not tight.calibrated and "> 1e+00)" in tight.qc
