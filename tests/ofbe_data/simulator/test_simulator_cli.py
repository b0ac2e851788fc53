"""``ofbe-simulate`` on the command line: exit codes and one-line reasons."""

from __future__ import annotations

import subprocess
import sys

from ofbe_data.cli.simulate import main as simulate_main


def test_simulate_writes_a_campaign(tmp_path, capsys):
    assert simulate_main(["tiny-multi-position", "--out", str(tmp_path / "mp"), "--quiet"]) == 0
    out = capsys.readouterr().out
    assert "campaign mp, seed 13, 2 sessions, 16 files" in out
    assert (tmp_path / "mp" / "mp-pc001" / "session.yaml").is_file()
    assert (tmp_path / "mp" / "_truth" / "mp-pc002.json").is_file()
    assert (tmp_path / "mp" / "_truth" / "simulation.yaml").is_file()


def test_bad_input_gives_one_line_reason_and_exit_2(tmp_path, capsys):
    assert simulate_main(["no-such-profile", "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert err[0].startswith("ofbe-simulate: error: no-such-profile: profile: expected a built-in")
    assert not (tmp_path / "x").exists()
    assert simulate_main(["tiny-rotated", "--out", str(tmp_path / "y"), "--jobs", "0"]) == 2


def test_console_script_help():
    done = subprocess.run([sys.executable, "-m", "ofbe_data.cli.simulate", "--help"], capture_output=True,
                          text=True, check=False)
    assert done.returncode == 0
    assert "tiny-gravity-aligned" in done.stdout and "--seed" in done.stdout
