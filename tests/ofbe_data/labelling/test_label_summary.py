"""What ofbe-label and ofbe-session check say about a run: sessions, labels of how many recordings
and poses, and folders that are not sessions (never skipped silently)."""

from __future__ import annotations

import shutil
from types import SimpleNamespace

from ofbe_data.cli.label import main as label_main
from ofbe_data.cli.label import summary
from ofbe_data.cli.session import main as session_main
from ofbe_data.labelling.batch import skipped_folders
from tests.helpers.paths import ROOT

EXAMPLES = ROOT / "raw" / "examples"


def _session(name: str, rows: list[dict], rejections: int = 0, warnings: int = 0) -> SimpleNamespace:
    return SimpleNamespace(manifest=SimpleNamespace(session=name), rows=rows,
                           rejections=[object()] * rejections, warnings=["w"] * warnings)


def test_poses_of_one_recording_are_counted_as_labels_of_one_recording() -> None:
    one = _session("mp", [{"recording": "r1", "pose": k} for k in range(18)], warnings=1)
    assert summary([one], 0) == ("1 session labelled, 0 failed; 18 labels of 1 recording (18 poses), "
                                 "0 rejected, 1 warning")
    two = _session("ga", [{"recording": "r1", "pose": None}, {"recording": "r2", "pose": float("nan")}], 1, 2)
    assert summary([one, two], 1) == ("2 sessions labelled, 1 failed; 20 labels of 3 recordings (18 poses), "
                                      "1 rejected, 3 warnings")


def test_a_run_that_labelled_nothing_does_not_say_it_labelled_a_session() -> None:
    assert summary([_session("s", [], rejections=3)], 0) == ("1 session read, 0 failed; nothing labelled, "
                                                             "3 rejected, 0 warnings")


def test_a_folder_without_session_yaml_is_named_not_skipped_silently(tmp_path, capsys) -> None:
    campaign = tmp_path / "campaign"
    shutil.copytree(EXAMPLES / "tiny-gravity-aligned" / "ga-pc001", campaign / "ga-pc001")
    (campaign / "ga-pc002").mkdir()          # a session whose manifest was forgotten
    (campaign / "ga-pc002" / "dut.csv").write_text("t,ax,ay,az\n")
    (campaign / "_truth").mkdir()            # meant to be passed over
    (campaign / ".cache").mkdir()
    assert skipped_folders([campaign]) == [campaign / "ga-pc002"]
    assert skipped_folders([campaign / "ga-pc001"]) == []
    note = f"note: {campaign / 'ga-pc002'}: no session.yaml in it, not a session (skipped)"
    out = str(tmp_path / "labels")
    assert label_main([str(campaign), "--out", out, "--jobs", "1", "--min-samples", "2000"]) == 0
    err = capsys.readouterr().err
    assert f"ofbe-label: {note}" in err and "_truth" not in err and ".cache" not in err
    assert "ofbe-label: 1 session labelled, 0 failed; " in err
    session_main(["check", str(campaign)])
    assert f"ofbe-session: {note}" in capsys.readouterr().err


def test_check_warns_when_two_sessions_put_a_device_in_one_power_cycle(tmp_path, capsys) -> None:
    """Two sessions left at one power_cycle for the same device (init's default) are said by check,
    not first by ofbe-export json; sessions of different power cycles are not."""
    campaign = tmp_path / "campaign"
    for name in ("ga-pc001", "ga-pc002"):
        shutil.copytree(EXAMPLES / "tiny-gravity-aligned" / name, campaign / name)
    second = campaign / "ga-pc002" / "session.yaml"
    text = second.read_text()
    assert "power_cycle: 2" in text
    session_main(["check", str(campaign)])
    assert "power_cycle" not in capsys.readouterr().err
    second.write_text(text.replace("power_cycle: 2", "power_cycle: 1"))
    session_main(["check", str(campaign)])
    err = capsys.readouterr().err
    warned = [line for line in err.splitlines() if "all say power_cycle" in line]
    start = ("ofbe-session: warning: sessions ga-pc001, ga-pc002 of campaign tiny-gravity-aligned all say "
             "power_cycle 1 for device ")
    assert warned and all(line.startswith(start) for line in warned)
    assert warned[0].endswith("give each session its own power_cycle in its session.yaml")
