"""``ofbe-predict MODEL RECORDING...``: bias of new stationary recordings from a saved model.

MODEL is a saved OFBENet (``.keras``, loaded in Keras' safe mode), a fitted
``gravity-prior`` (``.json``), or a folder of deployed models (``models/<dataset>``, see
:mod:`ofbe_model.deploy.final`): a folder holding one model for every device, or a model set
(``models.json``) of one model per device, from which each recording gets its own device's
model (``--estimator`` says which of the two kinds). A RECORDING is a session folder (every DUT file of every
recording its manifest names; format, device and local gravity from the manifest) or a
single ``ofbe-logger`` / ``mscip-csv`` file (``--device`` and ``--g-local`` then say what
the manifest would). Each file is read with the toolkit's validating readers; the first
``T`` samples of its longest still run (the static detector of the labeller, less the
margin where it borders motion) are the window the model sees, as the test signals of the
benchmark are.

Output: JSON (default) or a table, one entry per device file: the bias in m/s² and, for
methods that have one, its standard deviation. The model's training domain (devices, sample
rates, window length) is printed with it: a device the model never saw gets a warning, a
sample rate outside the trained range no estimate unless ``--allow-outside-domain``, and a
window whose ‖mean‖ is far from g_local (a unit mistake) none at all, nor a recording that
``ofbe-label`` would reject (garbled, an implausible rate or norm, saturated, clipped, dead or
stuck axes: the same checks, reported with its reason and words). Exit 0 when every file
got an estimate, 1 when some could not (a one-line reason each; the others are still printed), 2 on a usage
error.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ofbe_data.core.errors import OfbeError
from ofbe_data.io.formats import read_device_file
from ofbe_data.io.formats.mscip_csv import read_mscip_csv
from ofbe_data.io.formats.ofbe_logger import read_ofbe_logger
from ofbe_data.io.gravity import G0 as STANDARD_GRAVITY
from ofbe_data.io.manifest import MANIFEST_NAME, load_manifest
from ofbe_data.io.recording import Recording
from ofbe_data.labelling.checks import (
    MIN_CLIP_RATIO,
    clipped_samples,
    norm_problem,
    rate_problem,
    skipped_lines_problem,
    typical_norm_problem,
)
from ofbe_data.labelling.labels import GARBLED, IMPLAUSIBLE_NORM, IMPLAUSIBLE_RATE, SATURATED, LabelParams
from ofbe_data.labelling.stationarity import StaticParams, check_static, longest_run
from ofbe_model.deploy.defaults import DEFAULT_WINDOW, MODEL_FILES
from ofbe_model.deploy.final import SET_FORMAT, SET_NAME
from ofbe_model.estimators.base import Estimator, EstimatorError
from ofbe_model.estimators.domain import TrainingDomain, domain_problems, window_direction

BARE_FILES = ("a bare file is read as ofbe-logger or mscip-csv; for any other file (a generic csv, "
              "another logger's format) make its folder a session with `ofbe-session init FOLDER` and "
              "pass the folder")


@dataclass(frozen=True)
class Target:
    """One device file to estimate: where it is and what it is."""

    path: Path
    device: str
    g_local: float
    recording: Recording | None = None
    problem: str = ""


def load_model(path: str | Path) -> Estimator:
    """A saved OFBENet (``.keras``) or gravity-prior (``.json``).

    Raises
    ------
    EstimatorError
        Not a file of either kind, or not loadable (never executes code from it).
    """
    path = Path(path)
    if path.suffix == ".keras":
        from ofbe_model.ofbenet.network import OFBENet

        return OFBENet.load(path)
    if path.suffix == ".json":
        from ofbe_model.estimators.priors import GravityPrior

        return GravityPrior.load(path)
    raise EstimatorError(f"{path}: expected a saved OFBENet (.keras) or gravity-prior (.json), "
                         f"found a {path.suffix or 'suffix-less'} file")


def _set_members(folder: Path) -> dict[str, str]:
    """Device → subfolder of a model set's ``models.json``."""
    index = folder / SET_NAME
    try:
        doc = json.loads(index.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise EstimatorError(f"{index}: expected a model-set index ({SET_FORMAT}), found an unreadable file "
                             f"({exc})") from None
    devices = doc.get("devices") if isinstance(doc, dict) else None
    good = isinstance(doc, dict) and doc.get("format") == SET_FORMAT and isinstance(devices, dict) and all(
        isinstance(k, str) and isinstance(v, str) and v and Path(v).name == v and v not in (".", "..")
        for k, v in devices.items())
    if not good:
        raise EstimatorError(f"{index}: expected a model-set index ({SET_FORMAT}: 'devices', each a device "
                             f"id and its subfolder's name), found {str(doc)[:120]}")
    return devices


def model_files(path: str | Path, estimator: str = "ofbenet") -> dict[str | None, Path]:
    """The model file(s) ``ofbe-predict MODEL`` runs, by device.

    Parameters
    ----------
    path
        A model file; a deployed model's folder (``models/gravity-aligned``); or a model set's
        folder (``models/rotated``, with ``models.json``: one model per device).
    estimator
        Which deployed model of a folder: ``ofbenet`` (``final.keras``) or ``gravity-prior``
        (``gravity-prior.json``).

    Returns
    -------
    dict
        ``{None: file}`` for one model that serves every device, else device → file.

    Raises
    ------
    EstimatorError
        No such file or folder (a file that a model set's folder would hold per device is named
        with the folder to pass instead), an unknown estimator, or a folder without the file.
    """
    path = Path(path)
    if estimator not in MODEL_FILES:
        raise EstimatorError(f"--estimator: expected one of {', '.join(MODEL_FILES)}, found {estimator!r}")
    if path.is_dir():
        if (path / SET_NAME).is_file():
            members = _set_members(path)
            files = {device: path / sub / MODEL_FILES[estimator] for device, sub in members.items()}
            missing = [str(f) for f in files.values() if not f.is_file()]
            if missing:
                raise EstimatorError(f"{path / SET_NAME}: expected each device's model, found no "
                                     f"{', '.join(missing)}")
            return dict(files)
        file = path / MODEL_FILES[estimator]
        if not file.is_file():
            raise EstimatorError(f"{path}: expected a deployed model's folder holding "
                                 f"{MODEL_FILES[estimator]} (--estimator {estimator}) or a model set "
                                 f"({SET_NAME}), found neither")
        return {None: file}
    if not path.exists() and (path.parent / SET_NAME).is_file():
        members = _set_members(path.parent)
        raise EstimatorError(f"{path}: no such file; {path.parent} holds one model per device "
                             f"({', '.join(sorted(members))}): pass the folder {path.parent} and each "
                             f"recording gets its own device's model, or {path.parent}/<device>/{path.name}")
    return {None: path}


def predict_files(files: dict[str | None, Path], items: Sequence[Target], window_length: int | None,
                  allow_outside: bool = False) -> tuple[list[dict[str, Any]], dict[str, Estimator]]:
    """:func:`predict` with each target's own model (:func:`model_files`).

    Parameters
    ----------
    files
        ``{None: file}`` or device → file.
    items
        The targets.
    window_length
        Window length for models that take any length (None: :data:`DEFAULT_WINDOW`).
    allow_outside
        As in :func:`predict`.

    Returns
    -------
    results, models
        One result per target, in order (with ``model``, the file, when ``files`` is per
        device; a device the set has no model for gets an error naming the devices it has);
        the loaded models by file.
    """
    per_device = None not in files
    results: list[dict[str, Any] | None] = [None] * len(items)
    groups: dict[Path, list[int]] = {}
    for i, t in enumerate(items):
        file = files.get(t.device) if per_device else files[None]
        if file is None and t.recording is None:  # unreadable: that is its error, whatever the model
            results[i] = {"file": str(t.path), "device": t.device, "g_local": t.g_local, "error": t.problem}
            continue
        if file is None:
            results[i] = {"file": str(t.path), "device": t.device, "g_local": t.g_local,
                          "error": f"no model for device {t.device!r} in this model set (it has one for "
                                   f"{', '.join(sorted(str(d) for d in files))})"}
            continue
        groups.setdefault(file, []).append(i)
    models: dict[str, Estimator] = {}
    for file, index in groups.items():
        model = load_model(file)
        models[str(file)] = model
        length = window_length_of(model) or (window_length if window_length is not None else DEFAULT_WINDOW)
        entries = predict(model, [items[i] for i in index], length, allow_outside)
        for i, entry in zip(index, entries, strict=True):
            if per_device:
                entry = {**entry, "model": str(file)}
            results[i] = entry
    return [r for r in results if r is not None], models


def window_length_of(model: Estimator) -> int | None:
    """The window length a model needs, samples (None: any)."""
    keras_model = getattr(model, "model_", None)
    if keras_model is not None:
        return int(keras_model.input_shape[1])
    return None


def _read_bare(path: Path) -> Recording:
    with open(path, "rb") as fh:
        head = fh.read(4096)
    if b"Memsense" in head or b"MSCIP" in head.upper():
        return read_mscip_csv(path)
    return read_ofbe_logger(path)


def targets(paths: Sequence[str | Path], device: str | None, g_local: float | None) -> list[Target]:
    """The device files named by the arguments (sessions expanded), read."""
    out: list[Target] = []
    for arg in paths:
        p = Path(arg)
        if p.is_file() and p.name == MANIFEST_NAME:
            p = p.parent
        if (p / MANIFEST_NAME).is_file():
            m = load_manifest(p)
            for rec in m.recordings:
                for dev in m.duts:
                    path = m.file_path(rec, dev.id)
                    try:
                        out.append(Target(path, dev.id, m.g_local, read_device_file(path, dev)))
                    except OfbeError as exc:
                        out.append(Target(path, dev.id, m.g_local, problem=str(exc)))
        elif p.is_file():
            try:
                rec = _read_bare(p)
                name = device or rec.header.get("device") or p.stem
                out.append(Target(p, name, g_local or STANDARD_GRAVITY, rec))
            except OfbeError as exc:
                text = str(exc).removeprefix(f"{p}: ")  # the result names the file already
                out.append(Target(p, device or p.stem, g_local or STANDARD_GRAVITY,
                                  problem=f"{text}; {BARE_FILES}"))
        else:
            raise EstimatorError(f"{p}: expected a session folder or a raw device file, found no such path")
    return out


def still_run(rec: Recording, margin_s: float = 1.0, static: StaticParams | None = None) -> tuple[int, int]:
    """The longest still run of a recording less ``margin_s`` where it borders motion: the
    segment ``ofbe-label`` takes from a file without taps.

    Returns
    -------
    start, stop
        Half-open sample range (``stop <= start``: no still part longer than the margins).
    """
    check = check_static(rec.acc, rec.fs_hz, static or StaticParams())
    a, b = longest_run(check.static)
    margin = int(round(margin_s * rec.fs_hz))
    if a > 0:
        a += margin
    if b < rec.n:
        b -= margin
    return a, b


def first_still_window(rec: Recording, length: int, margin_s: float = 1.0,
                       static: StaticParams | None = None) -> tuple[np.ndarray | None, int, str]:
    """The first ``length`` samples of the longest still run of a recording (:func:`still_run`).

    Returns
    -------
    window, run_samples, problem
        (length, 3) m/s² or None with the reason.
    """
    a, b = still_run(rec, margin_s, static)
    n = max(0, b - a)
    if n < length:
        return None, n, f"{n} still samples, at least {length} needed"
    return rec.acc[a:a + length], n, ""


def _in_counts(rec: Recording) -> bool:
    """Whether the file holds raw counts scaled by a stated lsb_per_g (as ``ofbe-label`` judges)."""
    return rec.format == "ofbe-logger" or rec.header.get("acc_unit") == "counts"


def file_problem(rec: Recording, g: float, params: LabelParams | None = None) -> str | None:
    """What makes ``ofbe-label`` reject a whole file, as ``"reason: detail"``, or None.

    The same checks and words (:mod:`ofbe_data.labelling.checks`): too many skipped lines
    (``garbled``), a sample rate no logger has (``implausible-rate``), readings whose typical
    norm is no resting norm (``implausible-norm``). ``params``: ``ofbe-label``'s defaults when None.
    """
    params = params or LabelParams()
    garbled = skipped_lines_problem(rec.diagnostics, params.max_skipped_fraction, rec.header)
    if garbled is not None:
        return f"{GARBLED}: {garbled}"
    rate = rate_problem(rec.fs_hz, rec.nominal_rate_hz)
    if rate is not None and rate[1]:
        return f"{IMPLAUSIBLE_RATE}: {rate[0]}"
    norm = typical_norm_problem(rec.acc, g, params.max_norm_deviation, _in_counts(rec))
    if norm is not None:
        return f"{IMPLAUSIBLE_NORM}: {norm}"
    return None


def segment_problem(rec: Recording, start: int, stop: int, where: str = "the stationary segment",
                    ) -> str | None:
    """Saturated, clipped, dead or stuck samples in ``rec`` [start, stop), as
    ``"saturated: detail"`` in ``ofbe-label``'s words, or None.

    Parameters
    ----------
    rec
        The recording.
    start, stop
        Half-open sample range (the still run, or the window the model sees).
    where
        How the detail names the range.
    """
    flags = rec.saturated[start:stop]
    sat = int(flags.sum())
    if sat:
        first = int(rec.line[start + int(np.argmax(flags))])
        return f"{SATURATED}: {sat} saturated samples in {where} (first at line {first})"
    if stop - start < 2:
        return None
    scale = rec.full_scale
    clipped = clipped_samples(rec.acc[start:stop], bounds=None if scale is None else (scale.low, scale.high))
    if clipped is None:
        return None
    count, k, value, whole = clipped
    if whole:
        return (f"{SATURATED}: the {'xyz'[k]} axis reads {value:.5g} m/s² on every sample of {where} while "
                "the others vary: clipped at the logger's range, or stuck (record with a wider range)")
    return (f"{SATURATED}: {count} of {stop - start} samples of {where} sit at the same extreme "
            f"{'xyz'[k]} value {value:.5g} m/s², more than {MIN_CLIP_RATIO:g} times the value next to it: "
            "clipping at the logger's range? (record with a wider range)")


def plausibility_problem(rec: Recording, g: float, run: tuple[int, int], length: int) -> str | None:
    """Why ``ofbe-label`` would reject this recording, judged as it judges a file without taps
    (:func:`file_problem`, then :func:`segment_problem` on the still run), or why the first
    ``length`` samples of that run, the window the model sees, are saturated or stuck; None
    when neither.

    Parameters
    ----------
    rec
        The recording.
    g
        Local gravity, m/s².
    run
        Its still run, (start, stop) samples (:func:`still_run`).
    length
        Samples of the model's window.
    """
    bad = file_problem(rec, g)
    a, b = run
    if bad is not None or b <= a:
        return bad  # no still part: no window either, which the caller reports
    bad = segment_problem(rec, a, b)
    if bad is None and b - a > length:
        bad = segment_problem(rec, a, a + length, "the window the model sees")
    return bad


def trained_on(model: Estimator) -> str | None:
    """One line on the model's training data (None for models saved without the record)."""
    domain: TrainingDomain | None = getattr(model, "domain_", None)
    return None if domain is None else domain.describe()


def _screen(model: Estimator, t: Target, w: np.ndarray, allow_outside: bool, entry: dict[str, Any]) -> bool:
    """Plausibility and training-domain checks of one window; False when it gets no estimate."""
    assert t.recording is not None
    norm = norm_problem(w.mean(axis=0), t.g_local, counts=_in_counts(t.recording))
    if norm is not None:
        entry["error"] = f"{IMPLAUSIBLE_NORM}: {norm}"
        return False
    refusals, warns = domain_problems(getattr(model, "domain_", None), t.device, t.recording.fs_hz,
                                      window_direction(w))
    if refusals and not allow_outside:
        entry["error"] = ("outside the training domain: " + "; ".join(refusals)
                          + " (--allow-outside-domain to estimate anyway)")
        return False
    if refusals:
        entry["outside_domain"] = "; ".join(refusals)
    if refusals or warns:
        entry["warnings"] = refusals + warns
    return True


def predict(model: Estimator, items: Sequence[Target], length: int, allow_outside: bool = False
            ) -> list[dict[str, Any]]:
    """One result per target: bias (and std) or the problem.

    A recording that ``ofbe-label`` would reject (:func:`plausibility_problem`: garbled,
    implausible rate or norm, saturated, clipped, dead or stuck axes, in its words) gets no
    estimate, nor a window whose ‖mean‖ is implausible for its local gravity (a unit mistake, methods.md
    §9) or whose sample rate lies outside the model's training domain (the
    latter unless ``allow_outside``, and then the result carries ``outside_domain`` with the
    reasons): a sample rate, device or gravity direction the model was not trained on.
    """
    results: list[dict[str, Any]] = []
    ready, windows = [], []
    for t in items:
        entry: dict[str, Any] = {"file": str(t.path), "device": t.device, "g_local": t.g_local}
        if t.recording is None:
            entry["error"] = t.problem
        else:
            a, b = still_run(t.recording)
            n = max(0, b - a)
            w = t.recording.acc[a:a + length] if n >= length else None
            entry["still_samples"] = n
            entry["fs_hz"] = round(float(t.recording.fs_hz), 6)
            implausible = plausibility_problem(t.recording, t.g_local, (a, b), length)
            if implausible is not None:
                entry["error"] = implausible
            elif w is None:
                entry["error"] = f"{n} still samples, at least {length} needed"
            elif _screen(model, t, w, allow_outside, entry):
                ready.append(len(results))
                windows.append(w)
        results.append(entry)
    if windows:
        X = np.stack(windows).astype(np.float32)
        meta = pd.DataFrame({"device": [results[i]["device"] for i in ready],
                             "g_local": [results[i]["g_local"] for i in ready],
                             "fs_hz": [results[i]["fs_hz"] for i in ready]})
        bias = np.asarray(model.predict(X, meta), dtype=np.float64)
        std = np.asarray(model.predict_std(X, meta), dtype=np.float64) if model.has_std else None
        for j, i in enumerate(ready):
            if not (np.isfinite(bias[j]).all() and (std is None or np.isfinite(std[j]).all())):
                results[i]["error"] = ("the model's estimate is not finite (NaN or inf): the model file is "
                                       "broken (non-finite weights?); retrain or re-export it")
                continue
            results[i]["bias_m_s2"] = [round(float(v), 9) for v in bias[j]]
            results[i]["std_m_s2"] = None if std is None else [round(float(v), 9) for v in std[j]]
            results[i]["window_samples"] = length
    return results


