"""``ofbe-autocal --jobs/--scheduler``: the same bytes whatever the workers, a file that cannot
be read named with its line while the others finish."""

from __future__ import annotations

from pathlib import Path

import pytest

from ofbe_data.cli.autocal import main


@pytest.fixture(scope="module")
def wear(tiny_free_living: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The session's tiny-free-living campaign (conftest.py), and a folder of this module's own
    with ``bad.csv``: ``wear-001``'s epochs with a garbled line 5."""
    own = tmp_path_factory.mktemp("wear")
    bad = (tiny_free_living / "tfl" / "epochs" / "wear-001.csv").read_text().splitlines()
    bad[4] = "1,2,abc,0,0,0,20"
    (own / "bad.csv").write_text("\n".join(bad) + "\n")
    return tiny_free_living, own


def _inputs(wear: tuple[Path, Path]) -> list[str]:
    shared, own = wear
    epochs = shared / "tfl" / "epochs"
    return [str(epochs / "wear-001.csv"), str(own / "bad.csv"), str(epochs / "wear-002.csv"),
            str(shared / "tfl" / "wear-003" / "rec-01" / "wear-003.csv")]


def _outputs(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


@pytest.mark.parametrize("options", [["--jobs", "2"], pytest.param(["--jobs", "2", "--scheduler", "dask"],
                                                                    marks=pytest.mark.slow)],
                         ids=["processes", "dask"])
def test_workers_give_the_same_bytes_and_name_the_failed_file(wear: tuple[Path, Path], tmp_path: Path,
                                                             options: list[str],
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    assert main([*_inputs(wear), "--out", str(tmp_path / "one")]) == 1
    one_err = capsys.readouterr().err
    assert main([*_inputs(wear), "--out", str(tmp_path / "many"), *options]) == 1
    many_err = capsys.readouterr().err
    assert _outputs(tmp_path / "one") == _outputs(tmp_path / "many")
    assert sorted(_outputs(tmp_path / "one")) == ["autocal.params.yaml", "summary.csv", "summary.parquet",
                                                  "wear-001.epochs.parquet", "wear-002.epochs.parquet",
                                                  "wear-003.epochs.parquet"]
    line = (f"ofbe-autocal: error: {wear[1] / 'bad.csv'}:5: expected a finite number in column 'meanz', "
            "found 'abc'")
    assert line in one_err.splitlines() and line in many_err.splitlines()
    assert "3 read, " in many_err and ", 1 failed ->" in many_err


def test_jobs_below_one_is_a_usage_error(wear: tuple[Path, Path], tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    assert main([*_inputs(wear), "--out", str(tmp_path / "o"), "--jobs", "0"]) == 2
    assert "--jobs: expected an integer >= 1, found 0" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
