"""The benchmark: every estimator on every fold of a protocol (:mod:`~ofbe_model.benchmark.runner`,
``ofbe-benchmark``; the folds themselves are the dataset's, :mod:`ofbe_data.dataset.folds`),
metrics and paired tests
(:mod:`~ofbe_model.benchmark.statistics`) and the report: Table 3, t-tests, figures
(:mod:`~ofbe_model.benchmark.report`, :mod:`~ofbe_model.benchmark.figures`,
:mod:`~ofbe_model.benchmark.ordering`). It may import ``ofbe_data`` (not its command lines), the
estimators and OFBENet; ``ofbe-benchmark`` itself is :mod:`ofbe_model.cli.benchmark`.
"""
