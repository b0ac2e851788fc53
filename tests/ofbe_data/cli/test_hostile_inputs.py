"""Bad and hostile inputs from the bad-input campaign (issue 16): each gives one clear line or a
recorded rejection, the documented exit status, no traceback, no hang, nothing partial or stale.

The hostile files are built here. Commands run in subprocesses where a hang or a traceback is
what could go wrong (with a timeout), in-process otherwise.
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from ofbe_data.cli.label import main as label_main
from ofbe_data.cli.simulate import main as simulate_main
from ofbe_data.core.errors import ConfigError, ManifestError, OfbeError
from ofbe_data.io.manifest import load_manifest
from ofbe_data.io.typedconfig import read_section
from ofbe_data.io.yamlio import MAX_DEPTH, YamlDocument, YamlProblem
from ofbe_data.labelling.labels import label_params_from
from tests.helpers.paths import ROOT

EXAMPLES = ROOT / "raw" / "examples"
GA = EXAMPLES / "tiny-gravity-aligned"

BOMB = ('a: &a ["x", "x", "x", "x", "x", "x", "x", "x", "x"]\n'
        + "".join(f"{c}: &{c} [*{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}, *{p}]\n"
                  for p, c in zip("abcdefgh", "bcdefghi", strict=True)))


HANG_GUARD_S = 180.0
"""Bound of the hang guards: no healthy run reaches it, even a subprocess importing everything on a
busy 2-core laptop (the refusals take a few seconds)."""


def _run(args: list[str], timeout: float = 60, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", *args], capture_output=True, text=True, timeout=timeout,
                          cwd=cwd)


def _one_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def _copy_session(dest: Path, session: str = "ga-pc001") -> Path:
    shutil.copytree(GA / session, dest)
    return dest


# ----------------------------------------------------------------------------- hangs


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["manifest", "simulator config"])
def test_a_billion_laughs_document_is_refused_fast(tmp_path: Path, kind: str) -> None:
    if kind == "manifest":
        session = _copy_session(tmp_path / "s")
        (session / "session.yaml").write_text(BOMB)
        # a hang guard, not a speed test: expanding the aliases would not end in any bound; a healthy
        # refusal is a subprocess's imports and a parse, which a busy laptop may take many seconds for
        done = _run(["ofbe_data.cli.label", str(session), "--out", str(tmp_path / "labels"), "--quiet"],
                    timeout=HANG_GUARD_S)
        line = _one_line(done.stderr)
        assert done.returncode == 1 and "session.yaml" in line
    else:
        cfg = tmp_path / "bomb.yaml"
        cfg.write_text(BOMB)
        done = _run(["ofbe_data.cli.simulate", str(cfg), "--out", str(tmp_path / "camp")],
                    timeout=HANG_GUARD_S)
        line = _one_line(done.stderr)
        assert done.returncode == 2 and "bomb.yaml" in line
        assert not (tmp_path / "camp").exists()
    assert "at most 200000 values once aliases are expanded" in line


@pytest.mark.slow
def test_a_fifo_named_as_a_device_file_is_refused_not_waited_on(tmp_path: Path) -> None:
    session = _copy_session(tmp_path / "s")
    target = session / "rec-01" / "sparkfun-1.csv"
    target.unlink()
    os.mkfifo(target)
    done = _run(["ofbe_data.cli.label", str(session), "--out", str(tmp_path / "labels"),
                 "--min-samples", "1000", "--quiet"], timeout=HANG_GUARD_S)
    line = _one_line(done.stderr)
    assert done.returncode == 1
    assert f"{target}: expected a readable data file, found a FIFO (named pipe)" in line


@pytest.mark.slow
def test_deep_nesting_is_refused(tmp_path: Path) -> None:
    with pytest.raises(YamlProblem, match=f"nesting at most {MAX_DEPTH} levels deep"):
        YamlDocument("a: " + "[" * 20_000 + "]" * 20_000 + "\n")
    session = _copy_session(tmp_path / "s")
    (session / "session.yaml").write_text("a: " + "[" * 20_000 + "]" * 20_000 + "\n")
    with pytest.raises(ManifestError, match=f"nesting at most {MAX_DEPTH} levels deep"):
        load_manifest(session)


# ----------------------------------------------------------------------------- parameters


def test_yaml_exponent_numbers_are_numbers() -> None:
    assert YamlDocument("a: 1e9\nb: -2.5E-3\nc: 1.0e+3\nd: e9\n").data == {
        "a": 1e9, "b": -0.0025, "c": 1000.0, "d": "e9"}


@pytest.mark.parametrize("text, key", [
    ("label:\n  max_skipped_fraction: .nan\n", "label.max_skipped_fraction"),
    ("label:\n  static:\n    max_std_mps2: .inf\n", "label.static.max_std_mps2"),
])
def test_non_finite_parameters_are_errors(tmp_path: Path, text: str, key: str) -> None:
    path = tmp_path / "p.yaml"
    path.write_text(text)
    data = read_section(path, "label")
    with pytest.raises(ConfigError, match=r"expected a finite number, found (nan|inf)"):
        label_params_from(data, path)


def test_non_finite_simulator_config_is_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "nan.yaml"
    cfg.write_text("profile: tiny-rotated\ndut_model:\n  noise_mg: [.nan, 3, 4.5]\n")
    assert simulate_main([str(cfg), "--out", str(tmp_path / "c"), "--quiet"]) == 2
    assert _one_line(capsys.readouterr().err) == (
        f"ofbe-simulate: error: {cfg}: dut_model.noise_mg[0]: expected a finite number, found nan")
    assert not (tmp_path / "c").exists()


def test_a_huge_recording_length_is_refused_before_allocating(tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    cfg = tmp_path / "big.yaml"
    cfg.write_text("profile: tiny-rotated\nstationary_s: [1.0e+9, 1.0e+9]\n")
    assert simulate_main([str(cfg), "--out", str(tmp_path / "c"), "--quiet"]) == 2
    assert "stationary_s: expected at most 86400 s (one day) per recording" in capsys.readouterr().err


def test_params_files_resolve_their_profile(tmp_path: Path) -> None:
    (tmp_path / "pipelines" / "profiles").mkdir(parents=True)
    shutil.copy(ROOT / "pipelines" / "profiles" / "tiny.yaml", tmp_path / "pipelines" / "profiles")
    text = (ROOT / "params.yaml").read_text().replace("\nprofile: paper", "\nprofile: tiny", 1)
    (tmp_path / "params.yaml").write_text(text)
    tiny = yaml.safe_load((ROOT / "pipelines" / "profiles" / "tiny.yaml").read_text())
    assert read_section(tmp_path / "params.yaml", "train")["max_epochs"] == tiny["train"]["max_epochs"]
    (tmp_path / "params.yaml").write_text(text.replace("\nprofile: tiny", "\nprofile: nano", 1))
    with pytest.raises(ConfigError, match="profile: expected paper or one of tiny, found 'nano'"):
        read_section(tmp_path / "params.yaml", "train")


# ----------------------------------------------------------------------------- ofbe-label


def test_duplicate_session_ids_are_an_error_naming_both_folders(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    a = _copy_session(tmp_path / "a")
    b = _copy_session(tmp_path / "b")
    out = tmp_path / "labels"
    assert label_main([str(a), str(b), "--out", str(out), "--min-samples", "1000", "--quiet"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2
    for line in err:
        assert f"session tiny-gravity-aligned/ga-pc001 is in two folders of this batch, {a} and {b}" in line
    assert not (out / "tiny-gravity-aligned" / "ga-pc001.parquet").exists()


def test_a_failing_session_leaves_no_stale_labels(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    session = _copy_session(tmp_path / "s")
    out = tmp_path / "labels"
    assert label_main([str(session), "--out", str(out), "--min-samples", "1000", "--quiet"]) == 0
    old = out / "tiny-gravity-aligned" / "ga-pc001.parquet"
    assert old.is_file()
    (session / "rec-01" / "sparkfun-1.csv").write_bytes(b"\x00\x01garbage\n")
    assert label_main([str(session), "--out", str(out), "--min-samples", "1000", "--quiet"]) == 1
    err = capsys.readouterr().err
    assert not old.exists() and not old.with_name("ga-pc001.rejected.json").exists()
    assert f"removed its labels of an earlier run: {old}" in err


def test_all_time_stamps_equal_is_one_clear_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    session = _copy_session(tmp_path / "s")
    f = session / "rec-01" / "sparkfun-1.csv"
    f.write_text(re.sub(r"^\d{6,},", "4137731288,", f.read_text(), flags=re.M))
    assert label_main([str(session), "--out", str(tmp_path / "o"), "--min-samples", "1000", "--quiet"]) == 1
    line = _one_line(capsys.readouterr().err)
    assert f"{f}: expected at least two samples with increasing time stamps, found 1 usable sample(s)" in line
    assert "are all time stamps equal?" in line


@pytest.mark.parametrize("make, expected", [
    (lambda p: p.write_text("x"), "expected a folder for the labels, found an existing file"),
    (lambda p: (p.mkdir(), p.chmod(0o500)), "expected a folder the labels can be written to, found"),
])
def test_an_unusable_out_folder_is_a_usage_error(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                 make, expected: str) -> None:
    if expected.endswith("found") and os.geteuid() == 0:
        pytest.skip("root writes into read-only folders")
    out = tmp_path / "out"
    make(out)
    assert label_main([str(GA / "ga-pc001"), "--out", str(out), "--quiet"]) == 2
    assert expected in _one_line(capsys.readouterr().err)


def test_labelling_nothing_is_not_a_success(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "labels"
    assert label_main([str(GA / "ga-pc001"), "--out", str(out), "--min-samples", "10000000"]) == 1
    err = capsys.readouterr().err
    assert "ofbe-label: error: no recording was labelled (2 too-short; see the <session>.rejected.json" in err


@pytest.mark.slow
def test_ctrl_c_prints_one_line(tmp_path: Path) -> None:
    # a CI runner may start us with SIGINT ignored (a background job): give the command the default
    # disposition, as a terminal would, so that Python installs its KeyboardInterrupt handler
    proc = subprocess.Popen([sys.executable, "-m", "ofbe_data.cli.simulate", "rotated", "--out",
                             str(tmp_path / "camp"), "--jobs", "2"], stderr=subprocess.PIPE, text=True,
                            cwd=ROOT, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 60  # interrupt once the campaign is being written
    while not any(tmp_path.iterdir()) and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(0.5)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130
    last = [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip()][-1]
    assert last.startswith("ofbe-simulate: interrupted") and "Traceback" not in err
    assert not (tmp_path / "camp").exists()


# ----------------------------------------------------------------------------- property


_scalars = st.one_of(st.none(), st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=True),
                     st.text(max_size=12))
_yaml_values = st.recursive(_scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=8), inner, max_size=4)), max_leaves=30)
_manifest_like = st.fixed_dictionaries({}, optional={
    "format": st.one_of(st.just("ofbe-session/1"), _scalars),
    "campaign": _yaml_values, "session": _yaml_values, "kind": st.sampled_from(
        ["gravity-aligned", "rotated", "multi-position", "other"]),
    "power_cycle": _yaml_values, "site": _yaml_values, "devices": _yaml_values, "recordings": _yaml_values})


@pytest.mark.slow
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(doc=st.one_of(_manifest_like, _yaml_values), raw=st.binary(max_size=200))
def test_random_manifests_give_only_ofbe_errors(tmp_path: Path, doc: object, raw: bytes) -> None:
    for text in (yaml.safe_dump(doc, allow_unicode=True), raw.decode("utf-8", "replace")):
        folder = tmp_path / "s"
        folder.mkdir(exist_ok=True)
        (folder / "session.yaml").write_text(text, encoding="utf-8")
        t0 = time.monotonic()
        try:
            load_manifest(folder)
        except OfbeError:
            pass
        assert time.monotonic() - t0 < 60.0  # a hang guard (a parse that does not end), not a speed test


# ----------------------------------------------------------------------------- ofbe-dataset


@pytest.mark.slow
def test_export_refuses_a_licence_that_is_not_spdx(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    from ofbe_data.cli.dataset import main as dataset_main
    from ofbe_data.dataset.store import spdx_licence

    assert spdx_licence("cc-by-4.0") == "CC-BY-4.0" and spdx_licence("MIT OR CC0-1.0") == "MIT OR CC0-1.0"
    built = _built_dataset(tmp_path)
    out = tmp_path / "exported"
    assert dataset_main(["export", str(built), "--out", str(out), "--licence", "not a licence"]) == 1
    line = _one_line(capsys.readouterr().err)
    assert "licence: expected an SPDX licence id such as CC-BY-4.0" in line and "'not a licence'" in line
    assert not out.exists()
    assert dataset_main(["verify", str(built)]) == 0
    said = capsys.readouterr().out
    assert re.search(r"OK — ga \(ofbe-windows/1\): \d+ windows of 300 samples from \d+ recordings of 2 "
                     r"devices; protocols paper-gravity, grouped; 7 files match their SHA-256 sums", said)
    assert "{" not in said


@pytest.mark.slow
def test_a_full_disk_during_export_is_one_line_and_leaves_nothing(tmp_path: Path, capsys,
                                                                    monkeypatch) -> None:
    """Issue 24: a full disk during ``ofbe-dataset export`` was a raw OSError traceback."""
    import errno

    from ofbe_data.cli.dataset import main as dataset_main
    from ofbe_data.core import atomic as atomic_module

    built = _built_dataset(tmp_path)
    calls = []

    def full(src, dst, *args, **kwargs):
        calls.append(dst)
        if len(calls) == 2:  # the second file no longer fits
            raise OSError(errno.ENOSPC, "No space left on device", str(dst))
        return shutil.copyfile(src, dst)

    monkeypatch.setattr(atomic_module.shutil, "copyfile", full)
    out = tmp_path / "exported"
    assert dataset_main(["export", str(built), "--out", str(out)]) == 74  # EX_IOERR
    line = _one_line(capsys.readouterr().err)
    assert re.fullmatch(re.escape(f"ofbe-dataset: error: {out}/") + r"[\w.-]+: No space left on device "
                        r"\(\d+\.\d MB free on its disk\): the export could not be written; nothing partial "
                        r"is kept, free space and rerun", line), line
    assert not out.exists() and [p.name for p in tmp_path.iterdir() if p.name.startswith(".exported")] == []


def _built_dataset(tmp_path: Path) -> Path:
    from ofbe_data.dataset.build import DatasetParams, build_dataset
    from ofbe_data.labelling.batch import expand_sessions, label_sessions
    from ofbe_data.labelling.labels import LabelParams

    labels = tmp_path / "labels"
    label_sessions(expand_sessions([GA]), LabelParams(min_samples=1000), labels, progress=False)
    params = DatasetParams(window_length=300, stride=300, n_folds=3)
    return build_dataset(labels / "tiny-gravity-aligned", GA, tmp_path / "ds" / "ga", params, name="ga",
                         progress=False).path


# ----------------------------------------------------------------------------- silent wrong labels

ROT = EXAMPLES / "tiny-rotated"
FERRARIS = EXAMPLES / "imucal-ferraris" / "ferraris-pc001"


def _logger_rows(path: Path) -> tuple[list[str], list[list[int]]]:
    """An ofbe-logger file as (header and boot lines, data rows [t_us, ax, ay, az])."""
    head, rows = [], []
    for line in path.read_text().splitlines():
        parts = line.split(",")
        if len(parts) == 4 and all(p.strip().lstrip("-").isdigit() for p in parts):
            rows.append([int(p) for p in parts])
        else:
            head.append(line)
    return head, rows


def _write_logger(path: Path, head: list[str], rows: list[list[int]]) -> None:
    path.write_text("\n".join(head + [",".join(map(str, r)) for r in rows]) + "\n")


def _label(session: Path, tmp_path: Path, min_samples: int = 1000):
    from ofbe_data.labelling.labels import LabelParams, label_session

    return label_session(session, LabelParams(min_samples=min_samples))


def _tilt(session: Path, device: str, deg: float) -> None:
    import numpy as np

    f = session / "rec-01" / f"{device}.csv"
    head, rows = _logger_rows(f)
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    rot = np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    acc = np.array([r[1:] for r in rows], dtype=float) @ rot.T
    _write_logger(f, head, [[r[0], *map(int, np.rint(a))] for r, a in zip(rows, acc, strict=True)])


def test_a_tilted_gravity_aligned_device_is_rejected_as_not_level(tmp_path: Path) -> None:
    session = _copy_session(tmp_path / "s")
    _tilt(session, "sparkfun-1", 5.8)
    labels = _label(session, tmp_path)
    (rej,) = [r for r in labels.rejections if r.device == "sparkfun-1"]
    assert rej.reason == "not-level"
    assert re.match(r"the measured gravity direction is [4-7]\.\d\d° from the nearest axis \+z "
                    r"\(roll -?\d\.\d\d°, pitch -?\d\.\d\d°\), above label\.max_level_tilt_deg = 2\.87°: "
                    r"a level label would carry about \d+ mg", rej.detail), rej.detail
    # issue 22: both readings, and the documented way for a board known to be level
    assert re.search(r"One window cannot tell a tilt of [4-7]\.\d\d° from a tangential bias of about \d+ mg: "
                     r"if the board is known to be level \(a verified level mount\), set "
                     r"label\.max_level_tilt_deg above [4-7]\.\d\d \(in a params YAML given to ofbe-label "
                     r"--params\)", rej.detail), rej.detail
    assert [r["device"] for r in labels.rows] == ["sparkfun-2"]
    from ofbe_data.labelling.labels import LabelParams, label_session

    level = label_session(session, LabelParams(min_samples=1000, max_level_tilt_deg=8.0))
    (row,) = [r for r in level.rows if r["device"] == "sparkfun-1"]  # taken as bias, as asked
    assert row["label_method"] == "level" and abs(row["bias_y"]) > 0.5


@pytest.mark.slow
def test_session_plot_titles_fit_the_figure(tmp_path: Path, monkeypatch) -> None:
    """Issue 22: panel titles with a rejection's reason ran off the figure."""
    import matplotlib

    matplotlib.use("Agg")
    from ofbe_data.reports import session_plot

    session = _copy_session(tmp_path / "s")
    _tilt(session, "sparkfun-1", 5.8)
    labels = _label(session, tmp_path)
    figures = []
    monkeypatch.setattr(session_plot, "save_png", lambda fig, path: figures.append(fig) or Path(path))
    session_plot.plot_session(labels, tmp_path / "plot.png")
    (fig,) = figures
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    titles = [ax.title for ax in fig.axes if ax.title.get_text()] + [ax._left_title for ax in fig.axes
                                                                       if ax._left_title.get_text()]
    assert any("not-level" in t.get_text() for t in titles)
    for t in titles:
        box = t.get_window_extent(renderer)
        assert fig.bbox.x0 - 1 <= box.x0 and box.x1 <= fig.bbox.x1 + 1, (t.get_text(), box, fig.bbox)


