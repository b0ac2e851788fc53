"""Exception types of the toolkit.

Every error raised on bad input is one of these. Each message names the file (and the
line, where one is known), the field, what was expected and what was found, so that a
command-line tool can print it as a one-line reason.
"""

from __future__ import annotations

from pathlib import Path


class OfbeError(Exception):
    """Base class of every error the toolkit raises on bad input or configuration."""


def _where(path: str | Path | None, line: int | None) -> str:
    if path is None:
        return ""
    return f"{path}:{line}: " if line is not None else f"{path}: "


class ManifestError(OfbeError):
    """A ``session.yaml`` manifest does not follow raw-formats.md.

    Parameters
    ----------
    path
        The manifest file.
    field
        Dotted path of the offending field, e.g. ``recordings[2].files.memsense``.
    expected, found
        What the contract asks for and what the file holds.
    line
        1-based line of the field in the file, when known.
    """

    def __init__(
        self,
        path: str | Path,
        field: str,
        expected: str,
        found: str,
        line: int | None = None,
    ) -> None:
        self.path = Path(path)
        self.field = field
        self.expected = expected
        self.found = found
        self.line = line
        super().__init__(f"{_where(path, line)}{field}: expected {expected}, found {found}")


class RawFormatError(OfbeError):
    """A raw data file cannot be read as the format its manifest declares.

    Raised for structural problems (missing header, wrong columns, no data); single
    garbled data lines are not errors but counted and skipped (see
    :class:`ofbe_data.io.recording.ReadDiagnostics`).
    """

    def __init__(
        self, path: str | Path, expected: str, found: str, line: int | None = None
    ) -> None:
        self.path = Path(path)
        self.expected = expected
        self.found = found
        self.line = line
        super().__init__(f"{_where(path, line)}expected {expected}, found {found}")


class ConfigError(OfbeError):
    """A configuration (simulator profile or YAML file, or labelling parameters) is invalid.

    Parameters
    ----------
    source
        The configuration file or profile name.
    key
        Dotted path of the offending key.
    expected, found
        What is allowed and what was given.
    """

    def __init__(self, source: str | Path, key: str, expected: str, found: str) -> None:
        self.source = str(source)
        self.key = key
        self.expected = expected
        self.found = found
        super().__init__(f"{source}: {key}: expected {expected}, found {found}")


class OutputExistsError(OfbeError):
    """An output folder already exists and overwriting was not asked for."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        super().__init__(f"{path}: expected a path that does not exist yet, found an existing one "
                         "(pass --force to replace it)")
