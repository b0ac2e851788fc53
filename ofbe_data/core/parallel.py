"""Run one function over many items, in worker processes or on a Dask cluster, with a progress
bar: the toolkit's one execution layer.

:func:`map_progress` gives the results in input order; :func:`iter_ordered` streams them in
input order with a bounded number in flight. Both take a scheduler (``processes``, ``dask`` or
``tcp://host:port``, :mod:`ofbe_data.core.scheduler`); the results do not depend on it, nor on
the number of workers. Tasks take paths and parameters and return small results; a task that
writes a big output writes it atomically in its final place.

Failures: a task that raises is reported with its exception; a task whose worker process dies
is run again (``retries`` times; the tasks are idempotent) and then reported as a
:class:`~ofbe_data.core.scheduler.TaskFailure`. The other tasks always finish. With
``on_error="raise"`` (the default) the first failure in input order is raised once every task
is done: the task's own exception, or a :class:`~ofbe_data.core.scheduler.TaskError`; with
``on_error="collect"`` each failed item's result is its ``TaskFailure``.

Ctrl-C: the worker processes ignore it (they started with it blocked, and a terminal sends it
to them too); this process gets ``KeyboardInterrupt`` and stops its workers at once (SIGTERM,
which ends a task with its clean-up, then SIGKILL after :data:`STOP_S`), never waiting for a
task to end, before the exception goes on to the caller (whose temporary folder is then removed).
"""

from __future__ import annotations

import contextlib
import heapq
import multiprocessing
import os
import signal
import sys
import time
import traceback
from collections.abc import Callable, Iterator, Mapping, Sequence
from multiprocessing import connection
from multiprocessing.reduction import ForkingPickler
from typing import Any, Literal, NoReturn, TypeVar, overload

from tqdm import tqdm

from ofbe_data.core.atomic import interrupts_deferred
from ofbe_data.core.scheduler import (
    DEFAULT_RETRIES,
    PROCESSES,
    Outcome,
    TaskError,
    TaskFailure,
    check_scheduler,
    death_reason,
    failure_reason,
)
from ofbe_data.core.worker_setup import init_worker

__all__ = ["TaskError", "TaskFailure", "iter_ordered", "kept_workers", "map_progress"]

T = TypeVar("T")
R = TypeVar("R")

STOP_S = 5.0
"""How long stopping the worker processes waits for them to end (after SIGTERM, and again after
SIGKILL): an interrupted run never waits longer for a task."""


class _Stopped(BaseException):
    """In a worker: its parent stopped it (SIGTERM) while it ran a task or waited for one."""


def _stop(_signum: int, _frame: Any) -> None:
    raise _Stopped


class _RemoteTraceback(Exception):
    """A task's traceback in its worker, as text: the ``__cause__`` of its exception here."""

    def __str__(self) -> str:
        return str(self.args[0])


def _rebuild(exc: BaseException, tb: str) -> BaseException:
    exc.__cause__ = _RemoteTraceback(tb)
    return exc


class _Raised:
    """A task's exception on its way to the parent, with its traceback as text."""

    def __init__(self, exc: BaseException) -> None:
        self.exc = exc
        self.tb = "".join(traceback.format_exception(exc))

    def __reduce__(self) -> tuple[Any, ...]:
        return _rebuild, (self.exc, f'\n"""\n{self.tb}"""')


def _serve(conn: connection.Connection, env: Mapping[str, str]) -> None:
    """A worker process: runs each ``(index, pickled (fn, item))`` it receives and sends back
    ``(index, True, result)`` or ``(index, False, exception)``, until told to stop (None) or its
    parent is gone. SIGTERM ends the task with its clean-up (``finally``, atomic writes), then
    the process, by that signal."""
    init_worker(env)
    signal.signal(signal.SIGTERM, _stop)
    try:
        while True:
            try:
                task = conn.recv()
            except (EOFError, OSError):  # the parent is gone
                return
            if task is None:
                return
            index, payload = task
            try:
                fn, item = ForkingPickler.loads(payload)
                reply: tuple[int, bool, Any] = (index, True, fn(item))
            except _Stopped:
                raise
            except BaseException as exc:  # noqa: BLE001 - the parent reports it
                reply = (index, False, _Raised(exc))
            del task, payload
            try:
                conn.send(reply)
            except (EOFError, OSError):
                return
            except Exception as exc:  # noqa: BLE001 - an unpicklable result or exception
                what = "result" if reply[1] else f"exception ({failure_reason(reply[2].exc)})"
                conn.send((index, False, RuntimeError(f"the task's {what} cannot be pickled: {exc}")))
    except _Stopped:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        os.kill(os.getpid(), signal.SIGTERM)