def test_a_slight_tilt_is_kept_with_a_warning_and_its_measured_roll(tmp_path: Path) -> None:
    session = _copy_session(tmp_path / "s")
    (before,) = [r for r in _label(session, tmp_path).rows if r["device"] == "sparkfun-1"]
    _tilt(session, "sparkfun-1", -1.8)  # its roll was +0.6°: now about 2.4°, between warning and limit
    labels = _label(session, tmp_path)
    (row,) = [r for r in labels.rows if r["device"] == "sparkfun-1"]
    assert abs(row["roll_deg"] - before["roll_deg"] - 1.8) < 0.1 and row["label_method"] == "level"
    assert row["roll_deg"] != 0.0 and row["gravity_z"] == 1.0  # measured angles, the axis' label
    pattern = (r"rec-01/sparkfun-1: the measured gravity direction is 2\.\d\d° from the nearest axis \+z "
               r".*: a tilt, or a tangential bias of about \d+ mg \(one window cannot tell which\)")
    assert any(re.match(pattern, w) for w in labels.warnings), labels.warnings


def _ferraris_in_g(tmp_path: Path, acc_unit: str, time_unit: str = "s") -> Path:
    import pandas as pd

    session = tmp_path / "ferraris"
    shutil.copytree(FERRARIS, session)
    for f in session.glob("rec-*/imu.csv"):
        frame = pd.read_csv(f)
        for c in ("acc_x", "acc_y", "acc_z"):
            frame[c] = frame[c] / 2048.0
        frame.to_csv(f, index=False, float_format="%.6f")
    text = (session / "session.yaml").read_text()
    text = text.replace("acc_unit: counts\n    lsb_per_g: 2048.0\n", f"acc_unit: {acc_unit}\n")
    text = text.replace("time_unit: s\n", f"time_unit: {time_unit}\n")
    (session / "session.yaml").write_text(text)
    return session


