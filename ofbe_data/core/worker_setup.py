"""Set-up of every worker process ofbe starts (its own pool's, and the isolated process a Dask
worker runs a task in, :mod:`ofbe_data.core.scheduler`): the environment, and Ctrl-C left to the
parent."""

from __future__ import annotations

import os
import signal
from collections.abc import Mapping


def init_worker(env: Mapping[str, str]) -> None:
    """Worker set-up: its environment first (before any library reads it), and Ctrl-C left to
    the parent, which reports it once (no traceback per worker).

    A worker started by :class:`_Pool` starts with SIGINT blocked, so a Ctrl-C before this point
    is pending, not raised: ignoring the signal discards it, and it is unblocked after.
    """
    os.environ.update(env)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
