"""Estimators and what is built on them: the models, the benchmark, predictions.

The front door (each name is imported on first use, so that ``import ofbe_model`` stays light
and TensorFlow loads only when a network is made or loaded):

>>> import ofbe_model as om
>>> om.estimator_names()                                   # the registered estimators
>>> est = om.make_estimator("gravity-prior").fit(X, y)     # scikit-learn style, X (n, T, 3) m/s²
>>> model = om.load_model("models/rotated/sparkfun-1/final.keras")
>>> files = om.model_files("models/rotated")               # device → model file of a model set

- estimators: :func:`make_estimator`, :func:`estimator_names`, :class:`Estimator`,
  :class:`EstimatorError`, :class:`OFBENet`;
- predictions: :func:`load_model`, :func:`model_files`, :func:`targets` (the device files of
  session folders or bare files, read), :func:`predict_files` (each target with its own
  device's model).

The wings:

- :mod:`ofbe_model.estimators`: one interface and registry, one module per family
  (physics: level-mean, ls-trf, won2009; priors: prior-mean, gravity-prior; oracle);
- :mod:`ofbe_model.ofbenet`: the paper's CNN in Keras 3 and its training;
- :mod:`ofbe_model.benchmark`: the protocols' folds, every estimator on every fold, the
  statistics and the report (Table 3, t-tests, figures);
- :mod:`ofbe_model.deploy`: the deployed models, their cards, TensorFlow Lite and C exports;
- :mod:`ofbe_model.predict`: a saved model on session folders or bare device files;
- :mod:`ofbe_model.cli`: ``ofbe-train``, ``ofbe-benchmark``, ``ofbe-predict``, and the model formats
  of ``ofbe-export`` (``tflite``, ``c-header``; the command is the data package's).

It may import every part of ``ofbe_data`` except its command lines; nothing in ``ofbe_data``
imports it. Reports that are not about models (convergence, small angle, the index page) are
in :mod:`ofbe_data.reports`.
"""

from __future__ import annotations

from ofbe_data.core.front_door import lazy_names

_FRONT_DOOR = {
    "Estimator": "ofbe_model.estimators",
    "EstimatorError": "ofbe_model.estimators",
    "estimator_names": "ofbe_model.estimators",
    "make_estimator": "ofbe_model.estimators",
    "OFBENet": "ofbe_model.ofbenet",
    "load_model": "ofbe_model.predict",
    "model_files": "ofbe_model.predict",
    "targets": "ofbe_model.predict",
    "predict_files": "ofbe_model.predict",
}
"""Each front-door name and the module that defines it (imported on first use)."""

__all__ = sorted(_FRONT_DOOR)

__getattr__, __dir__ = lazy_names(__name__, _FRONT_DOOR)