def test_data_in_g_declared_as_m_s2_is_an_implausible_norm(tmp_path: Path) -> None:
    labels = _label(_ferraris_in_g(tmp_path, "m/s2"), tmp_path, min_samples=500)
    assert labels.rows == [] and len(labels.rejections) == 6
    for rej in labels.rejections:
        assert rej.reason == "implausible-norm"
        assert re.search(r"‖mean‖ = \d\.\d+ m/s² is 0\.\d+ × g_local \(9\.8100 m/s²\), more than 30% "
                         r"away: likely values in g declared as m/s2$", rej.detail), rej.detail


def test_counts_declared_as_m_s2_name_the_counts(tmp_path: Path) -> None:
    session = tmp_path / "ferraris"
    shutil.copytree(FERRARIS, session)
    text = (session / "session.yaml").read_text().replace("acc_unit: counts\n    lsb_per_g: 2048.0\n",
                                                          "acc_unit: m/s2\n")
    (session / "session.yaml").write_text(text)
    labels = _label(session, tmp_path, min_samples=500)
    assert {r.reason for r in labels.rejections} == {"implausible-norm"}
    assert "likely raw counts declared as m/s2 (about 2048 counts per g" in labels.rejections[0].detail


def test_time_in_s_declared_as_ms_is_an_implausible_rate(tmp_path: Path) -> None:
    labels = _label(_ferraris_in_g(tmp_path, "g", time_unit="ms"), tmp_path, min_samples=500)
    assert {r.reason for r in labels.rejections} == {"implausible-rate"} and labels.rows == []
    detail = labels.rejections[0].detail
    assert re.match(r"measured sample rate 2\.0\d+e\+05 Hz is outside 0\.5–20000 Hz "
                    r"\(time in s declared as ms or µs\?\)", detail), detail


