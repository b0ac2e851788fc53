"""Ctrl-C at any moment (issue 36): a command interrupted while Python imports its modules, while
it starts its workers, while they run, while it writes or ends prints one line and exits 130 (or
0 when it had already finished), never a traceback, never hangs, and leaves nothing partial: no
temporary file or folder in its output folder or its temporary folder, no process, and outputs
that are byte for byte those of an uninterrupted run, or absent.

Each command runs as its console script does (the script pip generates for
``ofbe_data.core.entry``), in a process group of its own, and SIGINT goes to the whole group as a
terminal sends it. The instants are counted from the script's first line after its import of
``ofbe_data.core.entry`` (Python's own start-up, before that, is out of any module's reach) and
spread from 0 to beyond the end of an uninterrupted run (measured first): set
``OFBE_INTERRUPT_INSTANTS`` to run more of them than the default 8 per command.

The batch commands covered: ``ofbe-simulate --jobs 2`` (local processes and an embedded Dask
cluster), ``ofbe-label --jobs 2``, ``ofbe-dataset build --jobs 2``, ``ofbe-autocal --jobs 2``,
``ofbe-session check`` and ``ofbe-export json``, on one campaign simulated and labelled once for
the module.
"""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from importlib import import_module
from pathlib import Path

import pytest

from ofbe_data.core.cli import EXIT_INTERRUPTED
from ofbe_data.core.entry import INTERRUPTED
from tests.helpers.paths import ROOT

pytestmark = pytest.mark.slow
"""Slow: a campaign or model fixture shared by the module (``-m "not slow"`` leaves it out)."""

INSTANTS = int(os.environ.get("OFBE_INTERRUPT_INSTANTS", "8"))
TIMEOUT_S = 120  # the machine may be slow and busy: a hang is far longer
MARK_FD = "OFBE_TEST_MARK_FD"

# the console script pip writes for ``ofbe-x = "ofbe_data.cli.entry:x"``, plus one line that tells
# the test the script has started (the instants are counted from there); in the ``__main__`` block,
# which a spawned process (a Dask worker) does not run when it imports the script again
SCRIPT = """#!{python}
# -*- coding: utf-8 -*-
import re
import sys
from {module} import {func}
if __name__ == '__main__':
    import os; os.write(int(os.environ["{mark}"]), b"."); os.close(int(os.environ["{mark}"]))
    sys.argv[0] = re.sub(r'(-script\\.pyw|\\.exe)?$', '', sys.argv[0])
    sys.exit({func}())
"""


def _entry(prog: str) -> tuple[str, str]:
    """``(module, function)`` of a command's console script: the first of the two packages' entry
    modules that has it (``ofbe-export`` has been in either)."""
    func = prog.removeprefix("ofbe-").replace("-", "_")
    for module in ("ofbe_data.cli.entry", "ofbe_model.cli.entry"):
        if hasattr(import_module(module), func):
            return module, func
    raise AssertionError(f"no console script {func} in ofbe_data.cli.entry or ofbe_model.cli.entry")


def _script(folder: Path, prog: str) -> Path:
    path = folder / prog
    module, func = _entry(prog)
    path.write_text(SCRIPT.format(python=sys.executable, module=module, func=func, mark=MARK_FD))
    path.chmod(0o755)
    return path


def _tree(root: Path) -> dict[str, bytes | None]:
    """Every file (its bytes) and folder (None) under ``root``, by relative path."""
    return {p.relative_to(root).as_posix(): (p.read_bytes() if p.is_file() else None)
            for p in sorted(root.rglob("*"))}


class Run:
    """One run of a command: exit status, stderr, seconds from the script's start to its end."""

    def __init__(self, code: int, err: str, seconds: float) -> None:
        self.code, self.err, self.seconds = code, err, seconds


