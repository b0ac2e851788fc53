"""OFBENet's Keras network (:func:`build_ofbenet`) and its scaling layers, all built-in Keras layers.

The scalings are Keras' own :class:`keras.layers.Rescaling` (``x · scale + offset``, per
channel, constants in the layer config, no weights):

``input_centring``
    ``scale 1, offset −mean``: ``x − mean``.
``input_scaling``
    ``scale 1/std, offset 0``: ``(x − mean) · (1/std)``.
``target_scaling``
    ``scale std, offset mean``: ``z · std + mean``, the last layer.

So the network holds no custom class, and a saved ``.keras`` file opens with plain Keras 3 in
an interpreter that never imports ofbe (``keras.saving.load_model(path)``, safe mode) and
predicts what :meth:`OFBENet.predict <ofbe_model.ofbenet.network.OFBENet.predict>` does.

Arithmetic (float32): ``1/std`` is stored as the float32 reciprocal of the float32 standard
deviation, so the input scaling is ``(x − mean) · fl32(1/fl32(std))``. That is exactly what
the custom ``Standardise`` layer of earlier models computed inside ``fit`` and ``predict``:
TensorFlow's graph optimiser turned its division by a constant into that multiplication
(only an eager call divided). The target scaling is the earlier ``Destandardise``'s
``z · std + mean``. A network built here therefore trains to the same weights and predicts
the same numbers, bit for bit, as the earlier one (tested against a copy of the old layers).

Models saved by earlier versions name the custom layers (``ofbe>Standardise``,
``ofbe>Destandardise``) in their configuration; ``OFBENet.load`` reads them with
:data:`LEGACY_OBJECTS` and :func:`upgrade_legacy` into this network (same weights, same
predictions), and saves them again without them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from ofbe_data.core.cli import import_tensorflow
from ofbe_model.estimators.base import EstimatorError
from ofbe_model.ofbenet.params import FILTERS, KERNEL_SIZE, LEAKY_SLOPE, OFBENetParams

import_tensorflow()  # before keras: TensorFlow's start-up lines stay off the terminal
import keras  # noqa: E402

#: Name of the layer whose output is the standardised bias (the training target's space).
HEAD_LAYER = "bias_scaled"
#: Names of the scaling layers: ``x − mean``, ``· 1/std`` (input), ``z · std + mean`` (output).
INPUT_CENTRING = "input_centring"
INPUT_SCALING = "input_scaling"
TARGET_SCALING = "target_scaling"

# ---------------------------------------------------------------------------------------------
# Scaling layers


def _constants(values: Sequence[float], name: str, positive: bool) -> tuple[float, ...]:
    try:
        out = tuple(float(v) for v in np.asarray(values, dtype=np.float64).reshape(-1))
    except (TypeError, ValueError) as exc:
        raise EstimatorError(f"{name}: expected a sequence of numbers, found {values!r}") from exc
    if not out or not all(math.isfinite(v) and (v > 0 if positive else True) for v in out):
        what = "positive finite numbers" if positive else "finite numbers"
        raise EstimatorError(f"{name}: expected a non-empty sequence of {what}, found {list(out)}")
    return out


def _pair(mean: Sequence[float], std: Sequence[float], what: str) -> tuple[tuple[float, ...], np.ndarray]:
    m = _constants(mean, f"{what}.mean", positive=False)
    s = _constants(std, f"{what}.std", positive=True)
    if len(m) != len(s):
        raise EstimatorError(f"{what}: expected mean and std of equal length, found {len(m)} and {len(s)}")
    s32 = np.asarray(s, dtype=np.float64).astype(np.float32)
    if not (np.isfinite(s32).all() and (s32 > 0).all() and np.isfinite(np.float32(1) / s32).all()):
        raise EstimatorError(f"{what}.std: expected values a float32 holds with a finite reciprocal, "
                             f"found {list(s)}")
    return m, s32


def input_scaling_layers(mean: Sequence[float], std: Sequence[float]
                         ) -> tuple[keras.layers.Rescaling, keras.layers.Rescaling]:
    """The input standardisation ``(x − mean) · (1/std)`` per channel, as two ``Rescaling`` layers.

    Parameters
    ----------
    mean, std
        One value per channel (last axis), m/s²; ``std`` positive.

    Returns
    -------
    centring, scaling
        :data:`INPUT_CENTRING` (scale 1, offset ``−mean``) and :data:`INPUT_SCALING` (scale
        ``fl32(1/fl32(std))``, offset 0), to apply in this order.

    Raises
    ------
    EstimatorError
        Constants that are not finite numbers, a ``std`` that is not positive, or ``mean``
        and ``std`` of different lengths.
    """
    m, s32 = _pair(mean, std, "Standardise")
    reciprocal = [float(v) for v in np.float32(1) / s32]  # float32 values, exact as Python floats
    return (keras.layers.Rescaling(scale=1.0, offset=[-v for v in m], name=INPUT_CENTRING),
            keras.layers.Rescaling(scale=reciprocal, offset=0.0, name=INPUT_SCALING))


def target_scaling_layer(mean: Sequence[float], std: Sequence[float],
                         name: str = TARGET_SCALING) -> keras.layers.Rescaling:
    """The target de-standardisation ``z · std + mean`` per channel, as a ``Rescaling`` layer.

    Parameters
    ----------
    mean, std
        One value per channel, m/s²; ``std`` positive.
    name
        The layer's name.

    Returns
    -------
    keras.layers.Rescaling
        Scale ``fl32(std)``, offset ``mean``.

    Raises
    ------
    EstimatorError
        As :func:`input_scaling_layers`.
    """
    m, s32 = _pair(mean, std, "Destandardise")
    return keras.layers.Rescaling(scale=[float(v) for v in s32], offset=list(m), name=name)


def _per_channel(value: Any, n: int, what: str, where: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=np.float32).reshape(-1)
    except (TypeError, ValueError):
        arr = np.full(0, np.nan, dtype=np.float32)
    if arr.size == 1:
        arr = np.repeat(arr, n)
    if arr.shape != (n,) or not np.isfinite(arr).all():
        raise EstimatorError(f"{where}: {what}: expected {n} finite numbers (one per axis), found {value!r}")
    return arr


def model_scalings(model: keras.Model, where: str = "model"
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The scaling constants of an OFBENet, as float32 (3,) arrays in m/s².

    Parameters
    ----------
    model
        An OFBENet (:func:`build_ofbenet`, or loaded by ``OFBENet.load``).
    where
        What to name in an error (the model file).

    Returns
    -------
    x_mean, x_scale, y_mean, y_std
        The model computes ``(x − x_mean) · x_scale`` first and ``z · y_std + y_mean`` last,
        with exactly these float32 numbers (``x_scale`` is ``1/std`` of the training windows).

    Raises
    ------
    EstimatorError
        A model whose layers 1 and 2 are not the input scaling ``Rescaling`` layers (scale 1,
        then offset 0) or whose last layer is not a ``Rescaling``, each of 3 axes.
    """
    layers = model.layers
    ok = (len(layers) >= 5 and all(isinstance(la, keras.layers.Rescaling) for la in (layers[1], layers[2],
                                                                                       layers[-1])))
    if not ok:
        found = [type(la).__name__ for la in layers[:3]] + ["…", type(layers[-1]).__name__]
        raise EstimatorError(f"{where}: expected an OFBENet graph (input, Rescaling, Rescaling, …, "
                             f"Rescaling), found layers {found}")
    one = _per_channel(layers[1].scale, 3, f"layer {layers[1].name!r} scale", where)
    zero = _per_channel(layers[2].offset, 3, f"layer {layers[2].name!r} offset", where)
    if not (np.all(one == 1) and np.all(zero == 0)):
        raise EstimatorError(f"{where}: expected the input scaling as x − mean (scale 1) then · 1/std "
                             f"(offset 0), found scale {one.tolist()} and offset {zero.tolist()}")
    x_mean = -_per_channel(layers[1].offset, 3, f"layer {layers[1].name!r} offset", where)
    x_scale = _per_channel(layers[2].scale, 3, f"layer {layers[2].name!r} scale", where)
    y_std = _per_channel(layers[-1].scale, 3, f"layer {layers[-1].name!r} scale", where)
    y_mean = _per_channel(layers[-1].offset, 3, f"layer {layers[-1].name!r} offset", where)
    return x_mean, x_scale, y_mean, y_std