class _Worker:
    """One worker process of a :class:`_Pool`, the parent's end of its pipe, and the item it runs."""

    def __init__(self, process: Any, conn: connection.Connection) -> None:
        self.process = process
        self.conn = conn
        self.item: int | None = None
        self.used = False


class _Pool:
    """Up to ``size`` worker processes that this process started and alone owns, each with its
    pipe: no thread and no lock (``concurrent.futures``' pool has both, and a Ctrl-C in the
    wrong instant left its shut-down waiting forever), so :meth:`stop` always ends in bounded time.

    Parameters
    ----------
    context
        The ``multiprocessing`` context that starts the workers.
    env
        Their environment (:func:`init_worker`).
    size
        How many may run at once.
    """

    def __init__(self, context: Any, env: Mapping[str, str], size: int, keep: bool = False) -> None:
        self.context, self.env, self.size = context, env, size
        self.key = _spawn_key(env) if keep else None
        self.workers: list[_Worker] = _adopt(self.key)

    @property
    def busy(self) -> list[_Worker]:
        return [w for w in self.workers if w.item is not None]

    def _start(self) -> _Worker:
        if self.context.get_start_method() != "fork":
            # started now, not inside the block below: starting it unblocks SIGINT in this thread
            from multiprocessing import resource_tracker

            resource_tracker.ensure_running()
        with interrupts_deferred():  # the worker starts with SIGINT blocked, and is known here
            ours, theirs = self.context.Pipe()
            try:
                process = self.context.Process(target=_serve, args=(theirs, self.env), daemon=False)
                process.start()
            except BaseException:
                ours.close()
                raise
            finally:
                theirs.close()
            worker = _Worker(process, ours)
            self.workers.append(worker)
        return worker

    def run(self, index: int, payload: bytes) -> tuple[bool, bool, int | None]:
        """Send an item to an idle worker (a new one if none): ``(sent, charged, exit code)``.

        When the worker is gone the item was not sent; a new worker's death is charged to the
        item (``charged``), an idle one's (since its last task) is not."""
        idle = [w for w in self.workers if w.item is None]
        worker = idle[0] if idle else self._start()
        try:
            worker.conn.send((index, payload))
        except OSError:
            return False, not worker.used, self._reap(worker)
        worker.item, worker.used = index, True
        return True, False, None

    def _reap(self, worker: _Worker) -> int | None:
        """Forget a worker that died (its pipe closed or its process ended); its exit code."""
        worker.conn.close()
        worker.process.join(STOP_S)
        if worker.process.exitcode is None:  # its pipe closed but it lives on: ended here
            worker.process.kill()
            worker.process.join(STOP_S)
        self.workers.remove(worker)
        return worker.process.exitcode

    def replies(self) -> list[tuple[int, tuple[bool, Any] | None, int | None]]:
        """Wait until a busy worker answers or dies: ``(item, (ok, value), None)`` per answer,
        ``(item, None, exit code)`` per death, in item order."""
        busy = sorted(self.busy, key=lambda w: w.item or 0)
        ready = set(connection.wait([w.conn for w in busy] + [w.process.sentinel for w in busy]))
        out: list[tuple[int, tuple[bool, Any] | None, int | None]] = []
        for w in busy:
            i = w.item
            assert i is not None
            if w.conn in ready:
                try:
                    index, ok, value = w.conn.recv()
                except (EOFError, OSError):  # died
                    w.item = None
                    out.append((i, None, self._reap(w)))
                    continue
                except Exception as exc:  # noqa: BLE001 - an answer that cannot be unpickled here
                    index, ok, value = i, False, exc
                assert index == i, (index, i)
                w.item = None
                out.append((i, (ok, value), None))
            elif w.process.sentinel in ready:  # ended, though something it started holds its pipe
                w.item = None
                out.append((i, None, self._reap(w)))
        return out

    def stop(self, finished: bool) -> None:
        """End every worker: told to once the run ``finished``; else at once, with SIGTERM (the
        task ends with its clean-up), then SIGKILL for any still running after :data:`STOP_S`.
        Inside :func:`kept_workers`, a finished run's workers are kept instead."""
        if finished and self.key is not None and _KEPT is not None:
            _KEPT.setdefault(self.key, []).extend(self.workers)
            self.workers = []
            return
        _end(self.workers, finished)
        self.workers = []


