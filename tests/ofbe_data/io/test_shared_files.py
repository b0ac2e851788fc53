"""One file, two devices: the rules compare files, not names, so a symbolic or hard link to a
file is that file (a link cannot make two devices read the same columns, or one file serve two
recordings)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from ofbe_data.core.errors import ManifestError
from ofbe_data.io.manifest import load_manifest
from ofbe_data.io.shared_files import file_identity, same_file_note

DEV = ("    model: X\n    role: dut\n    format: csv\n    delimiter: ';'\n"
       "    columns: {t: t, ax: a1x, ay: a1y, az: a1z}\n")


def _session(folder: Path, recordings: str) -> None:
    folder.mkdir(parents=True)
    rows = [f"{i / 100:.2f};0.01;0.02;9.81" for i in range(500)]
    (folder / "both.csv").write_text("t;a1x;a1y;a1z\n" + "\n".join(rows) + "\n")
    (folder / "session.yaml").write_text(
        "format: ofbe-session/1\ncampaign: camp\nsession: s1\nkind: gravity-aligned\n"
        "site: {gravity_mps2: 9.81}\npower_cycle: 1\ndevices:\n  imu_a:\n" + DEV + "  imu_b:\n" + DEV
        + recordings)


@pytest.mark.parametrize("link", ["symlink", "hardlink"])
def test_a_link_to_a_file_is_that_file(tmp_path: Path, link: str) -> None:
    folder = tmp_path / "camp" / "s1"
    _session(folder, "recordings:\n  - id: r1\n    files: {imu_a: both.csv, imu_b: link.csv}\n")
    (os.symlink if link == "symlink" else os.link)(folder / "both.csv", folder / "link.csv")
    with pytest.raises(ManifestError) as info:
        load_manifest(folder)
    assert str(info.value) == (
        f"{folder / 'session.yaml'}:22: recordings[0].files.imu_b: expected a file shared by devices of one "
        "recording only when each reads its own columns (format csv, different ax, ay, az), found "
        "'link.csv', also named for device 'imu_a' (the same file as 'both.csv', through a link)")


def test_a_link_cannot_serve_a_file_to_two_recordings(tmp_path: Path) -> None:
    folder = tmp_path / "camp" / "s1"
    _session(folder, "recordings:\n  - id: r1\n    files: {imu_a: both.csv, imu_b: other.csv}\n"
                     "  - id: r2\n    files: {imu_a: link.csv, imu_b: other2.csv}\n")
    (folder / "other.csv").write_text((folder / "both.csv").read_text())
    (folder / "other2.csv").write_text((folder / "both.csv").read_text())
    os.symlink("both.csv", folder / "link.csv")
    with pytest.raises(ManifestError, match=r"recordings\[1\]\.files\.imu_a: expected a file used in one "
                                            r"recording only, found 'link.csv', also named at "
                                            r"recordings\[0\]\.files\.imu_a \(the same file as 'both\.csv', "
                                            r"through a link\)"):
        load_manifest(folder)


def test_identity_is_the_file_and_names_of_missing_files_are_compared_as_written(tmp_path: Path) -> None:
    (tmp_path / "a.csv").write_text("x")
    os.symlink("a.csv", tmp_path / "b.csv")
    assert file_identity(tmp_path / "a.csv", "a.csv") == file_identity(tmp_path / "b.csv", "b.csv")
    assert file_identity(tmp_path / "gone.csv", "./sub/../gone.csv") == "gone.csv"
    assert same_file_note("a.csv", "./a.csv") == ""
    assert same_file_note("b.csv", "a.csv") == " (the same file as 'a.csv', through a link)"
