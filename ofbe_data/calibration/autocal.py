"""Results of an ``ofbe-autocal`` output folder, for ``ofbe-export ggir|json|imucal DIR``.

An autocal folder (docs/free-living.md) holds ``summary.parquet`` (one typed row per recording,
the columns of :data:`ofbe_data.freeliving.summary.COLUMNS`), ``summary.csv`` (the same values)
and ``<stem>.epochs.parquet``; it is recognised by its ``summary.parquet``
(:func:`is_autocal_folder`). Each row carries its coefficients in up to two conventions, both
in g (raw readings in g, a resting calibrated reading of norm 1 g: GGIR's unit sphere):

- GGIR's (``offset_*``, ``scale_*``, ``temp_offset_*``, ``temp_mean_c``):
  ``calibrated = (raw + offset)·scale + (T − temp_mean_c)·temp_offset``, per axis, as GGIR's
  g.getmeta applies ``backup.cal.coef`` (``scale(data, center = -offset, scale = 1/scale) +
  scale(temperature, center = meantempcal, scale = 1/tempoffset)``); empty for ofbe's ``full``
  model, whose cross-axis terms GGIR cannot apply;
- ofbe's (``ofbe_offset_*`` b, ``a_*`` A, ``ofbe_temp_slope_*`` c):
  ``raw = A·u + b + c·(T − temp_mean_c)``, u the unit gravity reaction; empty in GGIR's mode.

:class:`AutocalFile` holds both, ofbe's derived from GGIR's where the row has only those
(``A = diag(1/scale)``, ``b = −offset``, ``c = −temp_offset/scale``, the inverse of
:func:`ofbe_data.freeliving.ofbe.coefficient_columns`). The writers:

- :func:`ggir_autocal_table`: one ``backup.cal.coef`` for the folder, the columns GGIR's g.part1
  reads back by name (R/g.part1.R, ``main_part1``: ``scale.*``, ``offset.*``,
  ``temperature.offset.*``, ``meantempcal``, ``cal.error.start``, ``cal.error.end``,
  ``n.10sec.windows``, ``n.hours.considered``, ``QCmessage``, ``use.temperature``), the file's
  base name in ``filename`` (GGIR matches ``fnames[i]``, the data file's base name). A file the
  autocal run did not calibrate is written as identity with its QC message: what g.part1 itself
  applies to a file its g.calibrate could not calibrate (the identity reset after
  g.calibrate) and what GGIR's own ``data_quality_report.csv`` (the file its
  ``backup.cal.coef = "retrieve"`` reads back) holds for it. A calibrated ``full`` model has no
  form GGIR can apply: its row is left out (GGIR then calibrates that file itself), and said so;
- :func:`autocal_json_file`: ofbe's ``ofbe-calibration/1`` with the free-living fields;
- :func:`autocal_imucal_file`: imucal's ``FerrarisCalibrationInfo`` in g (``K_a R_a = A``,
  ``b_a = b``); imucal's model has no temperature term, so a temperature model is written at
  the reference temperature and its slope stated in ``comment``.

A file not calibrated gets no json or imucal file (one line says so); nothing is ever written
for it as if it were calibrated.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from ofbe_data import __version__
from ofbe_data.calibration.formats import (
    IMUCAL_FORMAT_VERSION,
    GgirExportError,
    ggir_lookup_name,
    imucal_accelerometer,
    json_document,
)
from ofbe_data.calibration.results import (
    TIME_RECORDING_HEADER,
    ZERO_G_OFFSET,
    CalibrationResult,
    CalibrationSourceError,
    SourceFile,
)
from ofbe_data.core.checksums import file_sha256
from ofbe_data.io.gravity import G0

AUTOCAL_SUMMARY = "summary.parquet"
"""The file that makes a folder an ``ofbe-autocal`` output (``ofbe_data.cli.autocal.SUMMARY_PARQUET``)."""
AXES = "xyz"
AUTOCAL_GGIR_COLUMNS = ("filename", "scale.x", "scale.y", "scale.z", "offset.x", "offset.y", "offset.z",
                        "temperature.offset.x", "temperature.offset.y", "temperature.offset.z", "meantempcal",
                        "use.temperature", "cal.error.start", "cal.error.end", "n.10sec.windows",
                        "n.hours.considered", "QCmessage", "file", "sha256", "mode", "model", "calibrated")
"""Columns of the GGIR file of an autocal folder: those g.part1 reads by name, then ofbe's own
(GGIR ignores them)."""
GGIR_NA = "NA"
"""A calibration error that is not known (no still epochs): R's own spelling, read as NA by fread."""


