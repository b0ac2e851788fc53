"""GGIR's own reading of ofbe's GGIR exports, replicated in Python line by line (wadpac/GGIR).

Sources (GGIR 3.x, as stored for wadpac/GGIR):

- R/g.part1.R (commit 119781288b05), ``main_part1``, the ``backup.cal.coef`` block:
  ``bcc.data = data.table::fread(params_rawdata[["backup.cal.coef"]], data.table = FALSE)``;
  ``bcc.data$filename = as.character(bcc.data$filename)``; for each row
  ``tmp = unlist(strsplit(as.character(bcc.data$filename[nri]), "meta_"))`` and, when
  ``length(tmp) > 1``, ``filename = tmp[2]`` cut at ``strsplit(filename, ".RData")[1]``; then
  ``bcc.i = which(bcc.data$filename == fnames[i])`` and, with ``bcc.i[1]``,
  ``C$scale = as.numeric(bcc.data[bcc.i[1], bcc.scalei])`` where ``bcc.scalei = which(colnames
  == "scale.x" | ... "scale.y" | ... "scale.z")`` (file order), likewise ``offset.*`` and
  ``temperature.offset.*``, ``C$meantempcal = bcc.data[bcc.i[1], bcc.meantempcali]``,
  ``C$QCmessage``, ``C$use.temp`` (``use.temperature``). ``fnames`` are base names
  (R/datadir2fnames.R: ``fnames = basename(fnamesfull)``).
- R/read.myacc.csv.R (commit c97a29067f9f): the header block ``fread(file, nrows =
  rmc.header.length, skip = rmc.firstrow.header - 1, header = FALSE)``, rows with a non-empty
  first cell, names in column 1 and values in column 2, ``sf = as.numeric(header[which(
  row.names(header) == rmc.headername.sf[1]), 1])``; the data ``fread(rmc.file, nrows = rmc.nrow,
  skip = rmc.firstrow.acc - 1 + rmc.skip, header = "auto")``, ``P[, c(rmc.col.time, rmc.col.acc,
  rmc.col.temp)]`` renamed ``time, x, y, z[, temperature]``, each ``as.numeric``.
- R/g.readaccfile.R (commit f9388615133f), the ``AD_HOC_CSV`` branch: for block 1
  ``testheader = fread(filename, nrows = 2, skip = rmc.firstrow.acc - 1, header = TRUE)`` and
  ``startpage + 1`` when ``as.numeric(colnames(testheader)[1])`` is NA (a column-name line);
  afterwards ``stop("Corrupt file. x column contains non-numeric data.")`` when a column is not
  numeric (fread types a column as character when one cell of it is not a number).

fread itself is replicated strictly: a line with another number of fields than the first
stops the read there ("Stopped early on line ..."), and a cell that is not a plain number (a
garbled field, a 0xFF byte) makes its column non-numeric. Both are errors here, so a file
passes only when GGIR reads every line of it as numbers.
"""

from __future__ import annotations

import io
import re
from dataclasses import dataclass

import numpy as np
import pandas as pd

NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?")
"""A cell fread types as a number (with ``dec = "."``)."""


class GgirReadError(AssertionError):
    """GGIR would not read the file whole (a test failure)."""


@dataclass(frozen=True)
class BackupRow:
    """What g.part1 takes from ``backup.cal.coef`` for one data file."""

    scale: np.ndarray
    offset: np.ndarray
    tempoffset: np.ndarray
    meantempcal: float
    qc_message: str
    use_temp: bool


def _r_strsplit(text: str, pattern: str) -> list[str]:
    """R's ``strsplit`` of one non-empty string by a regular expression (no trailing empty piece)."""
    pieces = re.split(pattern, text)
    if len(pieces) > 1 and pieces[-1] == "":
        pieces.pop()
    return pieces


