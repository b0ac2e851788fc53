"""What the estimators cost on an ESP32-class device: sizes, int8 accuracy, latency, memory.

Usage::

    python benchmarks/on_device.py [DATASET] [--model MODEL.keras] [--runs N]

``DATASET`` is a windowed dataset folder (default ``processed/datasets/rotated``); ``--model``
an OFBENet trained by ``ofbe-train`` on it (default: the first, in sorted order, of
``models/cv/<campaign>*/grouped/fold-0.seed-0.keras``). The model's folder names its benchmark
dataset, protocol and fold (``<models>/<dataset>/<protocol>/fold-<k>.seed-<s>.keras``); the
benchmark uses that fold's training windows as the int8 representative set (and to fit a
gravity-prior) and its test signals to score. It prints:

- sizes in bytes: the ``.keras`` file, the float32 and int8 ``.tflite`` files, the C header's
  tables;
- RMSE on the fold's test signals of Keras, the float32 and the int8 TFLite models (LiteRT
  interpreter) and of the gravity-prior, in Python and as the compiled C function;
- latency per window on this machine (mean of ``--runs``): the LiteRT interpreter on one
  window (built-in kernels, no delegate) and the C function; plus multiply-accumulates per
  window, which carry over to a device better than host timings;
- what fits an ESP32 (520 KB SRAM, 4 MB flash): model bytes (flash) and the tensor-arena
  estimate (:func:`ofbe_model.deploy.tflite.arena_estimate`, RAM).

Nothing is written outside a temporary folder. Needs ``ai-edge-litert`` and a C compiler.
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

SRAM_BYTES = 520 * 1024
FLASH_BYTES = 4 * 1024 * 1024
MODEL_NAME = re.compile(r"fold-(\d+)\.seed-(\d+)\.keras")


def default_model(dataset: Path) -> Path | None:
    """The first ``models/cv/<campaign>*/grouped/fold-0.seed-0.keras``, if any."""
    found = sorted(Path("models/cv").glob(f"{dataset.name}*/grouped/fold-0.seed-0.keras"))
    return found[0] if found else None


def rmse(err: np.ndarray) -> float:
    """sqrt(mean ‖e‖²), m/s²."""
    return float(np.sqrt(np.mean(np.sum(np.asarray(err, dtype=np.float64) ** 2, axis=1))))


def macs(content: bytes) -> int:
    """Multiply-accumulates of one invocation: CONV_2D, DEPTHWISE_CONV_2D and FULLY_CONNECTED."""
    from tensorflow.lite.python import schema_py_generated as schema

    flat = schema.ModelT.InitFromPackedBuf(content, 0)
    graph = flat.subgraphs[0]
    total = 0
    for op in graph.operators:
        code = flat.operatorCodes[op.opcodeIndex]
        builtin = max(int(code.builtinCode), int(code.deprecatedBuiltinCode))
        if builtin not in (3, 4, 9):
            continue
        out = graph.tensors[op.outputs[0]].shape
        weights = graph.tensors[op.inputs[1]].shape
        if builtin == 3:  # CONV_2D: weights (out_ch, kh, kw, in_ch)
            total += int(np.prod(out)) * int(np.prod(weights[1:]))
        elif builtin == 4:  # DEPTHWISE_CONV_2D: weights (1, kh, kw, ch)
            total += int(np.prod(out)) * int(weights[1] * weights[2])
        elif builtin == 9:  # FULLY_CONNECTED: weights (out, in)
            total += int(np.prod(out)) * int(weights[1])
    return total


def latency(interpreter: Any, window: np.ndarray, runs: int) -> float:
    """Mean seconds of ``invoke`` on one window (after one warm-up call)."""
    inp = interpreter.get_input_details()[0]
    interpreter.set_tensor(inp["index"], window)
    interpreter.invoke()
    t = time.perf_counter()
    for _ in range(runs):
        interpreter.set_tensor(inp["index"], window)
        interpreter.invoke()
    return (time.perf_counter() - t) / runs


def kib(n: float) -> str:
    return f"{n / 1024:.1f} KiB"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("dataset", nargs="?", default="processed/datasets/rotated", help="windowed dataset folder")
    p.add_argument("--model",
                   help="OFBENet .keras file (default: models/cv/<campaign>*/grouped/fold-0.seed-0.keras)")
    p.add_argument("--runs", type=int, default=200, help="invocations timed per model (default 200)")
    args = p.parse_args(argv)
    dataset = Path(args.dataset)
    model_path = Path(args.model) if args.model else default_model(dataset)
    if model_path is None or not model_path.is_file():
        where = model_path or f"models/cv/{dataset.name}*/grouped/fold-0.seed-0.keras"
        print(f"on_device: no trained model at {where}."
              f"\nTrain one (fold 0, one seed, ~1 min on two cores) with:\n"
              f"    ofbe-train {dataset} --protocol grouped --folds 0 --seeds 1 --out models\n"
              f"or pass --model.", file=sys.stderr)
        return 1
    match = MODEL_NAME.fullmatch(model_path.name)
    if match is None:
        print(f"on_device: {model_path}: expected a model named fold-<k>.seed-<s>.keras inside "
              f"<models>/<dataset>/<protocol>/ (as ofbe-train writes), found another name", file=sys.stderr)
        return 1
    fold, protocol, bench_name = int(match.group(1)), model_path.parent.name, model_path.parent.parent.name

    from ofbe_data import load_dataset
    from ofbe_data.dataset.folds import protocol_splits
    from ofbe_model.deploy.c_header import (
        compile_harness,
        device_indices,
        export_c_header,
        run_harness,
        table_bytes,
    )
    from ofbe_model.deploy.tflite import (
        arena_estimate,
        export_tflite,
        load_interpreter,
        quantise_input,
        run_tflite,
    )
    from ofbe_model.estimators.priors import GravityPrior
    from ofbe_model.ofbenet.network import OFBENet
    from ofbe_model.ofbenet.training import dataset_dirname

    ds = load_dataset(dataset)
    splits = [s for s in protocol_splits(ds.meta, str(ds.info["kind"]), protocol)
              if dataset_dirname(s.dataset) == bench_name and s.fold == fold]
    if not splits:
        print(f"on_device: {model_path}: expected {bench_name} fold {fold} of protocol {protocol} in "
              f"{dataset}, found none", file=sys.stderr)
        return 1
    split = splits[0]
    x_tr, y_tr = ds.X[split.train], ds.y[split.train]
    x_te, y_te = ds.X[split.test], ds.y[split.test]
    meta_tr = ds.meta.iloc[split.train].reset_index(drop=True)
    meta_te = ds.meta.iloc[split.test].reset_index(drop=True)
    print(f"{dataset}: {split.dataset}, {protocol} fold {fold}: {len(split.train)} training windows "
          f"(representative set), {len(split.test)} test signals of {ds.X.shape[1]} x 3 samples")
    print(f"model: {model_path}")

    with tempfile.TemporaryDirectory(prefix="ofbe-on-device-") as tmp:
        work = Path(tmp)
        t = time.perf_counter()
        sidecar = export_tflite(model_path, work, x_tr, name="ofbenet",
                                source=f"{dataset} {split.dataset} {protocol} fold {fold} training windows")
        export_s = time.perf_counter() - t
        f32, i8 = work / "ofbenet.float32.tflite", work / "ofbenet.int8.tflite"
        keras_pred = OFBENet.load(model_path).predict(x_te, meta_te)
        f32_pred = run_tflite(f32, x_te)
        i8_pred = run_tflite(i8, x_te, sidecar)
        arena = {k: arena_estimate(path) for k, path in (("float32", f32), ("int8", i8))}
        mac = macs(f32.read_bytes())
        lat_f32 = latency(load_interpreter(f32), x_te[:1].astype(np.float32), args.runs)
        lat_i8 = latency(load_interpreter(i8), quantise_input(x_te[:1], sidecar), args.runs)

        prior = GravityPrior(direction_model=True).fit(x_tr, y_tr, meta_tr)
        header = export_c_header(prior, work / "gravity_prior.h", name="gravity_prior")
        exe = compile_harness(header, work / "build")
        repeats = max(1, args.runs // max(1, len(x_te)))
        c_bias, _, status, c_seconds = run_harness(exe, x_te, meta_te["g_local"].to_numpy(),
                                                   device_indices(prior, meta_te["device"]), work / "build",
                                                   repeats=repeats)
        py_bias = prior.predict(x_te, meta_te)
        header_bytes, tables = header.stat().st_size, table_bytes(prior)

    keras_bytes = model_path.stat().st_size
    f32_bytes, i8_bytes = sidecar["models"]["float32"]["bytes"], sidecar["models"]["int8"]["bytes"]
    print(f"\nsizes (bytes; export took {export_s:.1f} s)")
    print(f"  keras file              {keras_bytes:>9d}")
    print(f"  float32 .tflite         {f32_bytes:>9d}")
    print(f"  int8 .tflite            {i8_bytes:>9d}")
    print(f"  C header tables         {tables:>9d}   (header source {header_bytes} bytes, "
          f"{len(prior.means_)} device(s))")
    r_keras, r_f32, r_i8 = rmse(keras_pred - y_te), rmse(f32_pred - y_te), rmse(i8_pred - y_te)
    print(f"\nRMSE on {len(y_te)} test signals (m/s^2; label RMS {rmse(y_te):.5f})")
    print(f"  OFBENet keras           {r_keras:.5f}")
    print(f"  OFBENet float32 tflite  {r_f32:.5f}   "
          f"(max |tflite - keras| {np.abs(f32_pred - keras_pred).max():.2e})")
    print(f"  OFBENet int8 tflite     {r_i8:.5f}   ({100 * (r_i8 / r_f32 - 1):+.2f} % vs float32; "
          f"max |int8 - float32| {np.abs(i8_pred - f32_pred).max():.4f})")
    print(f"  gravity-prior (direction model) Python {rmse(py_bias - y_te):.5f}, C {rmse(c_bias - y_te):.5f} "
          f"(max |C - Python| {np.abs(c_bias - py_bias).max():.2e}; status {sorted(set(status.tolist()))})")
    print(f"\nlatency per window on this host (mean of {args.runs} runs)")
    print(f"  LiteRT float32          {1e3 * lat_f32:8.3f} ms")
    print(f"  LiteRT int8             {1e3 * lat_i8:8.3f} ms")
    print(f"  C gravity-prior         {1e3 * c_seconds:8.3f} ms   (-O2, {repeats} x {len(x_te)} calls)")
    print(f"  OFBENet: {mac / 1e6:.2f} M multiply-accumulates per window; the C prior: "
          f"~{4 * 3 * ds.X.shape[1]} flops for the window mean plus a few hundred per device")
    print(f"\nESP32 (SRAM {kib(SRAM_BYTES)}, flash {FLASH_BYTES // 2**20} MiB)")
    for kind, size in (("float32", f32_bytes), ("int8", i8_bytes)):
        a = arena[kind]
        verdict = "fits" if a["arena_bytes"] < SRAM_BYTES and size < FLASH_BYTES else "does NOT fit"
        share = 100 * a["arena_bytes"] / SRAM_BYTES
        print(f"  OFBENet {kind:8s} flash {kib(size):>10s} ({100 * size / FLASH_BYTES:.1f} %), "
              f"arena estimate {kib(a['arena_bytes']):>10s} ({share:.0f} % of SRAM): {verdict}")
    print(f"  gravity-prior C  flash {kib(tables):>10s} of tables, RAM: the caller's window "
          f"({kib(12 * ds.X.shape[1])} as float32) and < 1 KiB of stack: fits")
    print("  (not all of the 520 KiB is free for data: part is instruction RAM and the rest is shared with "
          "the firmware; check heap_caps_get_free_size() on the device.)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
