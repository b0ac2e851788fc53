"""Where :func:`ofbe_data.core.parallel.map_progress` runs its tasks: the scheduler names, the
failure types every scheduler reports, and the Dask back end.

Three schedulers (``--scheduler``):

``processes``
    A local process pool (``concurrent.futures``), the default; Dask is never imported.
``dask``
    An embedded Dask ``LocalCluster``: ``jobs`` worker processes of one thread each, started
    for the call and closed after it.
``tcp://host:port``
    The scheduler of a running Dask cluster, joined as a client (its workers must see the
    same file system, since tasks take paths and write their outputs there).

Dask is imported here lazily, inside the functions that need it, so that ``import ofbe_data``
and every command run with the default scheduler stay fast.

A task that raises is reported with its exception; a task whose worker process dies (killed
by the kernel for memory, a crash in native code, ``os._exit``) is run again up to
``retries`` times (the toolkit's tasks are idempotent: they write whole files or none) and
then reported as a :class:`TaskFailure` whose reason says so.
"""

from __future__ import annotations

import contextlib
import heapq
import logging
import multiprocessing
import os
import pickle
import re
import shutil
import tempfile
import threading
import time
import uuid
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from typing import Any

from ofbe_data.core.atomic import interrupts_deferred
from ofbe_data.core.errors import OfbeError
from ofbe_data.core.worker_setup import init_worker

PROCESSES = "processes"
"""The local process pool (the default)."""
DASK = "dask"
"""An embedded Dask LocalCluster."""
DEFAULT_RETRIES = 1
"""Further attempts of a task whose worker process died, before it is reported failed."""

_ADDRESS = re.compile(r"tcp://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(\d{1,5})")
_EXPECTED = "processes, dask or a Dask scheduler address (tcp://host:port)"
_LOCAL_CONNECT_TIMEOUT = "5s"
"""Dask's connect timeout while an embedded cluster runs (everything on this machine): a result
fetched from a worker that has just died fails after this rather than after Dask's default
30 s, and its task runs again."""
_CONNECT_TIMEOUT = "30s"
"""How long joining a running cluster may take."""
_DEATH = re.compile(r"Worker process (\d+) (?:exited with status (\d+)|was killed by signal (\d+))")


@dataclass(frozen=True)
class TaskFailure:
    """One task that did not return: what :func:`~ofbe_data.core.parallel.map_progress` gives
    in its place with ``on_error="collect"``.

    Attributes
    ----------
    item_index
        Index of the task's item in the items given.
    reason
        One line: ``<ExceptionType>: <message>`` for a task that raised (the message alone
        for the toolkit's own errors), or what happened to its worker process.
    """

    item_index: int
    reason: str


class TaskError(OfbeError):
    """A task failed without an exception of its own (its worker process died), with
    ``on_error="raise"``.

    Parameters
    ----------
    failure
        The failure.
    name
        The item's name in the message (``item <index>`` when empty).
    """

    def __init__(self, failure: TaskFailure, name: str = "") -> None:
        self.failure = failure
        super().__init__(f"{name or f'item {failure.item_index}'}: {failure.reason}")


class SchedulerError(OfbeError):
    """The Dask scheduler cannot be reached, or the cluster went away during the run."""


def check_scheduler(value: str) -> str:
    """``value`` if it names a scheduler (``processes``, ``dask`` or ``tcp://host:port``).

    Raises
    ------
    ValueError
        Anything else; the message says what was expected and what was found.
    """
    if value in (PROCESSES, DASK) or _ADDRESS.fullmatch(value):
        if value.startswith("tcp://") and not 0 < int(value.rsplit(":", 1)[1]) < 65536:
            raise ValueError(f"expected a port 1-65535 in the address, found {value!r}")
        return value
    raise ValueError(f"expected {_EXPECTED}, found {value!r}")


