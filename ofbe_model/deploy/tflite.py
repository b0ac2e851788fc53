"""OFBENet as TensorFlow Lite for ESP32-class devices (products.md §Exports, ``tflite``).

:func:`export_tflite` writes three files into one folder:

``<name>.float32.tflite``
    The whole model in float32, both scalings inside the graph: a raw (1, T, 3) window in
    m/s² (sensor frame, row-major samples × axes) in, the (1, 3) bias in m/s² out.
``<name>.int8.tflite``
    Full-integer quantisation (every operator int8, int8 input and output tensors, weights
    per channel), calibrated on a representative set of windows. The scaling layers are
    *outside* this graph: the firmware standardises each sample per axis (float, or folded
    into the quantisation) and de-standardises the three outputs, with the constants of the
    sidecar. Keeping them outside lets the int8 input tensor resolve the standardised signal
    rather than raw m/s², where gravity (~9.8 m/s² on one axis) would take most of the 256
    levels of a per-tensor scale.
``<name>.tflite.json``
    The sidecar (format ``ofbe-tflite/1``): input shape and units, both models' sizes and
    SHA-256, the int8 input and output scale and zero point with the standardisation
    constants and the exact formulas (:func:`quantise_input`, :func:`dequantise_output` are
    their reference implementation), the representative set's size and source, and the ofbe
    and TensorFlow versions.

Conversion goes through a copy of the Keras model rebuilt as a chain of its own layers on a
fixed (1, T, 3) input (``TFLiteConverter.from_keras_model``; a ``tf.function`` concrete
function would keep Keras 3's resource variables as ``READ_VARIABLE`` ops that int8
calibration cannot run). The rebuilt chains are checked against the original model's output
before anything is written. BatchNormalization folds into the convolutions and Dropout
vanishes; the graph holds RESHAPE, CONV_2D, LEAKY_RELU, AVERAGE_POOL_2D, MEAN and
FULLY_CONNECTED (plus ADD and MUL for the float model's input scaling; its output scaling
folds into the last FULLY_CONNECTED), all TFLite Micro builtins.

Determinism: with one TensorFlow version, the same model and the same representative set
give byte-identical files (the tests convert twice); the converter embeds no time stamp.
Another TensorFlow version may give other bytes.

Running a model needs the LiteRT interpreter (``pip install ai-edge-litert``, in the dev
extra): :func:`load_interpreter`, :func:`run_tflite`, :func:`arena_estimate`. Exporting does
not.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import sys
import tempfile
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from ofbe_data import __version__
from ofbe_data.core.atomic import write_bytes_atomic
from ofbe_data.core.cli import VERBOSE_ENV, import_tensorflow
from ofbe_model.deploy.final import CARD_JSON, ModelCardError, dataset_hash
from ofbe_model.estimators.base import EstimatorError
from ofbe_model.ofbenet.layers import model_scalings
from ofbe_model.ofbenet.network import OFBENet

tf = import_tensorflow()  # before keras: TensorFlow's start-up lines stay off the terminal
import keras  # noqa: E402

TFLITE_FORMAT = "ofbe-tflite/1"
"""``format`` field of the sidecar."""
UNITS = "m/s^2"
"""Units of the windows and biases, as written in the sidecar."""
MAX_REPRESENTATIVE = 500
"""Default cap on the windows used to calibrate the int8 model (evenly spaced over those given)."""
INPUT_FORMULA = ("q[t][a] = clamp(round_half_away((x[t][a] - standardise_mean[a]) / standardise_std[a] "
                 "/ scale) + zero_point, -128, 127)  (x in m/s^2; C: lroundf)")
OUTPUT_FORMULA = "b[a] = (q[a] - zero_point) * scale * destandardise_std[a] + destandardise_mean[a]  (m/s^2)"

_NAME_CHARS = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-.")
_R = TypeVar("_R")


# ---------------------------------------------------------------------------------------------
# Small helpers


def check_name(name: str, what: str = "name") -> str:
    """A file stem for exported files: letters, digits, ``_ - .``, starting with a letter.

    Raises
    ------
    EstimatorError
        Anything else (the message names ``what``).
    """
    if not (isinstance(name, str) and name and name[0].isalpha() and set(name) <= _NAME_CHARS):
        raise EstimatorError(f"{what}: expected a file stem of letters, digits, '_', '-' and '.', starting "
                             f"with a letter, found {name!r}")
    return name


class CardDatasetMismatch(ModelCardError):
    """A model card whose training data is not the dataset given to calibrate the int8 model on."""


def check_card_dataset(model: str | Path, dataset: str | Path) -> None:
    """Refuse to calibrate a model on a dataset other than the one its card records.

    The ``model_card.json`` beside ``model`` (:mod:`ofbe_model.deploy.final`) states the SHA-256
    of its training dataset's ``SHA256SUMS`` (``training_data.sha256sums_sha256``); ``dataset``
    must have that hash. A model with no card, or a card about another file, is not checked.

    Raises
    ------
    CardDatasetMismatch
        The card states no hash, the dataset has no ``SHA256SUMS``, or the hashes differ (the
        message names the card, the hash it states and the dataset's).
    """
    model, dataset = Path(model), Path(dataset)
    card_file = model.parent / CARD_JSON
    try:
        card = json.loads(card_file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return  # no card (or none readable): card_dataset says so where the card is needed
    files = card.get("files") if isinstance(card, dict) else None
    if not isinstance(files, dict) or files.get("ofbenet") != model.name:
        return
    data = card.get("training_data")
    stated = data.get("sha256sums_sha256") if isinstance(data, dict) else None
    try:
        actual: str | None = dataset_hash(dataset)
    except OSError:
        actual = None
    if not (isinstance(stated, str) and stated):
        why = (f"{card_file}: training_data: expected the SHA-256 of the training dataset's SHA256SUMS "
               f"(sha256sums_sha256) to check {dataset} against, found none")
    elif actual is None:
        why = f"{dataset}: expected a dataset with a SHA256SUMS to check against {card_file}, found none"
    elif actual != stated:
        why = (f"{card_file}: states training data whose SHA256SUMS has SHA-256 {stated}, but {dataset} has "
               f"{actual}: the int8 model would be calibrated on windows it was not trained on")
    else:
        return
    raise CardDatasetMismatch(f"{why}; pass the dataset the model was trained on (--dataset DIR), or "
                              "retrain and redeploy the model on this one (its card then records it); "
                              "nothing written")


def _verbose() -> bool:
    return os.environ.get(VERBOSE_ENV, "") not in ("", "0")


def _quietly(what: str, fn: Callable[[], _R]) -> _R:
    """Run ``fn`` with file descriptors 1 and 2 and Python's warnings captured.

    The TFLite converter prints to both from C++ (MLIR diagnostics, "fully_quantize: …") and
    from Python (the SavedModel it writes on the way, UserWarnings); none of it reaches the
    terminal unless ``OFBE_VERBOSE=1``. On failure the captured text's last lines go into
    the :class:`EstimatorError`.
    """
    if _verbose():
        return fn()
    sys.stdout.flush()
    sys.stderr.flush()
    with tempfile.TemporaryFile() as log:
        saved = (os.dup(1), os.dup(2))
        try:
            os.dup2(log.fileno(), 1)
            os.dup2(log.fileno(), 2)
            with warnings.catch_warnings(), contextlib.redirect_stdout(io.StringIO()), \
                    contextlib.redirect_stderr(io.StringIO()):
                warnings.simplefilter("ignore")
                try:
                    return fn()
                except EstimatorError:
                    raise
                except Exception as exc:
                    log.seek(0)
                    lines = [ln for ln in log.read().decode("utf-8", "replace").splitlines() if ln.strip()]
                    text = str(exc).strip()
                    first = text.splitlines()[-1][:300] if text else type(exc).__name__
                    tail = f" (converter log: {lines[-1][:200]})" if lines else ""
                    raise EstimatorError(f"{what}: expected a TensorFlow Lite conversion, found an error: "
                                         f"{first}{tail}") from exc
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])


def _load(model: OFBENet | str | Path) -> tuple[keras.Model, str | None]:
    if isinstance(model, OFBENet):
        fitted = getattr(model, "model_", None)
        if fitted is None:
            raise EstimatorError("model: expected a fitted or loaded OFBENet, found one without a model "
                                 "(call fit or OFBENet.load)")
        return fitted, None
    if isinstance(model, str | Path):
        return OFBENet.load(model).model_, str(model)
    raise EstimatorError(f"model: expected an OFBENet or the path of a .keras file, found "
                         f"{type(model).__name__}")


def _chains(model: keras.Model, where: str) -> tuple[keras.Model, keras.Model, list[np.ndarray]]:
    """A copy of ``model`` as two fixed-batch chains: whole, and without its scaling layers.

    Returns
    -------
    full
        (1, T, 3) m/s² → (1, 3) m/s².
    core
        (1, T, 3) standardised → (1, 3) standardised bias.
    constants
        float32 x_mean, x_scale (1/std), y_mean, y_std, each (3,): the model computes
        ``(x − x_mean) · x_scale`` first and ``z · y_std + y_mean`` last.

    Raises
    ------
    EstimatorError
        The model does not start with the input scaling layers and end with the target
        scaling (:func:`ofbe_model.ofbenet.layers.model_scalings`).
    """
    consts = list(model_scalings(model, where))
    window_length = int(model.inputs[0].shape[1])
    copy = keras.models.clone_model(model)
    copy.set_weights(model.get_weights())

    def chain(part: list[keras.layers.Layer], name: str) -> keras.Model:
        x = inputs = keras.Input(shape=(window_length, 3), batch_size=1, name="window")
        for layer in part:
            x = layer(x)
        return keras.Model(inputs, x, name=name)

    full = chain(copy.layers[1:], "ofbenet")
    core = chain(copy.layers[3:-1], "ofbenet_int8_core")
    return full, core, consts


def _standardised(windows: np.ndarray, x_mean: np.ndarray, x_scale: np.ndarray) -> np.ndarray:
    """Windows as the model's input scaling makes them: ``(x − x_mean) · x_scale`` in float32."""
    return ((np.asarray(windows, dtype=np.float32) - x_mean) * x_scale).astype(np.float32)


def _check_chains(model: keras.Model, full: keras.Model, core: keras.Model, consts: list[np.ndarray],
                  windows: np.ndarray, where: str) -> None:
    """Both chains must reproduce the model on a few windows (they are a chain, not a DAG)."""
    x_mean, x_scale, y_mean, y_std = consts
    for w in windows[:4]:
        ref = np.asarray(model(w[None], training=False))
        got_full = np.asarray(full(w[None], training=False))
        z = np.asarray(core(_standardised(w[None], x_mean, x_scale), training=False))
        got_core = z * y_std + y_mean
        tol = 1e-5 * max(1.0, float(np.abs(ref).max()))
        if not (np.allclose(got_full, ref, rtol=1e-5, atol=tol) and np.allclose(got_core, ref, rtol=1e-4,
                                                                                 atol=tol)):
            raise EstimatorError(f"{where}: expected a model whose layers form one chain (OFBENet), found a "
                                 f"graph the chain copy does not reproduce ({ref.ravel()} vs "
                                 f"{got_full.ravel()})")


def _convert(model: keras.Model, representative: np.ndarray | None, where: str) -> bytes:
    """TFLite bytes of a Keras model: float32, or full-integer int8 calibrated on ``representative``."""
    def run() -> bytes:
        converter = tf.lite.TFLiteConverter.from_keras_model(model)
        if representative is not None:
            def windows() -> Iterator[list[np.ndarray]]:
                for i in range(representative.shape[0]):
                    yield [representative[i:i + 1]]

            converter.optimizations = [tf.lite.Optimize.DEFAULT]
            converter.representative_dataset = windows
            converter.target_spec.supported_ops = [tf.lite.OpsSet.TFLITE_BUILTINS_INT8]
            converter.inference_input_type = tf.int8
            converter.inference_output_type = tf.int8
        return bytes(converter.convert())

    return _quietly(where, run)


def _representative(windows: Any, window_length: int, limit: int) -> tuple[np.ndarray, int]:
    """(k, T, 3) float32 windows evenly spaced over those given, and how many were given."""
    try:
        x = np.asarray(windows, dtype=np.float32)
    except (TypeError, ValueError) as exc:
        raise EstimatorError(f"representative: expected an array of windows (N, T, 3) in m/s^2, found "
                             f"{type(windows).__name__} ({exc})") from None
    if x.ndim != 3 or x.shape[1:] != (window_length, 3) or x.shape[0] == 0:
        raise EstimatorError(f"representative: expected windows of shape (N >= 1, {window_length}, 3) m/s^2 "
                             f"(the model's window length), found shape {x.shape}")
    if not np.isfinite(x).all():
        raise EstimatorError("representative: expected finite values, found NaN or infinity")
    if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
        raise EstimatorError(f"max_representative: expected an integer >= 1, found {limit!r}")
    n = x.shape[0]
    keep = np.unique(np.linspace(0, n - 1, min(n, limit)).round().astype(np.int64))
    return np.ascontiguousarray(x[keep]), n


def _io_quantisation(content: bytes) -> tuple[tuple[float, int], tuple[float, int]]:
    """(scale, zero_point) of the input and of the output tensor of a TFLite flatbuffer."""
    schema = _schema()
    model = schema.ModelT.InitFromPackedBuf(content, 0)
    graph = model.subgraphs[0]
    out = []
    for index in (graph.inputs[0], graph.outputs[0]):
        q = graph.tensors[index].quantization
        if q is None or q.scale is None or len(q.scale) != 1:
            raise EstimatorError("int8 model: expected one scale and zero point on its input and output "
                                 "tensors, found none (the converter did not quantise them)")
        out.append((float(np.float32(q.scale[0])), int(q.zeroPoint[0])))
    return out[0], out[1]


def _schema() -> Any:
    """The TFLite flatbuffer schema module (generated code shipped with TensorFlow)."""
    try:
        from tensorflow.lite.python import schema_py_generated
    except ImportError:  # pragma: no cover - a TensorFlow without it
        from ai_edge_litert import schema_py_generated
    return schema_py_generated


# ---------------------------------------------------------------------------------------------
# Export


def export_tflite(model: OFBENet | str | Path, out_dir: str | Path, representative: np.ndarray, *,
                  name: str = "ofbenet", source: str = "windows given by the caller",
                  max_representative: int = MAX_REPRESENTATIVE) -> dict[str, Any]:
    """Write OFBENet as float32 and full-integer int8 TensorFlow Lite models plus a JSON sidecar.

    Parameters
    ----------
    model
        A fitted :class:`OFBENet`, or the path of a ``.keras`` file (:meth:`OFBENet.load`).
    out_dir
        Folder of the three files (created).
    representative
        (N, T, 3) windows in m/s² (sensor frame) to calibrate the int8 model on: training
        windows, never test signals. At most ``max_representative`` of them are used,
        evenly spaced over the N given.
    name
        Stem of the files: ``<name>.float32.tflite``, ``<name>.int8.tflite``,
        ``<name>.tflite.json``.
    source
        Where the representative windows come from, recorded in the sidecar.
    max_representative
        Cap on the calibration windows.

    Returns
    -------
    dict
        The sidecar as written (JSON-ready); ``sidecar["files"]`` names the three files,
        relative to ``out_dir``.

    Raises
    ------
    EstimatorError
        A model that cannot be read or is not an OFBENet chain, representative windows of the
        wrong shape or not finite, a bad name, or a failed conversion (naming what failed).
    """
    name = check_name(name)
    keras_model, model_path = _load(model)
    where = model_path or "model"
    window_length = int(keras_model.inputs[0].shape[1])
    windows, given = _representative(representative, window_length, max_representative)
    full, core, consts = _chains(keras_model, where)
    _check_chains(keras_model, full, core, consts, windows, where)
    x_mean, x_scale, y_mean, y_std = consts
    x_std = (1.0 / x_scale.astype(np.float64)).astype(np.float32)  # the training std to 1 float32 ulp
    standardised = _standardised(windows, x_mean, x_scale)
    float_bytes = _convert(full, None, f"{where} (float32)")
    int8_bytes = _convert(core, standardised, f"{where} (int8)")
    (in_scale, in_zero), (out_scale, out_zero) = _io_quantisation(int8_bytes)
    files = {"float32": f"{name}.float32.tflite", "int8": f"{name}.int8.tflite",
             "sidecar": f"{name}.tflite.json"}

    def described(content: bytes, dtype: str) -> dict[str, Any]:
        return {"file": files[dtype], "bytes": len(content), "sha256": hashlib.sha256(content).hexdigest(),
                "input_dtype": dtype, "output_dtype": dtype}

    sidecar: dict[str, Any] = {
        "format": TFLITE_FORMAT,
        "name": name,
        "ofbe_version": __version__,
        "tensorflow_version": tf.__version__,
        "source_model": model_path,
        "files": files,
        "window_length": window_length,
        "input_shape": [1, window_length, 3],
        "output_shape": [1, 3],
        "input_layout": "row-major (sample, axis): x0 y0 z0 x1 y1 z1 ..., sensor frame",
        "input_units": UNITS,
        "output_units": UNITS,
        "representative": {"windows_used": int(windows.shape[0]), "windows_given": given,
                           "selection": "evenly spaced over the windows given", "source": source},
        "deterministic_bytes": "yes for one TensorFlow version, model and representative set",
        "models": {
            "float32": {**described(float_bytes, "float32"),
                        "scaling": "inside the graph: raw m/s^2 in, m/s^2 out"},
            "int8": {**described(int8_bytes, "int8"),
                     "scaling": "outside the graph: standardise the input and de-standardise the output "
                                "with the constants below",
                     "input": {"scale": in_scale, "zero_point": in_zero,
                               "standardise_mean": x_mean.tolist(), "standardise_std": x_std.tolist(),
                               "units": UNITS, "formula": INPUT_FORMULA},
                     "output": {"scale": out_scale, "zero_point": out_zero,
                                "destandardise_mean": y_mean.tolist(), "destandardise_std": y_std.tolist(),
                                "units": UNITS, "formula": OUTPUT_FORMULA}},
        },
    }
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_bytes_atomic(out / files["float32"], float_bytes)
    write_bytes_atomic(out / files["int8"], int8_bytes)
    write_bytes_atomic(out / files["sidecar"],
                       (json.dumps(sidecar, indent=2, allow_nan=False) + "\n").encode("utf-8"))
    return sidecar


# ---------------------------------------------------------------------------------------------
# The sidecar's formulas, and running a model


def quantise_input(windows: np.ndarray, sidecar: dict[str, Any]) -> np.ndarray:
    """Raw windows as the int8 model's input, as the firmware computes it.

    Parameters
    ----------
    windows
        (N, T, 3) m/s².
    sidecar
        The dict :func:`export_tflite` wrote.

    Returns
    -------
    np.ndarray
        (N, T, 3) int8: ``clamp(round_half_away((x − mean)/std/scale) + zero_point, −128, 127)``.
    """
    info = sidecar["models"]["int8"]["input"]
    mean = np.asarray(info["standardise_mean"], dtype=np.float32)
    std = np.asarray(info["standardise_std"], dtype=np.float32)
    z = ((np.asarray(windows, dtype=np.float32) - mean) / std) / np.float32(info["scale"])
    q = np.sign(z) * np.floor(np.abs(z) + np.float32(0.5)) + info["zero_point"]
    return np.clip(q, -128, 127).astype(np.int8)


def dequantise_output(q: np.ndarray, sidecar: dict[str, Any]) -> np.ndarray:
    """The int8 model's output as biases in m/s²: (N, 3) int8 → (N, 3) float64."""
    info = sidecar["models"]["int8"]["output"]
    z = (np.asarray(q, dtype=np.float64) - info["zero_point"]) * info["scale"]
    return z * np.asarray(info["destandardise_std"]) + np.asarray(info["destandardise_mean"])


def load_interpreter(model: str | Path | bytes) -> Any:
    """A LiteRT interpreter with tensors allocated, on the built-in kernels (no delegates).

    Parameters
    ----------
    model
        A ``.tflite`` file or its bytes.

    Raises
    ------
    EstimatorError
        ``ai-edge-litert`` not installed, or a file it cannot read.
    """
    try:
        from ai_edge_litert.interpreter import Interpreter, OpResolverType
    except ImportError:
        raise EstimatorError("ai_edge_litert: expected the LiteRT interpreter to run a .tflite model "
                             "(pip install ai-edge-litert), found it not installed") from None
    kwargs = {"model_content": model} if isinstance(model, bytes) else {"model_path": str(model)}
    try:
        interpreter = Interpreter(**kwargs,
                                  experimental_op_resolver_type=OpResolverType.BUILTIN_WITHOUT_DEFAULT_DELEGATES)
        interpreter.allocate_tensors()
    except (ValueError, RuntimeError) as exc:
        where = "model bytes" if isinstance(model, bytes) else str(model)
        raise EstimatorError(f"{where}: expected a TensorFlow Lite model, found an error: {exc}") from None
    return interpreter


def run_tflite(model: str | Path | bytes, windows: np.ndarray, sidecar: dict[str, Any] | None = None,
               ) -> np.ndarray:
    """Biases from an exported model, one window per invocation (as on the device).

    Parameters
    ----------
    model
        ``<name>.float32.tflite`` or ``<name>.int8.tflite`` (path or bytes).
    windows
        (N, T, 3) m/s².
    sidecar
        Required for the int8 model: its input is quantised with :func:`quantise_input` and
        its output read with :func:`dequantise_output`.

    Returns
    -------
    np.ndarray
        (N, 3) float64 m/s².

    Raises
    ------
    EstimatorError
        Windows of another shape than the model's input, or an int8 model without a sidecar.
    """
    interpreter = load_interpreter(model)
    inp = interpreter.get_input_details()[0]
    out = interpreter.get_output_details()[0]
    x = np.asarray(windows, dtype=np.float32)
    if x.ndim != 3 or tuple(x.shape[1:]) != tuple(inp["shape"][1:]):
        raise EstimatorError(f"windows: expected shape (N, {inp['shape'][1]}, 3) m/s^2, found {x.shape}")
    quantised = inp["dtype"] == np.int8
    if quantised and sidecar is None:
        raise EstimatorError("sidecar: expected the .tflite.json sidecar to quantise the int8 model's "
                             "input, found none")
    if quantised and sidecar is not None:
        x = quantise_input(x, sidecar)
    result = np.empty((x.shape[0], 3), dtype=np.float64)
    for i in range(x.shape[0]):
        interpreter.set_tensor(inp["index"], x[i:i + 1])
        interpreter.invoke()
        result[i] = interpreter.get_tensor(out["index"])[0]
    if quantised and sidecar is not None:
        result = dequantise_output(result, sidecar)
    return result


#: TFLite builtin operator codes whose int8 kernels keep per-output-channel multipliers and shifts.
_PER_CHANNEL_OPS = frozenset({3, 4, 9})  # CONV_2D, DEPTHWISE_CONV_2D, FULLY_CONNECTED
#: Bytes per element of TFLite tensor types: float32, f16, i32, u8, i64, bool, i16, i8, f64.
_DTYPE_BYTES = {0: 4, 1: 2, 2: 4, 3: 1, 4: 8, 6: 1, 7: 2, 9: 1, 10: 8}


def arena_estimate(model: str | Path | bytes, alignment: int = 16) -> dict[str, int]:
    """An estimate of the TFLite Micro tensor arena a model needs (not a measurement).

    Activations: every non-constant tensor (the input and each operator's outputs) lives
    from the operator that writes it to the last one that reads it, padded to
    ``alignment`` bytes; the peak of the live bytes over the operators is what a greedy
    planner needs at least (RESHAPE outputs are counted as copies, so it errs high).
    Persistent: 16 bytes per tensor and 64 per operator (TFLM's evaluation structs), plus
    8 bytes per output channel of int8 convolutions and fully connected layers (their
    per-channel multipliers and shifts).

    Parameters
    ----------
    model
        A ``.tflite`` file or its bytes.
    alignment
        Byte alignment of every tensor.

    Returns
    -------
    dict
        ``activations_bytes``, ``persistent_bytes``, ``arena_bytes`` (their sum), ``ops``,
        ``tensors``.
    """
    content = model if isinstance(model, bytes) else Path(model).read_bytes()
    schema = _schema()
    try:
        flat = schema.ModelT.InitFromPackedBuf(content, 0)
    except Exception as exc:  # the generated flatbuffer code raises anything on a bad buffer
        raise EstimatorError(f"{'model bytes' if isinstance(model, bytes) else model}: expected a TensorFlow "
                             f"Lite flatbuffer, found an unreadable file ({exc})") from None
    graph = flat.subgraphs[0]
    ops = list(graph.operators or [])

    def size(index: int) -> int:
        t = graph.tensors[index]
        n = int(np.prod(t.shape)) if t.shape is not None else 1
        return -(-n * _DTYPE_BYTES.get(int(t.type), 4) // alignment) * alignment

    first = {int(i): 0 for i in graph.inputs}
    last = {int(i): len(ops) for i in graph.outputs}
    for k, op in enumerate(ops):
        for i in op.outputs:
            first.setdefault(int(i), k)
        for i in op.inputs:
            if int(i) in first:
                last[int(i)] = max(last.get(int(i), k), k)
    peak = max((sum(size(i) for i in first if first[i] <= k <= last.get(i, first[i]))
                for k in range(len(ops) + 1)), default=0)
    channels = 0
    for op in ops:
        code = flat.operatorCodes[op.opcodeIndex]
        builtin = max(int(code.builtinCode), int(code.deprecatedBuiltinCode))
        weights = graph.tensors[op.inputs[1]] if len(op.inputs) > 1 else None
        if builtin in _PER_CHANNEL_OPS and weights is not None and int(weights.type) == 9:
            channels += int(weights.shape[0] if builtin != 4 else weights.shape[-1])
    persistent = 16 * len(graph.tensors) + 64 * len(ops) + 8 * channels
    return {"activations_bytes": int(peak), "persistent_bytes": int(persistent),
            "arena_bytes": int(peak + persistent), "ops": len(ops), "tensors": len(graph.tensors)}
