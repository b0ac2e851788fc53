"""``ofbe-autocal --mode ggir`` on epoch data: GGIR's ``g.calibrate`` reproduced (issue 35, first slice).

The reference is GGIR's own result on its own example (tests/data/ggir-calibrate/: the still
epochs of a real wrist recording and what g.calibrate returned for them). The QC texts are
written out here as GGIR words them (R/g.calibrate.R), not taken from ofbe's constants.
"""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from ofbe_data.cli.autocal import main
from ofbe_data.freeliving import EpochFileError, EpochTable, GgirSettings, ggir_calibrate, read_epoch_csv
from tests.helpers.paths import TESTS

DATA = TESTS / "data" / "ggir-calibrate"
SPHERE = DATA / "spheredata.csv"
GGIR = json.loads((DATA / "ggir_result.json").read_text())

COEF_TOL = 1e-6
"""Scale (1), offset (g) and temperature offset (g/°C): absolute."""
ERROR_TOL_G = 1e-5
"""cal.error.start / cal.error.end, g: GGIR 3.x itself reports them to 1e-5 g."""

DONE = "recalibration done, no problems detected"
DONE_NO_TEMP = "recalibration done, but temperature values not used"
ATTEMPTED = ("recalibration attempted with all available data, but possibly not good enough: "
             "Check calibration error variable to varify this")
NOT_DECREASED = "recalibration not done because recalibration does not decrease error"
SPHERE_NOT_POPULATED = "recalibration not done because not enough points on all sides of the sphere"
NO_STILL = "recalibration not done because no non-movement data available"
TOO_SHORT = "recalibration not done because not enough data in the file or because file is corrupt"


@pytest.fixture(scope="module")
def sphere() -> EpochTable:
    return read_epoch_csv(SPHERE)


def _ggir(name: str) -> np.ndarray:
    return np.asarray(GGIR[name], dtype=float)


def _assert_ggir_coefficients(scale, offset, temp_offset) -> None:
    assert np.abs(np.asarray(scale) - _ggir("scale")).max() < COEF_TOL
    assert np.abs(np.asarray(offset) - _ggir("offset")).max() < COEF_TOL
    assert np.abs(np.asarray(temp_offset) - _ggir("tempoffset")).max() < COEF_TOL


def _identity(result) -> bool:
    return (np.array_equal(result.scale, np.ones(3)) and np.array_equal(result.offset, np.zeros(3))
            and np.array_equal(result.temp_offset, np.zeros(3)))


def test_the_reader_takes_ggirs_spheredata_as_it_is(sphere: EpochTable) -> None:
    assert sphere.n == GGIR["npoints"][0] == 10958
    assert sphere.ggir_spheredata and sphere.temperature_c is not None
    first = SPHERE.read_text().splitlines()[1].split(",")
    assert sphere.mean_g[0].tolist() == [float(v) for v in first[1:4]]
    assert sphere.sd_g[0].tolist() == [float(v) for v in first[4:7]]
    assert sphere.temperature_c[0] == float(first[7])


def test_ggir_calibrate_gives_ggirs_result_back(sphere: EpochTable) -> None:
    r = ggir_calibrate(sphere, hours=GGIR["nhoursused"][0])
    _assert_ggir_coefficients(r.scale, r.offset, r.temp_offset)
    assert abs(r.cal_error_start - GGIR["cal.error.start"][0]) < ERROR_TOL_G
    assert abs(r.cal_error_end - GGIR["cal.error.end"][0]) < ERROR_TOL_G
    assert r.qc == GGIR["QCmessage"][0] == DONE
    assert r.calibrated and r.use_temp == GGIR["use.temp"][0] and r.n_still == GGIR["npoints"][0]
    assert r.model == "ggir scale-offset+temperature" and 1 < r.iterations < 1000
    assert r.temp_mean_c == pytest.approx(float(np.mean(sphere.temperature_c)), abs=1e-12)


