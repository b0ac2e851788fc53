"""``ofbe-autocal --mode ofbe``: ofbe's calibration ladder on a wearable's still epochs.

Simulated wear with known truth (each test draws its own epochs: postures on the sphere, a
per-posture error, white noise, epochs that are not truly still, a temperature drift) checks
the fit, its standard errors and the model choice; GGIR's own example
(tests/data/ggir-calibrate/spheredata.csv) checks the held-out calibration error against
``--mode ggir`` and the coverage rule.
"""

from __future__ import annotations

import csv
import shutil
from datetime import UTC, datetime, timedelta, timezone
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from ofbe_data.cli.autocal import main
from ofbe_data.freeliving import (
    EpochTable,
    OfbeSettings,
    apply_ggir,
    ggir_calibrate,
    idle_sleep,
    ofbe_calibrate,
    read_epoch_csv,
)
from ofbe_data.freeliving.coverage import face_counts, missing_faces
from ofbe_data.freeliving.ladder import choose_wear_model
from ofbe_data.freeliving.ofbe import OFBE_COLUMNS, coefficient_columns
from ofbe_data.freeliving.robust import fit_robust, norm_residuals
from ofbe_data.freeliving.summary import COLUMNS, summary_row
from ofbe_data.labelling.conventions import matrix_from_imutk
from ofbe_data.labelling.multiposition._fit import fit_poses
from tests.helpers.paths import TESTS

SPHERE = TESTS / "data" / "ggir-calibrate" / "spheredata.csv"

DONE = "recalibration done: "
NOT_DECREASED = "recalibration not done because recalibration does not decrease error"
SPHERE_NOT_POPULATED = "recalibration not done because the sphere is not populated: "
TOO_FEW = "recalibration not done because too few still epochs"
NO_STILL = "recalibration not done because no still epochs"


class Wear:
    """Simulated still epochs of one recording and the device's truth (g, °C)."""

    def __init__(self, seed: int, n_postures: int = 60, angles_rad: float = 0.005,
                 slope_g_per_c: float = 5e-4, posture_mg: float = 0.5, white_mg: float = 0.3,
                 moving: float = 0.03, longest: int = 12) -> None:
        rng = np.random.default_rng(seed)
        self.s = 1.0 + rng.normal(0.0, 0.01, 3)  # imu_tk's input-referred scales
        self.angles = rng.normal(0.0, angles_rad, 3) if angles_rad else np.zeros(3)
        self.A = matrix_from_imutk(self.s, self.angles)
        self.b0 = rng.normal(0.0, 0.02, 3)  # offset at 0 °C
        self.c = rng.normal(0.0, slope_g_per_c, 3) if slope_g_per_c else np.zeros(3)
        means, temps, postures = [], [], []
        for k in range(n_postures):
            u = rng.normal(size=3)
            u /= np.linalg.norm(u)
            n = int(rng.integers(3, longest + 1))
            jitter = rng.normal(0.0, np.radians(1.0) / np.sqrt(2.0), (n, 3))
            uu = u + jitter - np.outer(jitter @ u, u)
            uu /= np.linalg.norm(uu, axis=1)[:, None]
            t = rng.uniform(18.0, 34.0) + rng.normal(0.0, 0.2, n)
            shared = rng.normal(0.0, posture_mg * 1e-3, 3)
            means.append(uu @ self.A.T + self.b0 + np.outer(t, self.c) + shared
                         + rng.normal(0.0, white_mg * 1e-3, (n, 3)))
            temps.append(t)
            postures.append(np.full(n, k))
        self.means = np.concatenate(means)
        self.temps = np.concatenate(temps)
        self.postures = np.concatenate(postures)
        self.moving = rng.random(len(self.means)) < moving  # not truly still: tens of mg off the sphere
        self.means[self.moving] += rng.normal(0.0, 0.03, (int(self.moving.sum()), 3))
        self.sds = rng.uniform(0.003, 0.008, self.means.shape)

    def truth(self, temp_ref_c: float) -> dict[str, float]:
        """ofbe's columns: b at the reference temperature, A, c."""
        b = self.b0 + self.c * temp_ref_c
        out = {f"ofbe_offset_{a}": b[i] for i, a in enumerate("xyz")}
        out |= {f"a_{r}{q}": self.A[i, j] for i, r in enumerate("xyz") for j, q in enumerate("xyz")}
        return out | {f"ofbe_temp_slope_{a}": self.c[i] for i, a in enumerate("xyz")}

    def table(self, name: str = "wear") -> EpochTable:
        return EpochTable(name, self.means, self.sds, self.temps)


