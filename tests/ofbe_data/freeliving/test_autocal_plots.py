"""``ofbe-autocal --plots``: one PNG per recording with still epochs, the same bytes again and
whatever ``--jobs``, drawn from the written outputs, its "after" points nearer the unit sphere
than its "before" points by the calibration error the summary states; a recording with no still
epoch gets a one-line note instead, and nothing else reaches the terminal.

The data: two simulated free-living recordings (``tiny-free-living``, 0.4 days of epochs each:
``wear-001`` not calibrated in ``--mode ofbe``, its sphere not populated; ``wear-002`` calibrated
with the ``full`` model; both calibrated in ``--mode ggir``), and an epoch csv of movement only.
"""

from __future__ import annotations

import csv
import shutil
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest

from ofbe_data.cli.autocal import main
from ofbe_data.freeliving.plots import calibrated_means, plot_data

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def wear(short_free_living: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two simulated recordings' epochs (a copy of the session's, conftest.py) and a file of
    movement (no epoch below 13 mg) beside them."""
    folder = tmp_path_factory.mktemp("wear") / "epochs"
    shutil.copytree(short_free_living / "fl" / "epochs", folder)
    rng = np.random.default_rng(5)
    moving = np.column_stack([rng.normal(0.0, 0.6, (60, 3)), rng.uniform(0.05, 0.3, (60, 3)),
                              np.full(60, 25.0)])
    with open(folder / "walk.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["meanx", "meany", "meanz", "sdx", "sdy", "sdz", "temperature"])
        w.writerows(moving.tolist())
    return folder


def _rows(out: Path) -> dict[str, dict[str, str]]:
    with open(out / "summary.csv", newline="") as fh:
        return {Path(r["file"]).stem: r for r in csv.DictReader(fh)}


def _png_size(data: bytes) -> tuple[int, int]:
    """Width and height from a PNG's IHDR chunk, its CRC checked."""
    assert data[:8] == PNG_SIGNATURE
    length, kind = struct.unpack(">I4s", data[8:16])
    assert kind == b"IHDR" and length == 13
    assert struct.unpack(">I", data[29:33])[0] == zlib.crc32(data[12:29])
    width, height = struct.unpack(">II", data[16:24])
    return width, height


def _figures(out: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(out.glob("*.png"))}