def test_a_rate_that_halves_mid_file_is_flagged(tmp_path: Path) -> None:
    session = _copy_session(tmp_path / "s")
    f = session / "rec-01" / "sparkfun-1.csv"
    head, rows = _logger_rows(f)
    half = len(rows) // 2
    _write_logger(f, head, rows[:half] + rows[half::2])
    labels = _label(session, tmp_path)
    pattern = (r"rec-01/sparkfun-1: sparkfun-1\.csv: the sample rate changes from 1[45]\d\.?\d* Hz "
               r"to 7\d\.?\d* Hz around line \d+; fs_hz")
    assert any(re.search(pattern, w) for w in labels.warnings), labels.warnings


def test_values_clipped_at_the_loggers_range_are_saturation(tmp_path: Path) -> None:
    session = _copy_session(tmp_path / "s")
    f = session / "rec-01" / "sparkfun-1.csv"
    head, rows = _logger_rows(f)
    _write_logger(f, head, [[t, ax, ay, min(az, 256)] for t, ax, ay, az in rows])
    labels = _label(session, tmp_path)
    (rej,) = [r for r in labels.rejections if r.device == "sparkfun-1"]
    assert rej.reason == "saturated"
    assert re.match(r"\d+ of \d+ samples of the stationary segment sit at the same extreme z value "
                    r"9\.80\d* m/s², more than 2 times the value next to it: clipping at the logger's "
                    r"range\? \(record with a wider range\)",
                    rej.detail), rej.detail


