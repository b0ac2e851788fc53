"""OFBENet's Keras layers: the scaling layers stored inside the model and the network itself
(:func:`build_ofbenet`).
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


@keras.saving.register_keras_serializable(package="ofbe")
class Standardise(keras.layers.Layer):
    """``z = (x − mean) / std`` per channel, with constants stored in the layer config.

    Parameters
    ----------
    mean, std
        One value per channel (last axis), in the input's units (m/s² for windows); ``std``
        positive.
    **kwargs
        Passed to :class:`keras.layers.Layer` (``name``...).
    """

    def __init__(self, mean: Sequence[float], std: Sequence[float], **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.mean = _constants(mean, "Standardise.mean", positive=False)
        self.std = _constants(std, "Standardise.std", positive=True)
        if len(self.mean) != len(self.std):
            raise EstimatorError(f"Standardise: expected mean and std of equal length, found "
                                 f"{len(self.mean)} and {len(self.std)}")

    def call(self, inputs: Any) -> Any:
        mean = keras.ops.convert_to_tensor(np.asarray(self.mean, dtype=np.float32), dtype=inputs.dtype)
        std = keras.ops.convert_to_tensor(np.asarray(self.std, dtype=np.float32), dtype=inputs.dtype)
        return (inputs - mean) / std

    def compute_output_shape(self, input_shape: tuple[int | None, ...]) -> tuple[int | None, ...]:
        return input_shape

    def get_config(self) -> dict[str, Any]:
        return {**super().get_config(), "mean": list(self.mean), "std": list(self.std)}


@keras.saving.register_keras_serializable(package="ofbe")
class Destandardise(keras.layers.Layer):
    """``y = z · std + mean`` per channel: the inverse of :class:`Standardise`.

    Parameters
    ----------
    mean, std
        One value per channel, in the output's units (m/s² for biases); ``std`` positive.
    **kwargs
        Passed to :class:`keras.layers.Layer`.
    """

    def __init__(self, mean: Sequence[float], std: Sequence[float], **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.mean = _constants(mean, "Destandardise.mean", positive=False)
        self.std = _constants(std, "Destandardise.std", positive=True)
        if len(self.mean) != len(self.std):
            raise EstimatorError(f"Destandardise: expected mean and std of equal length, found "
                                 f"{len(self.mean)} and {len(self.std)}")

    def call(self, inputs: Any) -> Any:
        mean = keras.ops.convert_to_tensor(np.asarray(self.mean, dtype=np.float32), dtype=inputs.dtype)
        std = keras.ops.convert_to_tensor(np.asarray(self.std, dtype=np.float32), dtype=inputs.dtype)
        return inputs * std + mean

    def compute_output_shape(self, input_shape: tuple[int | None, ...]) -> tuple[int | None, ...]:
        return input_shape

    def get_config(self) -> dict[str, Any]:
        return {**super().get_config(), "mean": list(self.mean), "std": list(self.std)}


# ---------------------------------------------------------------------------------------------
# The network

#: Name of the layer whose output is the standardised bias (the training target's space).
HEAD_LAYER = "bias_scaled"


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


def build_ofbenet(window_length: int, params: OFBENetParams, x_mean: Sequence[float],
                  x_std: Sequence[float], y_mean: Sequence[float], y_std: Sequence[float]) -> keras.Model:
    """The OFBENet Keras model, uncompiled, with both scalings inside.

    Parameters
    ----------
    window_length
        T, samples per window.
    params
        Architecture choices (``pool_size``, ``dense_units``, ``dense_activation``, ``dropout``).
    x_mean, x_std
        (3,) input scaling constants, m/s² (``std`` > 0): the first layer computes
        ``(x − x_mean) / x_std``.
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
    x = Standardise(x_mean, x_std, name="input_scaling")(inputs)
    for i, filters in enumerate(FILTERS, start=1):
        x = keras.layers.Conv1D(filters, KERNEL_SIZE, name=f"conv{i}")(x)
        x = keras.layers.BatchNormalization(name=f"bn{i}")(x)
        x = keras.layers.LeakyReLU(negative_slope=LEAKY_SLOPE, name=f"leaky_relu{i}")(x)
        x = keras.layers.AveragePooling1D(pool_size=params.pool_size, name=f"pool{i}")(x)
    x = keras.layers.GlobalAveragePooling1D(name="global_pool")(x)
    x = keras.layers.Dense(params.dense_units, activation=params.dense_activation, name="dense")(x)
    x = keras.layers.Dropout(params.dropout, name="dropout")(x)
    z = keras.layers.Dense(3, name=HEAD_LAYER)(x)
    outputs = Destandardise(y_mean, y_std, name="target_scaling")(z)
    return keras.Model(inputs, outputs, name="ofbenet")
