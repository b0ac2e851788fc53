"""``ofbe-export ggir|json|imucal DIR`` from an ``ofbe-autocal`` folder (issue 35).

ofbe-autocal runs on GGIR's own example (tests/data/ggir-calibrate/: the still epochs of a real
wrist recording and GGIR's result for them) beside a recording with no still epoch. The
exports are then read back by the other tool's own code: GGIR's reading of ``backup.cal.coef``
(replicated line by line, tests/ofbe_data/ggir_replica.py) with GGIR's correction
``(raw + offset)·scale + (T − meantempcal)·temperature.offset`` (R/g.getmeta.R), and imucal's
``load_calibration_info`` and ``calibrate``. Both must give back, on the still epochs autocal
kept, the calibration error the summary states.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from ofbe_data.calibration.autocal import AUTOCAL_SUMMARY
from ofbe_data.calibration.formats import GGIR_BACKUP_FILE
from ofbe_data.cli import autocal, export
from ofbe_data.io.gravity import G0
from tests.helpers.ggir_replica import backup_cal_coef
from tests.helpers.paths import TESTS

DATA = TESTS / "data" / "ggir-calibrate"
GGIR = json.loads((DATA / "ggir_result.json").read_text())
WRIST, MOVING = "a-wrist.csv", "b-moving.csv"
NO_STILL = "recalibration not done because no non-movement data available"
ERROR_TOL_G = 1e-9
"""The calibration error recomputed from the exported numbers against the summary's, g: the
coefficients are written to 1e-12 and the errors to 1e-12 g."""


def _autocal(tmp: Path, mode: str) -> Path:
    data = tmp / "in"
    if not data.exists():
        data.mkdir()
        shutil.copy(DATA / "spheredata.csv", data / WRIST)
        rng = np.random.default_rng(35)  # moving the whole time: sd above 13 mg on every axis
        rows = [f"{m[0]:.6f},{m[1]:.6f},{m[2]:.6f},{s[0]:.6f},{s[1]:.6f},{s[2]:.6f},{t:.3f}"
                for m, s, t in zip(rng.normal(0, 0.5, (200, 3)), rng.uniform(0.05, 0.3, (200, 3)),
                                   rng.uniform(20, 30, 200), strict=True)]
        (data / MOVING).write_text("meanx,meany,meanz,sdx,sdy,sdz,temperature\n" + "\n".join(rows) + "\n")
    out = tmp / mode
    assert autocal.main([str(data), "--out", str(out), "--mode", mode, "--quiet"]) == 0
    return out


@pytest.fixture(scope="module")
def ggir_folder(tmp_path_factory) -> Path:
    """``ofbe-autocal --mode ggir`` of the two recordings."""
    return _autocal(tmp_path_factory.mktemp("autocal"), "ggir")


@pytest.fixture(scope="module")
def ofbe_folder(tmp_path_factory) -> Path:
    """``ofbe-autocal`` (ofbe's ladder: a full+temperature model here) of the two recordings."""
    return _autocal(tmp_path_factory.mktemp("autocal"), "ofbe")


def _run(capsys, *argv: str | Path) -> tuple[int, str, str]:
    code = export.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _summary(folder: Path) -> pd.DataFrame:
    return pq.read_table(folder / AUTOCAL_SUMMARY).to_pandas().set_index(
        pd.Index([Path(f).name for f in pq.read_table(folder / AUTOCAL_SUMMARY)["file"].to_pylist()]))


def _still(folder: Path, name: str = WRIST) -> tuple[np.ndarray, np.ndarray]:
    """(means (n, 3) g, temperatures (n,) °C) of the epochs autocal's fit used."""
    epochs = pq.read_table(folder / f"{Path(name).stem}.epochs.parquet").to_pandas()
    used = epochs[epochs["used"]]
    return used[["mean_x", "mean_y", "mean_z"]].to_numpy(), used["temperature_c"].to_numpy()


def _sphere_error(calibrated: np.ndarray) -> float:
    return float(np.mean(np.abs(np.linalg.norm(calibrated, axis=1) - 1.0)))


def test_the_folder_is_recognised_by_autocals_own_summary_name() -> None:
    assert AUTOCAL_SUMMARY == autocal.SUMMARY_PARQUET


def test_ggir_reads_back_ggirs_own_numbers_and_its_formula_gives_the_error(tmp_path, ggir_folder,
                                                                          capsys) -> None:
    code, out, err = _run(capsys, "ggir", ggir_folder, "--out", f"{tmp_path}/")
    assert code == 0, err
    data = (tmp_path / GGIR_BACKUP_FILE).read_bytes()
    summary = _summary(ggir_folder)
    row = backup_cal_coef(data, WRIST)  # GGIR's g.part1 look-up by the data file's base name
    assert np.abs(row.scale - np.asarray(GGIR["scale"], float)).max() < 1e-6
    assert np.abs(row.offset - np.asarray(GGIR["offset"], float)).max() < 1e-6
    assert np.abs(row.tempoffset - np.asarray(GGIR["tempoffset"], float)).max() < 1e-6
    assert row.use_temp and row.qc_message == summary.loc[WRIST, "qc"]
    means, temps = _still(ggir_folder)
    calibrated = (means + row.offset) * row.scale + (temps[:, None] - row.meantempcal) * row.tempoffset
    assert abs(_sphere_error(calibrated) - summary.loc[WRIST, "cal_error_end_mg"] / 1000) < ERROR_TOL_G
    assert abs(_sphere_error(calibrated) - GGIR["cal.error.end"][0]) < 1e-5  # GGIR's own, to its 1e-5 g
    table = pd.read_csv(tmp_path / GGIR_BACKUP_FILE, keep_default_na=False)
    wrist = table.set_index("filename").loc[WRIST]
    assert wrist["n.10sec.windows"] == 10958 and abs(wrist["n.hours.considered"] - 10958 * 10 / 3600) < 1e-6
    assert float(wrist["cal.error.start"]) == summary.loc[WRIST, "cal_error_start_mg"] / 1000
    moving = backup_cal_coef(data, MOVING)  # not calibrated: identity, as GGIR writes and applies it
    assert moving.scale.tolist() == [1.0] * 3
    assert moving.offset.tolist() == moving.tempoffset.tolist() == [0.0] * 3
    assert moving.qc_message == NO_STILL and not moving.use_temp
    assert table.set_index("filename").loc[MOVING, "cal.error.start"] == "NA"
    assert err.splitlines() == [f"ofbe-export: ggir: {ggir_folder.parent / 'in' / MOVING}: not calibrated "
                                f"({NO_STILL}): an identity row, as GGIR writes and applies for a file it "
                                "cannot calibrate", "ofbe-export: ggir: 1 result file written"]
    assert out.split() == [str(tmp_path / GGIR_BACKUP_FILE)]


@pytest.mark.parametrize("mode", ["ggir", "ofbe"])
def test_imucal_round_trip_gives_the_error_the_summary_states(tmp_path, ggir_folder, ofbe_folder, capsys,
                                                              mode: str) -> None:
    from imucal.management import load_calibration_info

    folder = {"ggir": ggir_folder, "ofbe": ofbe_folder}[mode]
    code, out, err = _run(capsys, "imucal", folder, "--out", f"{tmp_path / 'cal'}/")
    assert code == 0, err
    assert sorted(p.name for p in (tmp_path / "cal").iterdir()) == ["a-wrist.imucal.json"]
    assert err.splitlines()[0] == (f"ofbe-export: warning: skipped {folder.parent / 'in' / MOVING}: not "
                                   f"calibrated ({_summary(folder).loc[MOVING, 'qc']})")
    cal = load_calibration_info(tmp_path / "cal" / "a-wrist.imucal.json")
    assert type(cal).__name__ == "FerrarisCalibrationInfo" and cal.from_acc_unit == "g"
    s = _summary(folder).loc[WRIST]
    means, temps = _still(folder)
    if mode == "ggir":  # GGIR's convention: c = -temp_offset / scale
        slope = -np.array([s[f"temp_offset_{a}"] / s[f"scale_{a}"] for a in "xyz"])
    else:
        slope = np.array([s[f"ofbe_temp_slope_{a}"] for a in "xyz"])
    drift = (temps - s["temp_mean_c"])[:, None] * slope  # imucal has no temperature term: removed first
    acc, _ = cal.calibrate(acc=means - drift, gyr=np.zeros_like(means), acc_unit="g", gyr_unit="deg/s")
    assert abs(_sphere_error(acc) - s["cal_error_end_mg"] / 1000) < ERROR_TOL_G
    if mode == "ggir":  # imucal's correction is GGIR's, sample for sample
        ggir = ((means + s[["offset_x", "offset_y", "offset_z"]].to_numpy(float))
                * s[["scale_x", "scale_y", "scale_z"]].to_numpy(float)
                + (temps - s["temp_mean_c"])[:, None] * s[["temp_offset_x", "temp_offset_y",
                                                          "temp_offset_z"]].to_numpy(float))
        np.testing.assert_allclose(acc, ggir, rtol=0, atol=1e-12)
    else:
        assert not np.allclose(cal.R_a, np.eye(3))  # the full model's cross-axis terms are carried


def test_json_carries_the_free_living_fields(tmp_path, ofbe_folder, capsys) -> None:
    code, _, err = _run(capsys, "json", ofbe_folder, "--out", f"{tmp_path / 'j'}/")
    assert code == 0, err
    doc = json.loads((tmp_path / "j" / "a-wrist.json").read_text())
    s = _summary(ofbe_folder).loc[WRIST]
    fl = doc["free_living"]
    assert doc["format"] == "ofbe-calibration/1" and doc["bias_kind"] == "zero-g-offset"
    assert fl["model"] == s["model"] == "ofbe full+temperature" and fl["qc"] == s["qc"] and fl["calibrated"]
    assert fl["cal_error_start_mg"] == s["cal_error_start_mg"]
    assert fl["cal_error_end_mg"] == s["cal_error_end_mg"]
    assert fl["A"] == doc["A"] == [[s[f"a_{r}{c}"] for c in "xyz"] for r in "xyz"]
    assert fl["offset_g"] == [s[f"ofbe_offset_{a}"] for a in "xyz"]
    assert doc["bias_m_s2"] == [s[f"ofbe_offset_{a}"] * G0 for a in "xyz"]
    assert fl["temp_slope_g_per_c"] == [s[f"ofbe_temp_slope_{a}"] for a in "xyz"]
    assert fl["temp_mean_c"] == doc["temperature_c"] == s["temp_mean_c"] and fl["ggir"] is None
    errors = {k: s[k] for k in s.index if k.endswith("_se") and pd.notna(s[k])}
    assert fl["standard_errors"] == errors and len(errors) == 3 + 6 + 3  # b, A's upper triangle, c
    assert doc["bias_se_m_s2"] == [s[f"ofbe_offset_{a}_se"] * G0 for a in "xyz"]
    assert [f["sha256"] for f in doc["source"]["files"]][0] == s["sha256"]


def test_ggir_leaves_out_a_full_model_and_says_so(tmp_path, ofbe_folder, capsys) -> None:
    """GGIR's correction is per axis: ofbe's full model (cross-axis terms) has no row GGIR could
    apply, so it is left out (GGIR then calibrates that file itself), never written wrong."""
    code, _, err = _run(capsys, "ggir", ofbe_folder, "--out", tmp_path / "g.csv")
    assert code == 0, err
    table = pd.read_csv(tmp_path / "g.csv")
    assert table["filename"].tolist() == [MOVING]
    assert (f"ofbe-export: ggir: {ofbe_folder.parent / 'in' / WRIST}: left out: its ofbe full+temperature "
            "model has cross-axis terms that GGIR's per-axis correction cannot apply") in err


def _copy(folder: Path, tmp: Path) -> Path:
    target = tmp / "copy"
    shutil.copytree(folder, target)
    return target


def test_a_damaged_summary_is_an_error_naming_it(tmp_path, ggir_folder, capsys) -> None:
    folder = _copy(ggir_folder, tmp_path)
    summary = folder / AUTOCAL_SUMMARY
    summary.write_bytes(b"PAR1 this is not a Parquet file PAR1")
    for name in ("ggir", "json", "imucal"):
        code, out, err = _run(capsys, name, folder, "--out", tmp_path / name)
        assert code == 1 and out == "" and err.count("\n") == 1
        assert err.startswith(f"ofbe-export: error: {summary}: expected ofbe-autocal's summary (Parquet), "
                              "found a file that cannot be read: ")
        assert not (tmp_path / name).exists()
    table = pq.read_table(ggir_folder / AUTOCAL_SUMMARY)
    pq.write_table(table.drop_columns(["scale_y"]), summary)
    code, _, err = _run(capsys, "json", folder, "--out", tmp_path / "j")
    assert code == 1 and err == (f"ofbe-export: error: {summary}: expected ofbe-autocal's "
                                 f"{table.num_columns} columns (docs/free-living.md), found 1 missing: "
                                 "scale_y\n")
    first = table["file"][0].as_py()
    column = table.schema.get_field_index("offset_y")
    offset_y = table["offset_y"].to_pylist()
    pq.write_table(table.set_column(column, "offset_y", pa.array([float("nan"), *offset_y[1:]])), summary)
    code, _, err = _run(capsys, "imucal", folder, "--out", tmp_path / "i")
    assert code == 1 and err == (f"ofbe-export: error: {summary}: row 1 ({first}): offset_y: expected a "
                                 "finite number or an empty cell, found nan\n")
    empty = pa.array([None, *offset_y[1:]], pa.float64())
    pq.write_table(table.set_column(column, "offset_y", empty), summary)
    code, _, err = _run(capsys, "ggir", folder, "--out", tmp_path / "g")
    assert code == 1 and err == (f"ofbe-export: error: {summary}: row 1 ({first}): expected "
                                 "GGIR's offset (offset_x, offset_y, offset_z) all given or all empty, found "
                                 "offset_y empty\n")
    assert not any((tmp_path / n).exists() for n in ("j", "i", "g"))


def test_what_an_autocal_folder_cannot_do_is_a_usage_error(tmp_path, ggir_folder, capsys) -> None:
    kalibr = ("kalibr takes a labels folder, a label file or ofbe-predict's JSON, found an ofbe-autocal "
              "folder (it exports as ggir, json or imucal)")
    cases = [(("kalibr", "--raw", tmp_path), kalibr),
             (("ros",), "ros takes a labels folder"),
             (("ggir", "--ggir-data"), "--ggir-data: "),
             (("json", "--raw", tmp_path), "--raw: "),
             (("json", "--store", tmp_path / "s"), "--store: ")]
    for (name, *more), words in cases:
        code, out, err = _run(capsys, name, ggir_folder, "--out", tmp_path / "o", *more)
        assert code == 2 and out == "" and err.count("\n") == 1 and words in err, (name, err)
    code, _, err = _run(capsys, "json", ggir_folder, "--store", tmp_path / "s")
    assert err == (f"ofbe-export: error: --store: {ggir_folder.parent / 'in' / WRIST}: expected a device and "
                   "a start time to file the calibration by, found none (an epoch csv names neither); leave "
                   "out --store\n")
    assert not (tmp_path / "o").exists() and not (tmp_path / "s").exists()


def test_no_calibrated_file_is_an_error_not_an_empty_export(tmp_path, ggir_folder, capsys) -> None:
    folder = _copy(ggir_folder, tmp_path)
    table = pq.read_table(folder / AUTOCAL_SUMMARY)
    pq.write_table(table.slice(1), folder / AUTOCAL_SUMMARY)  # only the moving recording
    code, _, err = _run(capsys, "json", folder, "--out", tmp_path / "j")
    assert code == 1 and err.splitlines()[-1] == (
        f"ofbe-export: error: {folder / AUTOCAL_SUMMARY}: expected at least one calibrated file, found none "
        "(1 not calibrated: see the qc column)")
    assert not (tmp_path / "j").exists()