def test_unclipped_quantised_noise_is_not_saturation() -> None:
    import numpy as np

    from ofbe_data.labelling.checks import clipped_samples

    rng = np.random.default_rng(3)
    for sigma in (0.3, 0.6, 1.0, 3.0):  # noise in LSB: the extremes thin out
        x = np.rint(rng.normal([3.0, -2.0, 260.0], sigma, (5000, 3)))
        assert clipped_samples(x) is None, sigma
    x = np.rint(rng.normal([3.0, -2.0, 260.0], 2.0, (5000, 3)))
    x[:, 2] = np.minimum(x[:, 2], 259.0)
    assert clipped_samples(x)[1:] == (2, 259.0, False)


def test_oversampled_or_coarse_readings_are_not_saturation() -> None:
    """Issue 22: a logger that writes each reading four times, and a sensor whose axis takes
    two or three levels, looked like a pile-up at an extreme."""
    import numpy as np

    from ofbe_data.labelling.checks import clipped_samples

    rng = np.random.default_rng(5)
    x = np.rint(rng.normal([3.0, -2.0, 260.0], 1.5, (3000, 3)))
    assert clipped_samples(x) is None
    assert clipped_samples(np.repeat(x, 4, axis=0)) is None  # oversampled: each reading 4 times
    for p in (0.3, 0.45, 0.7):  # an axis that takes two levels only (a quiet, coarse sensor)
        coarse = x.copy()
        coarse[:, 0] = np.where(rng.random(3000) < p, -0.27, -0.23)
        assert clipped_samples(coarse) is None, p
    clipped = np.repeat(x, 4, axis=0)
    clipped[:, 2] = np.minimum(clipped[:, 2], 259.0)  # really clipped, and oversampled
    assert clipped_samples(clipped)[1:] == (2, 259.0, False)