def test_the_comparison_can_fail(sphere: EpochTable) -> None:
    """The tolerances are tight enough to see a small change of the data or the model."""
    first_dropped = EpochTable("x", sphere.mean_g[1:], sphere.sd_g[1:], sphere.temperature_c[1:], True)
    r = ggir_calibrate(first_dropped, hours=84.0)
    assert np.abs(r.scale - _ggir("scale")).max() > COEF_TOL  # one epoch of 10,958 fewer
    no_temperature = EpochTable("x", sphere.mean_g, sphere.sd_g, None, True)
    r = ggir_calibrate(no_temperature, hours=84.0)
    assert np.abs(r.offset - _ggir("offset")).max() > 100 * COEF_TOL
    assert r.qc == DONE and r.model == "ggir scale-offset" and not r.temp_offset.any()


def test_the_epochs_alone_are_too_few_hours_for_ggir_to_accept(sphere: EpochTable) -> None:
    """Without GGIR's 84 h, the 10,958 still epochs are 30.4 h < minloadcrit (72 h): GGIR's fit,
    its "attempted" message, and g.part1 still applies the coefficients (the error fell)."""
    r = ggir_calibrate(sphere)
    assert r.hours == pytest.approx(10958 * 10 / 3600)
    assert r.qc == ATTEMPTED and r.calibrated
    _assert_ggir_coefficients(r.scale, r.offset, r.temp_offset)


def test_the_sphere_must_be_populated_on_both_sides_of_every_axis(sphere: EpochTable) -> None:
    keep = sphere.mean_g[:, 0] > -0.3
    half = EpochTable("half", sphere.mean_g[keep], sphere.sd_g[keep], sphere.temperature_c[keep], True)
    r = ggir_calibrate(half, hours=84.0)
    assert r.qc == SPHERE_NOT_POPULATED and not r.calibrated and _identity(r)
    assert r.cal_error_start is not None and r.cal_error_end is None and r.n_still == keep.sum()
    unchecked = ggir_calibrate(half, GgirSettings(sphere_check=False), hours=84.0)
    assert unchecked.qc != SPHERE_NOT_POPULATED and unchecked.cal_error_end is not None


def _raw_epochs(sphere: EpochTable, rng: np.random.Generator) -> EpochTable:
    """GGIR's still epochs among epochs GGIR passes over: a first epoch (GGIR drops it), moving
    epochs (sd ≥ 13 mg on an axis), clipping ones (|mean| ≥ 2 g), an all-zero one; shuffled (the
    fit does not depend on the order)."""
    n_other = 500
    means = rng.normal(0, 0.6, (n_other, 3))
    sds = rng.uniform(0.002, 0.012, (n_other, 3))
    half = n_other // 2
    sds[np.arange(half), rng.integers(0, 3, half)] = rng.uniform(0.013, 0.3, half)  # moving
    means[half:, 1] = rng.choice([-1, 1], n_other - half) * rng.uniform(2, 8, n_other - half)  # clipping
    means[7] = 0.0  # an idle epoch
    order = rng.permutation(sphere.n + n_other)
    means = np.concatenate([sphere.mean_g, means])[order]
    sds = np.concatenate([sphere.sd_g, sds])[order]
    temps = np.concatenate([sphere.temperature_c, rng.uniform(20, 30, n_other)])[order]
    return EpochTable("raw", np.concatenate([[[0.1, 0.2, 0.97]], means]),
                      np.concatenate([[[0.004] * 3], sds]), np.concatenate([[25.0], temps]))


def test_ggirs_still_selection_finds_ggirs_still_epochs_among_the_others(sphere: EpochTable) -> None:
    epochs = _raw_epochs(sphere, np.random.default_rng(35))
    n = epochs.n
    assert not epochs.ggir_spheredata and n == 1 + sphere.n + 500
    r = ggir_calibrate(epochs, hours=84.0)
    assert r.n_still == sphere.n and r.qc == DONE and r.calibrated and not r.still[0]
    _assert_ggir_coefficients(r.scale, r.offset, r.temp_offset)
    assert abs(r.cal_error_end - GGIR["cal.error.end"][0]) < ERROR_TOL_G
    assert ggir_calibrate(epochs).hours == pytest.approx((n - 1) * 10 / 3600)  # the idle epoch is not data


