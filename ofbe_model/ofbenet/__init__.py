"""OFBENet, the paper's CNN in Keras 3 (:mod:`~ofbe_model.ofbenet.network`), and its training
(:mod:`~ofbe_model.ofbenet.training`, ``ofbe-train``).

``OFBENet`` and ``OFBENetParams`` are imported on first use, so that importing this package
does not start TensorFlow. It may import ``ofbe_data`` (not its command lines) and the
estimator interface (:mod:`ofbe_model.estimators.base`).
"""

from __future__ import annotations

from typing import Any

__all__ = ["OFBENet", "OFBENetParams"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from ofbe_model.ofbenet import network

        return getattr(network, name)
    raise AttributeError(f"module 'ofbe_model.ofbenet' has no attribute {name!r}")
