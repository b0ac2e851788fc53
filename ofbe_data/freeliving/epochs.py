"""Epoch tables: one row per epoch of a wearable recording, in GGIR's ``spheredata`` layout.

An epoch csv has a header line and one row per epoch (10 s in GGIR) with the columns

- ``meanx``, ``meany``, ``meanz``: the epoch mean of each raw, uncalibrated axis, g;
- ``sdx``, ``sdy``, ``sdz``: the epoch standard deviation of each axis, g;
- ``temperature`` (optional): the epoch mean of the device temperature, °C.

Any other column is ignored (its cells are not read), in any order. A header that names the
column ``Euclidean Norm`` marks GGIR's own ``spheredata`` object (R/g.calibrate.R names its
columns ``"Euclidean Norm", "meanx", …`` only there): the still epochs GGIR already selected,
which :func:`~ofbe_data.freeliving.ggir.ggir_calibrate` then takes as they are.

Every cell of a column read must be a plain decimal number (``-0.25``, ``1e-3``); an empty
cell, ``NA``, ``nan`` or text is an error naming the file, the line and the column. Blank
lines are skipped.

:func:`idle_sleep` marks the epochs a device wrote while it was not measuring (ActiGraph's
idle-sleep mode repeats its last sample; other devices write zeros), which ``--mode ofbe``
leaves out.
"""

from __future__ import annotations

import csv
import io
import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ofbe_data.core.errors import RawFormatError

MEAN_COLUMNS = ("meanx", "meany", "meanz")
"""Epoch means of the x, y and z axes, g."""
SD_COLUMNS = ("sdx", "sdy", "sdz")
"""Epoch standard deviations of the x, y and z axes, g."""
TEMPERATURE_COLUMN = "temperature"
"""Optional epoch mean temperature, °C."""
SPHEREDATA_MARK = "Euclidean Norm"
"""The column that only GGIR's ``spheredata`` (its selection of still epochs) carries."""

_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
"""A plain decimal number, as R and pandas write one."""


def is_epoch_csv(path: str | Path) -> bool:
    """Whether a csv holds epochs rather than samples: its first non-blank line names
    ``meanx``, ``meany`` and ``meanz`` (any case, quoted or not, split on commas or semicolons)."""
    with open(path, "rb") as fh:
        head = fh.read(4096).decode("utf-8", errors="replace").lstrip("\ufeff").splitlines()
    first = next((line for line in head if line.strip()), "")
    names = {c.strip().strip('"').lower() for c in first.replace(";", ",").split(",")}
    return all(c in names for c in MEAN_COLUMNS)


class EpochFileError(RawFormatError):
    """An epoch csv cannot be read as GGIR's ``spheredata`` layout (a
    :class:`~ofbe_data.core.errors.RawFormatError`, whose message names the file and line).

    Parameters
    ----------
    path
        The file.
    expected, found
        What the layout asks for and what the file holds.
    line
        1-based line of the problem in the file, when there is one.
    """


@dataclass(frozen=True, eq=False)
class EpochTable:
    """The epochs of one recording.

    Attributes
    ----------
    path
        Where the epochs came from (named in messages).
    mean_g
        Shape (n, 3): epoch means of the raw x, y, z axes, g.
    sd_g
        Shape (n, 3): epoch standard deviations of the x, y, z axes, g.
    temperature_c
        Shape (n,): epoch mean temperature, °C; None when the file has no temperature.
    ggir_spheredata
        True when the epochs are GGIR's own ``spheredata`` (its still epochs, the recording's
        first epoch already dropped), as the ``Euclidean Norm`` column marks them.
    time_s
        Shape (n,): time of each epoch's first sample, s on the device clock (raw files read by
        :mod:`~ofbe_data.freeliving.raw`); None when the epochs come without times.
    """

    path: str
    mean_g: np.ndarray
    sd_g: np.ndarray
    temperature_c: np.ndarray | None = None
    ggir_spheredata: bool = False
    time_s: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = len(self.mean_g)
        if np.shape(self.mean_g) != (n, 3) or np.shape(self.sd_g) != (n, 3):
            raise ValueError(f"{self.path}: expected mean_g and sd_g of shape (n, 3), found "
                             f"{np.shape(self.mean_g)} and {np.shape(self.sd_g)}")
        if self.temperature_c is not None and np.shape(self.temperature_c) != (n,):
            raise ValueError(f"{self.path}: expected temperature_c of shape ({n},), found "
                             f"{np.shape(self.temperature_c)}")
        if self.time_s is not None and np.shape(self.time_s) != (n,):
            raise ValueError(f"{self.path}: expected time_s of shape ({n},), found {np.shape(self.time_s)}")

    @property
    def n(self) -> int:
        """Number of epochs."""
        return len(self.mean_g)


def _shown(text: str, limit: int = 40) -> str:
    """``text`` quoted for a message, cut to ``limit`` characters."""
    return repr(text if len(text) <= limit else text[:limit] + "…")