def _normalised_errors(wear: Wear, columns: dict[str, float | None], temp_ref_c: float) -> dict[str, float]:
    truth = wear.truth(temp_ref_c)
    return {n: (columns[n] - truth[n]) / columns[f"{n}_se"] for n in OFBE_COLUMNS if columns[f"{n}_se"]}


def test_standard_errors_cover_the_truth_over_30_simulated_recordings() -> None:
    """Normalised errors (estimate − truth)/SE of every fitted value, over 30 seeds: their standard
    deviation is near 1 (0.7–1.4), per kind of value and in all; and they would not be with the
    epochs taken as independent (each its own posture)."""
    z: dict[str, list[float]] = {"ofbe_offset": [], "a": [], "ofbe_temp_slope": []}
    naive = []
    for seed in range(30):
        wear = Wear(seed)
        fit = fit_robust(wear.means, "full+temperature", wear.temps).fit
        assert fit.determined
        for name, value in _normalised_errors(wear, coefficient_columns(fit), fit.temp_ref_c).items():
            z[name.rsplit("_", 1)[0]].append(value)
        if seed < 10:
            each = np.arange(len(wear.means))
            alone = fit_robust(wear.means, "full+temperature", wear.temps, postures=each)
            naive += list(_normalised_errors(wear, coefficient_columns(alone.fit), fit.temp_ref_c).values())
    spread = {kind: float(np.std(v)) for kind, v in z.items()}
    assert all(0.7 <= s <= 1.4 for s in spread.values()), spread
    assert 0.8 <= float(np.std(np.concatenate(list(z.values())))) <= 1.2
    assert len(z["a"]) == 30 * 6  # A's six upper-triangular entries are fitted, its zeros are not
    assert np.std(naive) > 1.5  # the test sees standard errors that ignore the postures


def test_the_ladder_takes_the_models_the_epochs_show_and_no_more() -> None:
    wear = Wear(101)
    full = choose_wear_model(wear.means, wear.temps)
    assert full.fit.fit.model == "full+temperature", full.reason
    assert "over scale-offset" in full.reason and "+temperature over" in full.reason
    plain = Wear(102, angles_rad=0.0, slope_g_per_c=0.0)
    choice = choose_wear_model(plain.means, plain.temps)
    assert choice.fit.fit.model == "scale-offset", choice.reason
    assert "full not used: its 3 more parameters are ideal within their errors" in choice.reason
    cool = Wear(103)
    steady = 25.0 + 0.1 * (np.arange(len(cool.temps)) % 3)
    flat = choose_wear_model(cool.means, steady)
    assert "no temperature slope: the still epochs span 0.2 °C, 5 needed" in flat.reason
    assert not flat.fit.fit.model.endswith("+temperature")


def test_epochs_that_are_not_truly_still_do_not_pull_the_fit() -> None:
    """8 % of the epochs 30–50 mg off along +x (a slow hand, a bus): the unweighted fit's x offset
    moves by more than 10 standard errors, the robust one stays within 3, and every epoch whose
    length moved by more than 10 mg has weight 0."""
    wear = Wear(7, moving=0.0, longest=30)
    rng = np.random.default_rng(70)
    bad = rng.random(len(wear.means)) < 0.08
    means = wear.means.copy()
    means[bad, 0] += rng.uniform(0.03, 0.05, int(bad.sum()))
    robust = fit_robust(means, "full+temperature", wear.temps)
    plain = fit_poses(means, 1.0, "full+temperature", 1e6, wear.temps)
    truth = wear.truth(robust.fit.temp_ref_c)["ofbe_offset_x"]
    se = np.sqrt(robust.fit.covariance[0, 0])
    assert abs(robust.fit.offset[0] - truth) < 3 * se and abs(plain.offset[0] - truth) > 10 * se
    longer = np.linalg.norm(means, axis=1) - np.linalg.norm(wear.means, axis=1) > 0.01
    assert longer.sum() > 20 and np.all(robust.weights[longer] == 0.0)
    assert np.median(robust.weights[~bad]) > 0.9


