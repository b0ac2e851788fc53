"""Estimators (one interface), OFBENet, training, evaluation, statistics, reports and figures.

- :mod:`ofbe_model.base`: the estimator interface and registry;
- :mod:`ofbe_model.estimators`: level-mean, ls-trf, won2009, prior-mean, gravity-prior, oracle;
- :mod:`ofbe_model.ofbenet`: the paper's CNN in Keras 3;
- :mod:`ofbe_model.evaluation`, :mod:`ofbe_model.benchmark`, :mod:`ofbe_model.statistics`,
  :mod:`ofbe_model.benchmark_report`: protocols' folds, the benchmark and its report;
- :mod:`ofbe_model.convergence_report`, :mod:`ofbe_model.small_angle_report`,
  :mod:`ofbe_model.figures`: the other reports and the shared figure style.
"""