def failure_reason(exc: BaseException) -> str:
    """One line for a task's exception: the toolkit's own errors as they are, others with
    their type (``ValueError: …``)."""
    text = " ".join(str(exc).split())
    if isinstance(exc, OfbeError) and text:
        return text
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def death_reason(attempts: int, exit_code: int | None) -> str:
    """The reason of a task whose worker process died on each of ``attempts`` attempts.

    A negative ``exit_code`` is a signal (−9: killed, often by the kernel for memory).
    """
    if exit_code is None:
        how = ""
    elif exit_code < 0:
        how = f" (killed by signal {-exit_code}{', out of memory?' if exit_code == -9 else ''})"
    else:
        how = f" (exit code {exit_code})"
    times = "once" if attempts == 1 else f"on each of {attempts} attempts"
    return f"its worker process died{how} {times}; nothing of it was kept"


class ChildDied(Exception):
    """In a Dask worker: the isolated process running a task died (see :func:`run_isolated`).

    Parameters
    ----------
    exit_code
        Its exit code (negative: the signal that killed it), or None when unknown.
    """

    def __init__(self, exit_code: int | None) -> None:
        super().__init__(exit_code)
        self.exit_code = exit_code


_CHILDREN: dict[tuple[tuple[str, str], ...], ProcessPoolExecutor] = {}
"""In a Dask worker: its isolated process per environment, kept for the next task."""


def _init_isolated(env: Mapping[str, str], parent: int) -> None:
    """Set-up of a :func:`run_isolated` process: the pool worker's, plus a watch that ends it
    when its Dask worker is gone (a killed worker cannot shut it down)."""
    init_worker(env)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(0)

    threading.Thread(target=watch, name="ofbe-parent-watch", daemon=True).start()


def _call_pickled(payload: bytes) -> bytes:
    """In a :func:`run_isolated` process: ``fn(item)`` from their pickle, and its result or
    exception pickled (so that the Dask worker passing them on never imports the task's modules)."""
    fn, item = pickle.loads(payload)
    try:
        outcome: tuple[bool, Any] = (True, fn(item))
    except Exception as exc:  # noqa: BLE001 - handed to the caller, which reports it
        outcome = (False, exc)
    try:
        return pickle.dumps(outcome, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception as exc:  # noqa: BLE001 - an unpicklable result or exception
        what = "result" if outcome[0] else f"exception ({failure_reason(outcome[1])})"
        return pickle.dumps((False, RuntimeError(f"the task's {what} cannot be pickled: {exc}")))


def run_isolated(payload: bytes, env: tuple[tuple[str, str], ...]) -> bytes:
    """A task in this Dask worker's own spawned process with environment ``env`` (started at the
    first task, kept for the next ones), as the process pool runs a ``worker_env`` task.

    A Dask worker is no place for such a task: its own threads draw from Python's global
    ``random`` while the task runs (Tornado's timer jitter), and libraries that seed and draw
    from it (Keras does) then give different results from run to run. The spawned process runs
    the task alone on its main thread.

    Parameters
    ----------
    payload
        ``pickle.dumps((fn, item))``: the worker does not unpickle it, so it never imports the
        task's modules (TensorFlow is imported once, in the spawned process).
    env
        The environment, as sorted pairs.

    Returns
    -------
    bytes
        ``pickle.dumps((True, result))`` or ``pickle.dumps((False, exception))``.

    Raises
    ------
    ChildDied
        The process died; the next task gets a fresh one.
    RuntimeError
        This worker is a daemonic process, which cannot start one.
    """
    pool = _CHILDREN.get(env)
    if pool is None:
        if multiprocessing.current_process().daemon:
            raise RuntimeError("this Dask worker is a daemonic process and cannot start the process a task "
                               "with a worker environment runs in: start the workers with "
                               "DASK_DISTRIBUTED__WORKER__DAEMON=False")
        pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"),
                                   initializer=_init_isolated, initargs=(dict(env), os.getpid()))
        _CHILDREN[env] = pool
    processes: dict[int, Any] = getattr(pool, "_processes", {})
    try:
        return pool.submit(_call_pickled, payload).result()
    except BrokenProcessPool:
        del _CHILDREN[env]
        pool.shutdown(wait=True)
        codes = [p.exitcode for p in processes.values() if p.exitcode is not None]
        raise ChildDied(codes[0] if codes else None) from None