def test_an_axis_clipped_on_every_sample_is_saturation(tmp_path: Path) -> None:
    """Issue 24: z held at the range on every sample was labelled (bias_z −0.006 m/s² where the
    unclipped data give +0.288); partial clipping was already rejected."""
    session = _copy_session(tmp_path / "s")
    f = session / "rec-01" / "sparkfun-1.csv"
    head, rows = _logger_rows(f)
    _write_logger(f, head, [[t, ax, ay, 250] for t, ax, ay, az in rows])
    labels = _label(session, tmp_path)
    (rej,) = [r for r in labels.rejections if r.device == "sparkfun-1"]
    assert rej.reason == "saturated" and rej.detail == (
        "the z axis reads 9.5768 m/s² on every sample of the stationary segment while the others vary: "
        "clipped at the logger's range, or stuck (record with a wider range)"), rej.detail


def test_a_mount_that_contradicts_the_reference_is_a_mount_mismatch(tmp_path: Path) -> None:
    session = tmp_path / "rot"
    shutil.copytree(ROT / "rot-pc001", session)
    text = (session / "session.yaml").read_text()
    # sparkfun-1 really sits as declared (identity); declare it turned 90° about z
    text = text.replace("    reference_to_sensor:\n    - [1, 0, 0]\n    - [0, 1, 0]\n    - [0, 0, 1]\n",
                        "    reference_to_sensor:\n    - [0, 1, 0]\n    - [-1, 0, 0]\n    - [0, 0, 1]\n", 1)
    (session / "session.yaml").write_text(text)
    labels = _label(session, tmp_path)
    mine = [r for r in labels.rejections if r.device == "sparkfun-1"]
    assert [r.reason for r in mine] == ["mount-mismatch", "mount-mismatch"]
    assert re.match(r"the DUT's measured gravity direction is \d+\.\d° from the one its declared "
                    r"reference_to_sensor predicts from the reference \(at most 10° expected\)",
                    mine[0].detail), mine[0].detail
    assert all(r["device"] == "sparkfun-2" for r in labels.rows) and len(labels.rows) == 2


