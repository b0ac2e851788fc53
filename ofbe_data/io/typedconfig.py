"""Typed configuration records from plain YAML data.

Shared by the simulator's configuration and the labelling parameters: every key is checked
against a dataclass's fields and every value against its annotation, and errors name the key
(:class:`~ofbe_data.core.errors.ConfigError`). Written here rather than taken from a validation
library because the toolkit's records are plain frozen dataclasses and the rules are few.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ofbe_data.core.errors import ConfigError
from ofbe_data.io.yamlio import YamlProblem, read_yaml


def _convert(value: Any, tp: Any, source: str | Path, key: str) -> Any:
    """Convert plain YAML data to the annotated type, or raise ConfigError."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        return _convert(value, inner[0], source, key)
    if dataclasses.is_dataclass(tp):
        return from_plain(value, tp, source, key)
    if tp is bool:
        if not isinstance(value, bool):
            raise ConfigError(source, key, "true or false", repr(value))
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(source, key, "an integer", repr(value))
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(source, key, "a number", repr(value))
        if not math.isfinite(value):
            # a NaN or infinite threshold silently switches its check off
            raise ConfigError(source, key, "a finite number", repr(value))
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise ConfigError(source, key, "a string", repr(value))
        return value
    if origin is tuple:
        if not isinstance(value, list | tuple):
            raise ConfigError(source, key, "a list", repr(value))
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(v, args[0], source, f"{key}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(source, key, f"a list of {len(args)} values", repr(value))
        return tuple(_convert(v, a, source, f"{key}[{i}]")
                     for i, (v, a) in enumerate(zip(value, args, strict=True)))
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(source, key, "a mapping", repr(value))
        return {str(k): _convert(v, args[1], source, f"{key}.{k}") for k, v in value.items()}
    raise ConfigError(source, key, f"a value of type {tp}", repr(value))  # pragma: no cover


def from_plain(data: Any, cls: Any, source: str | Path, prefix: str = "") -> Any:
    """Build dataclass ``cls`` from plain YAML/JSON data, checking every key and type.

    Parameters
    ----------
    data
        A mapping (nested mappings for nested dataclasses).
    cls
        The (frozen) dataclass to build; its annotations give the types.
    source
        File or name the data came from, for error messages.
    prefix
        Dotted key of ``data`` within the document ("" at the top).

    Returns
    -------
    An instance of ``cls``.

    Raises
    ------
    ConfigError
        An unknown key, a value of the wrong type, or a missing required key.
    """
    if not isinstance(data, dict):
        raise ConfigError(source, prefix or "<document>", "a mapping", repr(data))
    hints = typing.get_type_hints(cls)
    names = {f.name for f in dataclasses.fields(cls)}
    unknown = sorted(set(data) - names)
    if unknown:
        key = f"{prefix}.{unknown[0]}" if prefix else unknown[0]
        raise ConfigError(source, key, "one of " + ", ".join(sorted(names)), "an unknown key")
    kwargs = {}
    for name, value in data.items():
        key = f"{prefix}.{name}" if prefix else name
        kwargs[name] = _convert(value, hints[name], source, key)
    try:
        return cls(**kwargs)
    except TypeError as exc:
        raise ConfigError(source, prefix or "<document>", "all required keys", str(exc)) from None


def read_section(path: str | Path, section: str, whole_if_missing: bool = False) -> dict[str, Any]:
    """The plain mapping under ``section`` of a YAML file (e.g. params.yaml).

    Parameters
    ----------
    path
        The YAML file.
    section
        Top-level key.
    whole_if_missing
        Return the whole document when it has no such key (a file holding only that
        section); otherwise an empty mapping.

    A file with a top-level ``profile`` (params.yaml) is read with that profile's overrides
    merged, as the pipeline reads it (:func:`ofbe_data.io.pipeline_params.load_params`).

    Raises
    ------
    ConfigError
        Unreadable file, invalid YAML (with its line), an unknown profile, or a section that
        is not a mapping.
    """
    try:
        data = read_yaml(path).data
    except YamlProblem as exc:
        raise ConfigError(f"{path}:{exc.line}" if exc.line else path, exc.field, exc.expected,
                          exc.found) from None
    except OSError as exc:
        raise ConfigError(path, "<file>", "a readable YAML file", exc.strerror or str(exc)) from None
    if isinstance(data, dict) and isinstance(data.get("profile"), str):
        # a params file with a profile (params.yaml): its sections as the pipeline sees them
        from ofbe_data.io.pipeline_params import load_params

        data = load_params(path)
    if isinstance(data, dict) and section in data:
        data = data[section]
    elif not whole_if_missing:
        data = None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ConfigError(path, section, f"a mapping of {section} parameters", type(data).__name__)
    return data


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
