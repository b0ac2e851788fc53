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
"""

from __future__ import annotations

import heapq
import multiprocessing
import os
import signal
import sys
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from multiprocessing.queues import SimpleQueue
from typing import Any, Literal, NoReturn, TypeVar, overload

from tqdm import tqdm

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

__all__ = ["TaskError", "TaskFailure", "iter_ordered", "map_progress"]

T = TypeVar("T")
R = TypeVar("R")

_MARKS: SimpleQueue[tuple[int, int]] | None = None
"""In a pool worker: where it notes (pid, item index) before running an item."""


def _init_worker(env: Mapping[str, str], marks: SimpleQueue[tuple[int, int]] | None = None) -> None:
    """Worker set-up: its environment first (before any library reads it), and Ctrl-C left to
    the parent, which reports it once (no traceback per worker)."""
    global _MARKS
    os.environ.update(env)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _MARKS = marks


def _marked(fn: Callable[[Any], Any], index: int, item: Any) -> Any:
    """``fn(item)`` in a pool worker, after noting which item this process runs (so that the
    parent knows whose task it was when the process dies)."""
    if _MARKS is not None:
        _MARKS.put((os.getpid(), index))
    return fn(item)


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
    """Every item's :data:`Outcome` from a process pool, as each completes.

    When a worker process dies the pool breaks: the results already in are kept, the items
    that did not start are submitted again to a fresh pool, and the item the dead process
    was running (its exit code tells it from the ones the pool then stopped) is charged one
    attempt and run again, until it has died ``retries + 1`` times.
    """
    context = multiprocessing.get_context("spawn" if worker_env is not None else None)
    env = dict(worker_env or {})
    waiting = list(range(len(items)))  # a heap: the items to submit, the next one first
    deaths: dict[int, int] = {}
    while waiting:
        marks: SimpleQueue[tuple[int, int]] = context.SimpleQueue()
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=context, initializer=_init_worker,
                                   initargs=(env, marks))
        # the pool's pid → process map (kept past a break): the exit codes of its processes
        processes: dict[int, Any] = getattr(pool, "_processes", {})
        inflight: dict[Future[Any], int] = {}
        lost: list[int] = []
        broken = False
        try:
            while (waiting and not broken) or inflight:
                while waiting and not broken and waiting[0] < window():
                    try:
                        inflight[pool.submit(_marked, fn, waiting[0], items[waiting[0]])] = waiting[0]
                    except BrokenProcessPool:
                        broken = True
                    else:
                        heapq.heappop(waiting)
                if not inflight:
                    if broken:
                        break
                    raise RuntimeError("map_progress: nothing in flight and items left (window too small)")
                done, _ = wait(inflight, return_when=FIRST_COMPLETED)
                for fut in sorted(done, key=inflight.__getitem__):
                    i = inflight.pop(fut)
                    exc = fut.exception()
                    if isinstance(exc, BrokenProcessPool):
                        lost.append(i)
                        broken = True
                    else:
                        yield (i, None, exc) if exc is not None else (i, fut.result(), None)
        except BaseException:
            # Ctrl-C, or the caller stopped: drop the tasks not started, let the running ones finish
            pool.shutdown(wait=True, cancel_futures=True)
            marks.close()
            raise
        pool.shutdown(wait=True)
        if not lost:
            marks.close()
            continue
        last: dict[int, int] = {}  # pid → the last item that process started
        while not marks.empty():
            pid, i = marks.get()
            last[pid] = i
        marks.close()
        codes = {i: getattr(processes.get(pid), "exitcode", None) for pid, i in last.items() if i in lost}
        # a process that died ran its last item; the pool stopped the others (SIGTERM) after the
        # break, and the items they finished but whose results were not read yet go again
        died = [i for i, c in codes.items() if c is not None and c != -signal.SIGTERM]
        charged = died or list(codes) or lost
        again = [i for i in lost if i not in charged]
        for i in charged:
            deaths[i] = deaths.get(i, 0) + 1
            if deaths[i] > retries:
                yield i, None, TaskFailure(i, death_reason(deaths[i], codes.get(i)))
            else:
                again.append(i)
        for i in again:
            heapq.heappush(waiting, i)


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
        Environment of fresh worker processes (``spawn`` ones for ``processes``; on Dask, a
        spawned process of each worker, kept for its next tasks,
        :func:`~ofbe_data.core.scheduler.run_isolated`), set before they import anything and
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
        if items:
            for i, value, error in _outcomes(fn, items, jobs, scheduler, worker_env, retries,
                                             lambda: len(items)):
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
        close = getattr(stream, "close", None)
        if close is not None:
            close()
