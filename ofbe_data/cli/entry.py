"""The data package's console scripts: each imports its command inside
:func:`ofbe_data.core.entry.run`, so that a Ctrl-C during the imports (a second or two of numpy,
pandas, scipy) is one line and exit 130, not a traceback (pyproject.toml's ``[project.scripts]``).
"""

from __future__ import annotations

from ofbe_data.core.entry import run


def simulate() -> int:
    """``ofbe-simulate`` (:mod:`ofbe_data.cli.simulate`)."""
    return run("ofbe_data.cli.simulate", "ofbe-simulate")


def label() -> int:
    """``ofbe-label`` (:mod:`ofbe_data.cli.label`)."""
    return run("ofbe_data.cli.label", "ofbe-label")


def convergence() -> int:
    """``ofbe-convergence`` (:mod:`ofbe_data.cli.convergence`)."""
    return run("ofbe_data.cli.convergence", "ofbe-convergence")


def small_angle() -> int:
    """``ofbe-small-angle`` (:mod:`ofbe_data.cli.small_angle`)."""
    return run("ofbe_data.cli.small_angle", "ofbe-small-angle")


def dataset() -> int:
    """``ofbe-dataset`` (:mod:`ofbe_data.cli.dataset`)."""
    return run("ofbe_data.cli.dataset", "ofbe-dataset")


def index() -> int:
    """``ofbe-index`` (:mod:`ofbe_data.cli.index`)."""
    return run("ofbe_data.cli.index", "ofbe-index")


def session() -> int:
    """``ofbe-session`` (:mod:`ofbe_data.cli.session`)."""
    return run("ofbe_data.cli.session", "ofbe-session")


def autocal() -> int:
    """``ofbe-autocal`` (:mod:`ofbe_data.cli.autocal`)."""
    return run("ofbe_data.cli.autocal", "ofbe-autocal")