def backup_cal_coef(data: bytes, fname: str) -> BackupRow:
    """g.part1's look-up of data file ``fname`` (a base name) in a ``backup.cal.coef`` file."""
    bcc = pd.read_csv(io.BytesIO(data), dtype={"filename": str}, keep_default_na=False, na_values=[""])
    names = []
    for name in bcc["filename"].astype(str):
        tmp = _r_strsplit(name, "meta_")
        if len(tmp) > 1:
            name = _r_strsplit(tmp[1], ".RData")[0]
        names.append(name)
    rows = [i for i, name in enumerate(names) if name == fname]
    if not rows:
        raise GgirReadError(f"GGIR finds no backup.cal.coef row for {fname} (it would auto-calibrate)")
    row = bcc.iloc[rows[0]]
    cols = list(bcc.columns)

    def numeric(wanted: tuple[str, ...]) -> np.ndarray:
        values = pd.to_numeric(row[[c for c in cols if c in wanted]], errors="coerce").to_numpy(float)
        if values.shape != (3,) or not np.all(np.isfinite(values)):
            raise GgirReadError(f"{fname}: {wanted} give {values} (NA breaks GGIR's correction)")
        return values

    meantempcal = float(pd.to_numeric(row["meantempcal"], errors="coerce"))
    if not np.isfinite(meantempcal):
        raise GgirReadError(f"{fname}: meantempcal NA (GGIR: 'the condition has length > 1')")
    use_temp = row["use.temperature"]
    if isinstance(use_temp, str):  # fread reads TRUE/FALSE as logical
        use_temp = {"TRUE": True, "FALSE": False}[use_temp]
    return BackupRow(numeric(("scale.x", "scale.y", "scale.z")),
                     numeric(("offset.x", "offset.y", "offset.z")),
                     numeric(("temperature.offset.x", "temperature.offset.y", "temperature.offset.z")),
                     meantempcal, str(row["QCmessage"]), bool(use_temp))


def _fread_lines(lines: list[str], what: str) -> list[list[str]]:
    """fread's split of lines into fields: every line as wide as the first, or the read stops."""
    rows = [line.split(",") for line in lines]
    for k, row in enumerate(rows):
        if len(row) != len(rows[0]):
            raise GgirReadError(f"{what}: fread stops early on line {k + 1} of the block: expected "
                                f"{len(rows[0])} fields, found {len(row)}")
    return rows


def read_myacc_csv(data: bytes, settings: dict[str, str], what: str = "file") -> tuple[float, pd.DataFrame]:
    """(sample rate, data frame ``time, x, y, z[, temperature]``) as GGIR reads a whole ad-hoc csv
    with ``settings`` (the R literals of ``ggir-data.README.txt``)."""
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError as exc:
        raise GgirReadError(f"{what}: a byte that is not text ({exc}): its column would not be "
                            "numeric") from None
    lines = text.split("\n")
    if lines and lines[-1] == "":
        lines.pop()

    def integer(key: str) -> int:
        return int(settings[key])

    def columns(key: str) -> list[int]:
        if key not in settings:
            return []
        value = settings[key]
        inner = value[2:-1] if value.startswith("c(") else value
        return [int(v) for v in inner.split(",")]

    # the header block: names in column 1, values in column 2
    first, length = integer("rmc.firstrow.header"), integer("rmc.header.length")
    header = {}
    for cells in _fread_lines(lines[first - 1:first - 1 + length], f"{what} header"):
        if cells[0] != "":
            header[cells[0]] = cells[1]
    sf = float(header[settings["rmc.headername.sf"].strip('"')])
    # g.readaccfile block 1: a column-name line at rmc.firstrow.acc is skipped
    start = integer("rmc.firstrow.acc") - 1
    if not NUMBER.fullmatch(lines[start].split(",")[0]):
        start += 1
    rows = _fread_lines(lines[start:], what)
    picked = columns("rmc.col.time") + columns("rmc.col.acc") + columns("rmc.col.temp")
    names = ["time", "x", "y", "z"] + (["temperature"] if columns("rmc.col.temp") else [])
    out = {}
    for name, col in zip(names, picked, strict=True):
        cells = [row[col - 1] for row in rows]
        bad = [k for k, cell in enumerate(cells) if not NUMBER.fullmatch(cell)]
        if bad:
            raise GgirReadError(f"{what}: Corrupt file. {name} column contains non-numeric data "
                                f"(line {start + bad[0] + 1}: {cells[bad[0]]!r})")
        out[name] = np.array([float(cell) for cell in cells])
    if settings.get("rmc.unit.acc", '"g"') != '"g"' or settings.get("rmc.unit.time") != '"UNIXsec"':
        raise GgirReadError(f"{what}: this replica reads acceleration in g and UNIXsec times only")
    return sf, pd.DataFrame(out)
