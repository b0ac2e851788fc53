import json
from pathlib import Path

import matplotlib.image as mpimg
import pytest

from ofbe_data.cli.small_angle import main

FILES = ("small_angle.json", "small_angle.png", "small_angle_profile.png", "small_angle_profile.csv",
         "small_angle.md")


@pytest.fixture(scope="module")
def report(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("sa") / "small_angle"
    assert main(["--out", str(out)]) == 0
    return out


def test_files_exist(report):
    for name in FILES:
        assert (report / name).is_file(), name


@pytest.mark.parametrize("name", ["small_angle.png", "small_angle_profile.png"])
def test_pngs_are_valid(report, name):
    assert (report / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(report / name)
    assert img.ndim == 3 and img.shape[1] >= 600 and img.shape[0] >= 400
    assert img[..., :3].std() > 0.05  # not blank


def test_json_metrics(report):
    m = json.loads((report / "small_angle.json").read_text())
    assert m["format"] == "ofbe-small-angle/1"
    assert m["limit_mg"] == 50.0
    assert m["threshold_deg"]["pitch"] == pytest.approx(2.866, abs=0.005)
    assert m["threshold_deg"]["roll"] == pytest.approx(2.866, abs=0.005)
    assert m["formula_deg"] == pytest.approx(2.865984, abs=1e-6)
    assert m["grid"] == {"range_deg": 10.0, "step_deg": 0.05, "n_points": 401}
    assert m["measure"] == "max-axis"


def test_csv_profile(report):
    lines = (report / "small_angle_profile.csv").read_text().splitlines()
    assert lines[0] == "tilt_deg,leak_mg"
    assert lines[1] == "0.0000,0.000000"
    assert lines[-1].startswith("10.0000,173.648")
    assert len(lines) == 1 + 201


def test_markdown_cites_the_threshold(report):
    text = (report / "small_angle.md").read_text()
    assert "asin(0.05) = 2.8660°" in text and "±2.87°" in text


def test_second_run_is_byte_identical(report, tmp_path):
    assert main(["--out", str(tmp_path)]) == 0
    for name in ("small_angle.json", "small_angle_profile.csv", "small_angle.md"):
        assert (tmp_path / name).read_bytes() == (report / name).read_bytes(), name


@pytest.mark.parametrize("argv", [["--step-deg", "-1"], ["--range-deg", "0"], ["--limit-mg", "x"],
                                  ["--step-deg", "1e-6"], ["--measure", "rms"]])
def test_bad_options_exit_2(argv, tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--out", str(tmp_path / "x"), *argv])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "error:" in err
    assert not (tmp_path / "x").exists()