# ---------------------------------------------------------------------------------------------
# Models saved with the earlier custom scaling layers


class _LegacyScaling:
    """Reads a custom scaling layer of a model saved by an earlier ofbe (constants ``mean`` and
    ``std`` in its config) as a built-in layer. Not a layer: Keras only calls ``from_config``.

    ``ofbe>Destandardise`` becomes :func:`target_scaling_layer` (the same arithmetic);
    ``ofbe>Standardise`` becomes a ``Normalization`` with the same constants, which
    :func:`upgrade_legacy` replaces with :func:`input_scaling_layers`.
    """

    invert: bool = False

    @classmethod
    def from_config(cls, config: dict[str, Any]) -> keras.layers.Layer:
        what = "Destandardise" if cls.invert else "Standardise"
        if not isinstance(config, dict) or "mean" not in config or "std" not in config:
            raise EstimatorError(f"{what}: expected a config with mean and std, found {config!r}")
        if cls.invert:
            return target_scaling_layer(config["mean"], config["std"], name=str(config.get("name") or
                                                                                TARGET_SCALING))
        m, s32 = _pair(config["mean"], config["std"], what)
        return keras.layers.Normalization(axis=-1, mean=list(m), variance=[float(v) ** 2 for v in s32],
                                          name=str(config.get("name") or INPUT_SCALING))


