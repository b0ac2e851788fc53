"""The benchmark: protocols' folds (:mod:`~ofbe_model.benchmark.evaluation`), every estimator on
every fold (:mod:`~ofbe_model.benchmark.runner`, ``ofbe-benchmark``), metrics and paired tests
(:mod:`~ofbe_model.benchmark.statistics`) and the report: Table 3, t-tests, figures
(:mod:`~ofbe_model.benchmark.report`, :mod:`~ofbe_model.benchmark.figures`,
:mod:`~ofbe_model.benchmark.ordering`). It may import ``ofbe_data`` (not its command lines) and
the estimators; ``ofbe-benchmark`` itself is :mod:`ofbe_model.cli.benchmark`.
"""
