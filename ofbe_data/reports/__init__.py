"""Reports about the data rather than about models: convergence, small angle, the index page.

``ofbe-convergence`` (:mod:`~ofbe_data.reports.convergence`), ``ofbe-small-angle``
(:mod:`~ofbe_data.reports.small_angle`) and ``ofbe-index`` (:mod:`~ofbe_data.reports.index`,
which links every table and figure, the benchmark's included, by reading their files). They
live with the data because none of them needs a model; they may import every other part of
``ofbe_data`` but never ``ofbe_model``.
"""
