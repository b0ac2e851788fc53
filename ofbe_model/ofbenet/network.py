"""OFBENet: the paper's CNN bias estimator (methods.md §OFBENet, paper §3.3–3.4).

Architecture (fixed by the paper)::

    Input (T, 3) m/s²
    → input scaling (x − mean) · (1/std)    (inside the model: two keras Rescaling layers)
    → 3 × [Conv1D(kernel 5; 8, 32, 64 filters) → BatchNormalization
           → LeakyReLU(negative_slope=0.1) → AveragePooling1D(pool_size)]
    → GlobalAveragePooling1D → Dense(dense_units) → Dropout(dropout) → Dense(3)
    → target de-scaling z · std + mean      (inside the model: keras Rescaling)
    → (3,) m/s²

trained with MSE, Adam (lr 0.01), batch 8, ReduceLROnPlateau(factor 0.2, patience 15) and
EarlyStopping(patience 5, best weights restored). What the paper leaves open is a field of
:class:`OFBENetParams` with a documented default.

Both scalings live *inside* the Keras model as Keras' own ``Rescaling`` layers with their
constants in the layer config (:mod:`ofbe_model.ofbenet.layers`), so the network is built
from built-in Keras layers only: a saved ``.keras`` file maps raw m/s² windows to m/s²
biases on its own and loads with plain Keras 3, ``keras.saving.load_model(path)`` (safe mode),
in an interpreter that never imports ofbe, predicting what :meth:`OFBENet.predict` does (tested):
no Lambda layers, no custom classes, no pickled Python, no side files to keep in step.

Determinism: :meth:`OFBENet.fit` calls :func:`keras.utils.set_random_seed` (Python, NumPy
and TensorFlow seeds) and, without XLA, :func:`tf.config.experimental.enable_op_determinism`.
Both are process-wide: after such a fit every TensorFlow op in the process runs in
deterministic mode (some ops get slower, a few without a deterministic kernel raise). Keras
turns XLA off whenever op determinism is on, so ``jit_compile=True`` fits leave it off and
rely on XLA's CPU code being deterministic by itself (it is in the tests); a
``jit_compile=True`` fit in a process where an earlier fit already enabled op determinism
runs without XLA (Keras warns). On CPU, two fits of the same data with the same parameters
give bit-identical weights either way; the two settings do not give the same weights as
each other.
"""

from __future__ import annotations

import json
import os
import tempfile
import time
import warnings
import zipfile
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import pandas as pd

from ofbe_data.core.cli import import_tensorflow
from ofbe_data.core.errors import ConfigError
from ofbe_model.estimators.base import Estimator, EstimatorError, check_inputs, register
from ofbe_model.estimators.domain import TrainingDomain, domain_of
from ofbe_model.ofbenet.layers import LEGACY_OBJECTS, build_ofbenet, upgrade_legacy
from ofbe_model.ofbenet.params import (
    EVAL_BATCH,
    KERAS_FILES,
    PARAM_NAMES,
    REFUSED_CLASSES,
    SIDECAR_FORMAT,
    SIDECAR_NAME,
    STD_FLOOR,
    OFBENetParams,
)
from ofbe_model.ofbenet.trainer import copy_state, prescale, trainer_for

tf = import_tensorflow()  # before keras: TensorFlow's start-up lines stay off the terminal
import keras  # noqa: E402

# ---------------------------------------------------------------------------------------------
# Validation split and scaling statistics


def group_validation_split(meta: pd.DataFrame, fraction: float, seed: int) -> np.ndarray:
    """Which windows validate: whole (device, power_cycle) groups, dealt per device.

    For each device, ``round(fraction · n_groups)`` of its groups (at least one when the
    device has two or more) are drawn at random and all their windows validate.

    Parameters
    ----------
    meta
        One row per training window with ``device`` and ``power_cycle``.
    fraction
        Share of each device's groups to hold out, in [0, 1).
    seed
        Seed of the draw.

    Returns
    -------
    np.ndarray
        (N,) bool, True for validation windows.

    Raises
    ------
    EstimatorError
        No ``power_cycle`` column, or fewer than two groups in all (nothing to hold out).
    """
    n = len(meta)
    if fraction <= 0:
        return np.zeros(n, dtype=bool)
    if "power_cycle" not in meta.columns:
        raise EstimatorError("meta: expected a power_cycle column to hold out whole bias instances for "
                             "validation (or validation_split=0), found none")
    rng = np.random.default_rng(seed)
    device = meta["device"].astype(str).to_numpy()
    cycle = meta["power_cycle"].to_numpy()
    val = np.zeros(n, dtype=bool)
    for d in sorted(set(device)):
        mine = device == d
        groups = np.unique(cycle[mine])
        if groups.size < 2:
            continue
        k = min(groups.size - 1, max(1, int(round(fraction * groups.size))))
        held = rng.choice(groups, size=k, replace=False)
        val |= mine & np.isin(cycle, held)
    if not val.any():
        raise EstimatorError(f"meta: expected at least two (device, power_cycle) groups for a validation "
                             f"split of {fraction:g}, found {len(set(zip(device, cycle, strict=True)))}")
    return val


