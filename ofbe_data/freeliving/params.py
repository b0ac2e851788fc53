"""``ofbe-autocal --params FILE``: a run's settings in the ``autocal:`` section of a YAML file.

One record, :class:`AutocalParams`, holds every setting of both modes that a user tunes
(:class:`~ofbe_data.freeliving.ggir.GgirSettings`, :class:`~ofbe_data.freeliving.ofbe.OfbeSettings`),
the mode, and what a csv of samples may not say itself (its rate and unit). A file's section is
read and checked by the toolkit's typed-configuration reader
(:func:`ofbe_data.io.typedconfig.read_section`, :func:`~ofbe_data.io.typedconfig.from_plain`),
as params.yaml's sections are: an unknown key is refused with the file, the key and the closest
known key; a value of the wrong type or out of its range with the file, the key, what it takes
and what was found. Flags given on the command line override the file (:func:`with_overrides`).
Every key is checked whatever the mode, though each mode uses only its own (docs/free-living.md,
"Settings in a file").

:func:`params_yaml` writes the settings a run used (``DIR/autocal.params.yaml``), which
``--params`` reads back to the same record, so that a run can be repeated.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from ofbe_data.core.errors import ConfigError
from ofbe_data.freeliving.ggir import GgirSettings, SettingsError
from ofbe_data.freeliving.ofbe import OfbeSettings
from ofbe_data.io.typedconfig import from_plain, read_section

SECTION = "autocal"
"""The section of a parameter file that ``ofbe-autocal`` reads."""
PARAMS_NAME = "autocal.params.yaml"
"""The file in the output folder that records a run's settings."""
MODES = ("ofbe", "ggir")
UNITS = ("g", "mg", "m/s2")
"""Acceleration units a csv of samples may be declared in (``--unit``)."""
FLAGS: dict[str, str] = {"mode": "--mode", "epoch_s": "--epoch-s", "still_sd_g": "--still-sd-g",
                         "sphere_check": "--sphere-check/--no-sphere-check", "rate_hz": "--rate",
                         "unit": "--unit"}
"""The settings a command-line flag also sets, and the flag."""
COMMAND_LINE = "command line"
"""How an error names a value given by a flag."""

_GGIR_KEYS = tuple(f.name for f in dataclasses.fields(GgirSettings))
_OFBE_KEYS = tuple(f.name for f in dataclasses.fields(OfbeSettings))


@dataclass(frozen=True)
class AutocalParams:
    """The settings of one ``ofbe-autocal`` run (defaults: GGIR's and the ladder's).

    Attributes
    ----------
    mode
        ``ofbe`` (the ladder) or ``ggir`` (GGIR's ``g.calibrate``).
    epoch_s
        Length of one epoch, s (GGIR's 10); raw files are cut into epochs of this length.
    still_sd_g
        An epoch is still when its standard deviation is below this on every axis, g.
    sphere_check
        False skips the coverage rule of either mode.
    sphere_crit_g
        ggir mode: every axis needs still means below −this and above +this, g.
    min_load_hours
        ggir mode: a fit is accepted only from more than this many hours of data.
    model
        ofbe mode: ``auto`` (the ladder) or a model to force (``offset`` … ``full+temperature``).
    coverage_deg
        ofbe mode: each signed axis needs a still epoch within this angle, degrees.
    exclude_idle
        ofbe mode: leave idle-sleep epochs (standard deviation 0, zero or repeated means) out.
    alpha
        ofbe mode: significance level of the ladder's Wald tests.
    max_condition
        ofbe mode: largest condition number of a fitted model.
    rate_hz
        csv files of samples without a time column: their sample rate, Hz (None: from the file).
    unit
        csv files of samples: their acceleration unit, ``g``, ``mg`` or ``m/s2`` (None: from
        the file).
    """

    mode: str = "ofbe"
    epoch_s: float = GgirSettings.epoch_s
    still_sd_g: float = GgirSettings.still_sd_g
    sphere_check: bool = True
    sphere_crit_g: float = GgirSettings.sphere_crit_g
    min_load_hours: float = GgirSettings.min_load_hours
    model: str = OfbeSettings.model
    coverage_deg: float = OfbeSettings.coverage_deg
    exclude_idle: bool = OfbeSettings.exclude_idle
    alpha: float = OfbeSettings.alpha
    max_condition: float = OfbeSettings.max_condition
    rate_hz: float | None = None
    unit: str | None = None

    def settings(self) -> GgirSettings | OfbeSettings:
        """The mode's settings: :class:`GgirSettings` for ``ggir``, else :class:`OfbeSettings`.

        Raises
        ------
        SettingsError
            A setting out of its range.
        """
        return self.ggir_settings() if self.mode == "ggir" else self.ofbe_settings()

    def ggir_settings(self) -> GgirSettings:
        """:class:`GgirSettings` from the keys it has (a :class:`SettingsError` when out of range)."""
        return GgirSettings(**{k: getattr(self, k) for k in _GGIR_KEYS})

    def ofbe_settings(self) -> OfbeSettings:
        """:class:`OfbeSettings` from the keys it has (a :class:`SettingsError` when out of range)."""
        return OfbeSettings(**{k: getattr(self, k) for k in _OFBE_KEYS})


