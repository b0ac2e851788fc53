"""The model package's command lines, one module per command, each ``main(argv) -> int``.

``ofbe-train`` (:mod:`~ofbe_model.cli.train`), ``ofbe-benchmark``
(:mod:`~ofbe_model.cli.benchmark`) and ``ofbe-predict`` (:mod:`~ofbe_model.cli.predict`), built
like the data package's (:mod:`ofbe_data.cli`). Nothing imports this package but the console
scripts, ``pipelines/`` and the tests.
"""