@pytest.mark.slow
def test_figures_are_pngs_with_the_same_bytes_again_and_whatever_the_jobs(
        wear: Path, tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    argv = [str(wear), "--plots", "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "one")]) == 0
    one = capfd.readouterr()
    assert main([*argv, "--out", str(tmp_path / "again")]) == 0
    assert main([*argv, "--out", str(tmp_path / "two"), "--jobs", "2"]) == 0
    two = capfd.readouterr()
    figures = _figures(tmp_path / "one")
    assert sorted(figures) == ["wear-001.calibration.png", "wear-002.calibration.png"]
    assert all(_png_size(data) == (1800, 1400) for data in figures.values())  # 9 × 7 in at 200 dpi
    assert _figures(tmp_path / "again") == figures and _figures(tmp_path / "two") == figures
    assert b"tIME" not in figures["wear-002.calibration.png"]  # no time stamp in the file
    # the one note, nothing else on the terminal (no matplotlib message), with either scheduler
    note = f"ofbe-autocal: note: {wear / 'walk.csv'}: no figure: no still epochs to draw\n"
    assert one.out == two.out == "" and one.err == note and two.err == note * 2


@pytest.mark.parametrize("mode", ["ofbe", "ggir"])
def test_the_after_points_are_nearer_the_unit_sphere_by_the_stated_error(wear: Path, tmp_path: Path,
                                                                         mode: str) -> None:
    out = tmp_path / mode
    assert main([str(wear / "wear-001.csv"), str(wear / "wear-002.csv"), "--out", str(out), "--mode", mode,
                 "--quiet"]) == 0  # what a figure draws comes from the outputs
    rows = _rows(out)
    for stem, row in rows.items():
        data = plot_data(row, (out / f"{stem}.epochs.parquet").read_bytes())
        assert data is not None and data.n == int(row["n_still"]) and data.mode == mode
        before = np.mean(np.abs(data.norm_error_mg()))
        assert before == pytest.approx(float(row["cal_error_start_mg"]), abs=1e-6)
        assert data.temperature_c is not None and data.temperature_c.shape == (data.n,)
        if row["calibrated"] == "false":
            assert mode == "ofbe" and stem == "wear-001" and data.after_g is None
            continue
        assert data.after_g is not None and data.after_g.shape == data.before_g.shape == (data.n, 3)
        after = np.abs(data.norm_error_mg(after=True))
        assert np.mean(after) == pytest.approx(float(row["cal_error_end_mg"]), abs=1e-6)
        assert np.mean(after) < 0.2 * before  # 17-32 mg before, under 2 mg after
        assert np.median(after) < np.median(np.abs(data.norm_error_mg()))


def test_a_recording_without_still_epochs_or_temperature(wear: Path, tmp_path: Path,
                                                          capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(wear / "walk.csv"), "--out", str(tmp_path / "o"), "--plots", "--quiet"]) == 0
    note = f"ofbe-autocal: note: {wear / 'walk.csv'}: no figure: no still epochs to draw\n"
    assert capsys.readouterr().err == note
    assert not list((tmp_path / "o").glob("*.png"))
    row = _rows(tmp_path / "o")["walk"]
    assert plot_data(row, (tmp_path / "o" / "walk.epochs.parquet").read_bytes()) is None
    # without a temperature column the epochs are drawn against their row in the file
    lines = (wear / "wear-002.csv").read_text().splitlines()
    assert lines[0].split(",")[-1] == "temperature"
    (tmp_path / "cold.csv").write_text("\n".join(line.rsplit(",", 1)[0] for line in lines) + "\n")
    assert main([str(tmp_path / "cold.csv"), "--out", str(tmp_path / "c"), "--plots", "--quiet"]) == 0
    row = _rows(tmp_path / "c")["cold"]
    data = plot_data(row, (tmp_path / "c" / "cold.epochs.parquet").read_bytes())
    assert data is not None and data.temperature_c is None and row["calibrated"] == "true"
    assert np.all(np.diff(data.epoch) > 0)
    _png_size((tmp_path / "c" / "cold.calibration.png").read_bytes())


def test_calibrated_means_follow_each_convention() -> None:
    """GGIR's (raw + offset)·scale + (T − T̄)·temp_offset, and ofbe's A⁻¹(raw − b − c·(T − T̄)),
    from a row as summary.csv writes it (strings, empty where not fitted)."""
    raw = np.array([[0.02, 0.01, 1.03], [1.01, -0.02, 0.0]])
    temps = np.array([20.0, 30.0])
    ggir = {"mode": "ggir", "calibrated": "true", "temp_mean_c": "25.0", "offset_x": "-0.02",
            "offset_y": "-0.01", "offset_z": "-0.03", "scale_x": "1.0", "scale_y": "1.0", "scale_z": "1.0",
            "temp_offset_x": "0.001", "temp_offset_y": "0.0", "temp_offset_z": "0.0"}
    expected = (raw + [-0.02, -0.01, -0.03]) + (temps - 25.0)[:, None] * [0.001, 0.0, 0.0]
    assert np.allclose(calibrated_means(ggir, raw, temps), expected, atol=1e-15)
    a = np.array([[1.01, 0.002, 0.0], [0.0, 0.99, 0.0], [0.0, 0.0, 1.0]])
    ofbe = {"mode": "ofbe", "calibrated": "true", "temp_mean_c": "25.0", "ofbe_offset_x": "0.02",
            "ofbe_offset_y": "0.01", "ofbe_offset_z": "0.03", "ofbe_temp_slope_x": "-0.001",
            "ofbe_temp_slope_y": "", "ofbe_temp_slope_z": ""}
    ofbe |= {f"a_{r}{c}": str(float(a[i, j])) for i, r in enumerate("xyz") for j, c in enumerate("xyz")}
    # a row without every slope has no temperature term
    assert np.allclose(a @ calibrated_means(ofbe, raw, temps).T + [[0.02], [0.01], [0.03]], raw.T, atol=1e-15)
    assert calibrated_means({**ofbe, "calibrated": "false"}, raw, temps) is None
