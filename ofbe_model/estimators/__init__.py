"""The estimators behind one interface and registry (:mod:`~ofbe_model.estimators.base`).

``make_estimator(name, **params)`` builds any registered estimator; ``estimator_names()``
lists them. One module per family: :mod:`~ofbe_model.estimators.physics` (level-mean,
ls-trf, won2009), :mod:`~ofbe_model.estimators.priors` (prior-mean, gravity-prior),
:mod:`~ofbe_model.estimators.oracle` (oracle), with what they share in
:mod:`~ofbe_model.estimators.common`; OFBENet in :mod:`ofbe_model.ofbenet`. May import
``ofbe_data`` (never its command lines).
"""

from __future__ import annotations

from ofbe_model.estimators.base import Estimator, EstimatorError, estimator_names, make_estimator

__all__ = ["Estimator", "EstimatorError", "estimator_names", "make_estimator"]