class _LegacyStandardise(_LegacyScaling):
    invert = False


class _LegacyDestandardise(_LegacyScaling):
    invert = True


LEGACY_OBJECTS: dict[str, type] = {"ofbe>Standardise": _LegacyStandardise,
                                   "ofbe>Destandardise": _LegacyDestandardise}
"""``custom_objects`` for ``keras.saving.load_model`` that read the scaling layers of models saved
before they were Keras' own (registered name → reader)."""


def upgrade_legacy(model: keras.Model, where: str = "model") -> keras.Model:
    """An earlier OFBENet, read with :data:`LEGACY_OBJECTS`, as the network :func:`build_ofbenet` makes.

    The input scaling ``Normalization`` (what the earlier ``Standardise`` was read as) is
    replaced with :func:`input_scaling_layers` of the same constants, every other layer is
    copied with its weights: the result predicts what the earlier model did, bit for bit.

    Parameters
    ----------
    model
        The model as Keras loaded it.
    where
        What to name in an error.

    Returns
    -------
    keras.Model
        A new model of built-in layers only.

    Raises
    ------
    EstimatorError
        A model that is not one chain of layers starting with that ``Normalization``.
    """
    layers = model.layers
    first = layers[1] if len(layers) > 2 else None
    try:  # each layer called once, on the previous layer's output
        chain = all(la.input is prev.output for prev, la in zip(layers[:-1], layers[1:], strict=True))
    except (AttributeError, ValueError):  # a layer called more than once has no single input
        chain = False
    if not (chain and isinstance(first, keras.layers.Normalization) and not first.invert):
        kinds = [type(la).__name__ for la in layers]
        raise EstimatorError(f"{where}: expected an OFBENet saved by an earlier ofbe (one chain of layers "
                             f"from its Standardise layer), found layers {kinds}")
    mean = np.asarray(first.input_mean, dtype=np.float64).reshape(-1)
    std = np.sqrt(np.asarray(first.input_variance, dtype=np.float64).reshape(-1))  # exact: a float32 squared
    inputs = keras.Input(shape=tuple(model.inputs[0].shape[1:]), name=layers[0].name)
    x = inputs
    for layer in input_scaling_layers(mean, std):
        x = layer(x)
    for layer in layers[2:]:
        copy = type(layer).from_config(layer.get_config())
        x = copy(x)
        copy.set_weights(layer.get_weights())
    return keras.Model(inputs, x, name=model.name)


# ---------------------------------------------------------------------------------------------
# The network


