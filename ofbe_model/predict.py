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
methods that have one, its standard deviation. Exit 0 when every file got an estimate, 1
when some could not (a one-line reason each; the others are still printed), 2 on a usage
error.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ofbe_data.errors import OfbeError
from ofbe_data.gravity import G0 as STANDARD_GRAVITY
from ofbe_data.manifest import MANIFEST_NAME, load_manifest
from ofbe_data.rawio import read_device_file, read_mscip_csv, read_ofbe_logger
from ofbe_data.recording import Recording
from ofbe_data.stationarity import StaticParams, check_static, longest_run
from ofbe_model.base import Estimator, EstimatorError

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
        from ofbe_model.ofbenet import OFBENet

        return OFBENet.load(path)
    if path.suffix == ".json":
        from ofbe_model.estimators import GravityPrior

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


def predict(model: Estimator, items: Sequence[Target], length: int) -> list[dict[str, Any]]:
    """One result per target: bias (and std) or the problem."""
    results: list[dict[str, Any]] = []
    ready, windows = [], []
    for t in items:
        entry: dict[str, Any] = {"file": str(t.path), "device": t.device, "g_local": t.g_local}
        if t.recording is None:
            entry["error"] = t.problem
        else:
            w, n, problem = first_still_window(t.recording, length)
            entry["still_samples"] = n
            if w is None:
                entry["error"] = problem
            else:
                ready.append(len(results))
                windows.append(w)
        results.append(entry)
    if windows:
        X = np.stack(windows).astype(np.float32)
        meta = pd.DataFrame({"device": [results[i]["device"] for i in ready],
                             "g_local": [results[i]["g_local"] for i in ready]})
        bias = np.asarray(model.predict(X, meta), dtype=np.float64)
        std = np.asarray(model.predict_std(X, meta), dtype=np.float64) if model.has_std else None
        for j, i in enumerate(ready):
            results[i]["bias_m_s2"] = [round(float(v), 9) for v in bias[j]]
            results[i]["std_m_s2"] = None if std is None else [round(float(v), 9) for v in std[j]]
            results[i]["window_samples"] = length
    return results


def _table(results: Sequence[dict[str, Any]], method: str) -> str:
    g0 = 9.80665e-3
    head = "".join(f"{h:>9}" for h in ("bias x", "bias y", "bias z")) + "".join(
        f"{h:>8}" for h in ("std x", "std y", "std z"))
    lines = [f"{'device':<14}{head}  file   ({method}; mg)"]
    for r in results:
        if "error" in r:
            lines.append(f"{r['device']:<14}{'—':>9}{'—':>9}{'—':>9}{'':>24}  {r['file']}: {r['error']}")
            continue
        b = [v / g0 for v in r["bias_m_s2"]]
        s = ["" if r["std_m_s2"] is None else f"{v / g0:.2f}" for v in (r["std_m_s2"] or [None] * 3)]
        cells = "".join(f"{v:9.2f}" for v in b) + "".join(f"{v:>8}" for v in s)
        lines.append(f"{r['device']:<14}{cells}  {r['file']}")
    return "\n".join(lines)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="ofbe-predict",
                                description="Bias (and its standard deviation, where the method has one) of "
                                            "stationary recordings from a saved OFBENet or gravity-prior.")
    p.add_argument("model", help="saved model: .keras (OFBENet) or .json (gravity-prior)")
    p.add_argument("recordings", nargs="+", help="session folders or raw device files")
    p.add_argument("--device", help="device id for bare files (gravity-prior uses its per-device prior)")
    p.add_argument("--g-local", type=float,
                   help=f"local gravity for bare files, m/s² (default {STANDARD_GRAVITY})")
    p.add_argument("--window-length", type=int, help="samples per window for models that take any length "
                                                     f"(default {DEFAULT_WINDOW})")
    p.add_argument("--output", choices=("json", "table"), default="json")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        model = load_model(args.model)
        length = window_length_of(model) or args.window_length or DEFAULT_WINDOW
        items = targets(args.recordings, args.device, args.g_local)
        results = predict(model, items, length)
    except OfbeError as exc:
        print(f"ofbe-predict: error: {exc}", file=sys.stderr)
        return 2 if isinstance(exc, EstimatorError) else 1
    method = getattr(model, "name", type(model).__name__)
    if args.output == "json":
        print(json.dumps({"model": str(args.model), "method": method, "results": results}, indent=1))
    else:
        print(_table(results, method))
    failed = [r for r in results if "error" in r]
    for r in failed:
        print(f"ofbe-predict: error: {r['file']}: {r['error']}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
