"""The deployed models' file names, and the window ``ofbe-predict`` gives a model that takes
any length: apart from :mod:`ofbe_model.deploy.final` and :mod:`ofbe_model.predict` (pandas,
h5py), so that ``ofbe-predict --help`` shows them without importing those (:mod:`ofbe_model.cli`).
Both modules import these names from here.
"""

from __future__ import annotations

OFBENET_NAME = "final.keras"
"""A deployed OFBENet's file."""
PRIOR_NAME = "gravity-prior.json"
"""A deployed gravity-prior's file."""
MODEL_FILES = {"ofbenet": OFBENET_NAME, "gravity-prior": PRIOR_NAME}
"""The deployed models' file names (:mod:`ofbe_model.deploy.final`), by estimator."""
DEFAULT_WINDOW = 3000
"""Samples per window for a model that takes any length (``ofbe-predict --window-length``)."""
