"""The data's journey from raw files to shareable datasets, in wings.

- :mod:`ofbe_data.core`: errors, atomic writes, precision, geometry, the worker pool, the
  figure style, the shared command-line pieces;
- :mod:`ofbe_data.io`: manifests, device formats (one module per format behind a registry),
  typed recordings, YAML and configuration, local gravity;
- :mod:`ofbe_data.simulator`: simulated campaigns with their truth;
- :mod:`ofbe_data.labelling`: synchronisation, stationarity, orientation, the pose and campaign
  fits, convergence, labels and the label files;
- :mod:`ofbe_data.dataset`: windows, leak-free splits, the dataset store, export;
- :mod:`ofbe_data.reports`: the convergence, small-angle and index reports;
- :mod:`ofbe_data.cli`: the data package's commands.

Data flows one way, raw files → recordings → labels → windows/splits → datasets; the import
rules are in docs/architecture.md and enforced by tests/test_architecture.py.
``ofbe_data.load_dataset``, ``ofbe_data.read_labels`` and ``ofbe_data.find_calibration`` (the
calibration in force for a device at a time, :mod:`ofbe_data.calibration.store`) are imported on
first use, so that ``import ofbe_data`` stays light.
"""

from __future__ import annotations

from typing import Any

__version__ = "0.1.0"

__all__ = ["__version__", "find_calibration", "load_dataset", "read_labels"]


def __getattr__(name: str) -> Any:
    if name == "load_dataset":
        from ofbe_data.dataset.reader import load_dataset

        return load_dataset
    if name == "find_calibration":
        from ofbe_data.calibration.store import find_calibration

        return find_calibration
    if name == "read_labels":
        from ofbe_data.labelling.store import read_labels

        return read_labels
    raise AttributeError(f"module 'ofbe_data' has no attribute {name!r}")
