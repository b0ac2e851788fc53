"""The console scripts' entry points: a Ctrl-C at any moment of a command (while Python imports
its modules, while it runs, while it ends) prints one line and exits 130, with no traceback.

pyproject.toml's ``[project.scripts]`` point here (``ofbe-label = "ofbe_data.core.entry:label"``)
rather than at each command's ``main``: the script pip generates imports its target before it
calls it, and the second a command's modules take to import (NumPy, pandas, SciPy…) would
otherwise run outside any ``try``. This module imports only the standard library's small
modules; the command's own module is imported inside :func:`run`'s guard. Imported in a
command's process (``sys.argv[0]`` is ``ofbe-…``), it holds a Ctrl-C off from its own import
until :func:`run` takes over (:func:`take_over`). What comes before (Python's start-up and the
script's first line, about 0.1 s) is out of any module's reach.
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
from collections.abc import Callable
from typing import Any

EXIT_INTERRUPTED = 130
"""Stopped by Ctrl-C (128 + SIGINT, as shells report it)."""
INTERRUPTED = "interrupted; files already written are whole, nothing partial is left"
"""What ``<prog>: `` is followed by on a Ctrl-C (the same from :func:`ofbe_data.core.cli.command`)."""

_seen: list[int] = []
"""Each Ctrl-C this process got since this module's import."""


def _hold(signum: int, _frame: Any) -> None:
    """Between this module's import and :func:`run`: noted, raised by :func:`run`."""
    _seen.append(signum)


def _interrupt(signum: int, _frame: Any) -> None:
    """Python's own handler, which also notes the Ctrl-C: an extension module may turn the
    ``KeyboardInterrupt`` into another error (NumPy's import raises an ``ImportError``)."""
    _seen.append(signum)
    raise KeyboardInterrupt


def _a_command() -> bool:
    """Whether this process runs one of the toolkit's commands: a console script (``ofbe-…``), or
    ``python -m ofbe_data.cli.…`` (``ofbe_model.cli.…``), whose module is being run."""
    spec = getattr(sys.modules.get("__main__"), "__spec__", None)
    return (os.path.basename(sys.argv[0] if sys.argv else "").startswith("ofbe-")
            or (getattr(spec, "name", None) or "").startswith(("ofbe_data.cli.", "ofbe_model.cli.")))


if _a_command() and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
    signal.signal(signal.SIGINT, _hold)


def take_over() -> None:
    """Where this module's import holds Ctrl-C off (in a command's process), let it raise
    ``KeyboardInterrupt`` from here on, and raise one that came meanwhile; elsewhere (a test's
    process) nothing. What :func:`run` does first, and each command's ``main``
    (:func:`ofbe_data.core.cli.command`): a command started another way than through
    :func:`run` (``python -m ofbe_data.cli.label``) is covered from this module's import on.
    """
    if signal.getsignal(signal.SIGINT) is _hold:
        signal.signal(signal.SIGINT, _interrupt)
        if _seen:
            raise KeyboardInterrupt


def interrupted() -> bool:
    """Whether this process got a Ctrl-C while one of the toolkit's commands ran: what turns an
    error an extension module made of it (NumPy's import raises an ``ImportError``) back into
    the one line and exit 130 (:func:`run`, :func:`ofbe_data.core.cli.command`)."""
    return bool(_seen)


def _ignore_ctrl_c() -> None:
    """From here on a Ctrl-C is ignored: the command is over, the process only ends."""
    while True:
        try:
            signal.signal(signal.SIGINT, signal.SIG_IGN)
            return
        except KeyboardInterrupt:  # one pending, raised as the handler changes: over all the same
            continue


def _unraisable_hook(previous: Callable[[Any], Any]) -> Callable[[Any], Any]:
    """``sys.unraisablehook`` that raises a ``KeyboardInterrupt`` again rather than print it.

    A Ctrl-C that lands in a ``__del__`` or a weakref callback (run by the garbage collector at
    any allocation) cannot propagate: Python prints "Exception ignored in …" with a traceback
    and goes on. Here the interrupt is raised again in the command's own code a moment later
    (from a thread, so not inside this hook).
    """
    def hook(unraisable: Any) -> None:
        if isinstance(unraisable.exc_type, type) and issubclass(unraisable.exc_type, KeyboardInterrupt):
            import _thread
            import threading

            threading.Timer(0.02, _thread.interrupt_main).start()
            return
        previous(unraisable)

    return hook


def run(module: str, prog: str) -> Any:
    """Import ``module`` and return its ``main()``: what a console script runs.

    A Ctrl-C before ``main`` takes over (while the module imports) prints
    ``<prog>: interrupted; …`` on stderr and returns 130 (``main`` reports one while it runs
    itself, :func:`ofbe_data.core.cli.command`); so does any exception that escapes after a
    Ctrl-C, which a module may have made of it. Once ``main`` has returned, or that line is
    printed, Ctrl-C is ignored: only the interpreter's exit is left, whose clean-up (atexit)
    must not be cut short, and ``main``'s outputs are complete.

    Parameters
    ----------
    module
        The command's module, e.g. ``ofbe_data.cli.label``.
    prog
        The command's name, e.g. ``ofbe-label``.
    """
    code: Any = None
    returned = False
    sys.unraisablehook = _unraisable_hook(sys.unraisablehook)
    try:
        try:
            if signal.getsignal(signal.SIGINT) in (_hold, signal.default_int_handler):
                signal.signal(signal.SIGINT, _interrupt)
            if _seen:
                raise KeyboardInterrupt
            main = importlib.import_module(module).main
            code, returned = main(), True
        finally:
            _ignore_ctrl_c()
    except BaseException as exc:
        _ignore_ctrl_c()
        if not _seen and not isinstance(exc, KeyboardInterrupt):
            raise  # the command's own error, or its exit (argparse's)
        if not returned:  # a Ctrl-C, or what a module made of it
            print(f"{prog}: {INTERRUPTED}", file=sys.stderr)
            code = EXIT_INTERRUPTED
    return code


def console_script(module: str, prog: str) -> Callable[[], Any]:
    """A console script's function: ``run(module, prog)`` (pyproject.toml's ``[project.scripts]``
    names one per command, in :mod:`ofbe_data.cli.entry` and :mod:`ofbe_model.cli.entry`)."""

    def script() -> Any:
        return run(module, prog)

    script.__name__ = script.__qualname__ = prog.removeprefix("ofbe-").replace("-", "_")
    script.__doc__ = f"``{prog}`` (:mod:`{module}`)."
    script.command_module = module  # type: ignore[attr-defined]  # what it runs, for tests and docs
    return script