def test_a_rate_step_is_reported_in_file_order() -> None:
    """Issue 22: 100 Hz for 4000 samples then 50 Hz for 4500 was reported as "from 50 Hz to
    100 Hz around line 2" (the whole file's median is the later rate)."""
    import numpy as np

    from ofbe_data.labelling.checks import rate_step

    t = np.concatenate([np.arange(4000) * 0.01, 40.0 + np.arange(1, 4501) * 0.02])
    start, before, after = rate_step(t)
    assert 3500 <= start <= 4000 and before == pytest.approx(100.0) and after == pytest.approx(50.0)


def test_a_logger_header_with_lsb_per_g_ten_times_off_names_lsb_per_g(tmp_path: Path) -> None:
    """Issue 22: lsb_per_g 25.6 for 256 read as 'm/s² declared as g' (9.81 is within 10 % of 10)."""
    session = _copy_session(tmp_path / "s")
    for f in session.glob("rec-*/sparkfun-*.csv"):
        f.write_text(f.read_text().replace("lsb_per_g=256", "lsb_per_g=25.6"))
    labels = _label(session, tmp_path)
    assert labels.rows == [] and {r.reason for r in labels.rejections} == {"implausible-norm"}
    detail = labels.rejections[0].detail
    # the board's own 2 % of bias and scale on z make it 10.2
    assert detail.endswith("likely counts scaled with the wrong lsb_per_g (the readings come out 10.2 times "
                           "too large: lsb_per_g looks 10.2 times too small; check the range and resolution "
                           "of the logger)"), detail


