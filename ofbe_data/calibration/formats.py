"""Calibration results in the files other tools load, each convention converted once.

ofbe: ``f = A · u · g + b`` (output-referred, m/s², A the fitted map or the identity), corrected
by ``a = A⁻¹ (f − b)`` (:func:`ofbe_correct`). Per tool (derivations in docs/exports.md):

- imucal (Ferraris): ``a = R_a⁻¹ K_a⁻¹ (f − b_a)`` → ``K_a = diag(‖A_i,:‖)``,
  ``R_a = K_a⁻¹ A`` (unit rows), ``b_a = b`` in the raw unit m/s^2 (:func:`imucal_accelerometer`);
- GGIR (``backup.cal.coef``): ``a_g = (f_g + offset) · scale`` in g, per axis only →
  ``offset = −b / g0``, ``scale = 1 / ‖A_i,:‖`` (:func:`ggir_coefficients`; GGIR has no
  cross-axis terms, so a non-orthogonality A carries is not applied there);
- ROS: the bias to subtract, m/s², and the ``linear_acceleration_covariance`` diagonal std²
  (:func:`ros_bias_covariance`);
- Kalibr: accelerometer and gyroscope noise density and random walk (no bias), see
  :mod:`ofbe_data.calibration.noise`;
- ofbe JSON ``ofbe-calibration/1``: b and its std as they are.

Every writer returns the file's bytes (the command writes them atomically); every file
says which kind of bias it carries (zero-g offset or apparent bias).
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import PurePosixPath
from typing import Any

import numpy as np

from ofbe_data import __version__
from ofbe_data.calibration.defaults import DEFAULT_FRAME_ID, DEFAULT_ROSTOPIC, GGIR_CONVENTIONS, ROS_NODE
from ofbe_data.calibration.noise import MIN_CLUSTERS, RW_BOUND_CONFIDENCE, NoiseEstimate
from ofbe_data.calibration.results import ZERO_G_OFFSET, CalibrationExportError, CalibrationResult
from ofbe_data.io.gravity import G0
from ofbe_data.io.recording import TEMPERATURE, Recording
from ofbe_data.labelling.conventions import imucal_from_matrix

JSON_FORMAT = "ofbe-calibration/1"
"""``format`` of the ofbe calibration JSON."""
IMUCAL_FORMAT_VERSION = "2.0.0"
"""``_format_version`` of imucal 2.x calibration files, as imucal itself writes it."""
FORMAT_EXTENSIONS: dict[str, str] = {"imucal": "imucal.json", "kalibr": "kalibr.yaml", "ros": "ros.yaml",
                                     "ggir": "ggir.csv", "json": "json"}
"""File-name ending of each format (``<device>.pc<N>.<ending>``; in a store
``<device>_<YYYYmmddTHHMMSS>.<ending>``)."""
GGIR_COLUMNS = ("filename", "scale.x", "scale.y", "scale.z", "offset.x", "offset.y", "offset.z",
                "temperature.offset.x", "temperature.offset.y", "temperature.offset.z", "meantempcal",
                "use.temperature", "QCmessage", "device", "power_cycle", "bias_kind", "raw_file")
"""Columns of the GGIR file: those GGIR's ``backup.cal.coef`` reader looks up by name (g.part1),
then ofbe's own (GGIR ignores them)."""


# ----------------------------------------------------------------------------- conventions


def ofbe_correct(raw: np.ndarray, bias: Sequence[float], matrix: Any = None) -> np.ndarray:
    """ofbe's correction of (N, 3) readings in m/s²: ``a = A⁻¹ (f − b)`` (A (3, 3), default I)."""
    a = np.eye(3) if matrix is None else np.asarray(matrix, dtype=np.float64)
    return np.linalg.solve(a, (np.asarray(raw, dtype=np.float64) - np.asarray(bias, dtype=np.float64)).T).T


