"""Calibration results to export: one per (device, power cycle) of a labels folder, or one per
estimate of an ``ofbe-predict`` JSON.

ofbe's sensor model is output-referred, in m/s² (sensor-model.md):

    f = A · u · g + b,    so the correction is    a = A⁻¹ (f − b),

with b the zero-g offset and A the map a fit determined (the ``a_*`` label columns: diagonal for
a ``scale-offset`` fit, triangular for ``full``, the full 3×3 of a campaign fit; the identity
otherwise). What b a result carries is said by :attr:`CalibrationResult.bias_kind`:

- ``zero-g-offset``: the offset b of the campaign fit or of the multi-position fit
  (``label_method`` ``campaign-fit`` or ``multi-position`` with ``offset_x/y/z`` filled);
  shared by every recording of the power cycle, no uncertainty in the label file;
- ``apparent``: the apparent bias b_app = mean − g·u of the paper's labels (level and
  reference labels, and every prediction), averaged over the power cycle's recordings, with
  its standard deviation over them as the uncertainty when there is more than one.

The conversions to other tools' conventions are in :mod:`ofbe_data.calibration.formats`; the
raw recordings behind the labels (start times, stationary samples) in
:mod:`ofbe_data.calibration.noise`.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ofbe_data.core.errors import OfbeError
from ofbe_data.labelling.conventions import MATRIX_COLUMNS, imucal_from_matrix
from ofbe_data.labelling.labels import sha256_file
from ofbe_data.labelling.store import read_labels, read_provenance

ZERO_G_OFFSET = "zero-g-offset"
"""Bias kind: the zero-g offset b of f = A·u·g + b (campaign or multi-position fit)."""
APPARENT = "apparent"
"""Bias kind: the apparent bias b_app = mean − g·u (it absorbs (A − I)·u·g)."""
OFFSET_METHODS = frozenset({"campaign-fit", "multi-position"})
"""Label methods whose rows carry a determined zero-g offset in ``offset_x/y/z``."""
REQUIRED_COLUMNS = ("session", "recording", "device", "power_cycle", "g_local", "fs_hz",
                    "bias_x", "bias_y", "bias_z", "label_method")
"""Label-file columns an export needs (products.md)."""
OFFSET_AGREEMENT = 1e-6
"""Largest spread, m/s², of the offsets the rows of one power cycle may carry (they are one value)."""
SCALE_AGREEMENT = 1e-9
"""Largest spread of the scale factors the rows of one power cycle may carry (one value)."""
PROVENANCE_TIME_KEYS = ("written_utc", "created_utc", "time_utc")
"""Provenance keys of a label file that, when present, give the time it was written."""

TIME_RAW = "raw-file-utc-start"
TIME_PROVENANCE = "label-file-provenance"
TIME_LABEL_MTIME = "label-file-mtime"
TIME_RECORDING_HEADER = "recording-header-utc"
TIME_PREDICTIONS_MTIME = "predictions-file-mtime"


class CalibrationExportError(OfbeError):
    """An export cannot be made; the message names the file and what is wrong."""


class CalibrationSourceError(CalibrationExportError):
    """The labels or predictions given as the source cannot be read or hold no result."""


@dataclass(frozen=True)
class SourceFile:
    """A file a result was computed from, with the SHA-256 of its bytes."""

    path: str
    sha256: str

    def to_dict(self) -> dict[str, str]:
        return {"path": self.path, "sha256": self.sha256}


@dataclass(frozen=True)
class Segment:
    """The stationary interval of one labelled row in its raw file.

    ``raw_file`` is relative to the session folder, ``start_s``/``end_s`` on the device's own
    clock (the label file's ``segment_start_s``/``segment_end_s``).
    """

    session: str
    recording: str
    raw_file: str
    raw_sha256: str
    start_s: float
    end_s: float


@dataclass(frozen=True)
class CalibrationResult:
    """One device's accelerometer calibration for one power cycle (or one prediction).

    Attributes
    ----------
    device
        Device id.
    power_cycle
        Bias instance; None for a prediction (the recording's own power-on).
    bias
        b, m/s², sensor frame, output-referred (``f = A·u·g + b``).
    std
        Standard deviation of ``bias`` per axis, m/s², or None when unknown.
    bias_kind
        :data:`ZERO_G_OFFSET` or :data:`APPARENT`.
    method
        Label method(s) or the predicting method.
    scale
        Each axis' gain ‖A_i,:‖ (dimensionless, imucal's K_a); ones when ``scale_known`` is False.
    scale_known
        Whether the source carried a fitted map A (else A = I is assumed).
    scale_note
        Where A came from, or why it is the identity.
    matrix
        A, row-major (3 × 3); the identity when ``scale_known`` is False.
    bias_se
        Standard error of ``bias`` per axis, m/s², when the fit gave one.
    noise_std
        Standard deviation of one sample about its mean per axis, m/s², over the stationary
        segments (rms of the label rows' ``std_x/y/z``); None when unknown (predictions).
    g_local
        Local gravity, m/s².
    fs_hz
        Measured sample rate, Hz (None when unknown).
    temperature_c
        Mean temperature over the stationary segments, °C, when the files had one.
    n_rows
        Label rows (recordings × poses) or prediction entries averaged.
    sources
        The label files or the predictions JSON it came from.
    recordings
        ``session/recording`` of each row, or the predicted file.
    segments
        The rows' stationary intervals (labels only).
    stem
        File-name stem: ``<device>.pc<power_cycle>`` or ``<device>.<file stem>``.
    model
        The model file of a prediction.
    time_utc, time_source
        When the recording was made, as well as it is known, and how it was found (one of
        the ``TIME_*`` strings); set by :func:`attach_file_times` or
        :func:`ofbe_data.calibration.noise.attach_raw_times`.
    raw_files
        The raw files: ``<session>/<path in the session folder>`` for labels (relative to the
        campaign's raw folder), the predicted file's base name for a prediction.
    """

    device: str
    power_cycle: int | None
    bias: tuple[float, float, float]
    std: tuple[float, float, float] | None
    bias_kind: str
    method: str
    scale: tuple[float, float, float]
    scale_known: bool
    scale_note: str
    g_local: float
    fs_hz: float | None
    temperature_c: float | None
    n_rows: int
    sources: tuple[SourceFile, ...]
    recordings: tuple[str, ...]
    segments: tuple[Segment, ...] = ()
    stem: str = ""
    model: str | None = None
    time_utc: datetime | None = None
    time_source: str = ""
    raw_files: tuple[str, ...] = ()
    matrix: tuple[tuple[float, float, float], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    bias_se: tuple[float, float, float] | None = None
    noise_std: tuple[float, float, float] | None = None

    @property
    def what(self) -> str:
        """``<device> power cycle N`` or ``<device> (<file>)``, for messages."""
        if self.power_cycle is not None:
            return f"{self.device} power cycle {self.power_cycle}"
        return f"{self.device} ({self.recordings[0] if self.recordings else '?'})"


@dataclass(frozen=True)
class Collected:
    """Every result of one source.

    Attributes
    ----------
    kind
        ``labels`` or ``predictions``.
    path
        The source as given.
    results
        In (device, power cycle) or file order.
    skipped
        One line per prediction entry without an estimate (its file and the reason).
    """

    kind: str
    path: Path
    results: tuple[CalibrationResult, ...]
    skipped: tuple[str, ...] = ()


def _vec(values: Any) -> tuple[float, float, float]:
    a = np.asarray(values, dtype=np.float64).reshape(3)
    return float(a[0]), float(a[1]), float(a[2])


def _finite_or_none(value: Any) -> float | None:
    try:
        v = float(value)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


# ----------------------------------------------------------------------------- labels


def _label_files(path: Path) -> list[Path]:
    if path.is_dir():
        files = sorted(path.glob("*.parquet"))
        if not files:
            raise CalibrationSourceError(f"{path}: expected a labels folder with <session>.parquet files "
                                         "(processed/labels/<campaign>), found none")
        return files
    if path.is_file() and path.suffix == ".parquet":
        return [path]
    if not path.exists():
        raise CalibrationSourceError(f"{path}: expected a labels folder, a <session>.parquet label file or "
                                     "an ofbe-predict JSON, found no such path")
    raise CalibrationSourceError(f"{path}: expected a labels folder, a <session>.parquet label file or an "
                                 f"ofbe-predict JSON (.json), found a {path.suffix or 'suffix-less'} file")


def _read_one(path: Path) -> pd.DataFrame:
    try:
        frame = read_labels(path)
    except (OSError, ValueError) as exc:  # pyarrow's ArrowInvalid is a ValueError
        raise CalibrationSourceError(f"{path}: expected an ofbe label file (Parquet), found one that "
                                     f"cannot be read: {exc}") from None
    missing = [c for c in REQUIRED_COLUMNS if c not in frame.columns]
    if missing:
        raise CalibrationSourceError(f"{path}: expected the label columns {', '.join(REQUIRED_COLUMNS)}, "
                                     f"found {', '.join(missing)} missing")
    return frame


def _column(frame: pd.DataFrame, names: tuple[str, ...]) -> np.ndarray:
    """(n, len(names)) float array of the columns; NaN where a column is absent or null."""
    cols = [pd.to_numeric(frame[n], errors="coerce").to_numpy(dtype=np.float64) if n in frame.columns
            else np.full(len(frame), np.nan) for n in names]
    return np.stack(cols, axis=1)


def _shared(values: np.ndarray, tolerance: float, what: str, where: str) -> np.ndarray:
    """The one value every row of a power cycle carries (the first row's), checked."""
    spread = float(np.max(np.ptp(values, axis=0)))
    if spread > tolerance:
        raise CalibrationSourceError(f"{where}: expected one {what} shared by the power cycle's rows, "
                                     f"found values {spread:.3g} apart")
    return values[0]


MAP_MODELS = frozenset({"scale-offset", "full", "campaign", "scale-offset+temperature", "full+temperature"})
"""``fit_model`` values whose rows carry a fitted map A."""


def _map(rows: pd.DataFrame, kind: str, where: str) -> tuple[np.ndarray, bool, str]:
    """(A (3, 3), known, note): the fitted map where the rows' fit determined one, else I."""
    models = {str(m) for m in rows["fit_model"]} if "fit_model" in rows.columns else set()
    identity = np.eye(3)
    if kind != ZERO_G_OFFSET:
        return identity, False, "A identity: an apparent bias carries no map"
    entries = _column(rows, MATRIX_COLUMNS)
    if not np.all(np.isfinite(entries)):
        scales = _column(rows, ("scale_x", "scale_y", "scale_z"))
        if models == {"scale-offset"} and np.all(np.isfinite(scales)):  # labels from before the a_* columns
            entries = np.stack([np.diag(row).ravel() for row in scales])
        else:
            fitted = "/".join(sorted(models)) or "label"
            if models and models <= MAP_MODELS:
                why = "too few distinct poses"
            elif models:  # offset models fit no scales, whether auto chose them or they were forced
                stated = rows.get("fit_model_reason", pd.Series(dtype=str)).dropna()
                reasons = sorted({str(r) for r in stated if str(r)})
                why = "the model fits offsets only" + (f": {reasons[0]}" if reasons else "")
            else:
                why = "the label states no fit model"
            return identity, False, f"A identity: the {fitted} fit determined no map ({why})"
    matrix = _shared(entries, SCALE_AGREEMENT, "map A", where).reshape(3, 3)
    if not np.linalg.det(matrix) > 0:
        raise CalibrationSourceError(f"{where}: expected a map A with a positive determinant, found "
                                     f"{matrix.tolist()}")
    model = "/".join(sorted(models))
    return matrix, True, f"A from the {model} fit (f = A*a + b; scale = row norms of A)"


def _group_result(device: str, pc: int, rows: pd.DataFrame, files: list[Path], hashes: dict[Path, str]
                  ) -> CalibrationResult:
    """One (device, power cycle) group of label rows → a result."""
    where = f"{', '.join(str(files[i]) for i in sorted(set(rows['_file'])))}: {device} power cycle {pc}"
    offsets = _column(rows, ("offset_x", "offset_y", "offset_z"))
    methods = sorted({str(m) for m in rows["label_method"]})
    if np.all(np.isfinite(offsets)) and set(methods) <= OFFSET_METHODS:
        bias, std, kind = _shared(offsets, OFFSET_AGREEMENT, "zero-g offset", where), None, ZERO_G_OFFSET
    else:
        apparent = _column(rows, ("bias_x", "bias_y", "bias_z"))
        if not np.all(np.isfinite(apparent)):
            raise CalibrationSourceError(f"{where}: expected finite bias_x/y/z, found a missing value")
        bias, kind = apparent.mean(axis=0), APPARENT
        std = _vec(apparent.std(axis=0, ddof=1)) if len(rows) > 1 else None
    matrix, scale_known, scale_note = _map(rows, kind, where)
    scale = _vec(imucal_from_matrix(matrix)[0].diagonal())
    ses = _column(rows, ("offset_x_se", "offset_y_se", "offset_z_se"))
    bias_se = _vec(ses[0]) if kind == ZERO_G_OFFSET and np.all(np.isfinite(ses)) else None
    stds = _column(rows, ("std_x", "std_y", "std_z"))
    noise_std = _vec(np.sqrt(np.mean(stds**2, axis=0))) if np.all(np.isfinite(stds)) else None
    temps = _column(rows, ("temperature_c",))[:, 0]
    temps = temps[np.isfinite(temps)]
    fs = _column(rows, ("fs_hz",))[:, 0]
    fs = fs[np.isfinite(fs)]
    segs = []
    if {"raw_file", "segment_start_s", "segment_end_s"} <= set(rows.columns):
        for r in rows.itertuples(index=False):
            segs.append(Segment(str(r.session), str(r.recording), str(r.raw_file),
                                str(getattr(r, "raw_sha256", "") or ""),
                                float(r.segment_start_s), float(r.segment_end_s)))
    used = sorted(set(rows["_file"]))
    return CalibrationResult(
        device=device, power_cycle=pc, bias=_vec(bias), std=std, bias_kind=kind, method=",".join(methods),
        scale=scale, scale_known=scale_known, scale_note=scale_note, g_local=float(np.mean(rows["g_local"])),
        fs_hz=float(fs.mean()) if fs.size else None,
        temperature_c=float(temps.mean()) if temps.size else None, n_rows=len(rows),
        sources=tuple(SourceFile(str(files[i]), hashes[files[i]]) for i in used),
        recordings=tuple(dict.fromkeys(f"{r.session}/{r.recording}" for r in rows.itertuples(index=False))),
        segments=tuple(segs), stem=f"{device}.pc{pc}",
        raw_files=tuple(sorted({f"{s.session}/{Path(s.raw_file).as_posix()}" for s in segs})),
        matrix=tuple(_vec(row) for row in matrix), bias_se=bias_se, noise_std=noise_std)


def results_from_labels(path: str | Path) -> Collected:
    """One result per (device, power cycle) of a labels folder or one label file.

    Parameters
    ----------
    path
        ``processed/labels/<campaign>`` (every ``<session>.parquet`` in it) or one
        ``<session>.parquet``.

    Returns
    -------
    Collected
        Results sorted by device, then power cycle (``time_utc`` not yet set).

    Raises
    ------
    CalibrationSourceError
        No label file, an unreadable one, missing columns, no labelled row, or rows of one
        power cycle with different offsets.
    """
    path = Path(path)
    files = _label_files(path)
    frames = []
    for i, f in enumerate(files):
        frame = _read_one(f)
        frame["_file"] = i
        frames.append(frame)
    rows = pd.concat(frames, ignore_index=True)
    if rows.empty:
        raise CalibrationSourceError(f"{path}: expected labelled recordings, found none (every recording "
                                     "was rejected? see the <session>.rejected.json files)")
    hashes = {f: sha256_file(f) for f in files}
    results = []
    for (device, pc), group in rows.groupby(["device", "power_cycle"], sort=True):
        results.append(_group_result(str(device), int(pc), group, files, hashes))
    return Collected("labels", path, tuple(results))


# ----------------------------------------------------------------------------- predictions


def _triple(entry: dict[str, Any], key: str, where: str, optional: bool = False
            ) -> tuple[float, float, float] | None:
    value = entry.get(key)
    if value is None and optional:
        return None
    ok = isinstance(value, list) and len(value) == 3 and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    if not ok:
        raise CalibrationSourceError(f"{where}: {key}: expected 3 finite numbers (m/s²), found {value!r}")
    return _vec(value)


def results_from_predictions(path: str | Path) -> Collected:
    """One result per estimate of the JSON that ``ofbe-predict`` prints.

    Entries with an ``error`` (no estimate) are skipped and listed in ``skipped``. Every
    estimate is an apparent bias (what the estimators learn from the labels); ``std`` is the
    entry's ``std_m_s2`` when the method has one.

    Raises
    ------
    CalibrationSourceError
        Not JSON, not ofbe-predict's layout, a malformed entry, or no estimate at all.
    """
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise CalibrationSourceError(f"{path}: expected an ofbe-predict JSON, found no such file") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        line = f":{exc.lineno}" if isinstance(exc, json.JSONDecodeError) else ""
        raise CalibrationSourceError(f"{path}{line}: expected the JSON that ofbe-predict prints, found "
                                     f"unreadable text ({exc})") from None
    if not (isinstance(doc, dict) and isinstance(doc.get("results"), list)):
        raise CalibrationSourceError(f"{path}: expected ofbe-predict's JSON object with a 'results' list, "
                                     f"found {type(doc).__name__}")
    sha = sha256_file(path)
    method = str(doc.get("method") or "unknown")
    model = None if doc.get("model") is None else str(doc["model"])
    results, skipped = [], []
    for i, entry in enumerate(doc["results"]):
        where = f"{path}: results[{i}]"
        if not (isinstance(entry, dict) and isinstance(entry.get("device"), str)
                and isinstance(entry.get("file"), str)):
            raise CalibrationSourceError(f"{where}: expected an object with 'device' and 'file' strings, "
                                         f"found {entry!r:.80}")
        if "error" in entry or entry.get("bias_m_s2") is None:
            skipped.append(f"{entry['file']}: no estimate ({entry.get('error', 'no bias_m_s2')})")
            continue
        bias = _triple(entry, "bias_m_s2", where)
        std = _triple(entry, "std_m_s2", where, optional=True)
        g_local = _finite_or_none(entry.get("g_local"))
        if g_local is None or g_local <= 0:
            raise CalibrationSourceError(f"{where}: g_local: expected a positive number (m/s²), "
                                         f"found {entry.get('g_local')!r}")
        results.append(CalibrationResult(
            device=entry["device"], power_cycle=None, bias=bias, std=std, bias_kind=APPARENT, method=method,
            scale=(1.0, 1.0, 1.0), scale_known=False, scale_note="scale identity: a prediction has no scale",
            g_local=g_local,
            fs_hz=_finite_or_none(entry.get("fs_hz")),
            temperature_c=None, n_rows=1, sources=(SourceFile(str(path), sha),), recordings=(entry["file"],),
            model=model, raw_files=(Path(entry["file"]).name,)))
    if not results:
        raise CalibrationSourceError(f"{path}: expected at least one estimate, found none "
                                     f"({len(skipped)} entries without one)")
    stems = prediction_stems([(r.device, r.recordings[0]) for r in results])
    results = [replace(r, stem=stem) for r, stem in zip(results, stems, strict=True)]
    return Collected("predictions", path, tuple(results), tuple(skipped))


def prediction_stems(entries: list[tuple[str, str]]) -> list[str]:
    """File-name stems ``<device>.<file>`` of predictions, unique: the file's stem, with as many
    of its parent folders (joined by ``_``) as it takes to tell the entries apart."""
    def safe(text: str) -> str:
        return re.sub(r"[^A-Za-z0-9._-]", "-", text).strip(".") or "file"

    parts = []
    for _, f in entries:
        path = Path(f).with_suffix("")
        names = path.parts[1:] if path.anchor else path.parts  # no root or drive
        parts.append(tuple(safe(x) for x in names) or ("file",))
    longest = max(len(p) for p in parts)
    for k in range(1, longest + 1):
        stems = [f"{safe(d)}.{'_'.join(p[-k:])}" for (d, _), p in zip(entries, parts, strict=True)]
        if len(set(stems)) == len(stems):
            return stems
    return [f"{s}-{i + 1}" for i, s in enumerate(stems)]


def load_results(source: str | Path) -> Collected:
    """Results of a labels folder, a label file or an ``ofbe-predict`` JSON (by what it is)."""
    path = Path(source)
    if path.suffix == ".json" and not path.is_dir():
        return results_from_predictions(path)
    return results_from_labels(path)


# ----------------------------------------------------------------------------- times


def _mtime(path: str | Path) -> datetime:
    return datetime.fromtimestamp(os.stat(path).st_mtime, tz=UTC).replace(microsecond=0)


def _provenance_time(path: str | Path) -> datetime | None:
    try:
        prov = read_provenance(path)
    except (OSError, ValueError, KeyError):
        return None
    for key in PROVENANCE_TIME_KEYS:
        text = prov.get(key)
        if isinstance(text, str):
            try:
                when = datetime.fromisoformat(text.replace("Z", "+00:00"))
            except ValueError:
                continue
            return when if when.tzinfo else when.replace(tzinfo=UTC)
    return None


def _recording_header_time(path: str | Path) -> datetime | None:
    """UTC start stamp of a bare ofbe-logger / mscip-csv file, or None when unreadable."""
    from ofbe_data.io.formats.mscip_csv import read_mscip_csv
    from ofbe_data.io.formats.ofbe_logger import read_ofbe_logger

    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
        reader = read_mscip_csv if (b"Memsense" in head or b"MSCIP" in head.upper()) else read_ofbe_logger
        return reader(Path(path)).start_utc
    except (OSError, OfbeError):
        return None


def attach_file_times(collected: Collected) -> Collected:
    """Give every result a time without the raw recordings.

    Labels: the label file's provenance time when it has one (``PROVENANCE_TIME_KEYS``), else
    its modification time (the earliest of the result's files). Predictions: the UTC start
    stamp in the predicted file's header when it can be read, else the predictions file's
    modification time. :func:`ofbe_data.calibration.noise.attach_raw_times` gives labels the
    recordings' own start times instead.
    """
    out = []
    for r in collected.results:
        if collected.kind == "labels":
            times = [(_provenance_time(s.path), TIME_PROVENANCE) for s in r.sources]
            times = [t for t in times if t[0] is not None] or [(_mtime(s.path), TIME_LABEL_MTIME)
                                                               for s in r.sources]
            when, how = min(times, key=lambda t: t[0])
        else:
            header = _recording_header_time(r.recordings[0]) if Path(r.recordings[0]).is_file() else None
            when, how = ((header, TIME_RECORDING_HEADER) if header is not None
                         else (_mtime(collected.path), TIME_PREDICTIONS_MTIME))
        if when.tzinfo is None:
            when = when.replace(tzinfo=UTC)
        out.append(replace(r, time_utc=when.astimezone(UTC), time_source=how))
    return replace(collected, results=tuple(out))
