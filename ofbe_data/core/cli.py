"""What every command line shares: exit statuses, the one-line failure, ``--jobs``,
``--scheduler`` and ``--params``, and keeping library start-up noise off the terminal.

Every command (``ofbe_data.cli.*``, ``ofbe_model.cli.*``) is a ``main(argv) -> int`` that
parses its arguments, calls its wing, and turns an expected error into one line on stderr,
``<prog>: error: <message>``, and an exit status: :data:`EXIT_OK`, :data:`EXIT_DATA` (the
input data are bad or the work failed), :data:`EXIT_USAGE` (the command line or a
parameter file is wrong), :data:`EXIT_IO` (an output could not be written: a full disk, an
I/O error) or :data:`EXIT_INTERRUPTED` (Ctrl-C).
"""

from __future__ import annotations

import argparse
import functools
import os
import re
import shutil
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

from ofbe_data.core.atomic import is_write_failure
from ofbe_data.core.entry import EXIT_INTERRUPTED, INTERRUPTED, interrupted, take_over

EXIT_OK = 0
"""Success (or, for ``ofbe-label``, every session labelled or cleanly rejected)."""
EXIT_DATA = 1
"""Bad input data or a failed computation; the message names the file."""
EXIT_USAGE = 2
"""A usage or parameter error."""

VERBOSE_ENV = "OFBE_VERBOSE"
"""Set to 1 to let TensorFlow's and absl's start-up messages through (``--verbose`` does too)."""

EXIT_IO = 74
"""An output could not be written (a full disk, a quota, an I/O error): sysexits' ``EX_IOERR``."""

def io_failure(prog: str, exc: OSError, out: str | Path | None, what: str) -> int:
    """Report a file-system error in one line and return the exit status.

    The line names the file (``exc.filename``, else ``out``), the system's reason, and that
    nothing partial was kept (every writer of the toolkit writes a file or folder under a
    temporary name and removes it on failure). A failed write (:func:`is_write_failure`)
    also gives the free space on the disk it was going to, and returns :data:`EXIT_IO`; any
    other ``OSError`` (a permission, a missing folder) :data:`EXIT_DATA`.

    Parameters
    ----------
    prog
        The command's name.
    exc
        The error.
    out
        The output the command was writing, when ``exc`` names no file.
    what
        What could not be written, e.g. ``"the labels could not be written"``.
    """
    target = Path(exc.filename) if exc.filename else Path(out or ".")
    where = next((p for p in (target, *target.parents) if p.exists()), Path("."))
    target = public_path(target)
    reason = exc.strerror or str(exc)
    if not is_write_failure(exc):
        return fail(prog, f"{target}: {reason}: {what}; nothing partial is kept", EXIT_DATA)
    if "free on its disk" not in reason:
        try:
            reason += f" ({shutil.disk_usage(where).free / 1e6:.1f} MB free on its disk)"
        except OSError:
            reason += " (free space unknown)"
    return fail(prog, f"{target}: {reason}: {what}; nothing partial is kept, free space and rerun", EXIT_IO)


_TEMPORARY = re.compile(r"\.(.+)\.[A-Za-z0-9_]{8}\.tmp")
"""A temporary name of ``core.atomic`` (``mkstemp``/``mkdtemp``: ``.<name>.<8 characters>.tmp``)."""


def public_path(path: Path) -> Path:
    """``path`` with each temporary name of :mod:`ofbe_data.core.atomic` replaced by the name it
    was to be given (``out/.ds.k2j4x8q1.tmp/windows.h5`` → ``out/ds/windows.h5``): what a user
    looks for, since the temporary folder is removed on failure."""
    return Path(*[m.group(1) if (m := _TEMPORARY.fullmatch(part)) else part for part in path.parts])