def scaling_constants(windows: np.ndarray, labels: np.ndarray,
                      params: OFBENetParams) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Input and target scaling constants from training data.

    Parameters
    ----------
    windows
        (N, T, 3) m/s².
    labels
        (N, 3) m/s².
    params
        ``input_scaling`` and ``target_scaling`` pick the rule (see :class:`OFBENetParams`).

    Returns
    -------
    x_mean, x_std, y_mean, y_std
        Each (3,) float64, m/s²; identity (0, 1) where the scaling is ``"none"``.
    """
    ones, zeros = np.ones(3), np.zeros(3)
    if params.input_scaling == "none":
        x_mean, x_std = zeros, ones
    else:
        axes = (0, 1) if params.input_scaling == "per-axis-standardise" else None
        x_mean = np.broadcast_to(windows.mean(axis=axes, dtype=np.float64), (3,)).copy()
        x_std = np.broadcast_to(windows.std(axis=axes, dtype=np.float64), (3,)).copy()
    if params.target_scaling == "none":
        y_mean, y_std = zeros, ones
    else:
        y_mean = labels.mean(axis=0)
        y_std = labels.std(axis=0)
    x_std = np.where(x_std > STD_FLOOR, x_std, 1.0)
    y_std = np.where(y_std > STD_FLOOR, y_std, 1.0)
    return x_mean, x_std, y_mean, y_std


def _op_determinism_enabled() -> bool:
    """Whether TensorFlow's op determinism is on (no public getter exists; Keras uses this one)."""
    try:
        from tensorflow.python.framework.config import is_op_determinism_enabled
    except ImportError:  # pragma: no cover - a TensorFlow without it
        return False
    return bool(is_op_determinism_enabled())


def _batches(n: int, size: int) -> Iterator[slice]:
    for start in range(0, n, size):
        yield slice(start, min(n, start + size))


def _plain_history(history: Mapping[str, Sequence[Any]]) -> dict[str, list[float]]:
    return {str(k): [float(v) for v in vals] for k, vals in history.items()}


# ---------------------------------------------------------------------------------------------
# The estimator


