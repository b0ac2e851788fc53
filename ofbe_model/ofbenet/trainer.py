"""OFBENet's compiled trainer, kept per process so that one worker's fits trace Keras' training step once.

A fit trains the network between the input scaling and the scaled head (:data:`HEAD_LAYER`):
the inputs are scaled beforehand, exactly as the model's two ``Rescaling`` layers scale them
(:func:`prescale`: the same float32 multiplications and additions, one rounding each), so the
trainer's graph holds no constant of a fold and one compiled trainer serves every fit of the
same architecture, window length, batch size and learning rate in a process. Tracing and
compiling that graph takes 2–4 s, as long as a whole small fit's epochs; a worker that trains
thirty fits in a row (``ofbe-train``) now pays it once.

Each fit starts the trainer exactly where a freshly built one would be: every variable of every
layer (weights, batch-normalisation statistics, the dropout layer's random-seed state) is
copied from the freshly built model of that fit (:func:`~ofbe_model.ofbenet.layers.build_ofbenet`,
which draws them from the fit's seed), and the optimizer's variables (step count, learning rate,
moments) are reset to their values before the first step. The trainer's own layers are made
without drawing from any random generator, so building one changes nothing later in the fit.
The weights are bit-identical to those of a trainer built for the fit alone (tested).
"""

from __future__ import annotations

from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from ofbe_data.core.cli import import_tensorflow
from ofbe_model.ofbenet.layers import INPUT_CENTRING, INPUT_SCALING, body_layers
from ofbe_model.ofbenet.params import EVAL_BATCH, OFBENetParams

import_tensorflow()  # before keras: TensorFlow's start-up lines stay off the terminal
import keras  # noqa: E402

#: Training steps per call into the compiled graph (Keras ``steps_per_execution``): the same
#: steps in the same order, without a Python round trip after each batch of 8.
STEPS_PER_EXECUTION = 32


@dataclass
class _Entry:
    trainer: keras.Model
    optimizer_start: list[np.ndarray]


#: Trainers kept per process, the least recently used dropped first (a worker of the paper
#: pipeline uses four: fixed and open batch sizes, for training and for validation).
MAX_TRAINERS = 8
_TRAINERS: OrderedDict[tuple[object, ...], _Entry] = OrderedDict()


def trainer_key(window_length: int, params: OFBENetParams, n_train: int, n_val: int) -> tuple[object, ...]:
    """What the compiled trainer depends on: window length, architecture, batch, optimizer, XLA,
    and whether the training and validation batches have a static size.

    Keras batches ``n`` windows with a batch dimension fixed in the graph when ``n`` is a multiple
    of the batch size and left open otherwise (a last, partial batch); TensorFlow optimises the
    two graphs differently (the numbers differ in their last bits), and a trainer traced for an
    open batch size also serves fixed ones. Each kind gets its own trainer, as a fit with a trainer
    of its own would.
    """
    return (int(window_length), params.pool_size, params.dense_units, params.dense_activation,
            params.dropout, params.learning_rate, params.batch_size, params.jit_compile,
            n_train % params.batch_size == 0, n_val > 0 and n_val % EVAL_BATCH == 0)


def _build_trainer(window_length: int, params: OFBENetParams) -> _Entry:
    inputs = keras.Input(shape=(int(window_length), 3), name="window_scaled")
    x = inputs
    for layer in body_layers(params, draw=False):
        x = layer(x)
    trainer = keras.Model(inputs, x, name="ofbenet_train")
    trainer.compile(optimizer=keras.optimizers.Adam(learning_rate=params.learning_rate), loss="mse",
                    jit_compile=params.jit_compile, steps_per_execution=STEPS_PER_EXECUTION)
    trainer.optimizer.build(trainer.trainable_variables)
    return _Entry(trainer, [np.array(v.numpy()) for v in trainer.optimizer.variables])


def copy_state(source: keras.Model, target: keras.Model) -> None:
    """Assign every variable (seed states included) of ``target``'s layers that have any from
    ``source``'s layer of the same name (the network body: the scalings have none)."""
    for layer in target.layers:
        dst = layer.variables
        if not dst:
            continue
        src = source.get_layer(layer.name).variables
        if len(dst) != len(src):  # pragma: no cover - both come from the same layer list
            raise RuntimeError(f"ofbenet: layer {layer.name} has {len(src)} variables, its copy {len(dst)}")
        for d, s in zip(dst, src, strict=True):
            d.assign(s.value)


def trainer_for(model: keras.Model, params: OFBENetParams, n_train: int, n_val: int) -> keras.Model:
    """The compiled trainer for ``model``'s shape and ``params``, in the state ``model`` starts in.

    Parameters
    ----------
    model
        A freshly built OFBENet (:func:`~ofbe_model.ofbenet.layers.build_ofbenet`).
    params
        Its parameters.
    n_train, n_val
        Windows it trains and validates on (validation batches of :data:`EVAL_BATCH`).

    Returns
    -------
    keras.Model
        Input: (None, T, 3) windows scaled by :func:`prescale`; output: the scaled bias
        (:data:`HEAD_LAYER`). Compiled (Adam, MSE); its optimizer at step 0.
    """
    t = int(model.inputs[0].shape[1])
    key = trainer_key(t, params, n_train, n_val)
    entry = _TRAINERS.get(key)
    if entry is None:
        entry = _TRAINERS[key] = _build_trainer(t, params)
        while len(_TRAINERS) > MAX_TRAINERS:
            _TRAINERS.popitem(last=False)
    else:
        _TRAINERS.move_to_end(key)
        for v, value in zip(entry.trainer.optimizer.variables, entry.optimizer_start, strict=True):
            v.assign(value)
    copy_state(model, entry.trainer)
    return entry.trainer


def prescale(model: keras.Model, windows: np.ndarray) -> np.ndarray:
    """``windows`` through ``model``'s two input ``Rescaling`` layers, in NumPy, bit for bit.

    Each layer computes ``x · scale + offset`` in float32, a rounding after each operation, as
    NumPy's float32 arithmetic does.

    Parameters
    ----------
    model
        An OFBENet with its input scaling layers.
    windows
        (N, T, 3) float32, m/s².

    Returns
    -------
    np.ndarray
        (N, T, 3) float32, dimensionless.
    """
    x = np.asarray(windows, dtype=np.float32)
    for name in (INPUT_CENTRING, INPUT_SCALING):
        layer = model.get_layer(name)
        scale = np.asarray(layer.scale, dtype=np.float32)  # a number or one per channel
        offset = np.asarray(layer.offset, dtype=np.float32)
        with np.errstate(over="ignore", invalid="ignore"):  # as the layers: inf and NaN pass through
            x = x * scale
            x += offset
    return x


def clear() -> None:
    """Forget the compiled trainers of this process."""
    _TRAINERS.clear()
