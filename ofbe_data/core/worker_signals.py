"""Dask worker preload of the embedded cluster: Ctrl-C is left to the command's process.

A terminal's Ctrl-C reaches every process of its foreground group; the command closes the
cluster and prints one line, and a worker that also raised ``KeyboardInterrupt`` would print
a traceback of its own. Imported by each worker process at its start (Dask's
``distributed.worker.preload``); the workers start with SIGINT blocked until then (see
``ofbe_data.core.scheduler._children_ignore_ctrl_c``), and it is unblocked once ignored.
"""

from __future__ import annotations

import signal
import threading
from typing import Any


def _ignore_ctrl_c() -> None:
    """Ignore SIGINT in this process (only the main thread may set a handler)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)  # discards one pending while blocked
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def dask_setup(worker: Any) -> None:  # noqa: ARG001 - Dask's preload hook
    """Dask's preload hook: called once in each worker process as it starts."""
    _ignore_ctrl_c()


_ignore_ctrl_c()
