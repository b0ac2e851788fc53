"""The model package's console scripts: each imports its command inside
:func:`ofbe_data.core.entry.run`, so that a Ctrl-C during the imports (TensorFlow's take seconds)
is one line and exit 130, not a traceback (pyproject.toml's ``[project.scripts]``).
"""

from __future__ import annotations

from ofbe_data.core.entry import run


def train() -> int:
    """``ofbe-train`` (:mod:`ofbe_model.cli.train`)."""
    return run("ofbe_model.cli.train", "ofbe-train")


def benchmark() -> int:
    """``ofbe-benchmark`` (:mod:`ofbe_model.cli.benchmark`)."""
    return run("ofbe_model.cli.benchmark", "ofbe-benchmark")


def predict() -> int:
    """``ofbe-predict`` (:mod:`ofbe_model.cli.predict`)."""
    return run("ofbe_model.cli.predict", "ofbe-predict")


def export() -> int:
    """``ofbe-export`` (:mod:`ofbe_model.cli.export`)."""
    return run("ofbe_model.cli.export", "ofbe-export")
