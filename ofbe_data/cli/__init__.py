"""The data package's command lines, one module per command, each ``main(argv) -> int``.

``ofbe-simulate`` (:mod:`~ofbe_data.cli.simulate`), ``ofbe-label``
(:mod:`~ofbe_data.cli.label`), ``ofbe-dataset`` (:mod:`~ofbe_data.cli.dataset`),
``ofbe-convergence`` (:mod:`~ofbe_data.cli.convergence`), ``ofbe-small-angle``
(:mod:`~ofbe_data.cli.small_angle`), ``ofbe-index`` (:mod:`~ofbe_data.cli.index`), ``ofbe-session``
(:mod:`~ofbe_data.cli.session`), ``ofbe-autocal`` (:mod:`~ofbe_data.cli.autocal`) and ``ofbe-export``
(:mod:`~ofbe_data.cli.export`; the model package adds its formats through an entry point). A command
parses its arguments, calls its wing and turns errors into one line and an exit status
(:mod:`ofbe_data.core.cli`); the work itself is in the wings. Nothing imports this package
but the console scripts, ``pipelines/`` and the tests.
"""