def _run(script: Path, args: list[str], tmp: Path, at: float | None) -> Run:
    """Run ``script args`` with TMPDIR ``tmp``; send SIGINT to its group ``at`` seconds after the
    script started (never when None)."""
    read, write = os.pipe()
    # SOURCE_DATE_EPOCH: the time an export states it was written, the same in every run
    env = {**os.environ, "TMPDIR": str(tmp), MARK_FD: str(write), "SOURCE_DATE_EPOCH": "1800000000"}
    proc = subprocess.Popen(
        [sys.executable, str(script), *args], cwd=ROOT, env=env, stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE, text=True, pass_fds=(write,),
        start_new_session=True,  # a process group of its own, as a terminal's foreground job
        # a CI runner may start us with SIGINT ignored: the default, as a terminal gives
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    os.close(write)
    try:
        ready, _, _ = select.select([read], [], [], TIMEOUT_S)
        if not (ready and os.read(read, 1) == b"."):
            _, err = proc.communicate(timeout=TIMEOUT_S)
            pytest.fail(f"{script.name} did not start (exit status {proc.returncode}): {err[-3000:]}")
        started = time.monotonic()
        if at is not None:
            time.sleep(max(0.0, started + at - time.monotonic()))
            os.killpg(proc.pid, signal.SIGINT)
        try:
            _, err = proc.communicate(timeout=TIMEOUT_S)
        except subprocess.TimeoutExpired:
            pytest.fail(f"{script.name} hung after SIGINT at {at} s")
        seconds = time.monotonic() - started
    finally:
        os.close(read)
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    # nothing of the group left running (a worker would be an orphan now)
    deadline = time.monotonic() + 10
    while True:
        try:
            os.killpg(proc.pid, 0)
        except ProcessLookupError:
            break
        assert time.monotonic() < deadline, f"a process of {script.name}'s group outlived it"
        time.sleep(0.05)
    return Run(proc.returncode, err, seconds)


def _instants(duration: float, n: int) -> list[float]:
    """``n`` instants from 0 (the command's imports) to 1.25 × ``duration`` (after its end),
    closer together early on (in the square of the time: start-up is short, the work longer)."""
    n = max(2, n)
    last = max(0.1, 1.25 * duration)
    return [last * (k / (n - 1)) ** 2 for k in range(n)]


def _lines(err: str) -> list[str]:
    return [ln for ln in err.replace("\r", "\n").splitlines() if ln.strip()]


def _check(run: Run, prog: str, at: float, finished: list[str] | None = None) -> None:
    """One line and exit 130, or exit 0 with the lines an uninterrupted run prints on stderr
    (``finished``; none by default)."""
    lines = _lines(run.err)
    assert "Traceback" not in run.err and "KeyboardInterrupt" not in run.err, (at, run.err[-3000:])
    assert run.code in (0, EXIT_INTERRUPTED), (at, run.code, run.err[-3000:])
    if run.code == EXIT_INTERRUPTED:
        assert lines == [f"{prog}: {INTERRUPTED}"], (at, lines)
    else:
        assert lines == (finished or []), (at, lines)


def _simulate(script: Path, out: Path, temp: Path, scheduler: str, at: float | None) -> Run:
    return _run(script, ["tiny-fleet", "--out", str(out), "--jobs", "2", "--scheduler", scheduler, "--quiet"],
                temp, at)


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    """Uninterrupted runs: the campaign ``ofbe-simulate tiny-fleet`` writes and the labels
    ``ofbe-label`` writes of it, with their durations."""
    base = tmp_path_factory.mktemp("reference")
    temp = base / "tmp"
    temp.mkdir()
    camp = base / "camp"
    simulate = _simulate(_script(base, "ofbe-simulate"), camp, temp, "processes", None)
    assert simulate.code == 0, simulate.err
    labels = base / "labels"
    label = _run(_script(base, "ofbe-label"), [str(camp), "--out", str(labels), "--jobs", "2", "--quiet"],
                 temp, None)
    assert label.code == 0, label.err
    assert list(temp.iterdir()) == []
    return {"camp": camp, "campaign": _tree(camp), "simulate_s": simulate.seconds,
            "labels": _tree(labels), "label_s": label.seconds, "label_folder": labels / "camp"}


# The embedded-Dask case was opt-in for a while (one failure in about ten runs at stop 38, its cause
# not found); at stop 40 it passed 14 runs in a row, 4 of them beside the fast test loop (load 4 on
# two cores), and runs always.
@pytest.mark.parametrize("scheduler", ["processes", "dask"])
def test_ctrl_c_at_any_moment_of_ofbe_simulate(reference, tmp_path: Path, scheduler: str) -> None:
    script = _script(tmp_path, "ofbe-simulate")
    duration, instants = float(reference["simulate_s"]), INSTANTS  # type: ignore[arg-type]
    if scheduler == "dask":  # slower to start and stop: half the instants
        temp = tmp_path / "tmp"
        temp.mkdir()
        run = _simulate(script, tmp_path / "camp", temp, scheduler, None)
        assert run.code == 0 and _tree(tmp_path / "camp") == reference["campaign"], run.err
        assert list(temp.iterdir()) == []
        duration, instants = run.seconds, max(2, INSTANTS // 2)
    outcomes = []
    for k, at in enumerate(_instants(duration, instants)):
        temp, parent = tmp_path / f"tmp{k}", tmp_path / f"out{k}"
        temp.mkdir()
        parent.mkdir()
        out = parent / "camp"
        run = _simulate(script, out, temp, scheduler, at)
        _check(run, "ofbe-simulate", at)
        # the campaign is whole (the same bytes as an uninterrupted run's) or absent, with nothing beside it
        assert [p.name for p in parent.iterdir()] == (["camp"] if out.exists() else []), (at, run.code)
        if run.code == 0 or out.exists():
            assert _tree(out) == reference["campaign"], at
        assert list(temp.iterdir()) == [], at
        outcomes.append((round(at, 2), run.code))
    print(f"ofbe-simulate --scheduler {scheduler}: (instant s, exit status)", outcomes)


def test_ctrl_c_at_any_moment_of_ofbe_label(reference, tmp_path: Path) -> None:
    script = _script(tmp_path, "ofbe-label")
    whole: dict[str, bytes | None] = reference["labels"]  # type: ignore[assignment]
    outcomes = []
    for k, at in enumerate(_instants(float(reference["label_s"]), INSTANTS)):  # type: ignore[arg-type]
        temp = tmp_path / f"tmp{k}"
        temp.mkdir()
        out = tmp_path / f"labels{k}"
        run = _run(script, [str(reference["camp"]), "--out", str(out), "--jobs", "2", "--quiet"], temp, at)
        _check(run, "ofbe-label", at)
        # each label file is whole (the bytes of an uninterrupted run) or absent, no temporary name
        got = _tree(out) if out.exists() else {}
        assert set(got) <= set(whole), (at, sorted(set(got) - set(whole)))
        assert {name: data for name, data in got.items() if data is not None} == \
            {name: whole[name] for name, data in got.items() if data is not None}, at
        if run.code == 0:
            assert got == whole, at
        assert list(temp.iterdir()) == [], at
        outcomes.append((round(at, 2), run.code))
    print("ofbe-label: (instant s, exit status)", outcomes)


@pytest.fixture(scope="module")
def wear(tiny_free_living: Path) -> list[str]:
    """Three recordings of the session's ``tiny-free-living`` campaign (conftest.py) for
    ``ofbe-autocal``: two epoch csv files and one csv of samples (as ``test_autocal_jobs.py``)."""
    root = tiny_free_living
    return [str(root / "tfl" / "epochs" / "wear-001.csv"), str(root / "tfl" / "epochs" / "wear-002.csv"),
            str(root / "tfl" / "wear-003" / "rec-01" / "wear-003.csv")]


BATCH = ["dataset-build", "autocal", "session-check", "export-json"]
"""The other batch commands, by test id."""


def _batch_args(command: str, reference: dict[str, object], wear: list[str],
                out: Path) -> tuple[str, list[str]]:
    """The console script and arguments of one of :data:`BATCH`, writing to ``out``."""
    camp, labels = str(reference["camp"]), str(reference["label_folder"])
    return {
        "dataset-build": ("ofbe-dataset", ["build", labels, "--raw", camp, "--out", str(out), "--jobs", "2",
                                           "--quiet"]),
        "autocal": ("ofbe-autocal", [*wear, "--out", str(out), "--jobs", "2", "--quiet"]),
        "session-check": ("ofbe-session", ["check", camp]),
        "export-json": ("ofbe-export", ["json", labels, "--out", f"{out}/"]),
    }[command]


WHOLE_FOLDER = {"dataset-build"}
"""Commands whose output folder appears whole (a temporary folder renamed) or not at all; the
others write file by file, each whole."""


@pytest.mark.parametrize("command", BATCH)
def test_ctrl_c_at_any_moment_of_the_other_batch_commands(reference, wear: list[str], tmp_path: Path,
                                                          command: str) -> None:
    """``ofbe-dataset build``, ``ofbe-autocal`` (both with two worker processes), ``ofbe-session
    check`` (which writes nothing) and ``ofbe-export json``: one line and exit 130, or exit 0;
    each output whole (the bytes of an uninterrupted run) or absent, nothing beside it."""
    base = tmp_path / "whole"
    base.mkdir()
    temp = base / "tmp"
    temp.mkdir()
    prog, args = _batch_args(command, reference, wear, base / "out")
    script = _script(tmp_path, prog)
    whole_run = _run(script, args, temp, None)
    assert whole_run.code == 0, whole_run.err
    assert list(temp.iterdir()) == [], command
    whole = _tree(base / "out") if (base / "out").exists() else {}
    assert (whole == {}) == (command == "session-check"), command
    outcomes = []
    for k, at in enumerate(_instants(whole_run.seconds, INSTANTS)):
        temp, parent = tmp_path / f"tmp{k}", tmp_path / f"out{k}"
        temp.mkdir()
        parent.mkdir()
        out = parent / "out"
        run = _run(script, _batch_args(command, reference, wear, out)[1], temp, at)
        _check(run, prog, at, _lines(whole_run.err))
        assert [p.name for p in parent.iterdir()] in ([], ["out"]), (at, run.code, list(parent.iterdir()))
        got = _tree(out) if out.exists() else {}
        assert set(got) <= set(whole), (at, sorted(set(got) - set(whole)))
        assert {name: data for name, data in got.items() if data is not None} == \
            {name: whole[name] for name, data in got.items() if data is not None}, at
        if run.code == 0 or (command in WHOLE_FOLDER and out.exists()):
            assert got == whole, (at, run.code)
        assert list(temp.iterdir()) == [], (at, list(temp.iterdir()))
        outcomes.append((round(at, 2), run.code))
    print(f"{prog} ({command}): (instant s, exit status)", outcomes)
