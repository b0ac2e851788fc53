"""Typed configuration records from plain YAML data.

Shared by the simulator's configuration and the labelling parameters: every key is checked
against a dataclass's fields and every value against its annotation, and errors name the key
(:class:`~ofbe_data.core.errors.ConfigError`). Written here rather than taken from a validation
library because the toolkit's records are plain frozen dataclasses and the rules are few.

An unknown key is refused with where the key belongs, when it is known elsewhere in the same record
(``window_s`` → ``label.static.window_s``), in another configuration record (:data:`CONFIG_RECORDS`)
or in a session manifest (registered by :mod:`ofbe_data.io.manifest`), and with the closest
known key (:func:`closest_key`) when one is close (:func:`unknown_key_found`). The known keys are
always the records' own dataclass fields (:func:`record_keys`, :func:`key_paths`), so a field added
later is known at once.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib
import math
import types
import typing
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from ofbe_data.core.errors import ConfigError
from ofbe_data.io.mappings import closest_key
from ofbe_data.io.pipeline_params import load_params
from ofbe_data.io.yamlio import YamlProblem, read_yaml

KeyPaths = Mapping[str, tuple[str, ...]]
"""Each key of a document and the dotted paths where it is known (``fit_model`` → ``label.fit_model``)."""

CONFIG_RECORDS: tuple[tuple[str, str, str, str], ...] = (
    ("the label: section of params.yaml", "label", "ofbe_data.labelling.labels", "LabelParams"),
    ("the dataset: section of params.yaml", "dataset", "ofbe_data.dataset.build", "DatasetParams"),
    ("the convergence: section of params.yaml", "convergence", "ofbe_data.reports.convergence",
     "ConvergenceParams"),
    ("a simulator configuration", "", "ofbe_data.simulator.config", "SimConfig"),
)
"""The configuration records of ``ofbe_data`` that :func:`from_plain` reads: (where they are written,
the prefix of their keys, module, record). A key unknown where it was found is looked up in their
fields to say where it belongs. They live in wings above ``io``, which ``io`` never imports at module
level (docs/architecture.md): they are named here and imported on the error path only, when such a
message is written (:func:`key_homes`)."""


def record_keys(cls: Any) -> frozenset[str]:
    """The keys of a record's mapping: the field names of dataclass ``cls``."""
    return frozenset(f.name for f in dataclasses.fields(cls))