Outcome = tuple[int, Any, BaseException | TaskFailure | None]
"""(item index, result, error): error is None, the task's exception, or a :class:`TaskFailure`."""


class _DeathLog(logging.Handler):
    """Exit codes of the embedded cluster's worker processes, from its nannies' log."""

    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self.codes: dict[int, int] = {}

    def emit(self, record: logging.LogRecord) -> None:
        m = _DEATH.search(record.getMessage())
        if m:
            self.codes[int(m[1])] = int(m[2]) if m[2] is not None else -int(m[3])

    def code(self, pid: int | None, wait_s: float = 2.0) -> int | None:
        """The exit code of worker ``pid``, waiting a little for the nanny to log it."""
        deadline = time.monotonic() + wait_s
        while pid is not None and pid not in self.codes and time.monotonic() < deadline:
            time.sleep(0.05)
        return self.codes.get(pid) if pid is not None else None


_LOG_LOCK = threading.Lock()


@contextlib.contextmanager
def _quiet(verbose: bool) -> Iterator[_DeathLog]:
    """Dask's terminal logging raised to CRITICAL (unless ``verbose``), and the nannies' death
    messages captured, while a run lasts."""
    root = logging.getLogger("distributed")
    deaths = _DeathLog()
    nanny = logging.getLogger("distributed.nanny")
    with _LOG_LOCK:
        saved = [(h, h.level) for h in root.handlers if isinstance(h, logging.StreamHandler)]
        if not verbose:
            for h, _ in saved:
                h.setLevel(logging.CRITICAL)
        nanny.addHandler(deaths)
    try:
        yield deaths
    finally:
        with _LOG_LOCK:
            nanny.removeHandler(deaths)
            for h, level in saved:
                h.setLevel(level)


@contextlib.contextmanager
def _children_ignore_ctrl_c() -> Iterator[None]:
    """Start processes that leave Ctrl-C to this one.

    A terminal sends SIGINT to every process of the foreground group, the embedded cluster's
    worker processes included, and each would print its own ``KeyboardInterrupt`` traceback.
    The cluster starts inside this block, with Ctrl-C held off and SIGINT blocked in this thread
    (:func:`~ofbe_data.core.atomic.interrupts_deferred`): the threads it starts here (its IO
    loop) and the worker processes they start, now or after a death, inherit the block (a mask
    survives fork and exec), until the preload :mod:`ofbe_data.core.worker_signals` ignores
    Ctrl-C in each worker. A Ctrl-C while the cluster starts is raised as it is up; the caller
    then closes it (one line, exit 130, from ``core.cli.command``).
    """
    if threading.current_thread() is threading.main_thread():
        from multiprocessing import resource_tracker

        resource_tracker.ensure_running()  # its start unblocks SIGINT in this thread: not inside
    with interrupts_deferred():
        yield


@contextlib.contextmanager
def _scratch_space() -> Iterator[str]:
    """A folder of this run's own for the embedded cluster's scratch space (Dask's
    ``temporary-directory``), removed once the cluster is closed: Dask leaves its lock files in
    the system's temporary folder, those of a worker killed as a Ctrl-C closes the cluster too."""
    path = None
    try:
        with interrupts_deferred():  # the folder and its name here, or neither
            path = tempfile.mkdtemp(prefix="ofbe-dask-")
        yield path
    finally:
        if path is not None:
            with interrupts_deferred():
                for _ in range(20):  # a worker process that is still ending may write there a moment more
                    shutil.rmtree(path, ignore_errors=True)
                    if not os.path.exists(path):
                        break
                    time.sleep(0.1)