def imucal_accelerometer(bias: Sequence[float], matrix: Any = None
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K_a, R_a, b_a) of imucal's Ferraris model from ofbe's b and A.

    imucal corrects ``a = R_a⁻¹ K_a⁻¹ (f − b_a)`` (``FerrarisCalibrationInfo._calibrate_acc``):
    the bias is subtracted in the raw unit before scaling, exactly ofbe's ``A⁻¹ (f − b)``
    with ``K_a R_a = A``; imucal's own Ferraris fit gives R_a unit rows, so K_a holds the row
    norms of A (:func:`ofbe_data.labelling.conventions.imucal_from_matrix`) and ``b_a = b``
    (m/s², the file's ``from_acc_unit``).
    """
    k_a, r_a = imucal_from_matrix(np.eye(3) if matrix is None else matrix)
    return k_a, r_a, np.asarray(bias, dtype=np.float64)


def ggir_coefficients(bias: Sequence[float], matrix: Any = None, g0: float = G0,
                      unit_sphere_g: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(scale, offset) of GGIR's calibration from ofbe's b (m/s²) and A.

    GGIR applies ``scale(x, center = -offset, scale = 1/scale)``, i.e.
    ``a_g = (f_g + offset) · scale`` with readings in g (g.getmeta, g.calibrate). With
    ``f_g = f / g0`` and a per-axis gain s_i = ‖A_i,:‖: ``a / g0 = (f − b) / (g0 · s)`` holds
    for ``offset = −b / g0`` (g, the opposite sign of ofbe's b) and ``scale = 1 / s``. GGIR
    has no cross-axis terms; they are left out.

    With ``unit_sphere_g`` (the local gravity, m/s²) the scale is GGIR's own convention
    instead: ``a_g = a / g_local``, a resting reading of norm 1, which multiplies the scale by
    g0 / g_local (the offset, in g of the reading's unit, is the same).
    """
    k_a, _ = imucal_from_matrix(np.eye(3) if matrix is None else matrix)
    scale = 1.0 / k_a.diagonal()
    if unit_sphere_g is not None:
        scale = scale * (g0 / unit_sphere_g)
    return scale, -np.asarray(bias, dtype=np.float64) / g0


def ggir_apply(raw_g: np.ndarray, scale: Sequence[float], offset: Sequence[float]) -> np.ndarray:
    """GGIR's correction of (N, 3) readings in g: ``(raw + offset) · scale`` (temperature unused)."""
    return (np.asarray(raw_g, dtype=np.float64) + np.asarray(offset)) * np.asarray(scale)


def ros_bias_covariance(bias: Sequence[float], noise_std: Sequence[float] | None
                        ) -> tuple[list[float], list[float]]:
    """The bias to subtract (m/s²) and ``linear_acceleration_covariance`` (9 values, row-major).

    sensor_msgs/Imu's covariance is that of one measurement (one message's
    ``linear_acceleration``), row-major about x, y, z; all zeros means "unknown". Its diagonal
    is therefore the per-sample noise variance, std² in (m/s²)², of the stationary samples the
    calibration came from, not the uncertainty of the bias; without it the matrix is all zeros.
    """
    cov = [0.0] * 9
    if noise_std is not None:
        for i, s in enumerate(noise_std):
            cov[4 * i] = float(s) ** 2
    return [float(b) for b in bias], cov


# ----------------------------------------------------------------------------- helpers


def yaml_float(x: float) -> str:
    """A float as YAML 1.1 reads it back bit for bit (PyYAML needs ``1.0e-05``, not ``1e-05``)."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"expected a finite number, found {x!r}")
    text = repr(x)
    if "e" in text:
        mant, exp = text.split("e")
        if "." not in mant:
            mant += ".0"
        if exp[0] not in "+-":
            exp = "+" + exp
        text = f"{mant}e{exp}"
    return text


def _utc(when: datetime | None) -> str | None:
    """ISO 8601 UTC, ``…T12:00:00Z``, with the fraction of a second (trailing zeros dropped) when
    there is one."""
    if when is None:
        return None
    at = when.astimezone(UTC)
    text = at.strftime("%Y-%m-%dT%H:%M:%S")
    return text + ("Z" if at.microsecond == 0 else "." + f"{at.microsecond:06d}".rstrip("0") + "Z")


def _kind_words(r: CalibrationResult) -> str:
    if r.bias_kind == ZERO_G_OFFSET:
        return f"the zero-g offset b of the {r.method} fit"
    return (f"the apparent bias (mean - g*u; {r.method}), mean of {r.n_rows} "
            f"{'recording' if r.n_rows == 1 else 'recordings'}")


def _sources(r: CalibrationResult) -> str:
    return ", ".join(f"{s.path} (sha256 {s.sha256[:12]}...)" for s in r.sources)


def _header(r: CalibrationResult, written: datetime, what: str) -> list[str]:
    return [f"{what} written by ofbe {__version__} at {_utc(written)}",
            f"device {r.device}, power cycle {r.power_cycle if r.power_cycle is not None else 'unknown'}",
            f"bias_kind: {r.bias_kind} ({_kind_words(r)})",
            f"source: {_sources(r)}",
            f"time {_utc(r.time_utc)} ({r.time_source or 'unknown'})"]


# ----------------------------------------------------------------------------- writers


def imucal_file(r: CalibrationResult, written: datetime) -> bytes:
    """An imucal ``FerrarisCalibrationInfo`` JSON (``_format_version`` 2.0.0), as imucal writes it.

    Exactly the fields imucal's loader passes to the class (``load_calibration_info`` fails on
    others); what ofbe knows beyond K_a, R_a, b_a is said in ``comment``.
    """
    k_a, r_a, b_a = imucal_accelerometer(r.bias, r.matrix)
    comment = (f"ofbe {__version__} export, {_utc(written)}: device {r.device}, power cycle "
               f"{r.power_cycle if r.power_cycle is not None else 'unknown'}. bias_kind: {r.bias_kind}. "
               f"b_a is {_kind_words(r)}, in m/s^2, subtracted before scaling. K_a R_a = A: {r.scale_note}"
               f"{'' if r.scale_known else '; K_a and R_a identity'}. Gyroscope: ofbe has "
               "no gyroscope data; K_g and R_g are identity, K_ga and b_g zero (the gyroscope passes "
               "unchanged). "
               f"Source: {_sources(r)}. Time {_utc(r.time_utc)} ({r.time_source}).")
    doc = {"acc_unit": "m/s^2", "gyr_unit": "deg/s", "from_acc_unit": "m/s^2", "from_gyr_unit": "deg/s",
           "comment": comment, "K_a": k_a.tolist(), "R_a": r_a.tolist(), "b_a": b_a.tolist(),
           "K_g": np.eye(3).tolist(), "R_g": np.eye(3).tolist(), "K_ga": np.zeros((3, 3)).tolist(),
           "b_g": [0.0, 0.0, 0.0], "cal_type": "Ferraris", "_format_version": IMUCAL_FORMAT_VERSION}
    return json.dumps(doc, indent=4, allow_nan=False).encode()


class KalibrInputError(CalibrationExportError):
    """A field Kalibr requires has no value: no gyroscope data and no value given for it."""


def _kalibr_random_walk(noise: NoiseEstimate, what: str, unit: str) -> tuple[list[str], float]:
    """Comment lines and value of ``<what>_random_walk``: measured, or the flagged upper bound."""
    if noise.random_walk is not None:
        return ([f"# {what}_random_walk [{unit}]: largest axis of x, y, z = "
                 + ", ".join(f"{v:.4g}" for v in noise.random_walk) + f"; {noise.random_walk_note}"],
                max(noise.random_walk))
    bound = noise.random_walk_bound
    return ([f"# {what}_random_walk [{unit}]: UPPER BOUND, NOT A MEASUREMENT: {noise.random_walk_note}.",
             "#   Written: the largest random walk the Allan curve allows (K <= ADEV_up(tau)*sqrt(3/tau) at "
             f"every tau, ADEV_up its one-sided {RW_BOUND_CONFIDENCE:.0%} upper limit);",
             "#   largest axis of x, y, z = "
             + ", ".join(f"{v:.4g}" for v in bound) + ".",
             "#   Conservative: the true value is at most this; hours of static data measure it."],
            max(bound))


def _kalibr_density_lines(noise: NoiseEstimate, what: str, unit: str) -> list[str]:
    return [f"# {what}_noise_density [{unit}]: white-noise level N, ADEV(tau) = N/sqrt(tau) fitted on "
            f"tau = {noise.fit_taus_s[0]:.3g}..{noise.fit_taus_s[1]:.3g} s",
            "#   (= ADEV at tau = 1 s on that line); the largest axis of x, y, z = "
            + ", ".join(f"{v:.4g}" for v in noise.density)
            + " (fit slopes " + ", ".join(f"{v:.2f}" for v in noise.fit_slope) + ")"]


def kalibr_file(r: CalibrationResult, noise: NoiseEstimate, written: datetime,
                rostopic: str = DEFAULT_ROSTOPIC, gyro: NoiseEstimate | None = None,
                gyro_noise_density: float | None = None, gyro_random_walk: float | None = None) -> bytes:
    """Kalibr's ``imu.yaml``: every field its ``ImuParameters`` reader requires.

    Kalibr takes one value per quantity for all axes: the largest axis is written (the
    per-axis values are in the comments). A random walk the recordings are too short to show is
    replaced by its upper bound (:func:`~ofbe_data.calibration.noise.random_walk_bound`),
    flagged in the comment. Gyroscope values: the user's (``gyro_noise_density``, rad/s/√Hz,
    ``gyro_random_walk``, rad/s²/√Hz) where given, else the Allan analysis of the recordings'
    gyroscope columns (``gyro``).

    Raises
    ------
    KalibrInputError
        A gyroscope value is neither given nor measurable (``gyro`` None).
    """
    missing = [flag for flag, value in (("--gyro-noise-density", gyro_noise_density),
                                        ("--gyro-random-walk", gyro_random_walk)) if value is None]
    if gyro is None and missing:
        raise KalibrInputError(
            f"{r.what}: Kalibr requires gyroscope_noise_density and gyroscope_random_walk, and the raw files "
            f"have no gyroscope columns; give {' and '.join(missing)} (datasheet values, rad/s/sqrt(Hz) and "
            "rad/s^2/sqrt(Hz)), or map the gyroscope columns (gx, gy, gz) in session.yaml")
    for name, value in (("gyroscope_noise_density", gyro_noise_density),
                        ("gyroscope_random_walk", gyro_random_walk)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise KalibrInputError(f"{name}: expected a positive number, found {value!r}")
    lines = [f"# {line}" for line in _header(r, written, "Kalibr IMU noise parameters (imu.yaml)")]
    lines += [
        f"# accelerometer: overlapping Allan deviation of {noise.n_segments} stationary segments "
        f"({noise.total_s:.1f} s in all, shortest {noise.shortest_s:.1f} s), each tau pooled over the "
        f"segments holding at least {MIN_CLUSTERS} clusters of it: tau up to {noise.longest_tau_s:.3g} s "
        f"({noise.longest_tau_segments} segment{'' if noise.longest_tau_segments == 1 else 's'} there)",
        *_kalibr_density_lines(noise, "accelerometer", "m/s^2/sqrt(Hz)"),
        f"accelerometer_noise_density: {yaml_float(max(noise.density))}",
    ]
    rw_lines, rw = _kalibr_random_walk(noise, "accelerometer", "m/s^3/sqrt(Hz)")
    lines += [*rw_lines, f"accelerometer_random_walk: {yaml_float(rw)}"]
    if gyro is not None:
        lines.append("# gyroscope: the same analysis of the recordings' gyroscope columns (rad/s) over "
                     "the same segments")
    if gyro_noise_density is not None:
        lines += ["# gyroscope_noise_density [rad/s/sqrt(Hz)]: given by the user (--gyro-noise-density)",
                  f"gyroscope_noise_density: {yaml_float(gyro_noise_density)}"]
    else:
        assert gyro is not None
        lines += [*_kalibr_density_lines(gyro, "gyroscope", "rad/s/sqrt(Hz)"),
                  f"gyroscope_noise_density: {yaml_float(max(gyro.density))}"]
    if gyro_random_walk is not None:
        lines += ["# gyroscope_random_walk [rad/s^2/sqrt(Hz)]: given by the user (--gyro-random-walk)",
                  f"gyroscope_random_walk: {yaml_float(gyro_random_walk)}"]
    else:
        assert gyro is not None
        g_lines, g_rw = _kalibr_random_walk(gyro, "gyroscope", "rad/s^2/sqrt(Hz)")
        lines += [*g_lines, f"gyroscope_random_walk: {yaml_float(g_rw)}"]
    lines += [f"rostopic: {json.dumps(rostopic)}",
              f"update_rate: {yaml_float(round(noise.fs_hz, 6))}  # Hz, measured sample rate"]
    return ("\n".join(lines) + "\n").encode()


def ros_file(r: CalibrationResult, written: datetime, frame_id: str = DEFAULT_FRAME_ID,
             node: str = ROS_NODE) -> bytes:
    """A ROS 2 parameter file (``<node>: ros__parameters: …``) with the bias to subtract and the
    per-sample ``linear_acceleration_covariance`` of sensor_msgs/Imu.

    Every value is one of the types rcl's parameter parser accepts (string, integer, double, or
    a list of doubles); what is unknown is left out, never written as null or NaN.
    """
    bias, cov = ros_bias_covariance(r.bias, r.noise_std)
    lines = [f"# {line}" for line in _header(r, written, "Accelerometer bias for ROS 2")]
    lines += ["# linear_acceleration_bias [m/s^2, sensor frame]: subtract from sensor_msgs/Imu "
              "linear_acceleration",
              "# linear_acceleration_covariance [(m/s^2)^2]: row-major 3x3 about x, y, z, the covariance of "
              "one sample (sensor_msgs/Imu): diagonal = per-sample noise variance over the stationary "
              "segments" + ("" if r.noise_std is not None
                            else "; all zeros: unknown (sensor_msgs/Imu: covariance unknown)"),
              "# linear_acceleration_bias_std [m/s^2]: uncertainty of the bias itself, when known",
              "# No standard ROS node reads these parameters by name: an IMU driver (or a small node) "
              "subtracts the bias and copies the covariance into each message, where robot_localization "
              "and imu_filter_madgwick read it."]
    if not r.scale_known:
        lines.append(f"# {r.scale_note}; ROS corrects the bias only")
    else:
        lines.append("# " + r.scale_note + ": A = " + "; ".join(", ".join(f"{v:.10g}" for v in row)
                                                            for row in r.matrix)
                     + " (rows); a bias subtraction does not apply it: a = A^-1 (f - b)")
    params = [f"device: {json.dumps(r.device)}"]
    if r.power_cycle is not None:
        params.append(f"power_cycle: {int(r.power_cycle)}")
    params += [f"frame_id: {json.dumps(frame_id)}", f"bias_kind: {json.dumps(r.bias_kind)}",
               f"method: {json.dumps(r.method)}",
               "linear_acceleration_bias: [" + ", ".join(yaml_float(v) for v in bias) + "]"]
    uncertainty = r.bias_se if r.bias_se is not None else r.std
    if uncertainty is not None:
        params.append("linear_acceleration_bias_std: [" + ", ".join(yaml_float(v) for v in uncertainty) + "]")
    params.append("linear_acceleration_covariance: [" + ", ".join(yaml_float(v) for v in cov) + "]")
    lines += [f"{json.dumps(node)}:", "  ros__parameters:", *(f"    {p}" for p in params)]
    return ("\n".join(lines) + "\n").encode()


GGIR_BACKUP_FILE = "backup.cal.coef.csv"
"""Name of the one ``backup.cal.coef`` file of a GGIR export run (when ``--out`` is a folder)."""
GGIR_SAMPLE_RATE_KEY = "sample_rate"
"""Header key of the sample rate in the rebuilt data files (GGIR's ``rmc.headername.sf``)."""


class GgirExportError(CalibrationExportError):
    """The GGIR export would not do what GGIR reads it for: two rows for one data file name, a
    name GGIR rewrites before matching, or a recording with nothing to write."""


def ggir_lookup_name(filename: str) -> str:
    """The name GGIR compares with a data file's name for a ``filename`` cell of the file.

    GGIR's g.part1 (R/g.part1.R, ``main_part1``, the ``backup.cal.coef`` block) first rewrites
    every ``filename`` that holds ``meta_`` (its own milestone names,
    ``meta_<file>.RData``): ``tmp = unlist(strsplit(filename, "meta_"))``; when
    ``length(tmp) > 1`` the name becomes ``tmp[2]`` cut at the first match of the regular
    expression ``.RData``. Only then does it look the data file's name up
    (``which(bcc.data$filename == fnames[i])``).
    """
    pieces = _r_strsplit(filename, "meta_")
    if len(pieces) > 1:
        return _r_strsplit(pieces[1], ".RData")[0] if pieces[1] else ""
    return filename


def _r_strsplit(text: str, pattern: str) -> list[str]:
    """R's ``strsplit(text, pattern)`` (a regular expression) for one non-empty string: a match
    at the end adds no empty piece."""
    pieces = re.split(pattern, text)
    if len(pieces) > 1 and pieces[-1] == "":
        pieces.pop()
    return pieces


def _ggir_rows(r: CalibrationResult, written: datetime, g0: float, convention: str) -> list[list[Any]]:
    """The ``backup.cal.coef`` rows of one result: one per raw file, all with its coefficients."""
    if convention not in GGIR_CONVENTIONS:
        raise ValueError(f"convention: expected one of {', '.join(GGIR_CONVENTIONS)}, found {convention!r}")
    unit_sphere = convention == "unit-sphere"
    scale, offset = ggir_coefficients(r.bias, r.matrix, g0, r.g_local if unit_sphere else None)
    sphere = (f"GGIR's unit sphere: calibrated readings at rest have norm 1 (scale includes g0/g_local, "
              f"g_local = {r.g_local:.6f} m/s^2)" if unit_sphere
              else f"ofbe's local convention: calibrated readings at rest have norm g_local/g0 = "
                   f"{r.g_local / g0:.6f}")
    temp_note = ("meantempcal is the mean temperature of the segments" if r.temperature_c is not None
                 else "meantempcal 0: temperature unknown (the temperature offsets are 0: no effect)")
    qc = (f"ofbe {__version__} export {_utc(written)}: bias_kind {r.bias_kind}, {_kind_words(r)}; "
          f"offset = -b/g0 (g0 = {g0} m/s^2); {sphere}; {r.scale_note}; no temperature model; {temp_note}")
    temp = repr(float(r.temperature_c)) if r.temperature_c is not None else "0.0"
    return [[ggir_name(raw), *(repr(float(v)) for v in scale), *(repr(float(v)) for v in offset),
             "0.0", "0.0", "0.0", temp, "FALSE", qc, r.device,
             "" if r.power_cycle is None else r.power_cycle, r.bias_kind, raw]
            for raw in r.raw_files or (r.stem,)]


def ggir_table(results: Sequence[CalibrationResult], written: datetime, g0: float = G0,
               convention: str = "unit-sphere") -> bytes:
    """The one ``backup.cal.coef`` CSV of an export run: a row per raw file of every result.

    GGIR takes one calibration file per run, ``GGIR(..., backup.cal.coef = "<file>")`` (the
    ``backup.cal.coef`` parameter of g.part1; R/g.part1.R, ``main_part1``): it reads it whole
    (``bcc.data = data.table::fread(backup.cal.coef, data.table = FALSE)``; ``read.csv`` in
    GGIR 2.x), and for each data file takes the first row whose ``filename`` equals the file's
    base name (``bcc.i = which(bcc.data$filename == fnames[i])``, then ``bcc.i[1]``; ``fnames``
    are base names, R/datadir2fnames.R), reading ``scale.*``, ``offset.*`` and
    ``temperature.offset.*`` by column name in file order (``as.numeric``), ``meantempcal``,
    ``QCmessage`` and ``use.temperature``. Every device and power cycle therefore shares one
    file, one row per raw file (:func:`ggir_name`; ``raw_file`` says which file it stands for),
    and every name must be found as written: two rows of one name (GGIR would silently use
    the first) or a name GGIR rewrites before the look-up (:func:`ggir_lookup_name`) are
    refused. Every numeric cell holds a number (GGIR reads an empty one as NA and fails on it).

    Raises
    ------
    GgirExportError
        Two rows for one file name, or a name GGIR would rewrite.
    """
    rows: list[list[Any]] = []
    owner: dict[str, str] = {}
    for r in results:
        for row in _ggir_rows(r, written, g0, convention):
            name = row[0]
            if ggir_lookup_name(name) != name:
                raise GgirExportError(
                    f"{row[-1]}: expected a file name GGIR looks up as written, found {name!r}, which "
                    f"GGIR's g.part1 rewrites to {ggir_lookup_name(name)!r} (it strips 'meta_' names); "
                    "rename the file")
            if name in owner:
                raise GgirExportError(
                    f"{row[-1]}: expected one backup.cal.coef row per data file name, found {name!r} "
                    f"for both {owner[name]} and {r.what} (GGIR would use the first row for both)")
            owner[name] = r.what
            rows.append(row)
    buf = io.StringIO()
    out = csv.writer(buf, lineterminator="\n")
    out.writerow(GGIR_COLUMNS)
    out.writerows(rows)
    return buf.getvalue().encode()


def ggir_file(r: CalibrationResult, written: datetime, g0: float = G0,
              convention: str = "unit-sphere") -> bytes:
    """A ``backup.cal.coef`` CSV of one result alone (what ``--store`` files per device and power
    cycle): :func:`ggir_table` of ``[r]``."""
    return ggir_table([r], written, g0, convention)


def ggir_name(raw_file: str) -> str:
    """The file name GGIR matches a raw file by: its path from the campaign's raw folder with
    ``/`` replaced by ``__`` (``ga-pc001/rec-01/sparkfun-1.csv`` →
    ``ga-pc001__rec-01__sparkfun-1.csv``), unique where every raw file is ``<device>.csv``, and
    ending in ``.csv`` (``.csv`` is added to another ending: ``--ggir-data`` writes CSV, and GGIR
    picks its reader by the ending, R/g.inspectfile.R); a bare file name (a prediction's) stays
    as it is."""
    parts = PurePosixPath(raw_file).parts
    name = "__".join(parts)
    if len(parts) > 1 and not name.lower().endswith(".csv"):
        name += ".csv"
    return name


# ----------------------------------------------------------------------------- GGIR data files


GGIR_TIME_ANCHOR_AT_ZERO = frozenset({"mscip-csv"})
"""Formats whose header UTC start is the time of ``t = 0`` (``Time (s)`` relative to
``Start (UTC)``); in the others it is the time of the first sample."""


def ggir_read_settings(with_temperature: bool) -> dict[str, str]:
    """The ``rmc.*`` (and other) GGIR parameters that read :func:`ggir_data_file`'s files, as R
    literals.

    GGIR reads a csv that is not an ActiGraph/Axivity export through ``read.myacc.csv``
    (R/read.myacc.csv.R) once ``rmc.firstrow.acc`` is set (R/g.inspectfile.R: the
    ``AD_HOC_CSV`` format): the header block is ``fread(nrows = rmc.header.length, skip =
    rmc.firstrow.header - 1, header = FALSE)``, names in column 1, values in column 2, the
    sample rate the row named ``rmc.headername.sf``; the data start at line
    ``rmc.firstrow.acc`` (R/g.readaccfile.R skips that line when it holds column names), the
    columns picked by ``rmc.col.time``, ``rmc.col.acc``, ``rmc.col.temp``, acceleration in
    ``rmc.unit.acc`` (g), time as ``rmc.unit.time`` ``"UNIXsec"``. ``rmc.doresample = TRUE``
    puts the samples on GGIR's uniform grid from their time stamps (dropped samples, clock
    jitter); ``minimumFileSizeMB = 0`` keeps g.part1 from skipping files under its default
    2 MB; ``desiredtz`` is required (the time stamps are UTC instants).
    """
    settings = {"rmc.firstrow.header": "1", "rmc.header.length": "1",
                "rmc.headername.sf": f'"{GGIR_SAMPLE_RATE_KEY}"', "rmc.firstrow.acc": "2",
                "rmc.dec": '"."', "rmc.col.time": "1", "rmc.unit.time": '"UNIXsec"',
                "rmc.origin": '"1970-01-01"', "rmc.col.acc": "c(2, 3, 4)", "rmc.unit.acc": '"g"'}
    if with_temperature:
        settings |= {"rmc.col.temp": "5", "rmc.unit.temp": '"C"'}
    return settings | {"rmc.doresample": "TRUE", "minimumFileSizeMB": "0", "desiredtz": '"UTC"'}


def ggir_sample_rate(rec: Recording) -> float:
    """The sample rate a rebuilt file states: the header's nominal rate, else the measured one
    (kept plus missing samples over the span), rounded to a whole Hz within 0.5 % of one and
    to 1 mHz otherwise."""
    if rec.nominal_rate_hz is not None and math.isfinite(rec.nominal_rate_hz) and rec.nominal_rate_hz > 0:
        return float(rec.nominal_rate_hz)
    fs = rec.fs_hz
    if not (math.isfinite(fs) and fs > 0):
        raise GgirExportError(f"{rec.path}: expected at least two samples with increasing times to state a "
                              f"sample rate, found {rec.n}")
    whole = round(fs)
    return float(whole) if whole > 0 and abs(fs / whole - 1.0) <= 0.005 else round(fs, 3)


def ggir_data_file(rec: Recording, with_temperature: bool = False, g0: float = G0) -> bytes:
    """A recording as a clean CSV that GGIR's ``read.myacc.csv`` reads whole
    (:func:`ggir_read_settings`): the samples ofbe's validating reader kept, nothing else.

    Layout (ASCII, ``\n`` line ends, every line the same number of comma-separated fields, the
    way GGIR's own tests write a header block, tests/testthat/test_read.myacc.csv.R)::

        sample_rate,150,,            (the header block: name, value, padding)
        time,x,y,z                   (column names; ``,temperature`` with a temperature)
        1741944151.100000,0.01171875,-0.01953125,1.01171875

    ``time``: Unix seconds (UTC), 6 decimals: the header's UTC start plus the device clock
    since it (the start is the first sample's time, or ``t = 0``'s for ``mscip-csv``); without
    a UTC start, the device clock itself (seconds since 1970-01-01, or the epoch times a
    generic csv held). ``x, y, z``: the raw (uncalibrated) specific force in g, ``acc / g0``
    (GGIR applies ``backup.cal.coef`` to these), written with ``repr`` so they read back bit
    for bit. ``temperature`` (°C) only with ``with_temperature``.

    Raises
    ------
    GgirExportError
        No sample or a non-finite one, or a temperature asked for that the recording does not
        have (finite).
    """
    if rec.n == 0 or not np.all(np.isfinite(rec.acc)):
        raise GgirExportError(f"{rec.path}: expected finite samples to write for GGIR, found "
                              f"{'none' if rec.n == 0 else 'a non-finite one'}")
    fs = ggir_sample_rate(rec)
    temps = None
    if with_temperature:
        temps = rec.extra.get(TEMPERATURE)
        if temps is None or not np.all(np.isfinite(temps)):
            raise GgirExportError(f"{rec.path}: expected a finite temperature for every sample, found "
                                  f"{'none' if temps is None else 'a missing one'}")
    t = np.asarray(rec.t, dtype=np.float64)
    if rec.start_utc is not None:
        start = rec.start_utc if rec.start_utc.tzinfo else rec.start_utc.replace(tzinfo=UTC)
        anchor = 0.0 if rec.format in GGIR_TIME_ANCHOR_AT_ZERO else float(t[0])
        times = start.timestamp() + (t - anchor)
    else:
        times = t
    g = np.asarray(rec.acc, dtype=np.float64) / g0
    columns = ["time", "x", "y", "z"] + (["temperature"] if temps is not None else [])
    pad = "," * (len(columns) - 2)
    lines = [f"{GGIR_SAMPLE_RATE_KEY},{fs:.10g}{pad}", ",".join(columns)]
    if temps is None:
        lines += [f"{ti:.6f},{x!r},{y!r},{z!r}"
                  for ti, (x, y, z) in zip(times.tolist(), g.tolist(), strict=True)]
    else:
        lines += [f"{ti:.6f},{x!r},{y!r},{z!r},{c!r}"
                  for ti, (x, y, z), c in zip(times.tolist(), g.tolist(), np.asarray(temps, float).tolist(),
                                              strict=True)]
    return ("\n".join(lines) + "\n").encode("ascii")


def json_document(r: CalibrationResult, written: datetime) -> dict[str, Any]:
    """The ofbe calibration JSON (``ofbe-calibration/1``) as a dict."""
    return {
        "format": JSON_FORMAT, "device": r.device, "power_cycle": r.power_cycle,
        "bias_m_s2": list(r.bias), "bias_std_m_s2": None if r.std is None else list(r.std),
        "bias_kind": r.bias_kind,
        "convention": "f = A*u*g + b (output-referred, m/s^2, sensor frame); correct with a = A^-1 (f - b)",
        "bias_se_m_s2": None if r.bias_se is None else list(r.bias_se),
        "A": [list(row) for row in r.matrix], "scale": list(r.scale), "scale_known": r.scale_known,
        "scale_note": r.scale_note, "method": r.method, "model": r.model,
        "n_rows": r.n_rows, "g_local_m_s2": r.g_local, "fs_hz": r.fs_hz, "temperature_c": r.temperature_c,
        "recordings": list(r.recordings),
        "source": {"files": [s.to_dict() for s in r.sources]},
        "time_utc": _utc(r.time_utc), "time_source": r.time_source or None,
        "written_utc": _utc(written), "ofbe_version": __version__,
    }


def json_file(r: CalibrationResult, written: datetime) -> bytes:
    """The ofbe calibration JSON's bytes."""
    return (json.dumps(json_document(r, written), indent=2, allow_nan=False) + "\n").encode()