def test_an_epoch_equal_to_the_next_in_exactly_three_values_is_dropped_as_ggir_does() -> None:
    rng = np.random.default_rng(3)
    means = rng.normal(size=(120, 3))
    means /= np.linalg.norm(means, axis=1)[:, None]
    sds = rng.uniform(0.002, 0.01, (120, 3))
    both = EpochTable("d", np.insert(means, 50, means[50], axis=0),
                      np.insert(sds, 50, sds[50] * 0.5, axis=0))  # same means, other sds
    assert ggir_calibrate(both).n_still == ggir_calibrate(EpochTable("d", means, sds)).n_still == 119
    same_sds = EpochTable("s", means, np.tile(sds[0], (120, 1)))  # every epoch: 3 values as the next
    assert ggir_calibrate(same_sds).qc == TOO_SHORT


@pytest.mark.parametrize("case, qc", [("none", TOO_SHORT), ("51", TOO_SHORT), ("moving", NO_STILL),
                                      ("nine", NO_STILL)])
def test_too_little_data_or_no_still_data_is_a_qc_outcome_not_an_error(case: str, qc: str) -> None:
    rng = np.random.default_rng(7)
    n = {"none": 0, "51": 51, "moving": 400, "nine": 400}[case]
    means = rng.normal(0, 0.5, (n, 3))
    sds = rng.uniform(0.02, 0.2, (n, 3))
    if case == "nine":
        sds[1:10] = rng.uniform(0.001, 0.01, (9, 3))
    r = ggir_calibrate(EpochTable(case, means, sds, rng.uniform(20, 30, n)))
    assert r.qc == qc and not r.calibrated and _identity(r)
    assert r.cal_error_start is None and r.cal_error_end is None and r.n_still == 0 and r.n_epochs == n


