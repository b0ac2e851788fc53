"""Raw formats, manifest, labels, convergence, windows, splits, datasets and the simulator.

Data flows one way: raw files → typed recordings (:mod:`ofbe_data.rawio`) → labels →
windows/splits → datasets (:mod:`ofbe_data.datastore`) → estimators → reports.

``ofbe_data.load_dataset`` is :func:`ofbe_data.datastore.load_dataset`, imported on first
use so that ``import ofbe_data`` stays light.
"""

from __future__ import annotations

from typing import Any

__version__ = "0.1.0"

__all__ = ["__version__", "load_dataset"]


def __getattr__(name: str) -> Any:
    if name == "load_dataset":
        from ofbe_data.datastore import load_dataset

        return load_dataset
    raise AttributeError(f"module 'ofbe_data' has no attribute {name!r}")
