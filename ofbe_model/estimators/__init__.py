"""The estimators behind one interface and registry (:mod:`~ofbe_model.estimators.base`).

``make_estimator(name, **params)`` builds any registered estimator; ``estimator_names()``
lists them. One module per family: :mod:`~ofbe_model.estimators.physics` (level-mean,
ls-trf, won2009), :mod:`~ofbe_model.estimators.priors` (prior-mean, gravity-prior),
:mod:`~ofbe_model.estimators.oracle` (oracle), with what they share in
:mod:`~ofbe_model.estimators.common`; OFBENet in :mod:`ofbe_model.ofbenet`. Importing this
package registers them all: each family module registers its estimators (``@register``) when
imported here, and OFBENet, whose module starts TensorFlow, is registered by name and imported
on first use (:func:`~ofbe_model.estimators.base.register_lazy`). The registration order is the
order of the benchmark's default rows. May import ``ofbe_data`` (never its command lines).
"""

from __future__ import annotations

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

# The built-in estimators, registered in this order (the benchmark's default rows): the physics
# baselines, the priors, OFBENet, and last the oracle, which reads the simulator's truth.
# isort: off
from ofbe_model.estimators import physics  # noqa: E402, F401
from ofbe_model.estimators import priors  # noqa: E402, F401

register_lazy("ofbenet", "ofbe_model.ofbenet.network")

from ofbe_model.estimators import oracle  # noqa: E402, F401
# isort: on

__all__ = ["Estimator", "EstimatorError", "estimator_names", "make_estimator", "register", "register_lazy",
           "registered_names", "unregister"]
