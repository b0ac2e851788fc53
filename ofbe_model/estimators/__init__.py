"""The estimators behind one interface and registry (:mod:`~ofbe_model.estimators.base`).

``make_estimator(name, **params)`` builds any registered estimator; ``estimator_names()``
lists them. One module per family: :mod:`~ofbe_model.estimators.physics` (level-mean,
ls-trf, won2009), :mod:`~ofbe_model.estimators.priors` (prior-mean, gravity-prior),
:mod:`~ofbe_model.estimators.oracle` (oracle), with what they share in
:mod:`~ofbe_model.estimators.common`; OFBENet in :mod:`ofbe_model.ofbenet`. Importing this
package imports every public module in it (:func:`ofbe_data.core.plugins.import_submodules`), and
each family module registers its estimators (``@register``); OFBENet, whose module starts
TensorFlow, is registered by name in :mod:`~ofbe_model.estimators.ofbenet` and imported on first
use (:func:`~ofbe_model.estimators.base.register_lazy`). A new estimator is one new module: no
list to edit. The benchmark's default rows follow each estimator's ``order``. May import
``ofbe_data`` (never its command lines).
"""

from __future__ import annotations

from ofbe_data.core.plugins import import_submodules
from ofbe_model.estimators.base import (
    Estimator,
    EstimatorError,
    estimator_names,
    make_estimator,
    register,
    register_lazy,
    registered_names,
    unregister,
)

# Every public module here is imported, and each family module registers its estimators: adding an
# estimator is adding its module. The benchmark's default rows follow each one's Estimator.order.
import_submodules(__name__)

__all__ = ["Estimator", "EstimatorError", "estimator_names", "make_estimator", "register", "register_lazy",
           "registered_names", "unregister"]
