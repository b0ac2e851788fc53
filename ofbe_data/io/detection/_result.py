"""What detection is told about a data file and what it finds, for
:func:`ofbe_data.io.detection.sniff_text`.

:class:`Hints` holds what the command line says (each None: detect it); :class:`Detection` what
was found in one file: its format, every :class:`Decision` with its evidence in the order made,
and for a generic csv one :class:`Part` per accelerometer triad (each a device of its own in the
manifest). Plain data: the finding is done by :mod:`ofbe_data.io.detection`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ofbe_data.io.detection._units import fmt_num
from ofbe_data.io.manifest import CsvMapping


@dataclass(frozen=True)
class Hints:
    """What the command line says about a file (None: detect it).

    Attributes
    ----------
    rate_hz
        ``--rate``: the sample rate, Hz.
    acc_unit, lsb_per_g, zero_counts
        ``--unit``, ``--lsb-per-g``, ``--zero-counts``.
    time_unit
        ``--time-unit``.
    time_column
        ``--time-column``: the name (or index, without a header) of the time column.
    columns
        ``--columns``: every column key given (names, or indices without a header).
    gyro_unit
        ``--gyro-unit``: the unit of the angular-rate columns.
    """

    rate_hz: float | None = None
    acc_unit: str | None = None
    lsb_per_g: float | tuple[float, float, float] | None = None
    zero_counts: float | tuple[float, float, float] | None = None
    time_unit: str | None = None
    time_column: str | None = None
    columns: dict[str, str] | None = None
    gyro_unit: str | None = None


@dataclass(frozen=True)
class Decision:
    """One detected value and why.

    Attributes
    ----------
    key
        The manifest key it sets (``delimiter``, ``acc_unit``…) or a note's name (``rate``,
        ``rows``) when it sets none.
    value
        The value (as written in the manifest).
    evidence
        Why, in a few words a person can check.
    part
        The accelerometer triad it is about (see :class:`Part`), or None for the whole file.
    """

    key: str
    value: Any
    evidence: str
    part: str | None = None

    def line(self) -> str:
        """``key: value (evidence)``, or ``key [part]: value (evidence)``."""
        key = self.key if self.part is None else f"{self.key} [{self.part}]"
        return f"{key}: {show_value(self.value)} ({self.evidence})"


def show_value(value: Any) -> str:
    """A value as one short text (delimiters and comment prefixes quoted)."""
    if isinstance(value, str):
        return repr(value) if value in (",", ";", "\t", "#", "%", "//") else value
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {show_value(v)}" for k, v in value.items()) + "}"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return fmt_num(value, 6)
    return str(value)


@dataclass
class Part:
    """One accelerometer triad of a generic csv file: a device of its own in the manifest.

    Attributes
    ----------
    label
        What tells the triads of a file apart (``1`` for ``acc1_x``, ``left``…; ``''`` when
        the file has one).
    mapping
        The device's manifest mapping (its own ``ax``, ``ay``, ``az``; ``t`` and the layout
        shared with the file's other parts).
    direction
        (3,) unit vector of the mean reading at rest, or None.
    """

    label: str
    mapping: CsvMapping
    direction: np.ndarray | None = None


@dataclass
class Detection:
    """What :func:`sniff_text` found in one file.

    Attributes
    ----------
    path
        The file.
    format
        ``ofbe-logger``, ``mscip-csv``, ``mscip-bin`` or ``csv``.
    decisions
        Every decision with its evidence, in the order made.
    mapping
        The manifest mapping (``csv`` only; the first part's when the file has several).
    options
        The manifest keys of an ``mscip-bin`` entry (``sample_rate_hz``, ``acc_unit``).
    model
        The device model a header names, or None.
    rate_hz
        Sample rate as ``ofbe-session check`` reports it (kept and missing samples over the time
        span), Hz, or None.
    rows
        Data rows read (for the statistics), or None.
    direction
        (3,) unit vector of the mean reading at rest, or None.
    warnings
        Things a person should look at.
    parts
        One per accelerometer triad (``csv`` only): a file with two gives two devices.
    step_note
        The time stamps' evidence (median step, jitter, gaps; or the nominal rate a header states),
        shown with the rate.
    """

    path: Path
    format: str
    decisions: list[Decision] = field(default_factory=list)
    mapping: CsvMapping | None = None
    options: dict[str, Any] = field(default_factory=dict)
    model: str | None = None
    rate_hz: float | None = None
    rows: int | None = None
    direction: np.ndarray | None = None
    warnings: list[str] = field(default_factory=list)
    parts: list[Part] = field(default_factory=list)
    step_note: str = ""

    def add(self, key: str, value: Any, evidence: str, part: str | None = None) -> None:
        """Record a decision."""
        self.decisions.append(Decision(key, value, evidence, part))

    def evidence(self, key: str, part: str | None = None) -> str | None:
        """The evidence of the decision on ``key``: for ``part`` (a label of :attr:`parts`), else for
        the whole file, else (no part asked) for any part; None when there is none."""
        order = (part, None) if part is not None else (None,)
        for want in order:
            for d in self.decisions:
                if d.key == key and d.part == want:
                    return d.evidence
        if part is None:
            return next((d.evidence for d in self.decisions if d.key == key), None)
        return None

    def lines(self) -> list[str]:
        """One line per decision."""
        return [d.line() for d in self.decisions]
