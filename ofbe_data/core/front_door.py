"""A package's front door: the main names it exports, each imported from its module on first
use, so that importing the package stays light (PEP 562 module ``__getattr__`` and ``__dir__``;
``help(package)`` then lists them)."""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable, Mapping
from typing import Any


def lazy_names(package: str, table: Mapping[str, str]
               ) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The ``__getattr__`` and ``__dir__`` of ``package`` for the names of ``table``.

    Parameters
    ----------
    package
        The package's ``__name__``.
    table
        Front-door name → the module that defines it.

    Returns
    -------
    getattr, dir
        ``getattr(name)`` imports the name's module, keeps the value in the package (so the
        next use is a plain attribute) and returns it; an unknown name is an
        :class:`AttributeError` worded as Python's own. ``dir()`` lists the package's
        attributes and every front-door name.
    """
    def getattr_(name: str) -> Any:
        module = table.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(module), name)
        setattr(sys.modules[package], name, value)
        return value

    def dir_() -> list[str]:
        return sorted(set(vars(sys.modules[package])) | set(table))

    return getattr_, dir_
