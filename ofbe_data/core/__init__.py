"""The ground floor: what every wing uses and nothing of theirs.

Exceptions (:mod:`~ofbe_data.core.errors`), atomic writes (:mod:`~ofbe_data.core.atomic`),
the precision at which floats are written (:mod:`~ofbe_data.core.precision`), 3-vector
products without BLAS (:mod:`~ofbe_data.core.geometry`), the process pool with a progress bar
(:mod:`~ofbe_data.core.parallel`), the figure style (:mod:`~ofbe_data.core.figures`) and the
pieces every command line shares (:mod:`~ofbe_data.core.cli`). It imports only third-party
libraries: no other part of ``ofbe_data`` and never ``ofbe_model``.
"""