def test_the_coefficients_in_ggirs_convention_calibrate_as_ofbes_do() -> None:
    wear = Wear(11, angles_rad=0.0)
    fit = fit_robust(wear.means, "scale-offset+temperature", wear.temps).fit
    col = coefficient_columns(fit)
    axes = "xyz"
    ggir = apply_ggir(wear.means, wear.temps, np.array([col[f"scale_{a}"] for a in axes]),
                      np.array([col[f"offset_{a}"] for a in axes]),
                      np.array([col[f"temp_offset_{a}"] for a in axes]), fit.temp_ref_c)
    a = np.array([[col[f"a_{r}{q}"] for q in axes] for r in axes])
    b = np.array([col[f"ofbe_offset_{x}"] for x in axes])
    c = np.array([col[f"ofbe_temp_slope_{x}"] for x in axes])
    ofbe = np.linalg.solve(a, (wear.means - b - np.outer(wear.temps - fit.temp_ref_c, c)).T).T
    assert np.abs(ggir - ofbe).max() < 1e-12
    assert col["offset_x"] == -col["ofbe_offset_x"]
    assert col["offset_x_se"] == pytest.approx(col["ofbe_offset_x_se"], rel=1e-9)
    assert col["a_xy"] == 0.0 and col["a_xy_se"] is None and col["a_xx_se"] > 0
    full = coefficient_columns(fit_robust(wear.means, "full+temperature", wear.temps).fit)
    assert full["offset_x"] is None and full["scale_x"] is None and full["a_xy_se"] > 0  # GGIR has no place


@pytest.fixture(scope="module")
def sphere() -> EpochTable:
    return read_epoch_csv(SPHERE)


def _half(sphere: EpochTable, rows: slice) -> EpochTable:
    return EpochTable("half", sphere.mean_g[rows], sphere.sd_g[rows], sphere.temperature_c[rows], True)


def test_ofbe_mode_beats_ggir_mode_on_held_out_epochs_of_ggirs_example(sphere: EpochTable) -> None:
    """Fit on one half of GGIR's still epochs, GGIR's cal.error (mg) on the other half, both ways:
    ofbe's is at least 10 % below GGIR's (measured: 2.01 and 2.16 mg against 2.32 and 2.55)."""
    h = sphere.n // 2
    for fit_rows, test_rows in ((slice(0, h), slice(h, None)), (slice(h, None), slice(0, h))):
        train, test = _half(sphere, fit_rows), _half(sphere, test_rows)
        g = ggir_calibrate(train)
        ggir_mg = 1000 * np.mean(np.abs(np.linalg.norm(
            apply_ggir(test.mean_g, test.temperature_c, g.scale, g.offset, g.temp_offset, g.temp_mean_c),
            axis=1) - 1.0))
        r = ofbe_calibrate(train)
        assert r.calibrated and r.model == "full+temperature" and r.qc.startswith(DONE), r.qc
        fit = r.fit
        ofbe_mg = 1000 * np.mean(np.abs(norm_residuals(fit.params, test.mean_g,
                                                       test.temperature_c - fit.temp_ref_c, fit.model)))
        assert ofbe_mg <= 0.9 * ggir_mg, (ofbe_mg, ggir_mg)
        errors = [r.columns[f"{n}_se"] for n in OFBE_COLUMNS if r.columns[f"{n}_se"] is not None]
        assert len(errors) == 12 and all(0 < e < 0.003 for e in errors)


