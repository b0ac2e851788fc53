"""OFBENet's constants and the choices the paper leaves open (:class:`OFBENetParams`), without TensorFlow."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ofbe_data.core.errors import ConfigError

#: Kernel size of every Conv1D (paper).
FILTERS: tuple[int, int, int] = (8, 32, 64)
KERNEL_SIZE = 5
#: Negative slope of the LeakyReLU activations (paper's α).
LEAKY_SLOPE = 0.1
#: Windows per batch in prediction and validation (does not affect training).
EVAL_BATCH = 64
#: Member of the ``.keras`` archive holding the estimator's parameters and training record.
SIDECAR_NAME = "ofbe_ofbenet.json"
#: ``format`` of that member.
SIDECAR_FORMAT = "ofbe-ofbenet/1"
WORKER_ENV = {"TF_NUM_INTRAOP_THREADS": "1", "TF_NUM_INTEROP_THREADS": "1", "TF_CPP_MIN_LOG_LEVEL": "3"}
"""Every fit (cross-validation folds and final models) runs in a fresh worker process with one
TensorFlow thread. OFBENet's small batches do not gain from a second thread (a fit on two
cores took 18.7 s, on one 16.1 s), so two single-threaded workers train two fits at once; and
since the thread count is the same whatever ``--jobs``, so are the weights."""

INPUT_SCALINGS = ("per-axis-standardise", "global-standardise", "none")
TARGET_SCALINGS = ("standardise", "none")
DENSE_ACTIVATIONS = ("relu", "linear")

STD_FLOOR = 1e-12  # a (near-)constant channel is left unscaled rather than divided by ~0
KERAS_FILES = ("config.json", "metadata.json", "model.weights.h5")
REFUSED_CLASSES = frozenset({"Lambda", "__lambda__", "TFSMLayer", "TorchModuleWrapper", "JaxLayer",
                              "FlaxLayer"})


# ---------------------------------------------------------------------------------------------
# Parameters


@dataclass(frozen=True)
class OFBENetParams:
    """The choices the paper leaves open, with their defaults.

    Attributes
    ----------
    pool_size
        AveragePooling1D pool size (and stride) after each block. 4 keeps the time axis of a
        3000-sample window at 3000 → 749 → 186 → 45 samples before the global average.
    dense_units
        Width of the hidden Dense layer.
    dense_activation
        Activation of the hidden Dense layer: ``"relu"`` (default) or ``"linear"``.
    dropout
        Dropout rate after the hidden Dense layer, in [0, 1).
    input_scaling
        ``"per-axis-standardise"`` (default): subtract each axis' mean and divide by its
        standard deviation, both over all samples of the training windows (the validation
        windows excluded), so the gravity axis (~9.8 m/s²) and the level axes (~0) enter
        the first convolution on the same scale. ``"global-standardise"``: one mean and one
        standard deviation over all axes. ``"none"``: raw m/s². A (near-)constant axis is
        centred but not divided.
    target_scaling
        ``"standardise"`` (default): the network is trained on per-axis standardised labels
        (mean and standard deviation of the training labels), so the loss is dimensionless
        and the three axes weigh equally; the model's last layer maps back to m/s².
        ``"none"``: trained on labels in m/s², loss in (m/s²)².
    max_epochs
        Upper limit of training epochs; early stopping usually ends training well before
        (after 7–21 epochs on the simulated campaigns). The default, 100, bounds one fold of
        ~990 windows of 3000 × 3 at 1.2–1.7 min on two CPU cores, measured running all 100
        epochs (~0.8–0.9 s per epoch); an early-stopped fold takes ~15 s
        (benchmarks/ofbenet_speed.py).
    validation_split
        Fraction of the training bias instances (``device`` × ``power_cycle`` groups, dealt
        per device) held out for validation, early stopping and the learning-rate schedule.
        Splitting by group keeps windows that share a bias out of both sides. 0 trains on
        everything and monitors the training loss instead.
    learning_rate
        Adam's initial learning rate (paper: 0.01).
    batch_size
        Training batch size (paper: 8).
    lr_factor, lr_patience
        ReduceLROnPlateau factor and patience in epochs (paper: 0.2, 15). With the paper's
        early-stopping patience of 5 the learning rate is never reduced; the callback is kept
        to follow the paper.
    es_patience
        EarlyStopping patience in epochs (paper: 5); the best epoch's weights are restored.
    seed
        Seed of the validation split, weight initialisation, shuffling and dropout.
    jit_compile
        Compile the training step with XLA. Off by default: on a 2-core CPU an XLA epoch is
        15–30 % shorter but compiling takes 2–4 s for each trainer and batch shape (a process
        keeps its compiled trainer across fits, :mod:`ofbe_model.ofbenet.trainer`), every
        weight differs from the committed models' (benchmarks/ofbenet_speed.py); and without XLA the
        determinism rests on TensorFlow's op determinism rather than on XLA's code
        generation. With XLA, op determinism is not enabled (Keras would turn XLA off): see
        the module docstring. Both settings are deterministic on CPU but give different
        weights.
    """

    pool_size: int = 4
    dense_units: int = 64
    dense_activation: str = "relu"
    dropout: float = 0.2
    input_scaling: str = "per-axis-standardise"
    target_scaling: str = "standardise"
    max_epochs: int = 100
    validation_split: float = 0.2
    learning_rate: float = 0.01
    batch_size: int = 8
    lr_factor: float = 0.2
    lr_patience: int = 15
    es_patience: int = 5
    seed: int = 0
    jit_compile: bool = False

    def __post_init__(self) -> None:
        src = "OFBENetParams"
        ints = {"pool_size": 1, "dense_units": 1, "max_epochs": 1, "batch_size": 1, "lr_patience": 0,
                "es_patience": 0, "seed": 0}
        for key, low in ints.items():
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < low:
                raise ConfigError(src, key, f"an integer >= {low}", repr(value))
            object.__setattr__(self, key, int(value))
        # (name, lower, lower inclusive, upper, upper inclusive)
        ranges = {"dropout": (0.0, True, 1.0, False), "validation_split": (0.0, True, 1.0, False),
                  "learning_rate": (0.0, False, math.inf, False), "lr_factor": (0.0, False, 1.0, False)}
        for key, (lo, lo_in, hi, hi_in) in ranges.items():
            value = getattr(self, key)
            ok = (not isinstance(value, bool) and isinstance(value, int | float | np.integer | np.floating)
                  and math.isfinite(value) and (value >= lo if lo_in else value > lo)
                  and (value <= hi if hi_in else value < hi))
            if not ok:
                interval = f"{'[' if lo_in else '('}{lo:g}, {hi:g}{']' if hi_in else ')'}"
                raise ConfigError(src, key, f"a number in {interval}", repr(value))
            object.__setattr__(self, key, float(value))
        for key, allowed in (("input_scaling", INPUT_SCALINGS), ("target_scaling", TARGET_SCALINGS),
                             ("dense_activation", DENSE_ACTIVATIONS)):
            if getattr(self, key) not in allowed:
                raise ConfigError(src, key, f"one of {', '.join(allowed)}", repr(getattr(self, key)))
        if not isinstance(self.jit_compile, bool | np.bool_):
            raise ConfigError(src, "jit_compile", "true or false", repr(self.jit_compile))
        object.__setattr__(self, "jit_compile", bool(self.jit_compile))

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON-ready copy."""
        return dataclasses.asdict(self)


PARAM_NAMES = tuple(f.name for f in dataclasses.fields(OFBENetParams))
