"""OFBENet: architecture, scaling inside the model, learning, determinism, safe save/load, ofbe-train."""

from __future__ import annotations

import dataclasses
import inspect
import json
import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import keras
import matplotlib.image as mpimg
import numpy as np
import pandas as pd
import pytest
import tensorflow as tf

from ofbe_data.core.atomic import atomic_directory
from ofbe_data.core.errors import ConfigError
from ofbe_data.dataset.store import DatasetInfo
from ofbe_data.dataset.writer import WindowWriter
from ofbe_model.cli.train import main
from ofbe_model.estimators.base import EstimatorError, make_estimator
from ofbe_model.ofbenet import trainer
from ofbe_model.ofbenet.layers import (
    build_ofbenet,
    feature_length,
    input_scaling_layers,
    model_scalings,
    target_scaling_layer,
)
from ofbe_model.ofbenet.network import OFBENet, group_validation_split
from ofbe_model.ofbenet.params import FILTERS, SIDECAR_NAME, OFBENetParams
from ofbe_model.ofbenet.training import dataset_dirname, read_params, read_seed_count
from tests.helpers.paths import ROOT
from tests.helpers.plain_keras import plain_keras_predict

pytestmark = pytest.mark.slow
"""Slow: a campaign or model fixture shared by the module (``-m "not slow"`` leaves it out)."""

T = 200
G = 9.81


