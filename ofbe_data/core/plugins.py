"""Extension by dropping a file in: a package whose members register themselves imports all its
public modules (:func:`import_submodules`), so adding a member is its own module and nothing else.

The device formats (:mod:`ofbe_data.io.formats`), the estimators (:mod:`ofbe_model.estimators`)
and the export formats (:mod:`ofbe_data.calibration.exports`) are such packages. The order in which
their members are listed is each member's own ``order`` field, not the order of imports, so it
does not depend on file names or on the file system.
"""

from __future__ import annotations

import importlib
import pkgutil
from types import ModuleType

__all__ = ["import_submodules"]


def import_submodules(package: str) -> tuple[ModuleType, ...]:
    """Import every public module of ``package`` (its registrations run when imported).

    Parameters
    ----------
    package
        A package's dotted name, usually the ``__name__`` of its ``__init__``.

    Returns
    -------
    tuple of module
        The modules, sorted by name: private modules (``_name``) and subpackages are left out
        (a subpackage that registers members imports its own).
    """
    pkg = importlib.import_module(package)
    names = sorted(m.name for m in pkgutil.iter_modules(pkg.__path__)
                   if not m.ispkg and not m.name.startswith("_"))
    return tuple(importlib.import_module(f"{package}.{name}") for name in names)