def test_a_sphere_seen_from_one_side_of_x_is_not_calibrated_and_says_where(sphere: EpochTable) -> None:
    keep = sphere.mean_g[:, 0] > -0.3
    r = ofbe_calibrate(EpochTable("half", sphere.mean_g[keep], sphere.sd_g[keep], sphere.temperature_c[keep],
                                  True))
    assert r.qc == SPHERE_NOT_POPULATED + "no still epoch within 45° of -x"
    assert not r.calibrated and r.missing == ("-x",)
    assert r.cal_error_start is not None and r.cal_error_end is None
    assert r.columns["scale_x"] == 1.0 and r.columns["offset_x"] == 0.0 and r.columns["ofbe_offset_x"] is None
    expected = "OfbeSettings.model: expected auto or one of offset, scale-offset, full, offset\\+temperature"
    with pytest.raises(ValueError, match=expected + ".*found 'fulll'"):
        OfbeSettings(model="fulll")
    unchecked = ofbe_calibrate(EpochTable("half", sphere.mean_g[keep], sphere.sd_g[keep], None, True),
                               OfbeSettings(sphere_check=False))
    assert unchecked.fit is not None and not unchecked.qc.startswith(SPHERE_NOT_POPULATED)


def test_the_coverage_rule_counts_epochs_within_45_degrees_of_each_signed_axis() -> None:
    tilt = np.radians(44.0)
    means = np.array([[np.cos(tilt), np.sin(tilt), 0.0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1],
                      [0.0, -np.sin(np.radians(46.0)), -np.cos(np.radians(46.0))]])
    assert face_counts(means).tolist() == [1, 1, 1, 2, 1, 0]
    assert missing_faces(means) == ("-z",) and missing_faces(means, 50.0) == ()


def test_idle_sleep_epochs_are_left_out_and_counted() -> None:
    wear = Wear(21, n_postures=40)
    t = wear.table()
    n = t.n
    means = np.concatenate([t.mean_g[:100], np.repeat(t.mean_g[100:101], 12, axis=0), t.mean_g[101:],
                            np.zeros((3, 3)), [[0.0, 0.0, 1.0]] * 2])
    sds = np.concatenate([t.sd_g[:100], np.full((12, 3), 0.004), t.sd_g[101:], np.full((3, 3), 0.005),
                          np.zeros((2, 3))])
    temps = np.concatenate([t.temperature_c[:100], np.full(12, t.temperature_c[100]), t.temperature_c[101:],
                            np.full(5, 25.0)])
    padded = EpochTable("idle", means, sds, temps)
    idle = idle_sleep(padded)
    assert idle.sum() == 12 + 3 + 2 and not idle[:100].any() and idle[100:112].all()
    r = ofbe_calibrate(padded)
    clean = ofbe_calibrate(EpochTable("clean", np.delete(t.mean_g, 100, axis=0),
                                      np.delete(t.sd_g, 100, axis=0), np.delete(t.temperature_c, 100)))
    assert r.n_idle == 17 and r.n_still == n - 1 and r.n_epochs == n + 16
    assert r.qc.endswith("; 17 idle-sleep epochs left out (standard deviation 0, zero or repeated means)")
    assert r.columns == clean.columns and r.model == clean.model


