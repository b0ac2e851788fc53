"""The execution layer (ofbe_data.core.parallel, ofbe_data.core.scheduler): the same results in
the same order on a process pool, an embedded Dask cluster and a running one; a task that raises
and a worker that dies are reported with their exact reasons while the other items complete;
retries; ``--scheduler`` checked on every batch command."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ofbe_data.core import scheduler as scheduler_module
from ofbe_data.core.parallel import TaskError, TaskFailure, iter_ordered, kept_workers, map_progress
from ofbe_data.core.scheduler import SchedulerError, check_scheduler
from tests.helpers.paths import ROOT

SCHEDULERS = ("processes", "dask")
DIED_TWICE = "its worker process died (exit code 3) on each of 2 attempts; nothing of it was kept"


# ----------------------------------------------------------------------------- tasks (module level:
# the workers import them)


def _square(x: int) -> tuple[int, int]:
    """Later items finish first, so completion order is not input order."""
    time.sleep(0.01 * (12 - x))
    return x, x * x


def _faulty(x: int) -> int:
    if x == 3:
        os._exit(3)
    if x == 5:
        raise ValueError(f"item {x} is bad")
    return 10 * x


def _dies_once(args: tuple[int, str]) -> int:
    """Item 2 kills its worker the first time it runs (a marker file says it has run)."""
    x, marker = args
    if x == 2 and not Path(marker).exists():
        Path(marker).write_text("ran")
        os._exit(3)
    return x


def _env(_: int) -> str:
    return os.environ.get("OFBE_TEST_WORKER_ENV", "unset")


# ----------------------------------------------------------------------------- results


@pytest.mark.slow
def test_every_scheduler_gives_the_same_results_in_input_order(capsys) -> None:
    items = list(range(12))
    expected = [(x, x * x) for x in items]
    assert map_progress(_square, items, jobs=1, desc="squares") == expected
    for scheduler in SCHEDULERS:
        assert map_progress(_square, items, jobs=2, scheduler=scheduler, desc="squares") == expected
        err = capsys.readouterr().err
        assert "squares: 100%" in err and "12/12" in err, scheduler
        assert "distributed" not in err and "Traceback" not in err, scheduler


@pytest.mark.slow
def test_a_running_cluster_is_joined_by_its_address() -> None:
    import dask
    from distributed import LocalCluster

    expected = [(x, x * x) for x in range(6)]
    env = {"OFBE_TEST_WORKER_ENV": "remote"}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=50) as cluster:
        address = cluster.scheduler_address
        assert address.startswith("tcp://")
        assert map_progress(_square, list(range(6)), jobs=2, scheduler=address) == expected
        # a task with a worker environment runs in a process of its worker's: not from a daemonic one
        why = ("RuntimeError: this Dask worker is a daemonic process and cannot start the process a task "
               "with a worker environment runs in: start the workers with "
               "DASK_DISTRIBUTED__WORKER__DAEMON=False")
        assert map_progress(_env, [0], scheduler=address, worker_env=env, on_error="collect") == \
            [TaskFailure(0, why)]
    with dask.config.set({"distributed.worker.daemon": False}), \
            LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                         silence_logs=50) as cluster:
        assert map_progress(_env, [0, 1], jobs=2, scheduler=cluster.scheduler_address,
                            worker_env=env) == ["remote", "remote"]


def test_an_address_nobody_answers_is_one_line(monkeypatch) -> None:
    monkeypatch.setattr(scheduler_module, "_CONNECT_TIMEOUT", "1s")
    with pytest.raises(SchedulerError) as info:
        map_progress(_square, [1, 2], jobs=2, scheduler="tcp://127.0.0.1:9")
    assert str(info.value).startswith("--scheduler tcp://127.0.0.1:9: expected a running Dask scheduler, "
                                      "found none answering (")
    assert "\n" not in str(info.value)


@pytest.mark.slow
@pytest.mark.parametrize("scheduler", SCHEDULERS)
def test_the_worker_environment_is_set_before_the_task_runs(scheduler: str) -> None:
    env = {"OFBE_TEST_WORKER_ENV": "set"}
    assert map_progress(_env, [0, 1, 2], jobs=2, scheduler=scheduler, worker_env=env) == ["set"] * 3
    # with one job too: the environment is a worker's, never this process's
    assert map_progress(_env, [0], jobs=1, scheduler=scheduler, worker_env=env) == ["set"]
    assert "OFBE_TEST_WORKER_ENV" not in os.environ


@pytest.mark.slow
def test_the_default_scheduler_never_imports_dask() -> None:
    code = ("import sys\n"
            "import ofbe_data, ofbe_data.cli.label\n"
            "from ofbe_data.core.parallel import map_progress\n"
            "assert map_progress(abs, [-1, -2, -3], jobs=2, progress=False) == [1, 2, 3]\n"
            "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed'))\n"
            "assert not bad, bad\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr


@pytest.mark.slow
def test_iter_ordered_streams_in_input_order() -> None:
    items = list(range(12))
    for scheduler in SCHEDULERS:
        assert list(iter_ordered(_square, items, jobs=2, scheduler=scheduler, ahead=1)) == \
            [(x, x * x) for x in items], scheduler


# ----------------------------------------------------------------------------- failures


@pytest.mark.slow
@pytest.mark.parametrize("worker_env", [None, {"OFBE_TEST_WORKER_ENV": "set"}], ids=["shared", "own-process"])
@pytest.mark.parametrize("scheduler", SCHEDULERS)
def test_a_raising_task_and_a_dying_worker_are_named_and_the_others_complete(scheduler: str,
                                                                            worker_env: dict | None) -> None:
    # with a worker environment, Dask runs each task in a process of the worker's own
    results = map_progress(_faulty, list(range(8)), jobs=2, scheduler=scheduler, on_error="collect",
                           progress=False, worker_env=worker_env)
    assert results == [0, 10, 20, TaskFailure(3, DIED_TWICE), 40, TaskFailure(5, "ValueError: item 5 is bad"),
                       60, 70]


@pytest.mark.slow
@pytest.mark.parametrize("scheduler", SCHEDULERS)
def test_raise_mode_raises_the_first_failure_once_the_others_are_done(scheduler: str, tmp_path) -> None:
    with pytest.raises(TaskError) as info:
        map_progress(_faulty, [0, 3, 4], jobs=2, scheduler=scheduler, progress=False,
                     name=lambda x: f"session s{x}")
    assert str(info.value) == f"session s3: {DIED_TWICE}"
    assert info.value.failure == TaskFailure(1, DIED_TWICE)
    with pytest.raises(ValueError) as raised:
        map_progress(_faulty, [5, 1, 3], jobs=2, scheduler=scheduler, progress=False)
    assert str(raised.value) == "item 5 is bad"
    assert raised.value.__notes__ == ["1 other item failed too"]


def test_the_in_process_path_reports_a_raising_task_too() -> None:
    assert map_progress(_faulty, [1, 5, 2], on_error="collect") == \
        [10, TaskFailure(1, "ValueError: item 5 is bad"), 20]


@pytest.mark.slow
@pytest.mark.parametrize("scheduler", SCHEDULERS)
def test_a_task_whose_worker_died_once_is_retried(scheduler: str, tmp_path) -> None:
    items = [(x, str(tmp_path / "ran")) for x in range(5)]
    assert map_progress(_dies_once, items, jobs=2, scheduler=scheduler, progress=False) == list(range(5))
    assert (tmp_path / "ran").exists()
    (tmp_path / "ran").unlink()
    results = map_progress(_dies_once, items, jobs=2, scheduler=scheduler, retries=0, on_error="collect",
                           progress=False)
    once = "its worker process died (exit code 3) once; nothing of it was kept"
    assert results == [0, 1, TaskFailure(2, once), 3, 4]


@pytest.mark.slow
@pytest.mark.parametrize("scheduler", SCHEDULERS)
def test_iter_ordered_raises_at_the_failed_item(scheduler: str) -> None:
    got = []
    with pytest.raises(TaskError) as info:
        for value in iter_ordered(_faulty, [0, 1, 2, 3, 4], jobs=2, scheduler=scheduler):
            got.append(value)
    assert str(info.value) == f"item 3: {DIED_TWICE}"
    assert got == [0, 10, 20]


def _label_or_die(folder, params, keep_segments=False, manifest=None):
    """``label_session``, except that the worker labelling the second session dies."""
    from ofbe_data.labelling.labels import label_session

    if folder.name.endswith("pc002"):
        os._exit(3)
    return label_session(folder, params, keep_segments=keep_segments, manifest=manifest)


def test_ofbe_label_names_a_session_whose_worker_died_and_writes_the_others(tmp_path, capsys,
                                                                           monkeypatch) -> None:
    from ofbe_data.cli.label import main as label_main
    from ofbe_data.labelling import batch

    # the process pool forks its workers, which inherit the patched function
    monkeypatch.setattr(batch, "label_session", _label_or_die)
    raw = ROOT / "raw" / "examples" / "tiny-gravity-aligned"
    out = tmp_path / "labels"
    assert label_main([str(raw), "--out", str(out), "--jobs", "2", "--min-samples", "2000"]) == 1
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "error:" in line]
    assert lines == [f"ofbe-label: error: {raw / 'ga-pc002'}: {DIED_TWICE}"]
    assert "ofbe-label: 2 sessions labelled, 1 failed;" in err
    written = sorted(p.name for p in (out / "tiny-gravity-aligned").glob("*.parquet"))
    assert written == ["ga-pc001.parquet", "ga-pc003.parquet"]


# ----------------------------------------------------------------------------- --scheduler


def test_scheduler_names_are_checked() -> None:
    for good in ("processes", "dask", "tcp://10.0.0.5:8786", "tcp://head-node.local:8786", "tcp://[::1]:8786"):
        assert check_scheduler(good) == good
    with pytest.raises(ValueError, match=r"^expected a port 1-65535 in the address, found 'tcp://h:0'$"):
        check_scheduler("tcp://h:0")
    with pytest.raises(ValueError, match="^on_error: expected 'raise' or 'collect', found 'ignore'$"):
        map_progress(abs, [1], on_error="ignore")  # type: ignore[call-overload]


def _mains():
    from ofbe_data.cli.convergence import main as convergence
    from ofbe_data.cli.dataset import main as dataset
    from ofbe_data.cli.label import main as label
    from ofbe_data.cli.simulate import main as simulate
    from ofbe_model.cli.benchmark import main as benchmark
    from ofbe_model.cli.train import main as train

    return {"ofbe-label": (label, ["raw/x"]), "ofbe-convergence": (convergence, ["raw/x"]),
            "ofbe-dataset": (dataset, ["build", "labels/x", "--raw", "raw/x"]),
            "ofbe-simulate": (simulate, ["tiny-rotated", "--out", "raw/x"]),
            "ofbe-train": (train, ["ds", "--protocol", "grouped"]),
            "ofbe-benchmark": (benchmark, ["ds", "--protocol", "grouped"])}


@pytest.mark.parametrize("prog", ["ofbe-label", "ofbe-convergence", "ofbe-dataset", "ofbe-simulate",
                                  "ofbe-train", "ofbe-benchmark"])
def test_a_bad_scheduler_is_a_usage_error_naming_the_flag(prog: str, capsys, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    main, args = _mains()[prog]
    with pytest.raises(SystemExit) as info:
        main([*args, "--scheduler", "spark://x"])
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    sub = " build" if prog == "ofbe-dataset" else ""
    assert err[-1] == (f"{prog}{sub}: error: argument --scheduler: expected processes, dask or a Dask "
                       "scheduler address (tcp://host:port), found 'spark://x'")
    assert not any(tmp_path.iterdir())


# ----------------------------------------------------------------------------- kept workers


def _pid(_: int) -> int:
    time.sleep(0.2)  # long enough for both workers to take items
    return os.getpid()


def _zombie(pid: int) -> bool:
    """Whether child ``pid`` has ended (a zombie until its parent reaps it), on Linux."""
    stat = Path(f"/proc/{pid}/stat")
    return not stat.exists() or stat.read_text().rsplit(")", 1)[1].split()[0] == "Z"


@pytest.mark.slow
def test_kept_workers_serve_the_next_call_that_would_start_the_same_ones(monkeypatch) -> None:
    env = {"OFBE_TEST_WORKER_ENV": "set"}
    outside = [set(map_progress(_pid, range(4), jobs=2, worker_env=env, progress=False)) for _ in (0, 1)]
    assert not outside[0] & outside[1]  # outside the block, each call starts its own
    with kept_workers():
        first = set(map_progress(_pid, range(4), jobs=2, worker_env=env, progress=False))
        assert len(first) == 2
        assert set(map_progress(_pid, range(4), jobs=2, worker_env=env, progress=False)) == first
        assert set(map_progress(_pid, range(2), jobs=1, worker_env=env, progress=False)) < first
        # another environment, here or given: other workers
        assert not set(map_progress(_pid, range(2), jobs=1, worker_env={"OFBE_TEST_WORKER_ENV": "other"},
                                    progress=False)) & first
        monkeypatch.setenv("OFBE_TEST_PARENT_ENV", "changed")
        assert not set(map_progress(_pid, range(2), jobs=1, worker_env=env, progress=False)) & first
        monkeypatch.delenv("OFBE_TEST_PARENT_ENV")
        # a kept worker that died while idle is replaced, not charged to an item (retries=0)
        dead = min(first)
        os.kill(dead, 9)
        deadline = time.monotonic() + 60
        while not _zombie(dead) and time.monotonic() < deadline:
            time.sleep(0.05)
        again = set(map_progress(_pid, range(4), jobs=2, worker_env=env, retries=0, progress=False))
        assert dead not in again and max(first) in again and len(again) == 2
        kept = again
    # the block ended them all
    assert all(_zombie(pid) for pid in kept | first) and not os.environ.get("OFBE_TEST_PARENT_ENV")


@pytest.mark.slow
def test_an_interrupted_call_ends_its_workers_inside_the_block_too() -> None:
    env = {"OFBE_TEST_WORKER_ENV": "set"}
    with kept_workers():
        first = set(map_progress(_pid, range(2), jobs=1, worker_env=env, progress=False))
        stream = iter_ordered(_pid, list(range(6)), jobs=1, worker_env=env)
        assert next(stream) in first
        stream.close()  # the consumer stops early: as on Ctrl-C, the worker is stopped at once
        assert all(_zombie(pid) for pid in first)
        assert not set(map_progress(_pid, range(2), jobs=1, worker_env=env, progress=False)) & first
