"""A full disk and Ctrl-C, as a user meets them: real full file systems (a small tmpfs this
test mounts, so it runs where it may mount one: as root with the capability; skipped
otherwise) and a Ctrl-C sent to the whole process group, as a terminal sends it.

Every write fails the same way: one line ``<prog>: error: <file>: <reason> (<free> MB free on
its disk): … nothing partial is kept, free space and rerun``, exit 74 (``EX_IOERR``), and the
output folder as it was before the command (nothing partial, no temporary file).
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from pathlib import Path

import pytest

from ofbe_data.cli import dataset as dataset_cli
from ofbe_data.cli import label as label_cli
from ofbe_data.cli import simulate as simulate_cli
from ofbe_data.core.cli import EXIT_INTERRUPTED, EXIT_IO, public_path
from ofbe_data.dataset import writer
from tests.helpers.paths import ROOT

pytestmark = pytest.mark.slow
"""Slow: a campaign or model fixture shared by the module (``-m "not slow"`` leaves it out)."""

GA = ROOT / "raw" / "examples" / "tiny-gravity-aligned"
T = 1000


def _mount_tmpfs(where: Path, kib: int) -> bool:
    where.mkdir(parents=True, exist_ok=True)
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    done = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={kib}k", "tmpfs", str(where)],
                          capture_output=True)
    return done.returncode == 0


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[callable]:
    """``small_disk(kib)`` mounts a tmpfs of that size and returns its folder; unmounted after."""
    mounted: list[Path] = []

    def make(kib: int) -> Path:
        where = tmp_path / f"disk-{len(mounted)}"
        if not _mount_tmpfs(where, kib):
            pytest.skip("needs to mount a small tmpfs (root with CAP_SYS_ADMIN)")
        mounted.append(where)
        return where

    yield make
    for where in mounted:
        subprocess.run(["umount", "-l", str(where)], capture_output=True)


def _fill(disk: Path, leave_kib: int) -> None:
    """Fill ``disk`` but ``leave_kib`` KiB."""
    free = shutil.disk_usage(disk).free
    with open(disk / "filler", "wb") as fh:
        fh.write(b"\0" * max(0, free - leave_kib * 1024))


def _left(disk: Path) -> list[str]:
    return sorted(str(p.relative_to(disk)) for p in disk.rglob("*") if p.name != "filler")


_LINE = (r"{prog}: error: {file}: {reason}: {what}; nothing partial is kept, free space and rerun\n")


def _assert_one_line(err: str, prog: str, file: str, reason: str, what: str) -> None:
    pattern = _LINE.format(prog=re.escape(prog), file=file, reason=reason, what=re.escape(what))
    assert re.fullmatch(pattern, err), err


_NO_SPACE = r"No space left on device \(\d+\.\d MB free on its disk\)"


@pytest.fixture(scope="module")
def labelled(labelled_campaigns: Path) -> Path:
    """A gravity-aligned campaign of 10 power cycles (24 s each), labelled, in ``raw/ga`` and
    ``labels/ga``: enough for the paper-gravity protocol's 5 folds (the session's, conftest.py)."""
    return labelled_campaigns


def _build(labelled: Path, out: Path) -> list[str]:
    return ["build", str(labelled / "labels" / "ga"), "--raw", str(labelled / "raw" / "ga"),
            "--out", str(out), "--window-length", str(T), "--stride", str(T), "--quiet"]


def test_public_path_names_the_file_a_user_looks_for() -> None:
    assert public_path(Path("/d/.ds.k2j4x8_1.tmp/windows.h5")) == Path("/d/ds/windows.h5")
    assert public_path(Path("/d/labels/.ga-pc001.parquet.ab12cd34.tmp")) == Path("/d/labels/ga-pc001.parquet")
    assert public_path(Path("/d/.hidden/x.tmp")) == Path("/d/.hidden/x.tmp")


def test_labelling_onto_a_full_disk(small_disk, capsys) -> None:
    disk = small_disk(256)
    _fill(disk, 8)
    code = label_cli.main([str(GA / "ga-pc001"), "--out", str(disk / "labels"), "--quiet"])
    assert code == EXIT_IO
    _assert_one_line(capsys.readouterr().err, "ofbe-label", re.escape(str(disk)) + r"/labels\S*", _NO_SPACE,
                     "the labels could not be written")
    assert _left(disk) == []  # not even the empty folders the run made


def test_a_failed_labelling_run_keeps_the_folders_that_were_there(small_disk, capsys) -> None:
    disk = small_disk(256)
    (disk / "labels" / "mine").mkdir(parents=True)
    _fill(disk, 8)
    assert label_cli.main([str(GA / "ga-pc001"), "--out", str(disk / "labels"), "--quiet"]) == EXIT_IO
    capsys.readouterr()
    assert _left(disk) == ["labels", "labels/mine"]


def test_simulating_onto_a_full_disk(small_disk, capsys) -> None:
    disk = small_disk(256)
    code = simulate_cli.main(["tiny-rotated", "--out", str(disk / "camp"), "--quiet"])
    assert code == EXIT_IO
    _assert_one_line(capsys.readouterr().err, "ofbe-simulate", re.escape(str(disk)) + r"/camp\S*", _NO_SPACE,
                     "the campaign could not be written")
    assert _left(disk) == []


def test_a_dataset_too_big_for_its_disk_is_refused_before_it_is_written(labelled, small_disk, capsys) -> None:
    disk = small_disk(1024)
    code = dataset_cli.main(_build(labelled, disk / "ds"))
    assert code == EXIT_IO
    _assert_one_line(capsys.readouterr().err, "ofbe-dataset", re.escape(str(disk / "ds" / "windows.h5")),
                     r"expected \d+\.\d MB free for windows\.h5 \(120 windows\), "
                     r"found \d+\.\d MB free on its disk",
                     "the dataset could not be written")
    assert _left(disk) == []


def test_a_disk_that_fills_while_the_dataset_is_written(labelled, small_disk, capsys, monkeypatch) -> None:
    """Without the free-space check (another program fills the disk between the check and the
    write): HDF5 never writes to the disk itself, so the plain write fails with ENOSPC, the
    process lives (it used to end in a segmentation fault), and nothing is left."""
    disk = small_disk(384)
    monkeypatch.setattr(writer, "FREE_SPACE_RESERVE", -(2**40))
    code = dataset_cli.main(_build(labelled, disk / "ds"))
    assert code == EXIT_IO
    _assert_one_line(capsys.readouterr().err, "ofbe-dataset", re.escape(str(disk / "ds")) + r"/windows\.h5",
                     _NO_SPACE, "the dataset could not be written")
    assert _left(disk) == []


def test_a_signal_file_that_does_not_fit(labelled, small_disk, capsys) -> None:
    disk = small_disk(1800)
    code = dataset_cli.main(_build(labelled, disk / "ds"))
    err = capsys.readouterr().err
    assert code == EXIT_IO
    _assert_one_line(err, "ofbe-dataset", re.escape(str(disk / "ds" / "signals.parquet")),
                     r"expected \d+\.\d MB free for the signal Parquet files \(about the size of the HDF5 "
                     r"files\), found \d+\.\d MB free on its disk", "the dataset could not be written")
    assert _left(disk) == []


def test_exporting_onto_a_full_disk(labelled, small_disk, tmp_path, capsys) -> None:
    built = tmp_path / "ds"
    assert dataset_cli.main(_build(labelled, built)) == 0
    disk = small_disk(256)
    code = dataset_cli.main(["export", str(built), "--out", str(disk / "shared")])
    assert code == EXIT_IO
    _assert_one_line(capsys.readouterr().err, "ofbe-dataset", re.escape(str(disk)) + r"/shared\S*", _NO_SPACE,
                     "the export could not be written")
    assert _left(disk) == []


# ----------------------------------------------------------------------------- Ctrl-C


@pytest.mark.parametrize("scheduler", ["processes", "dask"])
def test_ctrl_c_at_the_terminal_prints_one_line_whatever_the_scheduler(tmp_path, scheduler) -> None:
    """A terminal's Ctrl-C goes to every process of the foreground group: the command's and its
    workers' (the embedded Dask cluster's too). One line, exit 130, no worker traceback."""
    out = tmp_path / f"camp-{uuid.uuid4().hex[:6]}"
    proc = subprocess.Popen(
        [sys.executable, "-m", "ofbe_data.cli.simulate", "rotated", "--out", str(out), "--jobs", "2",
         "--scheduler", scheduler], stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True, cwd=ROOT,
        start_new_session=True,  # its own process group, as a terminal's foreground job
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 90  # interrupt once the workers write the campaign
    while not any(tmp_path.glob(f".{out.name}*/**/*.csv")) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert proc.poll() is None, "finished before it could be interrupted"
    os.killpg(proc.pid, signal.SIGINT)
    try:
        _, err = proc.communicate(timeout=90)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    lines = [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip() and "%|" not in ln]
    assert proc.returncode == EXIT_INTERRUPTED, err[-3000:]
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err[-3000:]
    one = "ofbe-simulate: interrupted; files already written are whole, nothing partial is left"
    assert lines == [one], lines
    assert not out.exists() and not list(tmp_path.glob(f".{out.name}*"))