def _check(params: AutocalParams, source: str | Path, names: tuple[str, ...],
           key_of: Mapping[str, str] | None = None) -> AutocalParams:
    """``params`` when its values named in ``names`` are in range, else a ConfigError naming
    ``source`` and the key (``autocal.<name>``; for a flag, the name and the flag in ``found``)."""
    def error(name: str, expected: str, found: str) -> ConfigError:
        if key_of is not None:
            return ConfigError(source, name, expected, f"{found} (given by {key_of[name]})")
        return ConfigError(source, f"{SECTION}.{name}", expected, found)

    if "mode" in names and params.mode not in MODES:
        raise error("mode", " or ".join(MODES), repr(params.mode))
    if "rate_hz" in names and params.rate_hz is not None and not params.rate_hz > 0:
        raise error("rate_hz", "a positive sample rate, Hz, or null", repr(params.rate_hz))
    if "unit" in names and params.unit is not None and params.unit not in UNITS:
        raise error("unit", ", ".join(UNITS) + " or null", repr(params.unit))
    for build in (params.ggir_settings, params.ofbe_settings):
        try:
            build()
        except SettingsError as exc:
            if exc.name in names:
                raise error(exc.name, exc.expected, exc.found) from None
            raise  # pragma: no cover - a value checked before
    return params


def autocal_params_from(data: Mapping[str, Any] | None, source: str | Path = "<parameters>") -> AutocalParams:
    """Build :class:`AutocalParams` from a plain mapping (the ``autocal:`` section), checking keys,
    types and ranges.

    Parameters
    ----------
    data
        The section's keys and values (None or empty: the defaults).
    source
        The file they came from, named in errors.

    Raises
    ------
    ConfigError
        An unknown key (``FILE: autocal.stil_sd_g: expected one of …, found an unknown key (did you
        mean still_sd_g?)``), a value of the wrong type, or one out of range.
    """
    params: AutocalParams = from_plain(dict(data or {}), AutocalParams, source, SECTION)
    return _check(params, source, tuple(f.name for f in dataclasses.fields(AutocalParams)))


def load_autocal_params(path: str | Path) -> AutocalParams:
    """The settings in the ``autocal:`` section of a YAML file (a file holding only the section's
    keys is read as that section).

    Raises
    ------
    ConfigError
        The file cannot be read, is not YAML (with its line), or its section is refused
        (:func:`autocal_params_from`).
    """
    return autocal_params_from(read_section(path, SECTION, whole_if_missing=True), path)


def with_overrides(params: AutocalParams, **given: Any) -> AutocalParams:
    """``params`` with the values the command line gave (a None value is not given).

    Parameters
    ----------
    params
        The settings from the file (or the defaults).
    **given
        Keys of :data:`FLAGS` and the flags' values.

    Raises
    ------
    ConfigError
        A value out of range, named ``command line: <key>`` with its flag.
    """
    values = {k: v for k, v in given.items() if v is not None}
    unknown = sorted(set(values) - set(FLAGS))
    if unknown:
        raise ValueError(f"with_overrides: expected keys among {', '.join(FLAGS)}, "
                         f"found {', '.join(unknown)}")
    return _check(dataclasses.replace(params, **values), COMMAND_LINE, tuple(values), FLAGS)


def params_yaml(params: AutocalParams) -> bytes:
    """The bytes of ``DIR/autocal.params.yaml``: a comment line, then the ``autocal:`` section with
    every key in :class:`AutocalParams`' order (the same settings give the same bytes; read back
    by :func:`load_autocal_params` to the same record)."""
    body = yaml.safe_dump({SECTION: dataclasses.asdict(params)}, sort_keys=False, default_flow_style=False,
                          allow_unicode=True)
    head = ("# The settings of this ofbe-autocal run; repeat it with --params on this file "
            "(docs/free-living.md).\n")
    return (head + body).encode("utf-8")
