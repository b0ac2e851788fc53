"""``ofbe-predict MODEL RECORDING...``: bias of new stationary recordings from a saved model.

MODEL is a saved OFBENet (``.keras``, loaded in Keras' safe mode) or a fitted
``gravity-prior`` (``.json``). A RECORDING is a session folder (every DUT file of every
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
window whose ‖mean‖ is far from g_local (a unit mistake) none at all. Exit 0 when every file
got an estimate, 1 when some could not (a one-line reason each; the others are still printed), 2 on a usage
error.
"""

from __future__ import annotations

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
from ofbe_data.labelling.checks import norm_problem
from ofbe_data.labelling.stationarity import StaticParams, check_static, longest_run
from ofbe_model.estimators.base import Estimator, EstimatorError
from ofbe_model.estimators.domain import TrainingDomain, domain_problems, window_direction

DEFAULT_WINDOW = 3000


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
                out.append(Target(p, device or p.stem, g_local or STANDARD_GRAVITY, problem=str(exc)))
        else:
            raise EstimatorError(f"{p}: expected a session folder or a raw device file, found no such path")
    return out


def first_still_window(rec: Recording, length: int, margin_s: float = 1.0,
                       static: StaticParams | None = None) -> tuple[np.ndarray | None, int, str]:
    """The first ``length`` samples of the longest still run of a recording.

    Returns
    -------
    window, run_samples, problem
        (length, 3) m/s² or None with the reason.
    """
    check = check_static(rec.acc, rec.fs_hz, static or StaticParams())
    a, b = longest_run(check.static)
    margin = int(round(margin_s * rec.fs_hz))
    if a > 0:
        a += margin
    if b < rec.n:
        b -= margin
    n = max(0, b - a)
    if n < length:
        return None, n, f"{n} still samples, at least {length} needed"
    return rec.acc[a:a + length], n, ""


def trained_on(model: Estimator) -> str | None:
    """One line on the model's training data (None for models saved without the record)."""
    domain: TrainingDomain | None = getattr(model, "domain_", None)
    return None if domain is None else domain.describe()


def _screen(model: Estimator, t: Target, w: np.ndarray, allow_outside: bool, entry: dict[str, Any]) -> bool:
    """Plausibility and training-domain checks of one window; False when it gets no estimate."""
    assert t.recording is not None
    norm = norm_problem(w.mean(axis=0), t.g_local)
    if norm is not None:
        entry["error"] = f"implausible-norm: {norm}"
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

    A window whose ‖mean‖ is implausible for its local gravity (a unit mistake, methods.md
    §9) or whose sample rate lies outside the model's training domain gets no estimate (the
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
            w, n, problem = first_still_window(t.recording, length)
            entry["still_samples"] = n
            entry["fs_hz"] = round(float(t.recording.fs_hz), 6)
            if w is None:
                entry["error"] = problem
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
            results[i]["bias_m_s2"] = [round(float(v), 9) for v in bias[j]]
            results[i]["std_m_s2"] = None if std is None else [round(float(v), 9) for v in std[j]]
            results[i]["window_samples"] = length
    return results