def _end(workers: list[_Worker], finished: bool) -> None:
    """End ``workers`` (:meth:`_Pool.stop`)."""
    if workers:
        with interrupts_deferred():
            for w in workers:
                if finished:
                    # a worker whose pipe is gone has died already: the join and kill below end it
                    with contextlib.suppress(OSError):
                        w.conn.send(None)
                else:
                    w.process.terminate()
            deadline = time.monotonic() + STOP_S
            for w in workers:
                w.process.join(max(0.0, deadline - time.monotonic()))
            for w in workers:
                if w.process.exitcode is None:
                    w.process.kill()
                    w.process.join(STOP_S)
                w.conn.close()


_SpawnKey = tuple[str, tuple[str, ...], tuple[tuple[str, str], ...]]
_KEPT: dict[_SpawnKey, list[_Worker]] | None = None
"""Inside :func:`kept_workers`: the idle spawned workers of finished runs, by :func:`_spawn_key`."""


_PER_CALL = frozenset({"PYTEST_CURRENT_TEST"})
"""Environment variables that change from call to call without meaning anything to a worker
(pytest names the running test in one)."""


def _spawn_key(env: Mapping[str, str]) -> _SpawnKey:
    """What a spawned worker started with and keeps: this process's working folder, ``sys.path``
    and environment (but :data:`_PER_CALL`), ``env`` over it. A kept worker serves only a call
    that would start the same."""
    environ = {k: v for k, v in os.environ.items() if k not in _PER_CALL}
    return os.getcwd(), tuple(sys.path), tuple(sorted({**environ, **env}.items()))


def _adopt(key: _SpawnKey | None) -> list[_Worker]:
    """The kept workers started as ``key`` that are still alive (none outside
    :func:`kept_workers`); those that died while idle are ended and forgotten."""
    if key is None or _KEPT is None:
        return []
    kept = _KEPT.pop(key, [])
    alive = [w for w in kept if w.process.is_alive()]
    _end([w for w in kept if w not in alive], finished=False)
    return alive


@contextlib.contextmanager
def kept_workers() -> Iterator[None]:
    """Keep spawned workers from one call to the next, within this block.

    Outside it, every :func:`map_progress` or :func:`iter_ordered` call with a ``worker_env``
    starts its own fresh worker processes and ends them when it returns. Inside it, the workers
    of a call that finished are kept, idle, and the next call that would start the same workers
    (the same ``worker_env``, environment, working folder and ``sys.path``) sends its items to
    them before it starts any: TensorFlow's start in each (several seconds of CPU) is paid once
    per worker, not once per call, as when a notebook trains several times. A call that fails
    or is interrupted still ends its workers at once. The results do not
    change: a kept worker was set up (:func:`~ofbe_data.core.worker_setup.init_worker`) with the
    same environment, and a task must not depend on what its worker ran before, as it already
    must not with one worker for many items. The kept workers hold their memory until the
    block ends, where they are ended; they run the code imported when they started, so leave
    the block after editing a task's module. Nested blocks are one block.

    Examples
    --------
    >>> from ofbe_data.core.parallel import kept_workers
    >>> with kept_workers():  # doctest: +SKIP
    ...     train_many(["processed/datasets/rotated"], ["grouped"], "models/a", params, jobs=2)
    ...     train_many(["processed/datasets/rotated"], ["grouped"], "models/b", params, jobs=2)
    """
    global _KEPT
    if _KEPT is not None:
        yield
        return
    _KEPT = {}
    try:
        yield
    finally:
        kept, _KEPT = _KEPT, None
        _end([w for workers in kept.values() for w in workers], finished=True)


def _verbose() -> bool:
    return os.environ.get("OFBE_VERBOSE", "") not in ("", "0")


