"""``ofbe-predict``: a saved model's bias estimates for session folders or bare device files
(ofbe_model.predict).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Sequence
from typing import Any

from ofbe_data.core.cli import EXIT_USAGE, add_verbose, command, fail, quiet_libraries, with_examples
from ofbe_data.core.errors import OfbeError
from ofbe_data.io.gravity import G0 as STANDARD_GRAVITY
from ofbe_model.deploy.defaults import DEFAULT_WINDOW, MODEL_FILES

PROG = "ofbe-predict"
MIN_WINDOW = 2
"""Fewest samples a window may have (a mean and a spread need two)."""


def _table(results: Sequence[dict[str, Any]], method: str) -> str:
    g0 = 9.80665e-3
    head = "".join(f"{h:>14}" for h in ("bias x (mg)", "bias y (mg)", "bias z (mg)")) + "".join(
        f"{h:>13}" for h in ("std x (mg)", "std y (mg)", "std z (mg)"))
    lines = [f"{'device':<14}{head}  file   ({method}; 1 mg = 9.80665e-3 m/s²)"]
    for r in results:
        if "error" in r:
            lines.append(f"{r['device']:<14}{'—':>14}{'—':>14}{'—':>14}{'':>39}  {r['file']}: {r['error']}")
            continue
        b = [v / g0 for v in r["bias_m_s2"]]
        s = ["" if r["std_m_s2"] is None else f"{v / g0:.2f}" for v in (r["std_m_s2"] or [None] * 3)]
        cells = "".join(f"{v:14.2f}" for v in b) + "".join(f"{v:>13}" for v in s)
        lines.append(f"{r['device']:<14}{cells}  {r['file']}")
    return "\n".join(lines)


def _gravity(text: str) -> float:
    """``--g-local``: a finite gravity magnitude, m/s² (1–30: anywhere a board can rest)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number in m/s², found {text!r}") from None
    if not (math.isfinite(value) and 1.0 <= value <= 30.0):
        raise argparse.ArgumentTypeError(f"expected a finite gravity in m/s² (1 to 30), found {text!r}")
    return value


def _finite(obj: Any) -> Any:
    """``obj`` with every non-finite float replaced by None (JSON has no NaN)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite(v) for v in obj]
    return obj


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="ofbe-predict",
                                description="Bias (and its standard deviation, where the method has one) of "
                                            "stationary recordings from a saved OFBENet or gravity-prior.")
    p.add_argument("model", help="saved model: .keras (OFBENet) or .json (gravity-prior), or a folder of "
                                 "deployed models (models/<dataset>; a folder with models.json holds one "
                                 "model per device and each recording gets its own device's)")
    p.add_argument("--estimator", choices=tuple(MODEL_FILES), default="ofbenet",
                   help="which deployed model of a folder MODEL (default: %(default)s)")
    p.add_argument("recordings", nargs="+", help="session folders or raw device files")
    p.add_argument("--device", help="device id for bare files (gravity-prior uses its per-device prior)")
    p.add_argument("--g-local", type=_gravity,
                   help=f"local gravity for bare files, m/s² (default: {STANDARD_GRAVITY})")
    p.add_argument("--window-length", type=int, help="samples per window for models that take any length "
                                                     f"(default: {DEFAULT_WINDOW})")
    p.add_argument("--output", choices=("json", "table"), default="json",
                   help="json: one object per file on stdout, for ofbe-export; table: for reading")
    p.add_argument("--allow-outside-domain", action="store_true",
                   help="estimate even where the device, sample rate or gravity direction is outside what "
                        "the model was trained on (each such result says why in 'outside_domain')")
    add_verbose(p)
    return with_examples(
        p, "ofbe-predict models/rotated raw/rotated/rot-pc001                 # each board its own model",
        "ofbe-predict models/rotated raw/rotated/rot-pc001 --estimator gravity-prior --output table",
        "ofbe-predict models/gravity-aligned/final.keras mine/log.csv --device adxl-1 --g-local 9.8066")


@command(PROG)
def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``ofbe-predict``: 0 every file estimated, 1 a file failed, 2 usage."""
    return _run(_parser().parse_args(argv))


def _run(args: argparse.Namespace) -> int:
    """``ofbe-predict`` on its parsed arguments; the model's modules are imported here, after
    parsing and after the libraries' start-up lines are quietened (docs/architecture.md,
    "Command lines")."""
    quiet_libraries(args.verbose)
    from ofbe_model.estimators.base import EstimatorError
    from ofbe_model.predict import model_files, predict_files, targets, trained_on

    if args.window_length is not None and args.window_length < MIN_WINDOW:
        return fail(PROG, f"--window-length: expected an integer >= {MIN_WINDOW} (samples), found "
                          f"{args.window_length}", EXIT_USAGE)
    try:
        files = model_files(args.model, args.estimator)
        items = targets(args.recordings, args.device, args.g_local)
        results, models = predict_files(files, items, args.window_length, args.allow_outside_domain)
    except OfbeError as exc:
        print(f"ofbe-predict: error: {exc}", file=sys.stderr)
        return 2 if isinstance(exc, EstimatorError) else 1
    methods = sorted({getattr(m, "name", type(m).__name__) for m in models.values()})
    method = ", ".join(methods) or args.estimator
    domains = {file: trained_on(m) for file, m in models.items()}
    domain: Any = next(iter(domains.values()), None) if None in files else domains
    if args.output == "json":
        print(json.dumps(_finite({"model": str(args.model), "method": method, "trained_on": domain,
                                  "results": results}), indent=1, allow_nan=False))
    else:
        print(_table(results, method))
    for file, text in domains.items():
        where = "" if None in files else f" ({file})"
        text = text or "unknown data (a model saved before ofbe kept its training domain)"
        print(f"ofbe-predict: {method}{where} trained on {text}", file=sys.stderr)
    for r in results:
        for w in r.get("warnings", ()):
            print(f"ofbe-predict: warning: {r['file']}: {w}", file=sys.stderr)
    failed = [r for r in results if "error" in r]
    for r in failed:
        print(f"ofbe-predict: error: {r['file']}: {r['error']}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