def test_rows_sorted_by_another_column_are_named_and_sort_by_time_reads_them(tmp_path: Path) -> None:
    """Issue 22: a file whose rows are grouped by part (time runs backwards between parts) was
    rejected as garbled without the word time; it is named, and ``sort_by_time: true`` reads it
    in time order (raw/ untouched), giving the same label as the file in time order."""
    import numpy as np

    from ofbe_data.labelling.labels import LabelParams, label_session

    rng = np.random.default_rng(2)
    n = 3000
    acc = np.array([0.03, -0.02, 9.83]) + 0.01 * rng.standard_normal((n, 3))
    lines = [f"{i / 100:.2f},{'b' if i < n // 2 else 'a'},{a[0]:.5f},{a[1]:.5f},{a[2]:.5f}"
             for i, a in enumerate(acc)]
    by_part = sorted(lines, key=lambda ln: ln.split(",")[1])  # part a (the later half) first
    folder = tmp_path / "camp" / "s1"
    folder.mkdir(parents=True)
    (folder / "r1.csv").write_text("t,part,ax,ay,az\n" + "\n".join(by_part) + "\n")
    manifest = ("format: ofbe-session/1\ncampaign: camp\nsession: s1\nkind: gravity-aligned\n"
                "site: {gravity_mps2: 9.80665}\npower_cycle: 1\ndevices:\n  dut:\n    model: X\n"
                "    role: dut\n    format: csv\n    columns: {t: t, ax: ax, ay: ay, az: az}\n{extra}"
                "recordings:\n  - id: r1\n    files: {dut: r1.csv}\n")
    (folder / "session.yaml").write_text(manifest.replace("{extra}", ""))
    before = (folder / "r1.csv").read_bytes()
    labels = label_session(folder, LabelParams(min_samples=1000))
    (rej,) = labels.rejections
    assert rej.reason == "garbled" and "1500 with a time stamp that repeats or runs backwards" in rej.detail
    assert "sort_by_time: true" in rej.detail
    (folder / "session.yaml").write_text(manifest.replace("{extra}", "    sort_by_time: true\n"))
    labels = label_session(folder, LabelParams(min_samples=1000))
    assert labels.rejections == [] and (folder / "r1.csv").read_bytes() == before
    (row,) = labels.rows
    np.testing.assert_allclose([row[f"bias_{a}"] for a in "xyz"], [0.03, -0.02, 9.83 - 9.80665], atol=1e-3)


@pytest.mark.slow
def test_a_huge_sparse_file_is_refused_before_it_is_read(tmp_path: Path) -> None:
    """Issue 24: a 2 GB file (a good log, then a sparse tail) grew check and label to 24 GB and
    the kernel killed them. It is refused with where the data ends, before it is read
    (benchmarks/huge_file.py measures the peak memory)."""
    session = _copy_session(tmp_path / "s")
    f = session / "rec-01" / "sparkfun-1.csv"
    data_bytes = f.stat().st_size
    os.truncate(f, 2 * 2**30)  # sparse: no disk used
    done = _run(["ofbe_data.cli.label", str(session), "--out", str(tmp_path / "labels"), "--quiet"],
                timeout=120)
    assert done.returncode == 1 and not list((tmp_path / "labels").rglob("*.parquet"))
    (line,) = [ln for ln in done.stderr.splitlines() if "error:" in ln]  # and the summary line
    assert "Traceback" not in done.stderr
    assert line.endswith(
        f"sparkfun-1.csv: expected text data, found {(2 * 2**30 - data_bytes) / 1e6:.1f} MB from byte "
        f"{data_bytes} on that start with 4096 NUL bytes in a row (a preallocated or sparse file: "
        f"{data_bytes / 1e6:.1f} MB of it is data; keep the first {data_bytes} bytes in a copy, raw/ stays "
        "as it is)"), line
    checked = _run(["ofbe_data.cli.session", "check", str(session)], timeout=120)
    assert checked.returncode == 1 and "preallocated or sparse file" in checked.stdout
    loose = tmp_path / "loose"  # init on a folder of files (it read the file whole: 6.4 GB, 21 s)
    loose.mkdir()
    os.link(f, loose / f.name)
    init = _run(["ofbe_data.cli.session", "init", str(loose)], timeout=120)
    assert init.returncode == 1 and "Traceback" not in init.stderr
    reason = line.split("sparkfun-1.csv", 1)[1]  # the same words as ofbe-label's
    assert init.stderr.strip() == f"ofbe-session: error: {loose / f.name}{reason}", init.stderr
    assert f.stat().st_size == 2 * 2**30  # raw/ untouched


def test_likely_mistakes_are_named() -> None:
    from ofbe_data.labelling.checks import likely_mistake

    assert likely_mistake(1 / 9.80665) == "values in g declared as m/s2"
    assert likely_mistake(9.80665) == "values in m/s² declared as g"
    assert likely_mistake(1000.0) == "values in mg declared as g"
    assert likely_mistake(2.0).startswith("counts scaled with the wrong lsb_per_g (off by 2^1 = 2")
    assert likely_mistake(0.0) == "no signal (all readings zero or not finite)"
    assert likely_mistake(1.7) == "a unit or scale mistake, or a sensor that is not at rest"