def _close_whole(embedded: contextlib.ExitStack) -> None:
    """Close the embedded cluster and its client with Ctrl-C held off: one that comes meanwhile is
    raised once they are closed (:func:`~ofbe_data.core.atomic.interrupts_deferred`)."""
    with interrupts_deferred():
        embedded.close()


@contextlib.contextmanager
def dask_client(scheduler: str, jobs: int, worker_env: Mapping[str, str] | None = None,
                retries: int = DEFAULT_RETRIES, verbose: bool = False) -> Iterator[tuple[Any, _DeathLog]]:
    """A Dask client for one run: an embedded LocalCluster (``dask``) or a running cluster.

    Parameters
    ----------
    scheduler
        ``dask`` or ``tcp://host:port``.
    jobs
        Worker processes of the embedded cluster (one thread each).
    worker_env
        Environment of the embedded cluster's worker processes (its ``env``); the tasks that
        need it run in processes of their own (:func:`run_isolated`) on any cluster.
    retries
        Further attempts of a task whose worker died (the embedded scheduler's
        ``allowed-failures``; a running cluster keeps its own setting).
    verbose
        Let Dask's log through to the terminal.

    Yields
    ------
    (client, deaths)
        The ``distributed.Client`` and the log of worker exit codes.

    Raises
    ------
    SchedulerError
        The address does not answer.
    """
    import dask
    import distributed

    config: dict[str, Any] = {"distributed.scheduler.allowed-failures": retries,
                              # one task at a time on each worker: a death charges only its task
                              "distributed.scheduler.worker-saturation": 1.0,
                              # so that a worker may start the process of run_isolated
                              "distributed.worker.daemon": False}
    level = logging.WARNING if verbose else logging.CRITICAL
    with contextlib.ExitStack() as stack:
        if scheduler == DASK:
            config["distributed.comm.timeouts.connect"] = _LOCAL_CONNECT_TIMEOUT
            preload = [str(m) for m in dask.config.get("distributed.worker.preload", None) or []]
            # the user's preloads kept
            config["distributed.worker.preload"] = [*preload, "ofbe_data.core.worker_signals"]
            config["temporary-directory"] = stack.enter_context(_scratch_space())  # removed last
        stack.enter_context(dask.config.set(config))
        deaths = stack.enter_context(_quiet(verbose))
        if scheduler == DASK:
            env = {"env": dict(worker_env)} if worker_env else {}
            # the cluster and its client close whole, before the log levels and the scratch space
            # are given back: a Ctrl-C while they close waits until they are closed (a close cut
            # short went on in Dask's own thread, logging on the terminal and racing the removal
            # of its scratch space)
            embedded = contextlib.ExitStack()
            stack.callback(_close_whole, embedded)
            # no dashboard; the scheduler's HTTP server (metrics) on a free port, not on 8787,
            # where another cluster would make Dask warn on the terminal
            with _children_ignore_ctrl_c():
                cluster = embedded.enter_context(distributed.LocalCluster(
                    n_workers=jobs, threads_per_worker=1, processes=True, dashboard_address=None,
                    silence_logs=level, scheduler_kwargs={"dashboard_address": ":0"}, **env))
            client = embedded.enter_context(distributed.Client(cluster))
        else:
            try:
                client = stack.enter_context(distributed.Client(scheduler, timeout=_CONNECT_TIMEOUT))
            except OSError as exc:
                why = " ".join(str(exc).split())
                raise SchedulerError(f"--scheduler {scheduler}: expected a running Dask scheduler, found "
                                     f"none answering ({why})") from None
        yield client, deaths


