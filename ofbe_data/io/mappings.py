"""Small pure helpers on configuration mappings, shared by the typed configuration
(:mod:`ofbe_data.io.typedconfig`) and the pipeline's parameters
(:mod:`ofbe_data.io.pipeline_params`)."""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping
from typing import Any


def closest_key(key: str, known: Iterable[str]) -> str | None:
    """The known key most like ``key`` (:func:`difflib.get_close_matches`, cutoff 0.6), or None."""
    matches = difflib.get_close_matches(key, sorted(known), n=1)
    return matches[0] if matches else None


def deep_merge(base: Mapping[str, Any], over: Mapping[str, Any]) -> dict[str, Any]:
    """``base`` with ``over`` merged in: nested mappings key by key, other values replaced.

    Used for a configuration's overrides (simulator profiles, pipeline profiles).
    """
    out = dict(base)
    for key, value in over.items():
        if isinstance(value, Mapping) and isinstance(out.get(key), Mapping):
            out[key] = deep_merge(out[key], value)
        else:
            out[key] = value
    return out
