"""Estimators and what is built on them: the models, the benchmark, predictions.

- :mod:`ofbe_model.estimators`: one interface and registry, one module per family
  (physics: level-mean, ls-trf, won2009; priors: prior-mean, gravity-prior; oracle);
- :mod:`ofbe_model.ofbenet`: the paper's CNN in Keras 3 and its training;
- :mod:`ofbe_model.benchmark`: the protocols' folds, every estimator on every fold, the
  statistics and the report (Table 3, t-tests, figures);
- :mod:`ofbe_model.predict`: a saved model on session folders or bare device files;
- :mod:`ofbe_model.cli`: ``ofbe-train``, ``ofbe-benchmark``, ``ofbe-predict``.

It may import every part of ``ofbe_data`` except its command lines; nothing in ``ofbe_data``
imports it. Reports that are not about models (convergence, small angle, the index page) are
in :mod:`ofbe_data.reports`.
"""