def dask_outcomes(fn: Callable[[Any], Any], items: Sequence[Any], *, scheduler: str, jobs: int,
                  worker_env: Mapping[str, str] | None, retries: int, window: Callable[[], int],
                  verbose: bool) -> Iterator[Outcome]:
    """Run ``fn`` on every item on Dask and yield each :data:`Outcome` as it completes.

    Parameters
    ----------
    fn, items
        A picklable function and its arguments.
    scheduler, jobs, retries, verbose
        See :func:`dask_client`.
    worker_env
        When given, every task runs in its worker's own spawned process with this environment
        (:func:`run_isolated`), whose death is retried here like a worker's.
    window
        Items with an index below ``window()`` may be in flight (checked after each yield):
        bounds the results held when the caller consumes them in order. At most as many
        tasks as the cluster has threads are in flight.

    Yields
    ------
    Outcome

    Raises
    ------
    SchedulerError
        The scheduler cannot be reached or lost the tasks.
    """
    from distributed import KilledWorker, as_completed

    env = tuple(sorted(worker_env.items())) if worker_env is not None else None
    with dask_client(scheduler, max(1, jobs), worker_env, retries, verbose) as (client, deaths):
        prefix = f"{getattr(fn, '__name__', 'task')}-{uuid.uuid4().hex[:12]}"
        index: dict[str, int] = {}
        died: dict[int, int] = {}
        pending = as_completed()
        todo = list(range(len(items)))  # a heap: the items not submitted yet, or to run again

        def submit(i: int) -> None:
            key = f"{prefix}-{i}" + (f"-again{died[i]}" if i in died else "")
            if env is None:
                fut = client.submit(fn, items[i], key=key, pure=False)
            else:
                payload = pickle.dumps((fn, items[i]), protocol=pickle.HIGHEST_PROTOCOL)
                fut = client.submit(run_isolated, payload, env, key=key, pure=False)
            index[fut.key] = i
            pending.add(fut)

        threads, counted = 1, -1.0  # the cluster's threads, and when they were counted

        def fill() -> None:
            # no more tasks in flight than the cluster has threads: each worker runs one task at a
            # time, so a worker's death charges only the task it was running
            nonlocal threads, counted
            if time.monotonic() - counted > 1.0:
                threads, counted = max(1, sum(client.nthreads().values())), time.monotonic()
            free = threads - len(index)
            while free > 0 and todo and todo[0] < window():
                submit(heapq.heappop(todo))
                free -= 1

        fill()
        try:
            while index or todo:
                if pending.is_empty():  # pragma: no cover - the window always lets the next item in
                    fill()
                    if pending.is_empty():
                        raise RuntimeError("dask_outcomes: nothing in flight, items left (window too small)")
                fut = next(pending)
                i = index.pop(fut.key)
                try:
                    value = fut.result()
                    if env is None:
                        outcome: Outcome = (i, value, None)
                    else:
                        ok, value = pickle.loads(value)
                        outcome = (i, value, None) if ok else (i, None, value)
                except KilledWorker as exc:
                    worker = getattr(exc, "last_worker", None)
                    code = deaths.code(getattr(worker, "pid", None)) if scheduler == DASK else None
                    outcome = (i, None, TaskFailure(i, death_reason(exc.allowed_failures + 1, code)))
                except ChildDied as exc:
                    died[i] = died.get(i, 0) + 1
                    if died[i] <= retries:
                        heapq.heappush(todo, i)
                        fut.release()
                        fill()
                        continue
                    outcome = (i, None, TaskFailure(i, death_reason(died[i], exc.exit_code)))
                except Exception as exc:  # noqa: BLE001 - the task's own exception, or the cluster's
                    if fut.status != "error":
                        raise SchedulerError(f"--scheduler {scheduler}: the Dask cluster lost task {fut.key} "
                                             f"({fut.status}: {failure_reason(exc)})") from exc
                    outcome = (i, None, exc)
                fut.release()
                yield outcome
                fill()
        finally:
            if index:
                client.cancel(list(pending.futures))