def _decode(path: Path, data: bytes) -> str:
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise EpochFileError(path, "UTF-8 text", f"the byte 0x{data[exc.start]:02x}", line) from None


def _header(path: Path, names: list[str]) -> dict[str, int]:
    """Column index of each column read, from the header line (line 1)."""
    names = [n.strip() for n in names]
    wanted = (*MEAN_COLUMNS, *SD_COLUMNS, TEMPERATURE_COLUMN)
    for name in wanted:
        if names.count(name) > 1:
            raise EpochFileError(path, f"the column {name!r} once", f"it {names.count(name)} times", 1)
    missing = [n for n in (*MEAN_COLUMNS, *SD_COLUMNS) if n not in names]
    if missing:
        shown = ", ".join(_shown(n, 24) for n in names[:12]) + (", …" if len(names) > 12 else "")
        raise EpochFileError(path, "a header naming the columns meanx, meany, meanz, sdx, sdy, sdz "
                                   "(temperature optional)", f"no {', '.join(missing)} among {shown}", 1)
    return {n: names.index(n) for n in wanted if n in names}


def read_epoch_csv(path: str | Path) -> EpochTable:
    """Read an epoch csv (GGIR's ``spheredata`` layout, see the module docstring).

    Parameters
    ----------
    path
        The csv file.

    Returns
    -------
    EpochTable
        Its epochs, in file order; zero epochs when the file has a header only.

    Raises
    ------
    EpochFileError
        The file is empty, not UTF-8, lacks a required column, or has a line with another
        number of fields than the header or a cell that is not a plain number; the message
        names the file and line.
    OSError
        The file cannot be opened.
    """
    path = Path(path)
    return parse_epoch_csv(path.read_bytes(), path)


def parse_epoch_csv(data: bytes, path: str | Path) -> EpochTable:
    """Parse the bytes of an epoch csv (see :func:`read_epoch_csv`); ``path`` is named in errors.

    Raises
    ------
    EpochFileError
        As :func:`read_epoch_csv`.
    """
    path = Path(path)
    text = _decode(path, data)
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        first = next(reader, None)
        if first is None or not any(cell.strip() for cell in first):
            raise EpochFileError(path, "a header line naming meanx, meany, meanz, sdx, sdy, sdz",
                                 "an empty file" if first is None else "an empty line", 1)
        columns = _header(path, first)
        order = list(columns)
        index = [columns[n] for n in order]
        rows: list[list[float]] = []
        for cells in reader:
            if not cells or (len(cells) == 1 and not cells[0].strip()):
                continue  # a blank line
            if len(cells) != len(first):
                raise EpochFileError(path, f"{len(first)} fields (as the header)", f"{len(cells)}",
                                     reader.line_num)
            values = []
            for name, i in zip(order, index, strict=True):
                cell = cells[i].strip()
                value = float(cell) if _NUMBER.fullmatch(cell) else math.nan
                if not math.isfinite(value):  # text, an empty cell, NA, or beyond the float range (1e999)
                    raise EpochFileError(path, f"a finite number in column {name!r}", _shown(cell),
                                         reader.line_num)
                values.append(value)
            rows.append(values)
    except csv.Error as exc:
        raise EpochFileError(path, "csv", f"a malformed line ({exc})", reader.line_num) from None
    table = np.array(rows, dtype=np.float64).reshape(len(rows), len(order))
    col = {n: table[:, k] for k, n in enumerate(order)}
    return EpochTable(
        path=str(path),
        mean_g=np.column_stack([col[n] for n in MEAN_COLUMNS]),
        sd_g=np.column_stack([col[n] for n in SD_COLUMNS]),
        temperature_c=col.get(TEMPERATURE_COLUMN),
        ggir_spheredata=SPHEREDATA_MARK in [n.strip() for n in first],
    )


def idle_sleep(epochs: EpochTable) -> np.ndarray:
    """Which epochs a device wrote while it was not measuring (idle-sleep or constant windows).

    An epoch is idle when its standard deviation is exactly 0 on every axis (a constant
    signal: no accelerometer is that quiet), when its three means are exactly 0 (the value
    some devices write when idle), or when its three means are bit-identical to those of the
    epoch before or after it (a run of repeated means: ActiGraph's idle-sleep mode repeats
    its last sample until it wakes). A real still epoch has noise of a few mg, so two
    consecutive real epochs never agree to every bit.

    Parameters
    ----------
    epochs
        The epochs of one recording, in time order.

    Returns
    -------
    np.ndarray
        Shape (n,), bool: True for an idle epoch.
    """
    means, sds = epochs.mean_g, epochs.sd_g
    idle = np.all(sds == 0.0, axis=1) | np.all(means == 0.0, axis=1)
    if epochs.n > 1:
        repeated = np.all(means[1:] == means[:-1], axis=1)
        idle[1:] |= repeated
        idle[:-1] |= repeated
    return idle
