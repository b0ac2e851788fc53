"""OFBENet in the registry by name: its module (:mod:`ofbe_model.ofbenet.network`) starts
TensorFlow, so it is imported when an OFBENet is first made, not when the estimators are listed
(:func:`~ofbe_model.estimators.base.register_lazy`)."""

from __future__ import annotations

from ofbe_model.estimators.base import register_lazy

register_lazy("ofbenet", "ofbe_model.ofbenet.network", order=60)