def _nested(tp: Any) -> tuple[Any, str] | None:
    """The record held by annotation ``tp`` and how a path goes on into it: ``X`` or ``X | None`` →
    (X, ""), ``tuple[X, ...]`` → (X, "[i]"), ``dict[str, X]`` → (X, ".<key>"); None when it holds none."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if dataclasses.is_dataclass(tp):
        return tp, ""
    if origin in (typing.Union, types.UnionType):
        inner = [a for a in args if a is not type(None)]
        return _nested(inner[0]) if len(inner) == 1 else None
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
        found = _nested(args[0])
        return (found[0], "[i]" + found[1]) if found is not None else None
    if origin is dict and len(args) == 2:
        found = _nested(args[1])
        return (found[0], ".<key>" + found[1]) if found is not None else None
    return None


def _merge_paths(a: KeyPaths, b: KeyPaths) -> dict[str, tuple[str, ...]]:
    """The paths of ``a`` and ``b`` together, key by key, in order."""
    out = dict(a)
    for key, paths in b.items():
        out[key] = out.get(key, ()) + tuple(p for p in paths if p not in out.get(key, ()))
    return out


def key_paths(cls: Any, prefix: str = "", _outer: frozenset[Any] = frozenset()) -> dict[str, tuple[str, ...]]:
    """Every key of record ``cls`` and of the records nested in it, with its dotted paths.

    Parameters
    ----------
    cls
        A dataclass; fields annotated with a dataclass (or ``X | None``, ``tuple[X, ...]``,
        ``dict[str, X]``) are followed.
    prefix
        Path of the record in its document (``label`` for :class:`LabelParams`).

    Returns
    -------
    dict
        Key → its paths, e.g. ``key_paths(LabelParams, "label")["window_s"] ==
        ("label.static.window_s",)``.
    """
    hints = typing.get_type_hints(cls)
    out: dict[str, tuple[str, ...]] = {}
    for f in dataclasses.fields(cls):
        path = f"{prefix}.{f.name}" if prefix else f.name
        out = _merge_paths(out, {f.name: (path,)})
        inner = _nested(hints.get(f.name))
        if inner is not None and inner[0] not in _outer | {cls}:
            out = _merge_paths(out, key_paths(inner[0], path + inner[1], _outer | {cls}))
    return out


_cached_key_paths = functools.cache(key_paths)


@functools.cache
def _import_record(module: str, name: str) -> Any:
    """Record ``name`` of ``module`` (a failed import is not cached: it is tried again)."""
    return getattr(importlib.import_module(module), name)


def key_homes(key: str, skip: Any = None, manifest: bool = True) -> list[tuple[str, tuple[str, ...]]]:
    """Where ``key`` is known outside the document at hand.

    Parameters
    ----------
    key
        An unknown key.
    skip
        The record of the document at hand (its own paths are not "elsewhere").
    manifest
        Whether to look in a session manifest too (not when the document is one).

    Returns
    -------
    list
        (where, the key's paths there) for each record of :data:`CONFIG_RECORDS` that knows it
        (a record whose module cannot be imported is left out), then for ``session.yaml``.
    """
    homes: list[tuple[str, tuple[str, ...]]] = []
    for where, prefix, module, name in CONFIG_RECORDS:
        try:
            cls = _import_record(module, name)
        except (ImportError, AttributeError):  # a partial install, or a module still importing
            continue
        paths = _cached_key_paths(cls, prefix).get(key) if cls is not skip else None
        if paths:
            homes.append((where, paths))
    if manifest:
        for where, paths_of in _DOCUMENTS.items():
            paths = paths_of().get(key)
            if paths:
                homes.append((where, paths))
    return homes


_DOCUMENTS: dict[str, Callable[[], KeyPaths]] = {}
"""Documents below ``typedconfig``'s users whose keys an unknown-key message may point to
(``session.yaml``), registered by the module that defines them (:func:`register_document`)."""


def register_document(name: str, key_paths_of: Callable[[], KeyPaths]) -> None:
    """Make the keys of a document known to unknown-key messages of other documents.

    Parameters
    ----------
    name
        How messages name the document (``session.yaml``).
    key_paths_of
        Each key of the document and its dotted paths there (called when a message is written).
    """
    _DOCUMENTS[name] = key_paths_of


def _alternatives(paths: Sequence[str], limit: int = 3) -> str:
    """``a or b or c`` (and how many more beyond ``limit``)."""
    text = " or ".join(paths[:limit])
    return text + (f" (and {len(paths) - limit} more)" if len(paths) > limit else "")


def unknown_key_found(key: str, known: Iterable[str], own: Sequence[str] = (),
                      homes: Callable[[], Sequence[tuple[str, Sequence[str]]]] = list) -> str:
    """What an unknown key is, as an error's ``found``: ``an unknown key`` with what is known of it.

    Parameters
    ----------
    key
        The unknown key.
    known
        The keys known where it was found: the closest of them, when one is close, is offered
        (a typo).
    own
        The key's paths elsewhere in the same document (``site.latitude_deg``), if any.
    homes
        Otherwise, where else the key is known (:func:`key_homes`); called only when ``own`` is
        empty, since it may import the records.

    Returns
    -------
    str
        E.g. ``an unknown key (did you mean temperature_unit?)``, ``an unknown key (fit_model
        belongs in the label: section of params.yaml, as label.fit_model)``; where the key belongs
        comes first when both are known (it is certain, the closest key a guess).
    """
    if own:
        belongs = f"{key} belongs at {_alternatives(own)}"
    else:
        belongs = ", or in ".join(f"{where}, as {_alternatives(paths)}" for where, paths in homes())
        belongs = f"{key} belongs in {belongs}" if belongs else ""
    match = closest_key(key, known)
    hints = [h for h in (belongs, f"did you mean {match}?" if match is not None else "") if h]
    return "an unknown key" + (f" ({'; or '.join(hints)})" if hints else "")


def _convert(value: Any, tp: Any, source: str | Path, key: str, root: tuple[Any, str]) -> Any:
    """Convert plain YAML data to the annotated type, or raise ConfigError (``root``: the outermost
    record and its prefix, for where an unknown key belongs)."""
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        if value is None and type(None) in args:
            return None
        inner = [a for a in args if a is not type(None)]
        return _convert(value, inner[0], source, key, root)
    if dataclasses.is_dataclass(tp):
        return from_plain(value, tp, source, key, root)
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
            return tuple(_convert(v, args[0], source, f"{key}[{i}]", root) for i, v in enumerate(value))
        if len(value) != len(args):
            raise ConfigError(source, key, f"a list of {len(args)} values", repr(value))
        return tuple(_convert(v, a, source, f"{key}[{i}]", root)
                     for i, (v, a) in enumerate(zip(value, args, strict=True)))
    if origin is dict:
        if not isinstance(value, dict):
            raise ConfigError(source, key, "a mapping", repr(value))
        return {str(k): _convert(v, args[1], source, f"{key}.{k}", root) for k, v in value.items()}
    raise ConfigError(source, key, f"a value of type {tp}", repr(value))  # pragma: no cover


def from_plain(data: Any, cls: Any, source: str | Path, prefix: str = "",
               root: tuple[Any, str] | None = None) -> Any:
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
    root
        The outermost record being built and its prefix, when ``cls`` is nested in it (set by the
        recursion): an unknown key's message names where in it the key belongs.

    Returns
    -------
    An instance of ``cls``.

    Raises
    ------
    ConfigError
        An unknown key (with the closest known key, or where the key belongs: :func:`unknown_key_found`),
        a value of the wrong type, or a missing required key.
    """
    if not isinstance(data, dict):
        raise ConfigError(source, prefix or "<document>", "a mapping", repr(data))
    hints = typing.get_type_hints(cls)
    names = record_keys(cls)
    root = root if root is not None else (cls, prefix)
    unknown = sorted(str(k) for k in data if k not in names)
    if unknown:
        raise _unknown_key(unknown[0], names, source, prefix, root)
    kwargs = {}
    for name, value in data.items():
        key = f"{prefix}.{name}" if prefix else name
        kwargs[name] = _convert(value, hints[name], source, key, root)
    try:
        return cls(**kwargs)
    except TypeError as exc:
        raise ConfigError(source, prefix or "<document>", "all required keys", str(exc)) from None


def _unknown_key(name: str, names: frozenset[str], source: str | Path, prefix: str,
                 root: tuple[Any, str]) -> ConfigError:
    """The error for unknown key ``name`` of a record with keys ``names`` at ``prefix``."""
    own = _cached_key_paths(*root).get(name, ())
    found = unknown_key_found(name, names, own, lambda: key_homes(name, skip=root[0]))
    return ConfigError(source, f"{prefix}.{name}" if prefix else name, "one of " + ", ".join(sorted(names)),
                       found)


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
