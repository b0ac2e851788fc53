"""Run one function over many items, in worker processes when asked, with a progress bar."""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import TypeVar

from tqdm import tqdm

T = TypeVar("T")
R = TypeVar("R")


def _init_worker(env: Mapping[str, str]) -> None:
    """Worker set-up: its environment first (before any library reads it), and Ctrl-C left to
    the parent, which reports it once (no traceback per worker)."""
    os.environ.update(env)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def map_progress(fn: Callable[[T], R], items: Sequence[T], *, jobs: int = 1, desc: str = "",
                 unit: str = "item", progress: bool = True, worker_env: Mapping[str, str] | None = None,
                 postfix: Callable[[R], str] | None = None) -> list[R]:
    """``[fn(x) for x in items]``, in ``jobs`` processes when ``jobs > 1``, in order.

    Parameters
    ----------
    fn
        A picklable (module-level) function.
    items
        Its arguments.
    jobs
        Worker processes; 1 (or a single item) runs here unless ``worker_env`` is given.
    desc, unit
        Progress-bar text (on stderr; shown for two items or more when ``progress``).
    progress
        Show the bar.
    worker_env
        Environment of fresh ("spawn") worker processes, used for every item whatever
        ``jobs`` (then at least one worker): for libraries whose results depend on settings
        read once at start-up, such as TensorFlow's thread counts, so that the same items
        give the same results with one worker or many.
    postfix
        Text shown beside the bar after each result (e.g. what the last item did).
    """
    out: list[R] = []
    with tqdm(total=len(items), desc=desc, unit=unit, disable=not progress or len(items) < 2,
              file=sys.stderr) as bar:
        if worker_env is not None or (jobs > 1 and len(items) > 1):
            context = multiprocessing.get_context("spawn") if worker_env is not None else None
            pool = ProcessPoolExecutor(max_workers=max(1, min(jobs, len(items))), mp_context=context,
                                       initializer=_init_worker, initargs=(dict(worker_env or {}),))
            try:
                for r in pool.map(fn, items, chunksize=1):
                    out.append(r)
                    if postfix is not None:
                        bar.set_postfix_str(postfix(r))
                    bar.update()
            except BaseException:
                # Ctrl-C or a failure: drop the tasks not started, let the running ones finish
                pool.shutdown(wait=True, cancel_futures=True)
                raise
            pool.shutdown()
        else:
            for x in items:
                out.append(fn(x))
                if postfix is not None:
                    bar.set_postfix_str(postfix(out[-1]))
                bar.update()
    return out