def test_every_qc_outcome_is_one_line_and_identity_where_not_calibrated() -> None:
    rng = np.random.default_rng(5)
    moving = EpochTable("m", rng.normal(0, 0.5, (300, 3)), rng.uniform(0.02, 0.2, (300, 3)))
    r = ofbe_calibrate(moving)
    assert r.qc == NO_STILL + " (standard deviation below 13 mg on every axis and |mean| below 2 g)"
    sds = moving.sd_g.copy()
    sds[:7] = 0.005
    r = ofbe_calibrate(EpochTable("few", moving.mean_g, sds))
    assert r.qc == TOO_FEW + ": 7, at least 10 needed" and r.n_still == 7
    u = rng.normal(size=(400, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    r = ofbe_calibrate(EpochTable("calibrated", u, rng.uniform(0.003, 0.008, (400, 3))))
    assert r.qc.startswith(NOT_DECREASED + " (") and not r.calibrated and r.model is not None
    for result in (r, ofbe_calibrate(moving)):
        assert "\n" not in result.qc and result.columns["scale_y"] == 1.0 and result.columns["a_xx"] is None


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def _write_epochs(path: Path, wear: Wear) -> None:
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["meanx", "meany", "meanz", "sdx", "sdy", "sdz", "temperature"])
        w.writerows(np.column_stack([wear.means, wear.sds, wear.temps]).tolist())


def test_the_command_writes_the_summary_the_parquet_files_and_the_same_bytes_again(tmp_path: Path) -> None:
    data = tmp_path / "in"
    data.mkdir()
    square, wear = Wear(32, n_postures=40, angles_rad=0.0), Wear(31, n_postures=40)
    _write_epochs(data / "a-square.csv", square)
    _write_epochs(data / "b-wear.csv", wear)
    (data / "c-bad.csv").write_text("meanx,meany,meanz,sdx,sdy,sdz\n0,0,1,0.01,0.01\n")
    out = tmp_path / "out"
    argv = [str(data), "--out", str(out), "--quiet"]  # --mode ofbe is the default
    assert main(argv) == 1  # the bad file; the others are written
    rows = _rows(out / "summary.csv")
    assert list(rows[0]) == list(COLUMNS) and [Path(r["file"]).name for r in rows] == ["a-square.csv",
                                                                                      "b-wear.csv"]
    a, b = rows
    assert a["mode"] == b["mode"] == "ofbe" and a["calibrated"] == b["calibrated"] == "true"
    assert a["model"].startswith("ofbe scale-offset") and a["device"] == a["start_utc"] == ""
    assert float(a["offset_y"]) == -float(a["ofbe_offset_y"]) and float(a["scale_z_se"]) > 0
    assert a["a_xy"] == "0.0" and a["a_xy_se"] == "" and float(a["a_yy_se"]) > 0
    assert b["model"] == "ofbe full+temperature" and b["offset_x"] == "" and float(b["a_yz_se"]) > 0
    assert b["a_zx"] == "0.0" and b["a_zx_se"] == "" and b["temp_mean_c"] != ""
    assert float(b["cal_error_end_mg"]) < float(b["cal_error_start_mg"])
    table = pq.read_table(out / "summary.parquet").to_pylist()
    for row, typed in zip(rows, table, strict=True):
        assert typed["n_still"] == int(row["n_still"]) and typed["calibrated"] is True
        for k in (c for c in COLUMNS if c not in ("calibrated", "start_utc")):
            value = typed[k]
            shown = "" if value is None else repr(value) if isinstance(value, float) else str(value)
            assert shown == row[k], k
    epochs = pq.read_table(out / "b-wear.epochs.parquet").to_pydict()
    assert len(epochs["epoch"]) == len(wear.means) and all(epochs["used"]) and not any(epochs["idle"])
    assert epochs["mean_x"] == wear.means[:, 0].tolist() and min(epochs["weight"]) == 0.0
    first = {p.name: p.read_bytes() for p in out.iterdir()}
    assert set(first) == {"autocal.params.yaml", "summary.csv", "summary.parquet", "a-square.epochs.parquet",
                          "b-wear.epochs.parquet"}
    assert main(argv) == 1 and {p.name: p.read_bytes() for p in out.iterdir()} == first


def test_two_inputs_with_one_stem_are_refused(tmp_path: Path, capsys) -> None:
    for folder in ("x", "y"):
        (tmp_path / folder).mkdir()
        shutil.copy(SPHERE, tmp_path / folder / "s.csv")
    argv = [str(tmp_path / "x" / "s.csv"), str(tmp_path / "y" / "s.csv"), "--out", str(tmp_path / "o")]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "expected inputs with different names (both would write s.epochs.parquet)" in err
    assert not (tmp_path / "o").exists()


def test_the_summary_row_takes_a_device_and_a_start_time_when_a_reader_gives_them() -> None:
    r = ofbe_calibrate(EpochTable("m", np.zeros((0, 3)), np.zeros((0, 3))))
    start = datetime(2024, 5, 1, 8, 30, tzinfo=UTC)
    row = summary_row("f.cwa", "0" * 64, r, device="AX6-1234", start_utc=start)
    assert row["device"] == "AX6-1234" and row["start_utc"] == start and row["n_epochs"] == 0
    expected = r"start_utc: expected a time in UTC, found 2024-05-01T08:30:00\+02:00"
    with pytest.raises(ValueError, match=expected):
        summary_row("f.cwa", "0" * 64, r, start_utc=start.replace(tzinfo=timezone(timedelta(hours=2))))