def synthetic(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, pd.DataFrame]:
    """Level windows: label b (one per pair of windows = one power cycle), window = b + g·z + noise."""
    rng = np.random.default_rng(seed)
    b = rng.normal(0.0, 0.3, size=(n // 2, 3)).repeat(2, axis=0)
    x = (b[:, None, :] + np.array([0.0, 0.0, G]) + rng.normal(0.0, 0.05, size=(n, T, 3))).astype(np.float32)
    meta = pd.DataFrame({"device": "d1", "g_local": G, "power_cycle": np.arange(n) // 2})
    return x, b, meta


@pytest.fixture(scope="module")
def fitted() -> tuple[OFBENet, np.ndarray, np.ndarray, pd.DataFrame]:
    x, y, meta = synthetic(96, seed=0)
    est = OFBENet(max_epochs=20).fit(x, y, meta)
    xt, yt, mt = synthetic(64, seed=1)
    return est, xt, yt, mt


# --------------------------------------------------------------------------------------------
# architecture and parameters


def test_architecture_follows_the_paper() -> None:
    params = OFBENetParams()
    model = build_ofbenet(T, params, [0, 0, G], [1, 1, 1], [0, 0, 0], [1, 1, 1])
    kinds = [type(layer).__name__ for layer in model.layers]
    block = ["Conv1D", "BatchNormalization", "LeakyReLU", "AveragePooling1D"]
    assert kinds == ["InputLayer", "Rescaling", "Rescaling", *block * 3, "GlobalAveragePooling1D", "Dense",
                     "Dropout", "Dense", "Rescaling"]
    convs = [la for la in model.layers if isinstance(la, keras.layers.Conv1D)]
    assert tuple(c.filters for c in convs) == FILTERS == (8, 32, 64)
    assert all(c.kernel_size == (5,) for c in convs)
    assert all(la.negative_slope == pytest.approx(0.1) for la in model.layers
               if isinstance(la, keras.layers.LeakyReLU))
    assert all(la.pool_size == (params.pool_size,) for la in model.layers
               if isinstance(la, keras.layers.AveragePooling1D))
    dense = [la for la in model.layers if isinstance(la, keras.layers.Dense)]
    assert [d.units for d in dense] == [params.dense_units, 3]
    assert model.get_layer("dropout").rate == pytest.approx(params.dropout)
    assert tuple(model.input_shape) == (None, T, 3) and tuple(model.output_shape) == (None, 3)
    assert feature_length(3000, 4) == 45
    with pytest.raises(EstimatorError, match="window_length"):
        build_ofbenet(40, params, [0] * 3, [1] * 3, [0] * 3, [1] * 3)


def test_scaling_is_inside_the_model() -> None:
    x = np.random.default_rng(0).normal(size=(4, 7, 3)).astype(np.float32) + 5.0
    centre, scale = input_scaling_layers([1.0, 2.0, 3.0], [2.0, 4.0, 0.3])
    z = np.asarray(scale(centre(x)))
    # exactly (x − mean) · fl32(1/std) in float32
    reciprocal = np.float32(1) / np.float32([2.0, 4.0, 0.3])
    assert np.array_equal(z, (x - np.float32([1.0, 2.0, 3.0])) * reciprocal)
    y = np.asarray(target_scaling_layer([1.0, 2.0, 3.0], [2.0, 4.0, 0.3])(z[:, 0, :]))
    assert np.array_equal(y, z[:, 0, :] * np.float32([2.0, 4.0, 0.3]) + np.float32([1.0, 2.0, 3.0]))
    assert np.allclose(y, x[:, 0, :], atol=1e-5)
    # with a zero head, the model's output is exactly the target mean, in m/s², for raw input
    model = build_ofbenet(T, OFBENetParams(), [0, 0, G], [0.1, 0.1, 0.1], [0.05, -0.2, 0.3], [0.3, 0.3, 0.3])
    head = model.get_layer("bias_scaled")
    head.set_weights([np.zeros_like(w) for w in head.get_weights()])
    out = np.asarray(model.predict_on_batch(synthetic(4, 0)[0]))
    assert np.allclose(out, [0.05, -0.2, 0.3], atol=1e-6)
    expected = [np.float32([0, 0, G]), np.float32(1) / np.float32([0.1] * 3), np.float32([0.05, -0.2, 0.3]),
                np.float32([0.3] * 3)]
    assert all(np.array_equal(c, e) for c, e in zip(model_scalings(model), expected, strict=True))
    with pytest.raises(EstimatorError, match="std"):
        input_scaling_layers([0.0], [0.0])
    with pytest.raises(EstimatorError, match="OFBENet graph"):
        model_scalings(keras.Sequential([keras.Input((T, 3)), keras.layers.Dense(3)]))


def test_init_mirrors_params_and_registry() -> None:
    fields = {f.name: f.default for f in dataclasses.fields(OFBENetParams)}
    sig = inspect.signature(OFBENet.__init__).parameters
    assert {k: v.default for k, v in sig.items() if k != "self"} == fields
    est = make_estimator("ofbenet", dropout=0.3)
    assert isinstance(est, OFBENet) and est.get_params() == {**fields, "dropout": 0.3}
    assert OFBENet.name == "ofbenet" and OFBENet.needs_fit
    with pytest.raises(ConfigError, match="pool_size"):
        OFBENetParams(pool_size=0)
    x, y, meta = synthetic(8, 0)
    with pytest.raises(EstimatorError, match="dropout"):
        OFBENet(dropout=1.5).fit(x, y, meta)
    with pytest.raises(EstimatorError, match="fitted or loaded"):
        OFBENet().predict(x, meta)


def test_validation_split_keeps_bias_instances_apart() -> None:
    meta = pd.DataFrame({"device": np.repeat(["a", "b"], 30), "g_local": G,
                         "power_cycle": np.tile(np.arange(10).repeat(3), 2)})
    val = group_validation_split(meta, 0.2, seed=0)
    keys = list(zip(meta["device"], meta["power_cycle"], strict=True))
    assert not {k for k, v in zip(keys, val, strict=True) if v} & {k for k, v in zip(keys, val, strict=True)
                                                                     if not v}
    assert val[:30].sum() == 6 and val[30:].sum() == 6  # 2 of 10 cycles per device
    assert np.array_equal(val, group_validation_split(meta, 0.2, seed=0))
    with pytest.raises(EstimatorError, match="power_cycle"):
        group_validation_split(meta.drop(columns="power_cycle"), 0.2, seed=0)


# --------------------------------------------------------------------------------------------
# training


def test_learns_biases_in_label_units(fitted) -> None:
    est, xt, yt, mt = fitted
    loss = est.history_["loss"]
    assert set(est.history_) >= {"loss", "val_loss", "learning_rate"} and len(loss) <= 20
    assert loss[-1] < 0.5 * loss[0]
    pred = est.predict(xt, mt)  # raw m/s² windows in, m/s² out
    assert pred.shape == (64, 3) and pred.dtype == np.float64
    for axis in range(3):
        assert np.corrcoef(pred[:, axis], yt[:, axis])[0, 1] > 0.7
    assert np.sqrt(np.mean((pred - yt) ** 2)) < 0.6 * yt.std()
    assert est.n_train_ + est.n_val_ == 96 and est.n_val_ > 0
    with pytest.raises(EstimatorError, match="200 samples"):
        est.predict(xt[:, :100], mt)


def test_two_fits_are_identical() -> None:
    x, y, meta = synthetic(24, seed=3)
    a = OFBENet(max_epochs=2, seed=7).fit(x, y, meta)
    b = OFBENet(max_epochs=2, seed=7).fit(x, y, meta)
    wa, wb = a.model_.get_weights(), b.model_.get_weights()
    assert len(wa) == len(wb) and all(np.array_equal(p, q) for p, q in zip(wa, wb, strict=True))
    assert a.history_ == b.history_


def test_a_reused_trainer_trains_what_a_fresh_one_does() -> None:
    # the fits of one process share a compiled trainer (ofbe_model.ofbenet.trainer); whatever came
    # before, with other seeds and other sizes (32 training windows: whole batches of 8, a graph
    # with a fixed batch size; 20: a partial one, an open batch size), a fit gives the weights and
    # history of one with a trainer built for it alone
    data = [synthetic(40, seed=5), synthetic(26, seed=6)]
    plan = [(1, 1), (0, 0), (1, 0), (0, 1), (0, 0)]  # (data, seed)

    def fit(d: int, s: int) -> OFBENet:
        return OFBENet(max_epochs=2, seed=s).fit(*data[d])

    trainer.clear()
    reused = [fit(d, s) for d, s in plan]
    assert len(trainer._TRAINERS) == 2  # fixed and open batch sizes: TensorFlow optimises them differently
    fresh = []
    for d, s in plan:
        trainer.clear()
        fresh.append(fit(d, s))
    for a, b in zip(reused, fresh, strict=True):
        va, vb = [np.asarray(v) for v in a.model_.variables], [np.asarray(v) for v in b.model_.variables]
        assert len(va) == len(vb) and all(np.array_equal(p, q) for p, q in zip(va, vb, strict=True))
        assert a.history_ == b.history_


def test_the_trainers_kept_are_bounded(monkeypatch) -> None:
    # the least recently used trainer goes; a fit after that trains on a new one, the same weights
    monkeypatch.setattr(trainer, "MAX_TRAINERS", 1)
    data = [synthetic(40, seed=5), synthetic(26, seed=6)]
    trainer.clear()
    first = OFBENet(max_epochs=1, seed=2).fit(*data[0])
    OFBENet(max_epochs=1, seed=2).fit(*data[1])
    assert len(trainer._TRAINERS) == 1
    again = OFBENet(max_epochs=1, seed=2).fit(*data[0])
    assert all(np.array_equal(p, q) for p, q in zip(first.model_.get_weights(), again.model_.get_weights(),
                                                     strict=True))


def test_prescaling_is_the_models_own_input_scaling() -> None:
    x, _, _ = synthetic(6, seed=8)
    x[0, :3] = [[0.0, -0.0, 1e-30], [3e38, -3e38, 1.0], [np.nan, np.inf, -np.inf]]
    model = build_ofbenet(T, OFBENetParams(), [0.1, -0.2, 9.7], [0.05, 0.03, 0.31], [0, 0, 0], [1, 1, 1])
    inner = keras.Model(model.inputs, model.get_layer("input_scaling").output)
    want = np.asarray(inner(x, training=False))
    got = trainer.prescale(model, x)
    assert got.dtype == np.float32 and np.array_equal(got.view(np.uint32), want.view(np.uint32))


def test_xla_after_op_determinism_warns() -> None:
    tf.config.experimental.enable_op_determinism()  # as any earlier fit without XLA does
    x, y, meta = synthetic(8, seed=4)
    with pytest.warns(UserWarning, match="op determinism is already enabled"):
        OFBENet(max_epochs=1, validation_split=0.0, jit_compile=True).fit(x, y, meta)


def test_two_xla_fits_are_identical_in_a_fresh_process() -> None:
    # a fresh process: the fits above enabled op determinism, which makes Keras turn XLA off
    code = ("import numpy as np, pandas as pd, tensorflow as tf\n"
            "from ofbe_model.ofbenet.network import OFBENet\n"
            "rng = np.random.default_rng(0)\n"
            "x = rng.normal(size=(16, 200, 3)).astype(np.float32); y = rng.normal(size=(16, 3))\n"
            "meta = pd.DataFrame({'device': ['d1'] * 16, 'g_local': 9.81})\n"
            "est = OFBENet(max_epochs=2, validation_split=0.0, jit_compile=True)\n"
            "w = [est.fit(x, y, meta).model_.get_weights() for _ in (0, 1)]\n"
            "from tensorflow.python.framework.config import is_op_determinism_enabled as det\n"
            "print('XLA-IDENTICAL', all(np.array_equal(a, b) for a, b in zip(*w)), det())\n")
    env = {**os.environ, "TF_CPP_MIN_LOG_LEVEL": "3"}
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "XLA-IDENTICAL True False" in proc.stdout
    assert "doesn't support `jit_compile=True`" not in proc.stderr  # XLA really ran


# --------------------------------------------------------------------------------------------
# save and load


def test_save_then_load_in_a_fresh_process_predicts_identically(fitted, tmp_path) -> None:
    est, xt, _, mt = fitted
    path = est.save(tmp_path / "m" / "fold-0.keras")
    assert sorted(p.name for p in path.parent.iterdir()) == ["fold-0.keras"]  # no temporary left
    np.save(tmp_path / "x.npy", xt)
    code = ("import sys, numpy as np, pandas as pd\n"
            "from ofbe_model.ofbenet.network import OFBENet\n"
            "m = OFBENet.load(sys.argv[1]); x = np.load(sys.argv[2])\n"
            "meta = pd.DataFrame({'device': ['d1'] * len(x), 'g_local': 9.81})\n"
            "np.save(sys.argv[3], m.predict(x, meta))\n")
    env = {**os.environ, "TF_CPP_MIN_LOG_LEVEL": "3"}
    proc = subprocess.run([sys.executable, "-c", code, str(path), str(tmp_path / "x.npy"),
                           str(tmp_path / "p.npy")], capture_output=True, text=True, env=env, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert np.array_equal(np.load(tmp_path / "p.npy"), est.predict(xt, mt))
    loaded = OFBENet.load(path)
    assert loaded.get_params() == est.get_params() and loaded.history_ == est.history_
    assert loaded.best_epoch_ == est.best_epoch_ and loaded.window_length_ == T
    with pytest.raises(EstimatorError, match=".keras"):
        est.save(tmp_path / "model.h5")


def test_a_fold_model_loads_with_plain_keras_in_an_interpreter_without_ofbe(fitted, tmp_path) -> None:
    """What ofbe-train saves (OFBENet.save) opens with keras.saving.load_model alone, safe mode,
    in a fresh interpreter that never imports ofbe, and predicts exactly what OFBENet.load does."""
    est, xt, _, mt = fitted
    path = est.save(tmp_path / "fold-0.seed-0.keras")
    config = json.loads(zipfile.ZipFile(path).read("config.json"))
    modules = set(re.findall(r'"module": "([^"]+)"', json.dumps(config)))
    assert modules and all(m == "keras" or m.startswith("keras.") for m in modules), modules
    plain = plain_keras_predict(path, xt[:32], tmp_path / "child")
    ours = OFBENet.load(path).predict(xt[:32], mt[:32])
    # identical, not close: the same float32 graph (predict_on_batch and predict, one batch each)
    assert np.array_equal(plain[0].astype(np.float64), ours)
    assert np.array_equal(plain[1].astype(np.float64), ours)
    assert np.array_equal(ours, est.predict(xt[:32], mt[:32]))


#: The custom scaling layers models were saved with before they became Keras' own Rescaling
#: layers (ofbe_model/ofbenet/layers.py until then), copied: they write an earlier model file.
OLD_LAYERS = """\
import json, sys

import keras
import numpy as np


@keras.saving.register_keras_serializable(package="ofbe")
class Standardise(keras.layers.Layer):
    def __init__(self, mean, std, **kwargs):
        super().__init__(**kwargs)
        self.mean, self.std = [float(v) for v in mean], [float(v) for v in std]

    def call(self, inputs):
        mean = keras.ops.convert_to_tensor(np.asarray(self.mean, dtype=np.float32), dtype=inputs.dtype)
        std = keras.ops.convert_to_tensor(np.asarray(self.std, dtype=np.float32), dtype=inputs.dtype)
        return (inputs - mean) / std

    def compute_output_shape(self, input_shape):
        return input_shape

    def get_config(self):
        return {**super().get_config(), "mean": list(self.mean), "std": list(self.std)}


@keras.saving.register_keras_serializable(package="ofbe")
class Destandardise(Standardise):
    def call(self, inputs):
        mean = keras.ops.convert_to_tensor(np.asarray(self.mean, dtype=np.float32), dtype=inputs.dtype)
        std = keras.ops.convert_to_tensor(np.asarray(self.std, dtype=np.float32), dtype=inputs.dtype)
        return inputs * std + mean


new = keras.saving.load_model(sys.argv[1])
c = json.loads(sys.argv[2])
inputs = keras.Input(shape=tuple(new.inputs[0].shape[1:]), name="window")
x = Standardise(c["x_mean"], c["x_std"], name="input_scaling")(inputs)
for layer in new.layers[3:-1]:
    x = layer(x)
old = keras.Model(inputs, Destandardise(c["y_mean"], c["y_std"], name="target_scaling")(x), name="ofbenet")
old.save(sys.argv[3])
np.save(sys.argv[4], np.asarray(old.predict_on_batch(np.load(sys.argv[5]))))
"""


@pytest.mark.parametrize("module", ["ofbe_model.ofbenet.layers", "ofbe_model.ofbenet"])
def test_a_model_saved_with_the_earlier_custom_layers_loads_and_predicts_as_before(module, tmp_path) -> None:
    """A file with ofbe>Standardise / ofbe>Destandardise (what earlier versions wrote) still loads:
    rebuilt of Keras layers, it predicts what the earlier network predicted, bit for bit, and is
    saved again without the custom layers. The network built today computes the same numbers."""
    keras.utils.set_random_seed(5)
    consts = {"x_mean": [0.05, -0.1, G], "x_std": [0.3, 0.21, 0.07], "y_mean": [0.02, -0.03, 0.1],
              "y_std": [0.31, 0.29, 0.05]}
    new = OFBENet()
    new.model_ = build_ofbenet(T, OFBENetParams(), *consts.values())
    new_path = new.save(tmp_path / "new.keras")
    x = synthetic(16, seed=2)[0]
    np.save(tmp_path / "x.npy", x)
    env = {**os.environ, "TF_CPP_MIN_LOG_LEVEL": "3"}
    files = [str(tmp_path / name) for name in ("written.keras", "old.npy", "x.npy")]
    args = [str(new_path), json.dumps(consts), *files]
    proc = subprocess.run([sys.executable, "-c", OLD_LAYERS, *args], capture_output=True, text=True, env=env,
                          cwd=tmp_path, timeout=600)
    assert proc.returncode == 0, proc.stderr[-2000:]
    config = json.loads(zipfile.ZipFile(tmp_path / "written.keras").read("config.json"))
    for layer in config["config"]["layers"]:  # defined in __main__ here, in ofbe's module then
        if str(layer.get("registered_name")).startswith("ofbe>"):
            layer["module"] = module
    old_path = _rewrite(tmp_path / "written.keras", tmp_path / "old.keras", config)
    assert '"registered_name": "ofbe>Standardise"' in zipfile.ZipFile(old_path).read("config.json").decode()
    meta = pd.DataFrame({"device": ["d1"] * len(x), "g_local": G})
    before = np.load(tmp_path / "old.npy").astype(np.float64)
    loaded = OFBENet.load(old_path)
    assert [type(la).__name__ for la in loaded.model_.layers[1:3]] == ["Rescaling", "Rescaling"]
    assert np.array_equal(loaded.predict(x, meta), before)
    assert np.array_equal(new.predict(x, meta), before)  # today's network: the earlier arithmetic
    resaved = loaded.save(tmp_path / "resaved.keras")
    assert b"ofbe>" not in zipfile.ZipFile(resaved).read("config.json")
    assert np.array_equal(OFBENet.load(resaved).predict(x, meta), before)


@pytest.fixture(scope="module")
def saved(fitted, tmp_path_factory) -> Path:
    return fitted[0].save(tmp_path_factory.mktemp("saved") / "good.keras")


def _rewrite(src: Path, dest: Path, config: dict) -> Path:
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dest, "w") as zout:
        for name in zin.namelist():
            data = json.dumps(config).encode() if name == "config.json" else zin.read(name)
            zout.writestr(name, data)
    return dest


def test_load_refuses_what_is_not_a_model(tmp_path, saved) -> None:
    with pytest.raises(EstimatorError, match="no such file"):
        OFBENet.load(tmp_path / "missing.keras")
    text = tmp_path / "notes.keras"
    text.write_text("this is not a model\n")
    with pytest.raises(EstimatorError, match=r"notes\.keras.*not a zip archive"):
        OFBENet.load(text)
    with pytest.raises(EstimatorError, match="ending in"):
        OFBENet.load(tmp_path / "model.h5")
    bare = tmp_path / "bare.keras"
    with zipfile.ZipFile(bare, "w") as zf:
        zf.writestr("hello.txt", "hi")
    with pytest.raises(EstimatorError, match="without config.json"):
        OFBENet.load(bare)
    config = json.loads(zipfile.ZipFile(saved).read("config.json"))
    text_cfg = json.dumps(config).replace('"class_name": "Conv1D", "config"',
                                          '"class_name": "Evil", "config"', 1)
    text_cfg = text_cfg.replace('"module": "keras.layers", "class_name": "Evil"',
                                '"module": "os", "class_name": "Evil"', 1)
    evil = json.loads(text_cfg)
    assert "Evil" in text_cfg
    with pytest.raises(EstimatorError, match="Evil"):
        OFBENet.load(_rewrite(saved, tmp_path / "unknown.keras", evil))


def test_load_never_runs_a_lambda(tmp_path) -> None:
    marker = tmp_path / "executed"
    fn = eval(f"lambda x: (open({str(marker)!r}, 'w').close(), x)[1]")  # noqa: S307 - the test's payload
    inputs = keras.Input(shape=(T, 3))
    out = keras.layers.Dense(3)(keras.layers.GlobalAveragePooling1D()(keras.layers.Lambda(fn)(inputs)))
    path = tmp_path / "lambda.keras"
    keras.Model(inputs, out).save(path)
    marker.unlink()  # building the model ran the lambda; loading must not
    with pytest.raises(EstimatorError, match="Lambda"):
        OFBENet.load(path)
    assert not marker.exists()
    # and Keras' own safe mode, the second line of defence, refuses it as well
    with pytest.raises(ValueError):
        keras.saving.load_model(path, safe_mode=True)
    assert not marker.exists()


def test_load_refuses_a_bad_sidecar(tmp_path, saved) -> None:
    bad = tmp_path / "sidecar.keras"
    with zipfile.ZipFile(saved) as zin, zipfile.ZipFile(bad, "w") as zout:
        for name in zin.namelist():
            data = zin.read(name)
            if name == SIDECAR_NAME:
                doc = json.loads(data)
                doc["params"]["dropout"] = 7.0
                data = json.dumps(doc).encode()
            zout.writestr(name, data)
    with pytest.raises(EstimatorError, match="dropout"):
        OFBENet.load(bad)


# --------------------------------------------------------------------------------------------
# ofbe-train


def _tiny_dataset(path: Path, two_protocols: bool = False) -> None:
    """Rotated-kind dataset, 2 devices × 10 power cycles × 2 windows of T samples, grouped folds
    (and paper-rotated folds, another assignment of the power cycles, with ``two_protocols``)."""
    protocols = {"grouped": {"description": "by power cycle", "n_folds": 5, "seed": 0}}
    if two_protocols:
        protocols["paper-rotated"] = {"description": "power cycles modulo 5", "n_folds": 5, "seed": 0}
    info = DatasetInfo(name="tiny", campaign="c", kind="rotated", title="t", description="d", labelling="l",
                       window_length=T, stride=T, fs_hz=150.0, protocols=protocols)
    rng = np.random.default_rng(0)
    with atomic_directory(path) as tmp, WindowWriter(tmp, info) as w:
        for dev in ("d1", "d2"):
            for i in range(10):
                b = rng.normal(0.0, 0.3, size=3)
                meta = pd.DataFrame({
                    "campaign": ["c"] * 2, "session": [f"s{i}"] * 2, "recording": ["r"] * 2,
                    "device": [dev] * 2, "power_cycle": [i] * 2, "window_index": [0, 1],
                    "start_sample": [0, T], **{f"bias_{a}": [b[k]] * 2 for k, a in enumerate("xyz")},
                    **{f"offset_{a}": [np.nan] * 2 for a in "xyz"},
                    "gravity_x": [0.0] * 2, "gravity_y": [0.0] * 2, "gravity_z": [1.0] * 2,
                    "roll_deg": [0.0] * 2, "pitch_deg": [0.0] * 2, "g_local": [G] * 2,
                    "fs_hz": [150.0] * 2, "label_method": ["level"] * 2, "raw_sha256": ["0" * 64] * 2,
                    "fold_grouped": [i // 2] * 2,
                    **({"fold_paper-rotated": [i % 5] * 2} if two_protocols else {})})
                x = b + np.array([0.0, 0.0, G]) + rng.normal(0.0, 0.05, size=(2, T, 3))
                w.append(x, meta)


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("ds") / "tiny"
    _tiny_dataset(path)
    return path


def test_a_failed_train_leaves_no_folders_behind(tiny, tmp_path, capsys, monkeypatch) -> None:
    """Issue 24: a training run that failed (a scheduler nobody listens on, a fit that
    raises) left empty model folders behind; what the run made is removed, what was there
    before stays."""
    from ofbe_model.ofbenet import training

    out = tmp_path / "models"
    (out / "mine").mkdir(parents=True)

    def failing(*args, **kwargs):
        raise EstimatorError("fit failed")

    monkeypatch.setattr(training, "_fit_and_summarise", failing)
    code = main([str(tiny), "--protocol", "grouped", "--out", str(out), "--max-epochs", "1", "--quiet"])
    assert code == 1 and "fit failed" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["mine"]


def test_ofbe_train_writes_models_curves_and_summary(tiny, tmp_path, capsys) -> None:
    out = tmp_path / "models"
    base = [str(tiny), "--protocol", "grouped", "--out", str(out), "--max-epochs", "2"]
    assert main([*base, "--folds", "0", "--seeds", "2", "--jobs", "2"]) == 0
    err = capsys.readouterr().err
    assert "ofbe-train grouped: 100%" in err and re.search(r"fold 0 seed [01]: [12] epochs", err)
    assert "Epoch" not in err and "step" not in err  # no Keras per-epoch lines
    assert main([*base, "--folds", "1", "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    for dev in ("d1", "d2"):
        folder = out / dataset_dirname(f"c/{dev}") / "grouped"
        assert folder.name == "grouped" and folder.parent.name == f"c__{dev}"
        summary = json.loads((folder / "training.json").read_text())
        assert summary["dataset"] == f"c/{dev}" and summary["protocol"] == "grouped"
        # the second run kept fold 0's two seeds
        assert [(f["fold"], f["seed"]) for f in summary["folds"]] == [(0, 0), (0, 1), (1, 0)]
        for entry in summary["folds"]:
            k, seed = entry["fold"], entry["seed"]
            assert entry["params"]["seed"] == seed and entry["model"] == f"fold-{k}.seed-{seed}.keras"
            assert entry["epochs_run"] <= 2 and entry["n_train"] + entry["n_val"] == 16
            assert entry["n_test"] == 2 and entry["seconds"] > 0 and np.isfinite(entry["best_val_loss"])
            history = pd.read_csv(folder / f"fold-{k}.seed-{seed}.history.csv")
            assert list(history.columns) == ["epoch", "loss", "val_loss", "learning_rate"]
            assert len(history) == entry["epochs_run"]
            png = folder / f"fold-{k}.training.png"
            assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and mpimg.imread(png)[..., :3].std() > 0.05
            model = OFBENet.load(folder / entry["model"])
            x = np.zeros((2, T, 3), dtype=np.float32)
            assert model.predict(x, pd.DataFrame({"device": [dev] * 2, "g_local": G})).shape == (2, 3)
        # two seeds are two different models
        x = np.random.default_rng(0).normal(0.0, 1.0, (2, T, 3)).astype(np.float32)
        x += np.array([0, 0, G], np.float32)
        m = pd.DataFrame({"device": [dev] * 2, "g_local": G})
        p0 = OFBENet.load(folder / "fold-0.seed-0.keras").predict(x, m)
        p1 = OFBENet.load(folder / "fold-0.seed-1.keras").predict(x, m)
        assert not np.allclose(p0, p1)
        assert not [p for p in folder.iterdir() if p.name.startswith(".")]  # no temporaries


def test_seed_count_from_params_and_flag(write_text) -> None:
    assert read_seed_count(None) == 1
    assert read_seed_count(write_text("s.yaml", "train:\n  seeds: 3\n")) == 3
    assert read_seed_count(write_text("s2.yaml", "train:\n  seeds: 3\n"), seeds=5) == 5
    assert read_params(write_text("s3.yaml", "train:\n  seeds: 3\n  dropout: 0.1\n")).dropout == 0.1
    with pytest.raises(ConfigError, match=r"train\.seeds.*an integer >= 1.*0"):
        read_seed_count(write_text("bad.yaml", "train:\n  seeds: 0\n"))
    with pytest.raises(ConfigError, match=r"--seeds"):
        read_seed_count(None, seeds=-2)


def test_ofbe_train_usage_errors_exit_2(tiny, tmp_path, capsys, write_text) -> None:
    base = [str(tiny), "--out", str(tmp_path / "m")]
    bad = write_text("params.yaml", "train:\n  max_epochs: 2\n  dropout_rate: 0.5\n")
    assert main([*base, "--protocol", "grouped", "--params", str(bad)]) == 2
    err = capsys.readouterr().err.strip()
    assert "train.dropout_rate" in err and "an unknown key" in err and len(err.splitlines()) == 1
    out_of_range = write_text("range.yaml", "train:\n  validation_split: 1.5\n")
    assert main([*base, "--protocol", "grouped", "--params", str(out_of_range)]) == 2
    assert "train.validation_split" in capsys.readouterr().err
    assert main([*base, "--protocol", "paper-rotated"]) == 2
    assert capsys.readouterr().err.strip() == ("ofbe-train: error: --protocol: expected one of the protocols "
                                               f"of {tiny} (grouped), found 'paper-rotated'")
    assert main([*base, "--protocol", "grouped", "--folds", "7"]) == 2
    assert main([str(tmp_path / "nope"), "--protocol", "grouped"]) == 2
    assert main([*base, "--protocol", "grouped", "--max-epochs", "0"]) == 2
    assert "--max-epochs" in capsys.readouterr().err
    assert not (tmp_path / "m").exists()
    assert read_params(write_text("ok.yaml", "train:\n  dropout: 0.3\n")).dropout == 0.3


NOISE = ("I0000", "E0000", "W0000", "absl::InitializeLog", "cuda", "oneDNN", "cpu_feature_guard", "NodeDef")


def test_train_and_predict_print_no_tensorflow_start_up_lines(tiny, tmp_path) -> None:
    """The terminal shows progress and results, not TensorFlow's start-up or graph messages;
    ``--verbose`` (or OFBE_VERBOSE=1) lets them through. ofbe-train's own process never starts
    TensorFlow (its fits' workers do)."""
    env = {k: v for k, v in os.environ.items() if k not in ("TF_CPP_MIN_LOG_LEVEL", "OFBE_VERBOSE")}
    out = tmp_path / "models"
    # ofbe-train's main, then whether this process (not the fit's worker) imported TensorFlow
    code = ("import sys\nfrom ofbe_model.cli.train import main\ncode = main(sys.argv[1:])\n"
            "print('tensorflow here:', 'tensorflow' in sys.modules)\nsys.exit(code)\n")
    train = subprocess.run([sys.executable, "-c", code, str(tiny), "--protocol", "grouped",
                            "--out", str(out), "--folds", "0", "--max-epochs", "1"],
                           capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)
    assert train.returncode == 0, train.stderr[-2000:]
    assert train.stdout.strip().endswith("tensorflow here: False")  # only the worker starts it
    assert "ofbe-train grouped" in train.stderr and "trained grouped" in train.stderr
    assert not [m for m in NOISE if m in train.stderr], train.stderr[-2000:]
    model = out / "c__d1" / "grouped" / "fold-0.seed-0.keras"
    session = ROOT / "raw" / "examples" / "tiny-gravity-aligned" / "ga-pc001"
    # a model of device d1 on the example's sparkfun boards: outside its domain, asked anyway
    predict = subprocess.run([sys.executable, "-m", "ofbe_model.cli.predict", str(model), str(session),
                              "--window-length", str(T), "--allow-outside-domain"], capture_output=True,
                             text=True, env=env, cwd=ROOT, timeout=300)
    assert predict.returncode == 0, predict.stderr[-2000:]
    assert '"bias_m_s2"' in predict.stdout
    assert not [m for m in NOISE if m in predict.stderr], predict.stderr[-2000:]
    loud = subprocess.run([sys.executable, "-m", "ofbe_model.cli.predict", str(model), str(session),
                           "--window-length", str(T), "--verbose", "--allow-outside-domain"],
                          capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)
    assert loud.returncode == 0 and [m for m in NOISE if m in loud.stderr]


def test_one_pool_over_several_protocols_and_workers_trains_what_one_worker_on_each_alone_does(
        tmp_path, capsys) -> None:
    """Two protocols of one dataset in one call with two workers (each worker gets fits of both
    protocols) give the models and summaries of training each protocol alone with one worker:
    the models depend neither on the number of workers nor on what else a worker trained."""
    import zipfile

    data = tmp_path / "two"
    _tiny_dataset(data, two_protocols=True)
    common = ["--folds", "0", "--max-epochs", "1", "--quiet"]
    for protocol in ("grouped", "paper-rotated"):
        assert main([str(data), "--protocol", protocol, "--out", str(tmp_path / "alone"), "--jobs", "1",
                     *common]) == 0
    assert main([str(data), "--protocol", "grouped", "paper-rotated", "--out", str(tmp_path / "pooled"),
                 "--jobs", "2", *common]) == 0
    models = sorted(p.relative_to(tmp_path / "alone") for p in (tmp_path / "alone").rglob("*.keras"))
    assert len(models) == 4 and {m.parts[1] for m in models} == {"grouped", "paper-rotated"}
    for rel in models:
        weights = [zipfile.ZipFile(tmp_path / r / rel).read("model.weights.h5") for r in ("alone", "pooled")]
        assert weights[0] == weights[1], rel
    for summary in (tmp_path / "alone").rglob("training.json"):
        rel = summary.relative_to(tmp_path / "alone")
        runs = [json.loads((tmp_path / r / rel).read_text()) for r in ("alone", "pooled")]
        for run in runs:
            for entry in run["folds"]:
                entry.pop("seconds")
        assert runs[0] == runs[1], rel
    assert main([str(data), str(tmp_path / "missing"), "--protocol", "grouped"]) == 2
    missing = tmp_path / "missing"
    assert capsys.readouterr().err.strip() == (f"ofbe-train: error: {missing}: expected a dataset folder, "
                                               "found no such folder")
    assert main([str(data), "--protocol", "grouped", "paper-gravity"]) == 2
    assert capsys.readouterr().err.strip() == ("ofbe-train: error: --protocol: expected protocols of the "
                                               "datasets given, found 'paper-gravity' in none of them")
