"""Safe YAML reading with duplicate-key detection and line numbers for error messages.

PyYAML's ``safe_load`` silently keeps the last of two equal keys, which would hide a
duplicated device id in a manifest. We therefore *compose* the document first (composing
builds plain nodes with positions and constructs no Python objects), reject duplicate
keys with their line, and only then ``yaml.safe_load`` the same text.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import yaml

from ofbe_data.core.atomic import file_kind

FieldPath = Sequence[str | int]


class YamlProblem(Exception):
    """Internal: a YAML problem with the field path and line, re-raised by callers as
    their own error type."""

    def __init__(self, field: str, expected: str, found: str, line: int | None) -> None:
        super().__init__(f"{field}: expected {expected}, found {found}")
        self.field = field
        self.expected = expected
        self.found = found
        self.line = line


def format_field(path: FieldPath) -> str:
    """Render a field path: ``("recordings", 2, "id")`` → ``recordings[2].id``."""
    out = ""
    for part in path:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "<document>"


MAX_NODES = 200_000
"""Largest document, in nodes with every alias expanded: a few hundred bytes of nested aliases
("billion laughs") would otherwise expand to billions of values for whoever walks the data."""
MAX_DEPTH = 64
"""Deepest nesting of lists and mappings accepted (manifests and configurations need < 10)."""


def _check_size(root: yaml.Node) -> None:
    """Refuse a document whose alias-expanded size or nesting is beyond the limits.

    Sizes are computed once per distinct node (an alias is the same node object), without
    recursion, so the check itself is linear in the text.
    """
    size: dict[int, int] = {}
    depth: dict[int, int] = {}
    stack: list[tuple[yaml.Node, bool]] = [(root, False)]
    while stack:
        node, done = stack.pop()
        key = id(node)
        if key in size:
            continue
        children = ([n for pair in node.value for n in pair] if isinstance(node, yaml.MappingNode)
                    else list(node.value) if isinstance(node, yaml.SequenceNode) else [])
        if not done:
            stack.append((node, True))
            stack.extend((c, False) for c in children if id(c) not in size)
            continue
        size[key] = 1 + sum(size.get(id(c), 1) for c in children)
        depth[key] = 1 + max((depth.get(id(c), 1) for c in children), default=0)
        if size[key] > MAX_NODES:
            raise YamlProblem("<document>", f"at most {MAX_NODES} values once aliases are expanded",
                              "more (aliases nested to expand exponentially?)", node.start_mark.line + 1)
        if depth[key] > MAX_DEPTH:
            raise YamlProblem("<document>", f"nesting at most {MAX_DEPTH} levels deep", "deeper nesting",
                              node.start_mark.line + 1)


def _too_deep_at(text: str) -> int | None:
    """Line where the nesting first goes past :data:`MAX_DEPTH`, or None.

    Walks the event stream only as far as it parses, so it answers for a document that the
    parser itself refuses: PyYAML and libyaml have nesting limits of their own (different by
    version, with their own wording), and a document too deep for ours is refused with our
    message whichever of them stops first. The pure-Python parser is used: libyaml's scanner
    reads far ahead in flow context and can stop on its own limit before the first events.
    """
    depth = 0
    try:
        loader = yaml.SafeLoader(text)
    except yaml.YAMLError:  # the reader refuses the text itself (a control character)
        return None
    try:
        while loader.check_event():
            event = loader.get_event()
            if isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
                depth += 1
                if depth > MAX_DEPTH:
                    return event.start_mark.line + 1
            elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
                depth -= 1
    except (yaml.YAMLError, RecursionError):
        return None
    finally:
        loader.dispose()
    return None


def _check_duplicates(node: yaml.Node, path: list[str | int]) -> None:
    if isinstance(node, yaml.MappingNode):
        seen: dict[str, int] = {}
        for key_node, value_node in node.value:
            key = str(key_node.value)
            line = key_node.start_mark.line + 1
            if key in seen:
                raise YamlProblem(
                    format_field([*path, key]),
                    "unique keys",
                    f"a duplicate of the key on line {seen[key]}",
                    line,
                )
            seen[key] = line
            _check_duplicates(value_node, [*path, key])
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _check_duplicates(item, [*path, i])


class _Loader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # type: ignore[misc]
    """libyaml's safe loader when PyYAML was built with it (same safe constructors, ~10×
    faster), which also reads ``1e9`` and ``2.5E-3`` as numbers: PyYAML follows YAML 1.1,
    whose floats need a dot, and would return the string ``"1e9"``."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)
