"""The display order of methods in the benchmark's tables and figures: baselines first, the others
by name, the oracle last.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

# ----------------------------------------------------------------------------- ordering


def ordered_methods(methods: Iterable[str], baselines: Sequence[str], oracle: str | None,
                    method_order: Sequence[str] | None = None) -> list[str]:
    """A stable display order of methods.

    Parameters
    ----------
    methods
        The methods to order.
    baselines
        Baselines, in their order.
    oracle
        The oracle's name, or None.
    method_order
        Preferred order. When given, its methods (those present) come first in that order
        and any others follow in the default order, so none is dropped.

    Returns
    -------
    list of str
        Default order: baselines first (in their order), then the others alphabetically,
        the oracle last.
    """
    present = set(methods)
    default = ([b for b in baselines if b in present]
               + sorted(m for m in present if m not in baselines and m != oracle)
               + ([oracle] if oracle in present else []))
    if method_order is None:
        return default
    given = [m for m in dict.fromkeys(method_order) if m in present]
    return given + [m for m in default if m not in given]


def all_methods(summary: dict[str, Any], method_order: Sequence[str] | None = None) -> list[str]:
    names: set[str] = set()
    for ds in summary["datasets"].values():
        names.update(ds["methods"])
    return ordered_methods(names, summary["baselines"], summary.get("oracle"), method_order)
