"""Run one function over many items, in worker processes when asked, with a progress bar."""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import TypeVar

from tqdm import tqdm

T = TypeVar("T")
R = TypeVar("R")


def map_progress(fn: Callable[[T], R], items: Sequence[T], *, jobs: int = 1, desc: str = "",
                 unit: str = "item", progress: bool = True) -> list[R]:
    """``[fn(x) for x in items]``, in ``jobs`` processes when ``jobs > 1``, in order.

    Parameters
    ----------
    fn
        A picklable (module-level) function.
    items
        Its arguments.
    jobs
        Worker processes; 1 (or a single item) runs here.
    desc, unit
        Progress-bar text (on stderr; shown for two items or more when ``progress``).
    progress
        Show the bar.
    """
    bar = tqdm(total=len(items), desc=desc, unit=unit, disable=not progress or len(items) < 2,
               file=sys.stderr)
    out: list[R] = []
    if jobs > 1 and len(items) > 1:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            for r in pool.map(fn, items, chunksize=1):
                out.append(r)
                bar.update()
    else:
        for x in items:
            out.append(fn(x))
            bar.update()
    bar.close()
    return out