class HelpFormatter(argparse.HelpFormatter):
    """Every command's help layout: descriptions wrapped to the terminal, never inside a
    hyphenated word (profile and option names stay whole); a block whose first line ends with
    ``:`` and whose other lines are indented (``examples:``, ``formats:``) kept as written; an
    option's default shown one way, ``(default: X)``, added where its help does not already say
    it (options without a default, and flags, show none)."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        blocks = []
        for block in text.split("\n\n"):
            lines = block.splitlines()
            if len(lines) > 1 and lines[0].endswith(":") and all(ln.startswith("  ") for ln in lines[1:]):
                blocks.append("\n".join(indent + ln for ln in lines))
            else:
                blocks.append(textwrap.fill(" ".join(block.split()), width, initial_indent=indent,
                                            subsequent_indent=indent, break_on_hyphens=False))
        return "\n\n".join(blocks)

    def _split_lines(self, text: str, width: int) -> list[str]:
        return textwrap.wrap(" ".join(text.split()), width, break_on_hyphens=False)

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if ("%(default)" in text or "default" in text.lower() or action.default in (None, False)
                or action.default is argparse.SUPPRESS or not action.option_strings):
            return text
        return f"{text} (default: %(default)s)"


def with_examples(parser: argparse.ArgumentParser, *examples: str) -> argparse.ArgumentParser:
    """Give ``parser`` the shared :class:`HelpFormatter` and an ``examples:`` block (one command
    line each) after any epilog it has; returns it."""
    parser.formatter_class = HelpFormatter
    block = "examples:\n" + "\n".join(f"  {line}" for line in examples)
    parser.epilog = f"{block}\n\n{parser.epilog}" if parser.epilog else block
    return parser


def command(prog: str) -> Callable[[Callable[..., int]], Callable[..., int]]:
    """Decorate a command's ``main``: Ctrl-C prints one line and exits 130, a failed write
    (:func:`is_write_failure`) one line and 74, no traceback. A Ctrl-C while the command's
    modules were imported is raised as ``main`` starts (:func:`ofbe_data.core.entry.take_over`);
    one during the imports ``main`` makes after parsing its arguments, which a module may have
    turned into another error (:func:`ofbe_data.core.entry.interrupted`), is reported the same way.

    Files are written atomically everywhere, so an interrupted run leaves whole files or none.
    """
    def wrap(main: Callable[..., int]) -> Callable[..., int]:
        @functools.wraps(main)
        def run(*args: Any, **kwargs: Any) -> int:
            try:
                take_over()  # a Ctrl-C held since the command's imports is raised here
                return main(*args, **kwargs)
            except KeyboardInterrupt:
                print(f"{prog}: {INTERRUPTED}", file=sys.stderr)
                return EXIT_INTERRUPTED
            except OSError as exc:  # a write that no command-specific handler caught
                if not is_write_failure(exc):
                    raise
                return io_failure(prog, exc, None, "the output could not be written")
            except MemoryError:
                return fail(prog, "ran out of memory (is a length or size parameter far too large?); "
                                  "nothing partial was written", EXIT_DATA)
            except Exception:
                if not interrupted():
                    raise
                # what a module made of a Ctrl-C while the command's own imports ran (after parsing)
                print(f"{prog}: {INTERRUPTED}", file=sys.stderr)
                return EXIT_INTERRUPTED
        return run
    return wrap


def fail(prog: str, message: str, code: int) -> int:
    """Print ``<prog>: error: <message>`` on stderr and return ``code``."""
    print(f"{prog}: error: {message}", file=sys.stderr)
    return code


def add_jobs(parser: argparse.ArgumentParser, what: str = "worker processes") -> None:
    """``--jobs N`` (default 1)."""
    parser.add_argument("--jobs", type=int, default=1, help=f"{what} (default: %(default)s)")


def scheduler_arg(value: str) -> str:
    """``--scheduler``'s type: a scheduler name or address, checked
    (:func:`ofbe_data.core.scheduler.check_scheduler`).

    Raises
    ------
    argparse.ArgumentTypeError
        Anything else: argparse then exits 2 with ``argument --scheduler: expected …, found …``.
    """
    from ofbe_data.core.scheduler import check_scheduler

    try:
        return check_scheduler(value)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_scheduler(parser: argparse.ArgumentParser) -> None:
    """``--scheduler S``: where ``--jobs`` workers run (default ``processes``)."""
    parser.add_argument("--scheduler", type=scheduler_arg, default="processes", metavar="S",
                        help="processes (a local process pool, the default), dask (an embedded Dask "
                             "cluster of --jobs single-threaded workers) or the address of a running Dask "
                             "scheduler, tcp://host:port (its workers must see the same files); the outputs "
                             "are the same whatever the scheduler")


def add_params(parser: argparse.ArgumentParser, section: str, what: str) -> None:
    """``--params FILE``: a YAML file whose ``<section>:`` section sets ``what``."""
    parser.add_argument("--params", help=f"YAML file whose '{section}:' section sets {what}")


def add_verbose(parser: argparse.ArgumentParser) -> None:
    """``--verbose``: let the libraries' start-up messages through (see :func:`quiet_libraries`)."""
    parser.add_argument("--verbose", action="store_true",
                        help=f"show TensorFlow's start-up messages (also {VERBOSE_ENV}=1)")


def _verbose(verbose: bool) -> bool:
    return verbose or os.environ.get(VERBOSE_ENV, "") not in ("", "0")


def quiet_libraries(verbose: bool = False) -> None:
    """Keep TensorFlow's and absl's messages off the terminal unless asked for.

    TensorFlow's C++ core logs CPU-instruction notes, CUDA probing and graph warnings
    (``E0000 … NodeDef mentions attribute …``) to stderr. This sets ``TF_CPP_MIN_LOG_LEVEL=3``
    (unless the environment sets it) and lowers the TensorFlow, absl and Keras Python loggers
    to errors. With ``verbose`` or ``OFBE_VERBOSE=1`` nothing is changed. Call it before
    TensorFlow is imported; :func:`import_tensorflow` does.
    """
    if verbose:
        os.environ[VERBOSE_ENV] = "1"  # for the TensorFlow import that comes later
    if _verbose(verbose):
        return
    os.environ.setdefault("TF_CPP_MIN_LOG_LEVEL", "3")
    import logging

    for name in ("tensorflow", "absl", "keras"):
        logging.getLogger(name).setLevel(logging.ERROR)


def import_tensorflow(verbose: bool = False) -> ModuleType:
    """``import tensorflow`` without its start-up lines on the terminal (see :func:`quiet_libraries`).

    Some of those lines (absl's "All log messages before absl::InitializeLog()…", the CUDA
    stub's probe) are written by C++ code before any log level applies, so the process's
    stderr is pointed at /dev/null while the import runs; an import error is still raised,
    as a Python exception, after stderr is back.
    """
    if "tensorflow" in sys.modules or _verbose(verbose):
        import tensorflow

        return tensorflow
    quiet_libraries(verbose)
    sys.stderr.flush()
    saved = os.dup(2)
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        import tensorflow
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)
    return tensorflow
