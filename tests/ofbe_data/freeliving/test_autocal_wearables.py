"""``ofbe-autocal`` on the real wearable test files of the GGIR projects (tests/data/wearables,
Apache-2.0): every recording read, a "not enough still data" verdict for each (they are minutes
long), the corrupt blocks named, and a csv that does not say its rate refused with the flag
that settles it."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import pytest

from ofbe_data.cli.autocal import main
from ofbe_data.core.checksums import file_sha256
from tests.helpers.paths import TESTS

DATA = TESTS / "data" / "wearables"
RAW = ("ax3_testfile.cwa", "ax3_testfile_corrupt_blocks_0_13_14_142_143_144.cwa", "ax6_testfile.cwa",
       "GENEActiv_testfile.bin", "actigraph_testfile.gt3x")


def _rows(out: Path) -> dict[str, dict[str, str]]:
    with open(out / "summary.csv", newline="") as fh:
        return {Path(r["file"]).name: r for r in csv.DictReader(fh)}


@pytest.mark.parametrize("mode", ["ofbe", "ggir"])
def test_each_wearable_is_read_and_judged_too_short_never_an_error(tmp_path: Path, mode: str,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    for name in RAW:
        shutil.copyfile(DATA / name, tmp_path / name)
    assert main([str(tmp_path), "--out", str(tmp_path / "out"), "--mode", mode]) == 0
    err = capsys.readouterr().err
    rows = _rows(tmp_path / "out")
    assert sorted(rows) == sorted(RAW)
    assert {r["calibrated"] for r in rows.values()} == {"false"}
    assert all(r["qc"].startswith("recalibration not done because") for r in rows.values())
    assert rows["GENEActiv_testfile.bin"]["device"].startswith("GENEActiv")
    assert rows["actigraph_testfile.gt3x"]["start_utc"] == "2020-08-26T08:09:00+00:00"
    assert ("ax3_testfile_corrupt_blocks_0_13_14_142_143_144.cwa: 6 bad data block(s) skipped and filled in "
            "as GGIR does: 0 (byte 1024, checksum), 13 (byte 7680, checksum), 14 (byte 8192, checksum), "
            "142 (byte 73728, checksum), 143 (byte 74240, checksum), 144 (byte 74752, checksum)") in err
    assert (tmp_path / "out" / "ax6_testfile.epochs.parquet").is_file()
    # the GGIRread test file is the first 64 KiB of a recording: its last page is cut short, and said so
    assert ("GENEActiv_testfile.bin: 1 bad data block(s) named: 16 (byte 62543, truncated: 231 of 300 "
            "samples read)") in err
    # each file's SHA-256, computed while it was read, is that of its bytes
    assert all(r["sha256"] == file_sha256(tmp_path / name) for name, r in rows.items())


def test_a_sample_csv_without_its_rate_names_the_flag_and_reads_with_it(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    src = tmp_path / "ax6_testfile_formatted_timestamps.csv"
    shutil.copyfile(DATA / src.name, src)
    assert main([str(src), "--out", str(tmp_path / "a")]) == 1
    assert "no time column and no sample rate in the file: give --rate HZ" in capsys.readouterr().err
    assert main([str(src), "--out", str(tmp_path / "b"), "--rate", "100", "--unit", "g"]) == 0
    assert _rows(tmp_path / "b")[src.name]["calibrated"] == "false"
