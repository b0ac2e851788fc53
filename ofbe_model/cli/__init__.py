"""The model package's command lines, one module per command, each ``main(argv) -> int``.

``ofbe-train`` (:mod:`~ofbe_model.cli.train`), ``ofbe-benchmark``
(:mod:`~ofbe_model.cli.benchmark`) and ``ofbe-predict`` (:mod:`~ofbe_model.cli.predict`), built
like the data package's (:mod:`ofbe_data.cli`); and the model formats of ``ofbe-export``
(``tflite``, ``c-header``: :mod:`~ofbe_model.cli.export_formats`), which the data package's
command loads through the entry-point group ``ofbe.export_formats`` (pyproject.toml). Nothing
imports this package but the console scripts, that entry point, ``pipelines/`` and the tests.
"""