def test_a_fit_that_raises_the_error_is_not_applied() -> None:
    """Epochs on the unit sphere but a few 9 mg long on one side: GGIR's least squares spreads
    their error over all, so the mean error grows; g.part1 then keeps identity."""
    rng = np.random.default_rng(1)
    v = rng.normal(size=(200, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    v[np.argsort(-v[:, 0])[:8]] *= 1.009
    r = ggir_calibrate(EpochTable("grow", v, rng.uniform(0.004, 0.008, (200, 3))), hours=100.0)
    assert r.qc == NOT_DECREASED and not r.calibrated and _identity(r)
    assert r.cal_error_end > r.cal_error_start + 1e-5


def test_a_temperature_that_does_not_vary_is_not_used(sphere: EpochTable) -> None:
    flat = EpochTable("flat", sphere.mean_g, sphere.sd_g, np.full(sphere.n, 25.0), True)
    r = ggir_calibrate(flat, hours=84.0)
    assert not r.use_temp and r.qc == DONE_NO_TEMP and r.calibrated and not r.temp_offset.any()


@pytest.mark.parametrize("text, line, expected", [
    ("", 1, "expected a header line naming meanx"),
    ("meanx,meany,meanz,sdx,sdy\n1,2,3,4,5\n", 1, "found no sdz among 'meanx'"),
    ("meanx,meany,meanz,sdx,sdy,sdz\n0,0,1,0.01,0.01,0.01\n0,0,1,0.01,abc,0.01\n", 3,
     "expected a finite number in column 'sdy', found 'abc'"),
    ("meanx,meany,meanz,sdx,sdy,sdz,temperature\n0,0,1,0.01,0.01,0.01,NA\n", 2,
     "expected a finite number in column 'temperature', found 'NA'"),
    ("meanx,meany,meanz,sdx,sdy,sdz\n\n0,0,1,0.01,0.01\n", 3, "expected 6 fields (as the header), found 5"),
    ("meanx,meanx,meany,meanz,sdx,sdy,sdz\n", 1, "expected the column 'meanx' once"),
    (b"meanx,meany,meanz,sdx,sdy,sdz\n0,0,1,0.01,0.01,0.0\xff\n", 2,
     "expected UTF-8 text, found the byte 0xff"),
])
def test_a_bad_epoch_file_is_an_error_naming_file_line_and_what_was_found(tmp_path: Path, text, line: int,
                                                                         expected: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(EpochFileError) as err:
        read_epoch_csv(path)
    assert str(err.value).startswith(f"{path}:{line}: ") and expected in str(err.value)


def test_other_columns_are_ignored_and_a_header_only_file_is_no_epochs(tmp_path: Path) -> None:
    path = tmp_path / "e.csv"
    path.write_text('"","sdz","note","meanz","meany","meanx","sdy","sdx"\n'
                    '"1",0.003,hello,0.98,0.1,-0.2,0.002,0.001\n')
    t = read_epoch_csv(path)
    assert t.mean_g.tolist() == [[-0.2, 0.1, 0.98]] and t.sd_g.tolist() == [[0.001, 0.002, 0.003]]
    assert t.temperature_c is None and not t.ggir_spheredata
    path.write_text("meanx,meany,meanz,sdx,sdy,sdz\n")
    assert read_epoch_csv(path).n == 0 and ggir_calibrate(read_epoch_csv(path)).qc == TOO_SHORT


def _summary(out: Path) -> list[dict[str, str]]:
    with open(out / "summary.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def test_the_command_writes_ggirs_numbers_and_names_a_bad_file(tmp_path: Path, capsys) -> None:
    data = tmp_path / "in"
    data.mkdir()
    shutil.copy(SPHERE, data / "a-spheredata.csv")
    (data / "b-broken.csv").write_text("meanx,meany,meanz,sdx,sdy,sdz\n0,0,1,0.01,0.01\n")
    (data / "c-moving.csv").write_text("meanx,meany,meanz,sdx,sdy,sdz\n"
                                       + "0.1,0.2,0.9,0.05,0.06,0.07\n" * 3
                                       + "".join(f"0.1,0.2,0.9,0.05,0.06,{0.07 + k * 1e-4}\n"
                                                 for k in range(80)))
    (data / "d.cwa").write_bytes(b"MD")
    out = tmp_path / "out"
    argv = [str(data), str(data / "d.cwa"), "--out", str(out), "--mode", "ggir", "--quiet"]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert f"ofbe-autocal: error: {data / 'b-broken.csv'}:2: expected 6 fields" in err
    assert (f"ofbe-autocal: error: {data / 'd.cwa'} (byte 0): expected an Axivity .cwa header ('MD', 1024 "
            "bytes), found 2 bytes") in err
    rows = _summary(out)
    assert [Path(r["file"]).name for r in rows] == ["a-spheredata.csv", "c-moving.csv"]
    a, c = rows
    assert a["mode"] == "ggir" and a["model"] == "ggir scale-offset+temperature"
    assert a["n_epochs"] == a["n_still"] == "10958" and a["calibrated"] == "true" and a["qc"] == ATTEMPTED
    quantities = ("scale", "offset", "temp_offset")
    _assert_ggir_coefficients(*([float(a[f"{q}_{x}"]) for x in "xyz"] for q in quantities))
    assert abs(float(a["cal_error_start_mg"]) / 1000 - GGIR["cal.error.start"][0]) < ERROR_TOL_G
    assert abs(float(a["cal_error_end_mg"]) / 1000 - GGIR["cal.error.end"][0]) < ERROR_TOL_G
    assert c["qc"] == NO_STILL and c["calibrated"] == "false" and c["cal_error_start_mg"] == ""
    assert [c[f"scale_{x}"] for x in "xyz"] == ["1.0"] * 3 and c["temp_mean_c"] == ""
    new = [k for k in a if k.startswith(("ofbe_", "a_")) or k.endswith("_se") or k in ("device", "start_utc")]
    assert len(new) == 2 + 15 + 24 and all(r[k] == "" for r in rows for k in new)  # GGIR gives no SEs
    first = (out / "summary.csv").read_bytes()
    assert main(argv) == 1 and (out / "summary.csv").read_bytes() == first  # the same bytes again


def test_the_command_refuses_a_missing_file_and_a_bad_value(tmp_path: Path, capsys) -> None:
    assert main([str(tmp_path / "missing.csv"), "--out", str(tmp_path / "o"), "--mode", "ggir"]) == 2
    assert "missing.csv: no such file or folder" in capsys.readouterr().err
    assert main([str(SPHERE), "--out", str(tmp_path / "o"), "--mode", "ggir", "--still-sd-g", "-1"]) == 2
    assert "still_sd_g: expected a positive number" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