def feature_length(window_length: int, pool_size: int) -> int:
    """Time steps left before the global average: each block is a 'valid' Conv1D (−4) and a
    pooling (// pool_size).

    Parameters
    ----------
    window_length
        T, samples.
    pool_size
        Pooling size and stride.
    """
    n = window_length
    for _ in FILTERS:
        n = (n - (KERNEL_SIZE - 1)) // pool_size
    return n


def body_layers(params: OFBENetParams, draw: bool = True) -> list[keras.layers.Layer]:
    """The network between the input scaling and the scaled head (:data:`HEAD_LAYER`), in order.

    Parameters
    ----------
    params
        Architecture choices (``pool_size``, ``dense_units``, ``dense_activation``, ``dropout``).
    draw
        True: Keras' default initialisers and an unseeded dropout, which draw from the global
        random state (set by :func:`keras.utils.set_random_seed`). False: zero weights and a
        dropout seeded 0, nothing drawn: for layers whose variables are assigned afterwards.
    """
    init = {} if draw else {"kernel_initializer": "zeros"}
    layers: list[keras.layers.Layer] = []
    for i, filters in enumerate(FILTERS, start=1):
        layers += [keras.layers.Conv1D(filters, KERNEL_SIZE, name=f"conv{i}", **init),
                   keras.layers.BatchNormalization(name=f"bn{i}"),
                   keras.layers.LeakyReLU(negative_slope=LEAKY_SLOPE, name=f"leaky_relu{i}"),
                   keras.layers.AveragePooling1D(pool_size=params.pool_size, name=f"pool{i}")]
    return [*layers, keras.layers.GlobalAveragePooling1D(name="global_pool"),
            keras.layers.Dense(params.dense_units, activation=params.dense_activation, name="dense", **init),
            keras.layers.Dropout(params.dropout, name="dropout", seed=None if draw else 0),
            keras.layers.Dense(3, name=HEAD_LAYER, **init)]


def build_ofbenet(window_length: int, params: OFBENetParams, x_mean: Sequence[float],
                  x_std: Sequence[float], y_mean: Sequence[float], y_std: Sequence[float]) -> keras.Model:
    """The OFBENet Keras model, uncompiled, with both scalings inside, of built-in Keras layers only.

    Parameters
    ----------
    window_length
        T, samples per window.
    params
        Architecture choices (``pool_size``, ``dense_units``, ``dense_activation``, ``dropout``).
    x_mean, x_std
        (3,) input scaling constants, m/s² (``std`` > 0): the first two layers compute
        ``(x − x_mean) · (1/x_std)`` (:func:`input_scaling_layers`).
    y_mean, y_std
        (3,) target scaling constants, m/s²: the last layer computes ``z · y_std + y_mean``.

    Returns
    -------
    keras.Model
        Input ``window`` (None, T, 3) m/s² → output (None, 3) m/s². The layer named
        :data:`HEAD_LAYER` gives the scaled output the network is trained on.

    Raises
    ------
    EstimatorError
        A window too short for three blocks, or invalid scaling constants.
    """
    if isinstance(window_length, bool) or not isinstance(window_length, int | np.integer):
        raise EstimatorError(f"window_length: expected an integer, found {window_length!r}")
    n_feat = feature_length(int(window_length), params.pool_size)
    if n_feat < 1:
        raise EstimatorError(f"window_length: expected a window long enough for three Conv1D(kernel "
                             f"{KERNEL_SIZE}) + AveragePooling1D({params.pool_size}) blocks, found "
                             f"{window_length} samples")
    for name, values in (("x_mean", x_mean), ("x_std", x_std), ("y_mean", y_mean), ("y_std", y_std)):
        if len(_constants(values, name, positive=name.endswith("std"))) != 3:
            raise EstimatorError(f"{name}: expected 3 values (x, y, z), found {len(values)}")
    inputs = keras.Input(shape=(int(window_length), 3), name="window")
    x = inputs
    for layer in input_scaling_layers(x_mean, x_std):
        x = layer(x)
    for layer in body_layers(params):
        x = layer(x)
    outputs = target_scaling_layer(y_mean, y_std)(x)
    return keras.Model(inputs, outputs, name="ofbenet")