def _local_outcomes(fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[Outcome]:
    for i, x in enumerate(items):
        try:
            value = fn(x)
        except Exception as exc:  # noqa: BLE001 - reported like a worker's
            yield i, None, exc
        else:
            yield i, value, None


def _pool_outcomes(fn: Callable[[Any], Any], items: Sequence[Any], workers: int,
                   worker_env: Mapping[str, str] | None, retries: int,
                   window: Callable[[], int]) -> Iterator[Outcome]:
    """Every item's :data:`Outcome` from ``workers`` processes of this call's own, as each completes.

    A worker that dies charges one attempt to the item it was running, which runs again (on a
    new worker) until it has died ``retries + 1`` times; the other workers go on. When this
    ends early (an exception here or in the caller, Ctrl-C included, or the caller stops
    reading), every worker is stopped at once (:meth:`_Pool.stop`) before it goes on.
    """
    context = multiprocessing.get_context("spawn" if worker_env is not None else None)
    pool = _Pool(context, dict(worker_env or {}), workers, keep=worker_env is not None)
    waiting = list(range(len(items)))  # a heap: the items to run, the next one first
    deaths: dict[int, int] = {}
    finished = False

    def died(i: int, code: int | None) -> Outcome | None:
        deaths[i] = deaths.get(i, 0) + 1
        if deaths[i] > retries:
            return i, None, TaskFailure(i, death_reason(deaths[i], code))
        heapq.heappush(waiting, i)
        return None

    try:
        while waiting or pool.busy:
            while waiting and waiting[0] < window() and len(pool.busy) < pool.size:
                i = heapq.heappop(waiting)
                try:
                    payload = bytes(ForkingPickler.dumps((fn, items[i])))
                except Exception as exc:  # noqa: BLE001 - an item that cannot be sent, reported as its failure
                    yield i, None, exc
                    continue
                sent, charged, code = pool.run(i, payload)
                if sent:
                    continue
                if not charged:
                    heapq.heappush(waiting, i)  # an idle worker had died: the item goes to a new one
                elif (failed := died(i, code)) is not None:
                    yield failed
            if not pool.busy:
                if waiting:
                    raise RuntimeError("map_progress: nothing in flight and items left (window too small)")
                break
            for i, reply, code in pool.replies():
                if reply is None:
                    if (failed := died(i, code)) is not None:
                        yield failed
                else:
                    ok, value = reply
                    yield (i, value, None) if ok else (i, None, value)
        finished = True
    finally:
        pool.stop(finished)


def _outcomes(fn: Callable[[Any], Any], items: Sequence[Any], jobs: int, scheduler: str,
              worker_env: Mapping[str, str] | None, retries: int,
              window: Callable[[], int]) -> Iterator[Outcome]:
    """Every item's :data:`Outcome` on the chosen scheduler, as each completes."""
    check_scheduler(scheduler)
    workers = max(1, min(jobs, len(items)))
    if scheduler != PROCESSES:
        from ofbe_data.core.scheduler import dask_outcomes

        return dask_outcomes(fn, items, scheduler=scheduler, jobs=workers, worker_env=worker_env,
                             retries=retries, window=window, verbose=_verbose())
    if worker_env is not None or (jobs > 1 and len(items) > 1):
        return _pool_outcomes(fn, items, workers, worker_env, retries, window)
    return _local_outcomes(fn, items)


@overload
def map_progress(fn: Callable[[T], R], items: Sequence[T], *, jobs: int = ..., desc: str = ...,
                 unit: str = ..., progress: bool = ..., worker_env: Mapping[str, str] | None = ...,
                 postfix: Callable[[R], str] | None = ..., scheduler: str = ...,
                 on_error: Literal["raise"] = ..., retries: int = ...,
                 name: Callable[[T], str] | None = ...) -> list[R]: ...


@overload
def map_progress(fn: Callable[[T], R], items: Sequence[T], *, jobs: int = ..., desc: str = ...,
                 unit: str = ..., progress: bool = ..., worker_env: Mapping[str, str] | None = ...,
                 postfix: Callable[[R], str] | None = ..., scheduler: str = ...,
                 on_error: Literal["collect"], retries: int = ...,
                 name: Callable[[T], str] | None = ...) -> list[R | TaskFailure]: ...


def map_progress(fn: Callable[[T], R], items: Sequence[T], *, jobs: int = 1, desc: str = "",
                 unit: str = "item", progress: bool = True, worker_env: Mapping[str, str] | None = None,
                 postfix: Callable[[R], str] | None = None, scheduler: str = PROCESSES,
                 on_error: Literal["raise", "collect"] = "raise", retries: int = DEFAULT_RETRIES,
                 name: Callable[[T], str] | None = None) -> list[R] | list[R | TaskFailure]:
    """``[fn(x) for x in items]``, in ``jobs`` workers, in order.

    Parameters
    ----------
    fn
        A picklable (module-level) function.
    items
        Its arguments.
    jobs
        Workers; with ``processes``, 1 (or a single item) runs here unless ``worker_env`` is
        given.
    desc, unit
        Progress-bar text (on stderr; shown for two items or more when ``progress``).
    progress
        Show the bar.
    worker_env
        Environment of fresh worker processes (``spawn`` ones for ``processes``, this call's
        own unless inside :func:`kept_workers`; on Dask, a spawned process of each worker, kept
        for its next tasks, :func:`~ofbe_data.core.scheduler.run_isolated`), set before they
        import anything and
        used for every item whatever ``jobs``: for libraries whose results depend on settings
        read once at start-up, such as TensorFlow's thread counts, or that draw from Python's
        global ``random`` (which a Dask worker's own threads draw from too), so that the same
        items give the same results with one worker or many, on any scheduler.
    postfix
        Text shown beside the bar after each result (e.g. what the last item did).
    scheduler
        ``processes`` (a local process pool; Dask is not imported), ``dask`` (an embedded
        Dask LocalCluster of ``jobs`` single-threaded worker processes, for this call) or a
        Dask scheduler address ``tcp://host:port``.
    on_error
        ``raise``: once every item is done, raise the first failure in input order (the
        task's exception, or :class:`~ofbe_data.core.scheduler.TaskError` when its worker
        died). ``collect``: a failed item's result is its
        :class:`~ofbe_data.core.scheduler.TaskFailure`.
    retries
        Further attempts of an item whose worker process died (not of one that raised).
    name
        The item's name in a :class:`~ofbe_data.core.scheduler.TaskError` (``item <i>``
        when None).

    Returns
    -------
    list
        One result per item, in input order.

    Raises
    ------
    ValueError
        An unknown ``scheduler`` or ``on_error``.
    SchedulerError
        The Dask scheduler cannot be reached.
    """
    if on_error not in ("raise", "collect"):
        raise ValueError(f"on_error: expected 'raise' or 'collect', found {on_error!r}")
    check_scheduler(scheduler)
    out: list[Any] = [None] * len(items)
    errors: dict[int, BaseException | TaskFailure] = {}
    with tqdm(total=len(items), desc=desc, unit=unit, disable=not progress or len(items) < 2,
              file=sys.stderr) as bar:
        stream = (_outcomes(fn, items, jobs, scheduler, worker_env, retries, lambda: len(items))
                  if items else ())
        try:
            for i, value, error in stream:
                if error is None:
                    out[i] = value
                    if postfix is not None:
                        bar.set_postfix_str(postfix(value))
                else:
                    errors[i] = error
                    out[i] = (error if isinstance(error, TaskFailure)
                              else TaskFailure(i, failure_reason(error)))
                    bar.set_postfix_str(f"{name(items[i]) if name else f'item {i}'} failed")
                bar.update()
        finally:  # on Ctrl-C here too, the workers are stopped before the exception goes on
            _close(stream)
    if errors and on_error == "raise":
        first = min(errors)
        _raise(errors[first], name(items[first]) if name else "", len(errors) - 1)
    return out


def _raise(error: BaseException | TaskFailure, name: str, others: int) -> NoReturn:
    """Raise a failure: the task's exception, or a :class:`TaskError` for a dead worker."""
    exc = TaskError(error, name) if isinstance(error, TaskFailure) else error
    if others:
        exc.add_note(f"{others} other item{'s' if others > 1 else ''} failed too")
    raise exc


def iter_ordered(fn: Callable[[T], R], items: Sequence[T], *, jobs: int = 1, scheduler: str = PROCESSES,
                 ahead: int = 2, worker_env: Mapping[str, str] | None = None, retries: int = DEFAULT_RETRIES,
                 name: Callable[[T], str] | None = None) -> Iterator[R]:
    """``fn(x) for x in items``, streamed in input order from ``jobs`` workers, with at most
    ``jobs * (1 + ahead)`` items in flight or waiting to be consumed (bounded memory).

    Parameters
    ----------
    fn, items, jobs, scheduler, worker_env, retries, name
        As for :func:`map_progress`.
    ahead
        Items in flight per worker beyond the one being consumed.

    Yields
    ------
    The results, in input order.

    Raises
    ------
    Exception
        When the next result is a failure: the task's exception, or
        :class:`~ofbe_data.core.scheduler.TaskError`; the items in flight are dropped.
    """
    check_scheduler(scheduler)
    nxt = 0
    limit = max(1, jobs) * (1 + max(0, ahead))
    done: dict[int, tuple[Any, BaseException | TaskFailure | None]] = {}
    stream = (_outcomes(fn, items, jobs, scheduler, worker_env, retries, lambda: nxt + limit)
              if items else None)
    try:
        for i, value, error in stream or ():
            done[i] = (value, error)
            while nxt in done:
                value, error = done.pop(nxt)
                if error is not None:
                    _raise(error, name(items[nxt]) if name else "", 0)
                nxt += 1
                yield value
    finally:
        _close(stream)


def _close(stream: Any) -> None:
    """Close an outcome stream (a generator): its workers or cluster are stopped before this returns."""
    close = getattr(stream, "close", None)
    if close is not None:
        close()