@register
class OFBENet(Estimator):
    """The paper's CNN behind the estimator interface.

    Parameters
    ----------
    pool_size, dense_units, dense_activation, dropout, input_scaling, target_scaling, max_epochs,
    validation_split, learning_rate, batch_size, lr_factor, lr_patience, es_patience, seed, jit_compile
        As :class:`OFBENetParams` (same names, same defaults); stored unchanged, checked in :meth:`fit`.

    Attributes
    ----------
    model_
        The fitted :class:`keras.Model`: raw (N, T, 3) m/s² windows → (N, 3) m/s² biases.
    history_
        Per-epoch training record, ``{"loss": [...], "val_loss": [...], "learning_rate":
        [...]}`` (``val_loss`` only with a validation split). Losses are MSEs of the training
        targets: dimensionless with ``target_scaling="standardise"``, (m/s²)² otherwise.
    window_length_
        T the model was trained on, samples.
    n_train_, n_val_
        Windows trained on and validated on.
    best_epoch_
        1-based epoch whose weights were kept (lowest monitored loss).
    fit_seconds_
        Wall time of :meth:`fit`, s.
    """

    name: ClassVar[str] = "ofbenet"
    order: ClassVar[int] = 60
    needs_fit: ClassVar[bool] = True

    def __init__(self, *, pool_size: int = OFBENetParams.pool_size,
                 dense_units: int = OFBENetParams.dense_units,
                 dense_activation: str = OFBENetParams.dense_activation,
                 dropout: float = OFBENetParams.dropout,
                 input_scaling: str = OFBENetParams.input_scaling,
                 target_scaling: str = OFBENetParams.target_scaling,
                 max_epochs: int = OFBENetParams.max_epochs,
                 validation_split: float = OFBENetParams.validation_split,
                 learning_rate: float = OFBENetParams.learning_rate,
                 batch_size: int = OFBENetParams.batch_size,
                 lr_factor: float = OFBENetParams.lr_factor,
                 lr_patience: int = OFBENetParams.lr_patience,
                 es_patience: int = OFBENetParams.es_patience,
                 seed: int = OFBENetParams.seed,
                 jit_compile: bool = OFBENetParams.jit_compile) -> None:
        self.pool_size = pool_size
        self.dense_units = dense_units
        self.dense_activation = dense_activation
        self.dropout = dropout
        self.input_scaling = input_scaling
        self.target_scaling = target_scaling
        self.max_epochs = max_epochs
        self.validation_split = validation_split
        self.learning_rate = learning_rate
        self.batch_size = batch_size
        self.lr_factor = lr_factor
        self.lr_patience = lr_patience
        self.es_patience = es_patience
        self.seed = seed
        self.jit_compile = jit_compile

    @classmethod
    def from_params(cls, params: OFBENetParams) -> OFBENet:
        """A new estimator with the values of ``params``."""
        return cls(**params.to_dict())

    @property
    def params(self) -> OFBENetParams:
        """The current parameters, checked.

        Raises
        ------
        EstimatorError
            A parameter out of range (the message names it).
        """
        try:
            return OFBENetParams(**self.get_params())
        except ConfigError as exc:
            raise EstimatorError(f"ofbenet: {exc}") from None

    # -- training ---------------------------------------------------------------------------

    def fit(self, windows: np.ndarray, labels: np.ndarray, meta: pd.DataFrame, *,
            verbose: int = 0, on_epoch: Callable[[int, dict[str, float]], None] | None = None,
            ) -> OFBENet:
        """Train on windows and their labels.

        Parameters
        ----------
        windows
            (N, T, 3) m/s², sensor frame.
        labels
            (N, 3) apparent-bias labels, m/s².
        meta
            N rows with ``device`` and ``g_local`` and, when ``validation_split`` > 0,
            ``power_cycle`` (validation holds out whole bias instances).
        verbose
            Keras progress: 0 silent, 2 one line per epoch (1, a progress bar, also works).
        on_epoch
            Called after every epoch with the 1-based epoch and its logs (``loss``,
            ``val_loss``…): a caller's own progress display (``ofbe-train``'s bar).

        Returns
        -------
        self

        Raises
        ------
        EstimatorError
            Bad shapes or meta, a bad parameter, a window too short for the network, too few
            groups to validate on, or a loss that became NaN or infinite.
        """
        params = self.params
        check_inputs(windows, meta, labels)
        x = np.asarray(windows, dtype=np.float32)
        y = np.asarray(labels, dtype=np.float64)
        if not (np.isfinite(x).all() and np.isfinite(y).all()):
            raise EstimatorError("windows, labels: expected finite values, found NaN or infinity")
        t0 = time.perf_counter()
        keras.utils.set_random_seed(params.seed)
        if not params.jit_compile:
            # Keras turns XLA off whenever op determinism is on, so it is only enabled without XLA
            tf.config.experimental.enable_op_determinism()
        elif _op_determinism_enabled():
            warnings.warn("ofbenet: jit_compile=True, but op determinism is already enabled in this process "
                          "(by an earlier fit without XLA), so Keras trains without XLA: the weights differ "
                          "from a fit with XLA in a fresh process", UserWarning, stacklevel=2)
        val = group_validation_split(meta.reset_index(drop=True), params.validation_split, params.seed)
        x_tr, y_tr = x[~val], y[~val]
        if x_tr.shape[0] == 0:
            raise EstimatorError("meta: expected training windows left after the validation split, "
                                 "found none")
        x_mean, x_std, y_mean, y_std = scaling_constants(x_tr, y_tr, params)
        model = build_ofbenet(int(x.shape[1]), params, x_mean, x_std, y_mean, y_std)
        trainer = trainer_for(model, params, int(x_tr.shape[0]), int(val.sum()))  # compiled once per process

        def target(v: np.ndarray) -> np.ndarray:
            return ((v - y_mean) / y_std).astype(np.float32)

        monitor = "val_loss" if val.any() else "loss"
        callbacks = [
            keras.callbacks.TerminateOnNaN(),
            keras.callbacks.ReduceLROnPlateau(monitor=monitor, factor=params.lr_factor,
                                              patience=params.lr_patience, verbose=0),
            keras.callbacks.EarlyStopping(monitor=monitor, patience=params.es_patience,
                                          restore_best_weights=True, verbose=0),
        ]
        if on_epoch is not None:
            callbacks.append(keras.callbacks.LambdaCallback(
                on_epoch_end=lambda epoch, logs: on_epoch(epoch + 1, dict(logs or {}))))
        validation = (prescale(model, x[val]), target(y[val])) if val.any() else None
        fit = {"batch_size": params.batch_size, "epochs": params.max_epochs, "verbose": verbose}
        hist = trainer.fit(prescale(model, x_tr), target(y_tr), validation_data=validation,
                           validation_batch_size=EVAL_BATCH, shuffle=True, callbacks=callbacks, **fit)
        copy_state(trainer, model)
        history = _plain_history(hist.history)
        losses = np.asarray(history.get(monitor, []), dtype=np.float64)
        if losses.size == 0 or not np.isfinite(losses).all():
            raise EstimatorError(f"ofbenet: expected a finite {monitor} in every epoch, found "
                                 f"{losses.tolist()} (training diverged: lower learning_rate)")
        self.model_ = model
        self.history_ = history
        self.window_length_ = int(x.shape[1])
        self.n_train_ = int(x_tr.shape[0])
        self.n_val_ = int(val.sum())
        self.best_epoch_ = int(np.argmin(losses)) + 1
        self.fit_seconds_ = time.perf_counter() - t0
        self.domain_ = domain_of(windows, meta)
        return self

    # -- prediction -------------------------------------------------------------------------

    def _check_fitted(self) -> keras.Model:
        model = getattr(self, "model_", None)
        if model is None:
            raise EstimatorError("ofbenet: expected a fitted or loaded model, found none (call fit or load)")
        return model

    def predict(self, windows: np.ndarray, meta: pd.DataFrame) -> np.ndarray:
        """Bias estimates.

        Parameters
        ----------
        windows
            (N, T, 3) m/s² with the T the model was trained on.
        meta
            N rows (``device``, ``g_local``; not otherwise used).

        Returns
        -------
        np.ndarray
            (N, 3) float64, m/s².

        Raises
        ------
        EstimatorError
            No model yet, bad shapes or meta, or a window length the model was not built for.
        """
        model = self._check_fitted()
        check_inputs(windows, meta)
        x = np.asarray(windows, dtype=np.float32)
        t = int(model.inputs[0].shape[1])
        if x.shape[1] != t:
            raise EstimatorError(f"windows: expected windows of {t} samples (what the model was trained on), "
                                 f"found {x.shape[1]}")
        out = np.empty((x.shape[0], 3), dtype=np.float64)
        # called eagerly: the same kernels and numbers as predict_on_batch (checked bit for bit),
        # without tracing a graph for each loaded model (the benchmark loads one per fold and seed)
        for s in _batches(x.shape[0], EVAL_BATCH):
            out[s] = np.asarray(model(x[s], training=False), dtype=np.float64)
        return out

    # -- persistence ------------------------------------------------------------------------

    def _sidecar(self) -> dict[str, Any]:
        return {"format": SIDECAR_FORMAT, "estimator": self.name, "params": self.params.to_dict(),
                "window_length": getattr(self, "window_length_", None),
                "history": getattr(self, "history_", None), "n_train": getattr(self, "n_train_", None),
                "n_val": getattr(self, "n_val_", None), "best_epoch": getattr(self, "best_epoch_", None),
                "fit_seconds": getattr(self, "fit_seconds_", None),
                "training_domain": None if getattr(self, "domain_", None) is None else self.domain_.to_dict(),
                "versions": {"keras": keras.__version__, "tensorflow": tf.__version__}}

    def save(self, path: str | Path) -> Path:
        """Write the model as one ``.keras`` file, atomically.

        The Keras archive (architecture with both scalings, weights) gets one more member,
        :data:`SIDECAR_NAME`, with the estimator's parameters and training history as JSON.
        The file is written under a temporary name in the same folder and renamed, so a
        reader sees the old file or the complete new one.

        Parameters
        ----------
        path
            Target file, ending in ``.keras``; its folder is created.

        Returns
        -------
        Path
            The written file.

        Raises
        ------
        EstimatorError
            No model yet, or a path not ending in ``.keras``.
        """
        model = self._check_fitted()
        path = Path(path)
        if path.suffix != ".keras":
            raise EstimatorError(f"{path}: expected a file name ending in .keras, "
                                 f"found {path.suffix or 'none'}")
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp_name = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp.keras", dir=path.parent)
        os.close(fd)
        tmp = Path(tmp_name)
        try:
            model.save(tmp, overwrite=True)
            with zipfile.ZipFile(tmp, "a", compression=zipfile.ZIP_DEFLATED) as zf:
                zf.writestr(SIDECAR_NAME, json.dumps(self._sidecar(), indent=2, allow_nan=False))
            mask = os.umask(0)
            os.umask(mask)
            os.chmod(tmp, 0o666 & ~mask)
            os.replace(tmp, path)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        return path

    @classmethod
    def load(cls, path: str | Path) -> OFBENet:
        """Read a model written by :meth:`save`, without executing code from the file.

        The archive's ``config.json`` is checked first: every serialised object must come
        from Keras (or be a scaling layer of a model saved by an earlier ofbe: such a model
        is read with :data:`~ofbe_model.ofbenet.layers.LEGACY_OBJECTS` and rebuilt of Keras
        layers by :func:`~ofbe_model.ofbenet.layers.upgrade_legacy`, predicting as before),
        and Lambda-like layers are refused. Then ``keras.saving.load_model(path,
        safe_mode=True, compile=False)`` builds it, and the result must map (None, T, 3) to
        (None, 3).

        Parameters
        ----------
        path
            A ``.keras`` file.

        Returns
        -------
        OFBENet
            With ``model_`` set and, when the file has them, the saved parameters,
            ``history_`` and training record (defaults otherwise).

        Raises
        ------
        EstimatorError
            A missing file, a file that is not a ``.keras`` archive, a configuration with
            unsafe or foreign objects, or a model of another shape (the message names the
            file and what was expected).
        """
        path = Path(path)
        expected = "an OFBENet .keras model file (a zip archive written by OFBENet.save)"
        if path.suffix != ".keras":
            raise EstimatorError(f"{path}: expected {expected}, found a file name ending in "
                                 f"{path.suffix or 'no suffix'}")
        if not path.is_file():
            raise EstimatorError(f"{path}: expected {expected}, found no such file")
        if not zipfile.is_zipfile(path):
            raise EstimatorError(f"{path}: expected {expected}, found a file that is not a zip archive")
        try:
            with zipfile.ZipFile(path) as zf:
                names = set(zf.namelist())
                missing = [n for n in KERAS_FILES if n not in names]
                if missing:
                    raise EstimatorError(f"{path}: expected {expected}, found an archive without "
                                         f"{', '.join(missing)}")
                config = json.loads(zf.read("config.json"))
                sidecar = json.loads(zf.read(SIDECAR_NAME)) if SIDECAR_NAME in names else None
        except (zipfile.BadZipFile, OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
            raise EstimatorError(f"{path}: expected {expected}, found an unreadable archive ({exc})") from exc
        legacy = _check_config(config, path)
        try:
            model = keras.saving.load_model(path, safe_mode=True, compile=False,
                                            custom_objects=LEGACY_OBJECTS if legacy else None)
        except Exception as exc:  # Keras raises ValueError, TypeError, KeyError, OSError... on bad files
            first = str(exc).splitlines()[0][:300] if str(exc) else type(exc).__name__
            raise EstimatorError(f"{path}: expected {expected} that Keras loads in safe mode, found an "
                                 f"error: {first}") from exc
        if legacy:
            model = upgrade_legacy(model, str(path))
        if (not isinstance(model, keras.Model) or len(model.inputs) != 1 or len(model.outputs) != 1
                or len(model.inputs[0].shape) != 3 or model.inputs[0].shape[2] != 3
                or model.inputs[0].shape[1] is None or tuple(model.outputs[0].shape)[1:] != (3,)):
            shapes = ([tuple(i.shape) for i in model.inputs], [tuple(o.shape) for o in model.outputs]) \
                if isinstance(model, keras.Model) else type(model).__name__
            raise EstimatorError(f"{path}: expected a model mapping (None, T, 3) windows to (None, 3) "
                                 f"biases, found {shapes}")
        est = cls._from_sidecar(sidecar, path)
        est.model_ = model
        est.window_length_ = int(model.inputs[0].shape[1])
        return est

    @classmethod
    def _from_sidecar(cls, sidecar: Any, path: Path) -> OFBENet:
        if sidecar is None:
            return cls()
        if not isinstance(sidecar, dict) or sidecar.get("format") != SIDECAR_FORMAT:
            found = sidecar.get("format") if isinstance(sidecar, dict) else type(sidecar).__name__
            raise EstimatorError(f"{path}: {SIDECAR_NAME}: expected format {SIDECAR_FORMAT}, found {found!r}")
        params = sidecar.get("params")
        if not isinstance(params, dict) or set(params) - set(PARAM_NAMES):
            raise EstimatorError(f"{path}: {SIDECAR_NAME}: params: expected a mapping of OFBENet parameters "
                                 f"({', '.join(PARAM_NAMES)}), found {params!r}")
        try:
            est = cls.from_params(OFBENetParams(**params))
        except ConfigError as exc:
            raise EstimatorError(f"{path}: {SIDECAR_NAME}: {exc}") from None
        history = sidecar.get("history")
        if isinstance(history, dict):
            est.history_ = _plain_history(history)
        for key in ("n_train", "n_val", "best_epoch"):
            if isinstance(sidecar.get(key), int):
                setattr(est, f"{key}_", sidecar[key])
        if isinstance(sidecar.get("fit_seconds"), int | float):
            est.fit_seconds_ = float(sidecar["fit_seconds"])
        est.domain_ = TrainingDomain.from_dict(sidecar.get("training_domain"))
        return est


#: Modules the custom scaling layers of earlier models were saved from (ofbe 0.1.0, and later
#: ``ofbe_model.ofbenet.layers`` until they became Keras' own ``Normalization``).
_LAYER_MODULES = frozenset({"ofbe_model.ofbenet.layers", "ofbe_model.ofbenet"})


def _check_config(config: Any, path: Path) -> bool:
    """Refuse a model configuration naming anything but Keras objects (and the custom scaling
    layers of models saved by an earlier ofbe).

    Returns
    -------
    bool
        Whether it names such an earlier layer (:data:`~ofbe_model.ofbenet.layers.LEGACY_OBJECTS`).

    Raises
    ------
    EstimatorError
        A Lambda-like layer, an object from another module, or a model that is not a
        Functional model.
    """
    legacy = False
    if not isinstance(config, dict) or config.get("class_name") != "Functional":
        found = config.get("class_name") if isinstance(config, dict) else type(config).__name__
        raise EstimatorError(f"{path}: config.json: expected a Functional Keras model, found {found!r}")
    stack: list[Any] = [config]
    while stack:
        node = stack.pop()
        if isinstance(node, list):
            stack.extend(node)
            continue
        if not isinstance(node, dict):
            continue
        stack.extend(node.values())
        cls_name = node.get("class_name")
        if cls_name is None or cls_name == "__keras_tensor__":  # the latter: a reference to a layer output
            continue
        if cls_name in REFUSED_CLASSES:
            raise EstimatorError(f"{path}: config.json: expected only layers that carry no code, found a "
                                 f"{cls_name!r} object (refused: it could execute code)")
        module = node.get("module")
        registered = node.get("registered_name")
        keras_builtin = isinstance(module, str) and (module == "keras" or module.startswith("keras."))
        if module == "builtins" and cls_name == "function":
            keras_builtin = True
        if module in _LAYER_MODULES and registered in LEGACY_OBJECTS:
            legacy = True
        elif not keras_builtin:
            raise EstimatorError(f"{path}: config.json: expected Keras objects only (and the scaling "
                                 f"layers of models saved by earlier ofbe), found {cls_name!r} from module "
                                 f"{module!r}")
    return legacy