class AutocalSourceError(CalibrationSourceError):
    """An autocal folder whose ``summary.parquet`` cannot be read or holds what autocal never writes."""


@dataclass(frozen=True)
class AutocalFile:
    """One row of an autocal summary: a recording, its QC outcome and, when calibrated, its
    coefficients.

    Attributes
    ----------
    row
        The row's number in ``summary.parquet`` (1 = the first file).
    file, sha256, device, start_utc
        The recording as autocal named it, the SHA-256 of its bytes, its device and start (an
        aware UTC time) where the raw file told them (None for epoch csv files).
    hours, n_epochs, n_still
        Hours of data, epochs, still epochs.
    mode, model, calibrated, qc
        ``ggir`` or ``ofbe``, the model fitted (None when none was), whether the coefficients
        are applied, the QC line.
    cal_error_start_mg, cal_error_end_mg
        GGIR's calibration error before and after, mg (None where not computed).
    temp_mean_c
        The reference temperature τ₀ of the temperature terms, °C (None without).
    ggir
        (offset (3,) g, scale (3,), temp_offset (3,) g/°C) in GGIR's convention; None when the
        row has none (a ``full`` model, or not calibrated).
    offset_g, matrix, temp_slope
        ofbe's b (3,) g, A (3, 3) and c (3,) g/°C (None: no temperature term) of a calibrated
        file; b zero, A identity otherwise.
    map_fitted
        Whether the model fitted A (scale-offset, full), not only offsets.
    errors
        Every standard error the row has, by its column name (``ofbe_offset_x_se`` …).
    """

    row: int
    file: str
    sha256: str
    device: str | None
    start_utc: datetime | None
    hours: float
    n_epochs: int
    n_still: int
    mode: str
    model: str | None
    calibrated: bool
    qc: str
    cal_error_start_mg: float | None
    cal_error_end_mg: float | None
    temp_mean_c: float | None
    ggir: tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]] | None
    offset_g: tuple[float, float, float] = (0.0, 0.0, 0.0)
    matrix: tuple[tuple[float, ...], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    temp_slope: tuple[float, float, float] | None = None
    map_fitted: bool = False
    errors: dict[str, float] = field(default_factory=dict)

    @property
    def name(self) -> str:
        """The file's base name: what GGIR matches a data file by."""
        return Path(self.file).name

    @property
    def stem(self) -> str:
        """The file's name without its suffix: the stem of its export files (autocal's epochs
        files use the same stem, so these are unique in a folder)."""
        return Path(self.file).stem


@dataclass(frozen=True)
class AutocalFolder:
    """An autocal output folder read: its summary (with the SHA-256 of its bytes) and its rows."""

    path: Path
    summary: Path
    sha256: str
    files: tuple[AutocalFile, ...]


def is_autocal_folder(path: str | Path) -> bool:
    """Whether ``path`` is an ``ofbe-autocal`` output folder (it holds :data:`AUTOCAL_SUMMARY`)."""
    return Path(path).is_dir() and (Path(path) / AUTOCAL_SUMMARY).is_file()


def _number(row: dict[str, Any], name: str, where: str) -> float | None:
    value = row[name]
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise AutocalSourceError(f"{where}: {name}: expected a finite number or an empty cell, "
                                 f"found {value!r}")
    return float(value)


def _triple(row: dict[str, Any], names: list[str], where: str, what: str) -> tuple[float, ...] | None:
    """The row's values of ``names``: all of them, or None when all are empty."""
    values = [_number(row, n, where) for n in names]
    if all(v is None for v in values):
        return None
    if any(v is None for v in values):
        empty = [n for n, v in zip(names, values, strict=True) if v is None]
        raise AutocalSourceError(f"{where}: expected {what} ({', '.join(names)}) all given or all empty, "
                                 f"found {', '.join(empty)} empty")
    return tuple(float(v) for v in values if v is not None)


def _ofbe_coefficients(row: dict[str, Any], ggir: tuple[tuple[float, ...], ...] | None, where: str
                       ) -> dict[str, Any]:
    """b, A, c (ofbe's convention) of a calibrated row: its own columns, else from GGIR's."""
    offset = _triple(row, [f"ofbe_offset_{a}" for a in AXES], where, "ofbe's offset")
    if offset is not None:
        entries = _triple(row, [f"a_{r}{c}" for r in AXES for c in AXES], where, "ofbe's map A")
        slope = _triple(row, [f"ofbe_temp_slope_{a}" for a in AXES], where, "ofbe's temperature slope")
        matrix = np.eye(3) if entries is None else np.asarray(entries).reshape(3, 3)
        fitted = entries is not None
    elif ggir is not None:
        g_offset, scale, temp_offset = (np.asarray(v) for v in ggir)
        if not np.all(scale > 0):
            raise AutocalSourceError(f"{where}: expected positive scale_x/y/z, found {scale.tolist()}")
        offset = tuple((-g_offset).tolist())
        matrix, fitted = np.diag(1.0 / scale), not np.all(scale == 1.0)
        slope = tuple((-temp_offset / scale).tolist()) if np.any(temp_offset != 0) else None
    else:
        raise AutocalSourceError(f"{where}: expected the coefficients of a calibrated file (GGIR's offset_*, "
                                 "scale_*, temp_offset_* or ofbe's ofbe_offset_*), found them empty")
    if not np.linalg.det(matrix) > 0:
        raise AutocalSourceError(f"{where}: expected a map A with a positive determinant, "
                                 f"found {matrix.tolist()}")
    if slope is not None and row["temp_mean_c"] is None:
        raise AutocalSourceError(f"{where}: expected temp_mean_c for a temperature model, found it empty")
    return {"offset_g": tuple(float(v) for v in offset), "matrix": tuple(tuple(r) for r in matrix.tolist()),
            "temp_slope": None if slope is None else tuple(float(v) for v in slope), "map_fitted": fitted}


def _file_row(number: int, row: dict[str, Any], summary: Path, error_columns: tuple[str, ...]) -> AutocalFile:
    where = f"{summary}: row {number}"
    file = row["file"]
    if not isinstance(file, str) or not file:
        raise AutocalSourceError(f"{where}: file: expected the recording's name, found {file!r}")
    where = f"{where} ({file})"
    if row["mode"] not in ("ggir", "ofbe"):
        raise AutocalSourceError(f"{where}: mode: expected ggir or ofbe, found {row['mode']!r}")
    if not isinstance(row["calibrated"], bool):
        raise AutocalSourceError(f"{where}: calibrated: expected true or false, found {row['calibrated']!r}")
    for name in ("n_epochs", "n_still"):
        if not isinstance(row[name], int) or row[name] < 0:
            raise AutocalSourceError(f"{where}: {name}: expected a count, found {row[name]!r}")
    ggir = None
    triples = [_triple(row, [f"{q}_{a}" for a in AXES], where, f"GGIR's {q}")
               for q in ("offset", "scale", "temp_offset")]
    if any(t is not None for t in triples):
        if any(t is None for t in triples):
            raise AutocalSourceError(f"{where}: expected GGIR's offset_*, scale_* and temp_offset_* all "
                                     "given or all empty, found some empty")
        ggir = (triples[0], triples[1], triples[2])  # type: ignore[assignment]
    hours = _number(row, "hours", where)
    common = dict(
        row=number, file=file, sha256=str(row["sha256"] or ""), device=row["device"] or None,
        start_utc=row["start_utc"], hours=0.0 if hours is None else hours, n_epochs=row["n_epochs"],
        n_still=row["n_still"], mode=row["mode"], model=row["model"] or None, calibrated=row["calibrated"],
        qc=str(row["qc"] or ""), cal_error_start_mg=_number(row, "cal_error_start_mg", where),
        cal_error_end_mg=_number(row, "cal_error_end_mg", where),
        temp_mean_c=_number(row, "temp_mean_c", where), ggir=ggir,
        errors={n: v for n in error_columns if (v := _number(row, n, where)) is not None})
    if not row["calibrated"]:
        return AutocalFile(**common)  # type: ignore[arg-type]
    return AutocalFile(**common, **_ofbe_coefficients(row, ggir, where))  # type: ignore[arg-type]


def read_autocal(folder: str | Path) -> AutocalFolder:
    """Every row of an autocal folder's ``summary.parquet``, checked.

    Parameters
    ----------
    folder
        An ``ofbe-autocal --out`` folder.

    Returns
    -------
    AutocalFolder
        Its rows in the summary's order.

    Raises
    ------
    AutocalSourceError
        No summary, one that cannot be read as Parquet, a column missing, no row, or a row
        autocal would not write (a value that is not a finite number, a convention half
        filled, a calibrated row without coefficients); the message names the file and row.
    """
    from ofbe_data.freeliving.summary import COLUMNS  # the contract's columns (imported when needed)

    folder = Path(folder)
    summary = folder / AUTOCAL_SUMMARY
    if not summary.is_file():
        raise AutocalSourceError(f"{folder}: expected an ofbe-autocal folder holding {AUTOCAL_SUMMARY}, "
                                 "found none")
    try:
        table = pq.read_table(summary)
    except (OSError, pa.ArrowException, ValueError) as exc:
        raise AutocalSourceError(f"{summary}: expected ofbe-autocal's summary (Parquet), found a file that "
                                 f"cannot be read: {exc}") from None
    missing = [c for c in COLUMNS if c not in table.column_names]
    if missing:
        raise AutocalSourceError(f"{summary}: expected ofbe-autocal's {len(COLUMNS)} columns "
                                 f"(docs/free-living.md), found {len(missing)} missing: "
                                 f"{', '.join(missing[:6])}{', …' if len(missing) > 6 else ''}")
    rows = table.select(list(COLUMNS)).to_pylist()
    if not rows:
        raise AutocalSourceError(f"{summary}: expected a row per recording, found none")
    error_columns = tuple(c for c in COLUMNS if c.endswith("_se"))
    files = tuple(_file_row(i + 1, row, summary, error_columns) for i, row in enumerate(rows))
    return AutocalFolder(folder, summary, file_sha256(summary), files)


def calibrated_files(folder: AutocalFolder) -> tuple[list[AutocalFile], list[str]]:
    """The calibrated files of a folder, and one line for each of the others.

    Raises
    ------
    AutocalSourceError
        No file was calibrated.
    """
    done = [f for f in folder.files if f.calibrated]
    skipped = [f"{f.file}: not calibrated ({f.qc})" for f in folder.files if not f.calibrated]
    if not done:
        raise AutocalSourceError(f"{folder.summary}: expected at least one calibrated file, found none "
                                 f"({len(skipped)} not calibrated: see the qc column)")
    return done, skipped


# ----------------------------------------------------------------------------- GGIR


def _uses_temperature(f: AutocalFile) -> bool:
    return f.calibrated and f.model is not None and "+temperature" in f.model


def _mg_to_g(value: float | None) -> str:
    return GGIR_NA if value is None else repr(value / 1000.0)


def ggir_autocal_table(folder: AutocalFolder) -> tuple[bytes, list[str]]:
    """The one ``backup.cal.coef`` CSV of an autocal folder, and one line per file that is not
    a calibrated row (identity, or left out).

    Every file is a row under its base name (GGIR's ``fnames``: R/datadir2fnames.R); a file
    not calibrated is identity with its QC message, a ``full`` model is left out (module
    notes). ``cal.error.*`` are in g as GGIR writes them (``NA`` where autocal had none),
    ``n.10sec.windows`` the still epochs, ``n.hours.considered`` the hours, ``meantempcal`` the
    reference temperature (0 without one: the temperature offsets are then 0, so GGIR's
    ``(T − meantempcal)·temperature.offset`` adds nothing).

    Raises
    ------
    GgirExportError
        Two files of one base name (GGIR would use the first row for both), a name GGIR
        rewrites before matching (:func:`ofbe_data.calibration.formats.ggir_lookup_name`), or
        no row at all.
    """
    rows: list[list[str]] = []
    notes: list[str] = []
    owner: dict[str, str] = {}
    for f in folder.files:
        if f.calibrated and f.ggir is None:
            notes.append(f"{f.file}: left out: its {f.model} model has cross-axis terms that GGIR's "
                         "per-axis correction cannot apply (GGIR calibrates this file itself; the json and "
                         "imucal exports carry the full A; ofbe-autocal --mode ggir gives per-axis "
                         "coefficients)")
            continue
        if ggir_lookup_name(f.name) != f.name:
            raise GgirExportError(f"{f.file}: expected a file name GGIR looks up as written, found "
                                  f"{f.name!r}, which GGIR's g.part1 rewrites to "
                                  f"{ggir_lookup_name(f.name)!r} (it strips 'meta_' names); rename the file")
        if f.name in owner:
            raise GgirExportError(f"{f.file}: expected one backup.cal.coef row per data file name, found "
                                  f"{f.name!r} for both {owner[f.name]} and {f.file} (GGIR would use the "
                                  "first row for both)")
        owner[f.name] = f.file
        if f.calibrated and f.ggir is not None:
            offset, scale, temp_offset = f.ggir
        else:
            offset, scale, temp_offset = (0.0,) * 3, (1.0,) * 3, (0.0,) * 3
            notes.append(f"{f.file}: not calibrated ({f.qc}): an identity row, as GGIR writes and applies "
                         "for a file it cannot calibrate")
        mean_temp = f.temp_mean_c if f.calibrated and f.temp_mean_c is not None else 0.0
        rows.append([f.name, *(repr(float(v)) for v in (*scale, *offset, *temp_offset)),
                     repr(float(mean_temp)), "TRUE" if _uses_temperature(f) else "FALSE",
                     _mg_to_g(f.cal_error_start_mg), _mg_to_g(f.cal_error_end_mg), str(f.n_still),
                     repr(float(f.hours)), f.qc, f.file, f.sha256, f.mode, f.model or "",
                     "TRUE" if f.calibrated else "FALSE"])
    if not rows:
        raise GgirExportError(f"{folder.summary}: expected at least one file GGIR can take, found none "
                              "(every calibrated file has a full model; run ofbe-autocal --mode ggir)")
    buf = io.StringIO()
    out = csv.writer(buf, lineterminator="\n")
    out.writerow(AUTOCAL_GGIR_COLUMNS)
    out.writerows(rows)
    return buf.getvalue().encode(), notes


# ----------------------------------------------------------------------------- ofbe JSON and imucal


def _model_words(f: AutocalFile) -> str:
    return f"ofbe-autocal --mode {f.mode}, {f.model} model"


def autocal_result(folder: AutocalFolder, f: AutocalFile) -> CalibrationResult:
    """A calibrated file as a :class:`~ofbe_data.calibration.results.CalibrationResult` in m/s²:
    ``f = A·u·g0 + b·g0`` (GGIR's unit sphere: ``g_local`` is g0), b the zero-g offset of the fit
    at the reference temperature."""
    k = np.sqrt(np.sum(np.asarray(f.matrix) ** 2, axis=1))
    ses = [f.errors.get(f"ofbe_offset_{a}_se") for a in AXES]
    if any(s is None for s in ses):  # GGIR's columns: offset = -b, so the same standard error
        ses = [f.errors.get(f"offset_{a}_se") for a in AXES]
    bias_se = None if any(s is None for s in ses) else tuple(float(s) * G0 for s in ses if s is not None)
    note = (f"A from the {_model_words(f)} (raw = A*u + b, g)" if f.map_fitted
            else f"A identity: the {_model_words(f)} fits offsets only")
    return CalibrationResult(
        device=f.device or f.stem, power_cycle=None, bias=tuple(float(v) * G0 for v in f.offset_g),  # type: ignore[arg-type]
        std=None, bias_kind=ZERO_G_OFFSET, method=f"ofbe-autocal-{f.mode}", scale=tuple(k.tolist()),  # type: ignore[arg-type]
        scale_known=f.map_fitted, scale_note=note, g_local=G0, fs_hz=None, temperature_c=f.temp_mean_c,
        n_rows=f.n_still,
        sources=(SourceFile(f.file, f.sha256), SourceFile(str(folder.summary), folder.sha256)),
        recordings=(f.file,), stem=f.stem, time_utc=f.start_utc,
        time_source=TIME_RECORDING_HEADER if f.start_utc is not None else "", raw_files=(f.name,),
        matrix=f.matrix, bias_se=bias_se)  # type: ignore[arg-type]


def free_living_fields(f: AutocalFile) -> dict[str, Any]:
    """The free-living block of the JSON: the QC outcome, the errors, both conventions and every
    standard error (by the summary's column names)."""
    ggir = None if f.ggir is None else {"offset_g": list(f.ggir[0]), "scale": list(f.ggir[1]),
                                        "temp_offset_g_per_c": list(f.ggir[2])}
    return {
        "file": f.file, "sha256": f.sha256, "mode": f.mode, "model": f.model, "calibrated": f.calibrated,
        "qc": f.qc, "hours": f.hours, "n_epochs": f.n_epochs, "n_still": f.n_still,
        "cal_error_start_mg": f.cal_error_start_mg, "cal_error_end_mg": f.cal_error_end_mg,
        "convention": "raw = A*u + offset_g + temp_slope_g_per_c*(T - temp_mean_c), g (u the unit gravity "
                      "reaction); GGIR's: calibrated = (raw + offset)*scale + (T - temp_mean_c)*temp_offset",
        "offset_g": list(f.offset_g), "A": [list(r) for r in f.matrix],
        "temp_slope_g_per_c": None if f.temp_slope is None else list(f.temp_slope),
        "temp_mean_c": f.temp_mean_c, "ggir": ggir, "standard_errors": dict(sorted(f.errors.items())),
    }


def autocal_json_file(folder: AutocalFolder, f: AutocalFile, written: datetime) -> bytes:
    """ofbe's ``ofbe-calibration/1`` JSON of a calibrated file
    (:func:`ofbe_data.calibration.formats.json_document`) with ``free_living``
    (:func:`free_living_fields`)."""
    doc = json_document(autocal_result(folder, f), written) | {"free_living": free_living_fields(f)}
    return (json.dumps(doc, indent=2, allow_nan=False) + "\n").encode()


def autocal_imucal_file(folder: AutocalFolder, f: AutocalFile, written: datetime) -> bytes:
    """An imucal ``FerrarisCalibrationInfo`` JSON of a calibrated file, in g (``from_acc_unit``
    and ``acc_unit`` ``g``): ``a = R_a⁻¹ K_a⁻¹ (raw − b_a)`` with ``K_a R_a = A`` and ``b_a = b``
    (:func:`ofbe_data.calibration.formats.imucal_accelerometer`), a resting reading calibrated to
    norm 1 g. imucal has no temperature term: a temperature model's ``b_a`` is the offset at its
    reference temperature, and the slope (to subtract, ``c·(T − τ₀)``, before imucal's
    correction) is stated in ``comment``. The gyroscope is identity."""
    k_a, r_a, b_a = imucal_accelerometer(f.offset_g, f.matrix)
    if f.temp_slope is None:
        temperature = "no temperature term"
    else:
        slope = ", ".join(repr(v) for v in f.temp_slope)
        temperature = (f"imucal has no temperature term: b_a is the offset at T0 = {f.temp_mean_c!r} C; "
                       f"subtract c*(T - T0) from the raw readings first, c = [{slope}] g/C")
    when = written.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")
    comment = (f"ofbe {__version__} export of ofbe-autocal ({f.mode} mode) at {when}: {f.file} (sha256 "
               f"{f.sha256[:12]}...), {f.model} model, {f.qc}. Units g: raw readings in g, a resting "
               "calibrated reading has norm 1 g (GGIR's unit sphere). b_a is the zero-g offset b, subtracted "
               f"before scaling; K_a R_a = A ({'fitted' if f.map_fitted else 'identity: offsets only'}); "
               f"{temperature}. Gyroscope: none in the data; K_g and R_g identity, K_ga and b_g zero. "
               f"Source: {folder.summary}.")
    doc = {"acc_unit": "g", "gyr_unit": "deg/s", "from_acc_unit": "g", "from_gyr_unit": "deg/s",
           "comment": comment, "K_a": k_a.tolist(), "R_a": r_a.tolist(), "b_a": b_a.tolist(),
           "K_g": np.eye(3).tolist(), "R_g": np.eye(3).tolist(), "K_ga": np.zeros((3, 3)).tolist(),
           "b_g": [0.0, 0.0, 0.0], "cal_type": "Ferraris", "_format_version": IMUCAL_FORMAT_VERSION}
    return json.dumps(doc, indent=4, allow_nan=False).encode()
