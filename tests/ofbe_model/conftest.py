"""Fixtures of the model package's tests."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from ofbe_data.core.parallel import kept_workers


@pytest.fixture(scope="module", autouse=True)
def _kept_training_workers() -> Iterator[None]:
    """The spawned training workers (TensorFlow started in each, about 8 s of CPU) serve every
    test of a module, as in a notebook that trains several times
    (:func:`~ofbe_data.core.parallel.kept_workers`): the models must not depend on what a worker
    fitted before, which these tests check too. Module-scoped, so that no other package's tests
    run inside the block; each command-line run in a subprocess and each pipeline stage starts
    its own workers."""
    with kept_workers():
        yield