_LOADER = _Loader


def _parse_problem(exc: yaml.YAMLError | RecursionError, text: str) -> YamlProblem:
    """The :class:`YamlProblem` for a document the parser refused, with its line.

    Nesting beyond :data:`MAX_DEPTH` is named as such whether the parser stopped on our limit's
    side or on one of its own (PyYAML recurses; newer libyaml has a depth limit with its own
    wording), so the message does not depend on the installed PyYAML.
    """
    deep_line = _too_deep_at(text)
    if deep_line is not None or isinstance(exc, RecursionError):
        return YamlProblem("<document>", f"nesting at most {MAX_DEPTH} levels deep", "deeper nesting",
                           deep_line)
    if isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else None
        return YamlProblem("<document>", "valid YAML", exc.problem or exc.context or "a syntax error", line)
    # e.g. a control character: a ReaderError has no mark
    position = getattr(exc, "position", None)
    line = text[:position].count("\n") + 1 if isinstance(position, int) else None
    reason = getattr(exc, "reason", None) or str(exc).splitlines()[0]
    char = getattr(exc, "character", None)
    found = f"{reason} (character {char!r})" if char is not None else reason
    return YamlProblem("<document>", "YAML text", found, line)


class YamlDocument:
    """A parsed YAML document that remembers where each field sits.

    Parameters
    ----------
    text
        The YAML text.

    Attributes
    ----------
    data
        The document as plain Python objects (``yaml.safe_load``).
    """

    def __init__(self, text: str) -> None:
        loader = _LOADER(text)
        try:
            # one parse: compose (keeps line numbers), check duplicates, then construct
            self._root = loader.get_single_node()
            if self._root is not None:
                _check_size(self._root)
                _check_duplicates(self._root, [])
            self.data: Any = loader.construct_document(self._root) if self._root is not None else None
        except (yaml.YAMLError, RecursionError) as exc:
            problem = _parse_problem(exc, text)
        else:
            return
        finally:
            loader.dispose()
        raise problem from None

    def line_of(self, path: FieldPath) -> int | None:
        """1-based line of the field at ``path`` (or of its deepest existing parent)."""
        node = self._root
        line = node.start_mark.line + 1 if node is not None else None
        for part in path:
            if isinstance(node, yaml.MappingNode):
                for key_node, value_node in node.value:
                    if str(key_node.value) == str(part):
                        line = key_node.start_mark.line + 1
                        node = value_node
                        break
                else:
                    return line
            elif isinstance(node, yaml.SequenceNode) and isinstance(part, int):
                if not 0 <= part < len(node.value):
                    return line
                node = node.value[part]
                line = node.start_mark.line + 1
            else:
                return line
        return line


def read_yaml(path: str | Path) -> YamlDocument:
    """Read a YAML file as UTF-8 into a :class:`YamlDocument`.

    Raises
    ------
    YamlProblem
        On a syntax error or a duplicate key, with the line.
    OSError
        When the file cannot be read.
    """
    kind = file_kind(path)
    if kind is not None:
        if kind == "no such file":
            raise FileNotFoundError(2, "No such file or directory", str(path))
        raise YamlProblem("<file>", "a regular YAML file", kind, None)
    raw = Path(path).read_bytes()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise YamlProblem("<document>", "UTF-8 text", f"byte 0x{raw[exc.start]:02x}", line) from None
    return YamlDocument(text)
