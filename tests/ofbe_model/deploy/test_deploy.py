"""Exports for ESP32-class devices, checked through the other tools' own code: OFBENet as TFLite
run by the LiteRT interpreter, the gravity-prior as a C header compiled by the system compiler."""

from __future__ import annotations

import hashlib
import json
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ofbe_model.deploy.c_header import (
    C_EDEVICE,
    C_EINVAL,
    C_EWINDOW,
    C_OK,
    compile_harness,
    device_indices,
    export_c_header,
    find_c_compiler,
    header_text,
    run_harness,
    table_bytes,
)
from ofbe_model.deploy.tflite import (
    dequantise_output,
    export_tflite,
    load_interpreter,
    quantise_input,
    run_tflite,
)
from ofbe_model.estimators.base import EstimatorError
from ofbe_model.estimators.common import MG
from ofbe_model.estimators.priors import GravityPrior
from ofbe_model.ofbenet.layers import model_scalings
from ofbe_model.ofbenet.network import OFBENet

pytestmark = pytest.mark.slow
"""Slow: a campaign or model fixture shared by the module (``-m "not slow"`` leaves it out)."""

G = 9.81
T_NET = 200
T_PRIOR = 3000

needs_litert = pytest.mark.skipif(
    __import__("importlib").util.find_spec("ai_edge_litert") is None,
    reason="the LiteRT interpreter is not installed (pip install ai-edge-litert, in the dev extra)")
needs_cc = pytest.mark.skipif(find_c_compiler() is None,
                              reason="no C compiler (cc, gcc or clang on PATH, or $CC) to build the C header")


def rmse(err: np.ndarray) -> float:
    """sqrt(mean ‖e‖²), the paper's vector RMSE, m/s²."""
    return float(np.sqrt(np.mean(np.sum(err**2, axis=1))))


# --------------------------------------------------------------------------------------------
# OFBENet → TFLite


def level_windows(n: int, seed: int) -> tuple[np.ndarray, np.ndarray, pd.DataFrame]:
    """Level windows of T_NET samples: a bias per pair of windows (one power cycle), gravity on z, noise."""
    rng = np.random.default_rng(seed)
    b = rng.normal(0.0, 0.3, size=(n // 2, 3)).repeat(2, axis=0)
    x = b[:, None, :] + np.array([0.0, 0.0, G]) + rng.normal(0.0, 0.05, size=(n, T_NET, 3))
    x = x.astype(np.float32)
    return x, b, pd.DataFrame({"device": "d1", "g_local": G, "power_cycle": np.arange(n) // 2})


@pytest.fixture(scope="module")
def net() -> dict:
    """A small OFBENet (~10 s), its training windows and held-out windows with labels and Keras output."""
    x, y, meta = level_windows(192, seed=0)
    est = OFBENet(max_epochs=24, es_patience=10, learning_rate=0.003, batch_size=16).fit(x, y, meta)
    xt, yt, mt = level_windows(64, seed=1)
    return {"est": est, "x": x, "xt": xt, "yt": yt, "keras": est.predict(xt, mt)}


@pytest.fixture(scope="module")
def exported(net: dict, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("tflite")
    sidecar = export_tflite(net["est"], out, net["x"], name="tiny", source="synthetic level windows")
    return out, sidecar


def test_export_writes_two_models_and_a_sidecar(net: dict, exported: tuple[Path, dict]) -> None:
    out, sidecar = exported
    assert sorted(p.name for p in out.iterdir()) == ["tiny.float32.tflite", "tiny.int8.tflite",
                                                      "tiny.tflite.json"]
    assert json.loads((out / "tiny.tflite.json").read_text()) == sidecar
    assert sidecar["format"] == "ofbe-tflite/1" and sidecar["ofbe_version"]
    assert sidecar["input_shape"] == [1, T_NET, 3] and sidecar["output_shape"] == [1, 3]
    assert sidecar["input_units"] == sidecar["output_units"] == "m/s^2"
    assert sidecar["representative"] == {"windows_used": 192, "windows_given": 192,
                                         "source": "synthetic level windows",
                                         "selection": "evenly spaced over the windows given"}
    for kind in ("float32", "int8"):
        entry = sidecar["models"][kind]
        content = (out / entry["file"]).read_bytes()
        assert entry["bytes"] == len(content) and entry["sha256"] == hashlib.sha256(content).hexdigest()
    assert sidecar["models"]["int8"]["bytes"] < 0.6 * sidecar["models"]["float32"]["bytes"]
    x_mean, x_scale, y_mean, y_std = model_scalings(net["est"].model_)
    int8 = sidecar["models"]["int8"]
    assert np.array_equal(np.float32(int8["input"]["standardise_mean"]), x_mean)
    np.testing.assert_allclose(int8["input"]["standardise_std"], 1.0 / x_scale, rtol=1e-7)  # 1/std inside
    assert np.array_equal(np.float32(int8["output"]["destandardise_mean"]), y_mean)
    assert np.array_equal(np.float32(int8["output"]["destandardise_std"]), y_std)


@needs_litert
def test_float32_model_agrees_with_keras(net: dict, exported: tuple[Path, dict]) -> None:
    out, sidecar = exported
    got = run_tflite(out / "tiny.float32.tflite", net["xt"])
    np.testing.assert_allclose(got, net["keras"], rtol=1e-4, atol=1e-4 * np.abs(net["keras"]).max())


@needs_litert
def test_int8_model_is_within_five_percent_of_the_float_rmse(net: dict, exported: tuple[Path, dict]) -> None:
    out, sidecar = exported
    float_rmse = rmse(run_tflite(out / "tiny.float32.tflite", net["xt"]) - net["yt"])
    int8_rmse = rmse(run_tflite(out / "tiny.int8.tflite", net["xt"], sidecar) - net["yt"])
    label_rms = rmse(net["yt"])
    assert float_rmse < 0.5 * label_rms  # the model has learned something to lose
    assert int8_rmse <= 1.05 * float_rmse, (int8_rmse, float_rmse)


@needs_litert
def test_the_sidecar_quantisation_is_the_interpreters(net: dict, exported: tuple[Path, dict]) -> None:
    out, sidecar = exported
    interpreter = load_interpreter(out / "tiny.int8.tflite")
    inp, outp = interpreter.get_input_details()[0], interpreter.get_output_details()[0]
    assert inp["dtype"] == outp["dtype"] == np.int8
    assert tuple(inp["shape"]) == (1, T_NET, 3)
    info = sidecar["models"]["int8"]
    for details, side in ((inp, info["input"]), (outp, info["output"])):
        assert details["quantization"] == (pytest.approx(side["scale"], rel=1e-7), side["zero_point"])
    # the firmware's m/s² → int8 is the interpreter's int8 → real, inverted to half a step
    scale, zero = inp["quantization"]
    q = quantise_input(net["xt"], sidecar)
    mean, std = np.float32(info["input"]["standardise_mean"]), np.float32(info["input"]["standardise_std"])
    z = (net["xt"] - mean) / std
    inside = (q > -128) & (q < 127)
    assert inside.mean() > 0.99
    assert np.all(np.abs((q.astype(np.float64) - zero) * scale - z)[inside] <= 0.5 * scale * (1 + 1e-5))
    # and int8 → m/s² of the raw output tensor, through the sidecar, is what run_tflite reports
    interpreter.set_tensor(inp["index"], q[:1])
    interpreter.invoke()
    raw = interpreter.get_tensor(outp["index"])
    expected = ((raw.astype(np.float64) - info["output"]["zero_point"]) * info["output"]["scale"]
                * np.asarray(info["output"]["destandardise_std"]) + info["output"]["destandardise_mean"])
    np.testing.assert_allclose(dequantise_output(raw, sidecar), expected, rtol=1e-12)
    got = run_tflite(out / "tiny.int8.tflite", net["xt"][:1], sidecar)
    np.testing.assert_allclose(got, expected, rtol=1e-12)


def test_export_is_deterministic_and_reads_a_keras_file(net: dict, exported: tuple[Path, dict],
                                                         tmp_path: Path) -> None:
    out, sidecar = exported
    path = net["est"].save(tmp_path / "model.keras")
    again = export_tflite(path, tmp_path / "again", net["x"], name="tiny", source="synthetic level windows")
    assert again["source_model"] == str(path)
    for kind in ("float32", "int8"):
        name = f"tiny.{kind}.tflite"
        assert (tmp_path / "again" / name).read_bytes() == (out / name).read_bytes()
    assert {k: v for k, v in again.items() if k != "source_model"} == \
        {k: v for k, v in sidecar.items() if k != "source_model"}


def test_export_errors_name_what_was_expected(net: dict, tmp_path: Path) -> None:
    with pytest.raises(EstimatorError, match=r"representative: expected windows of shape \(N >= 1, 200, 3\)"):
        export_tflite(net["est"], tmp_path, net["x"][:, :100], name="x")
    with pytest.raises(EstimatorError, match="representative: expected finite"):
        export_tflite(net["est"], tmp_path, np.full((2, T_NET, 3), np.nan, dtype=np.float32), name="x")
    with pytest.raises(EstimatorError, match="name: expected a file stem"):
        export_tflite(net["est"], tmp_path, net["x"], name="../up")
    with pytest.raises(EstimatorError, match="expected a fitted or loaded OFBENet"):
        export_tflite(OFBENet(), tmp_path, net["x"])
    with pytest.raises(EstimatorError, match=r"missing\.keras: expected an OFBENet \.keras model file"):
        export_tflite(tmp_path / "missing.keras", tmp_path, net["x"])
    assert list(tmp_path.iterdir()) == []


# --------------------------------------------------------------------------------------------
# gravity-prior → C header


DEVICES = ["d0", "d1", "d2", "d3"]


def prior_windows(rng: np.random.Generator, devices: list[str], n_per: int, offset: dict,
                  misalign: dict) -> tuple[np.ndarray, np.ndarray, pd.DataFrame]:
    """Windows f = A_d·u·g + b + noise at random tilts: device offsets N(0, 80 mg), turn-on spread
    (4, 4, 12) mg, a small misalignment A_d per device (what the direction model learns)."""
    dev = np.repeat(devices, n_per)
    spread = np.array([4.0, 4.0, 12.0]) * MG
    b = np.array([offset[d] for d in dev]) + rng.standard_normal((len(dev), 3)) * spread
    u = rng.standard_normal((len(dev), 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    mean = G * np.einsum("nij,nj->ni", np.array([misalign[d] for d in dev]), u) + b
    x = (mean[:, None, :] + rng.standard_normal((len(dev), T_PRIOR, 3)) * 0.02).astype(np.float32)
    return x, b, pd.DataFrame({"device": dev, "g_local": G})


@pytest.fixture(scope="module")
def prior_data() -> dict:
    """240 training windows of four devices; 100 test windows: 80 of those devices, 20 of a new one."""
    rng = np.random.default_rng(2024)
    offset = {d: rng.normal(0.0, 80.0 * MG, 3) for d in [*DEVICES, "new"]}
    misalign = {d: np.eye(3) + rng.normal(0.0, 2e-3, (3, 3)) for d in [*DEVICES, "new"]}
    train = prior_windows(rng, DEVICES, 60, offset, misalign)
    test = [prior_windows(rng, DEVICES, 20, offset, misalign),
            prior_windows(rng, ["new"], 20, offset, misalign)]
    xt = np.concatenate([t[0] for t in test])
    mt = pd.concat([t[2] for t in test], ignore_index=True)
    return {"train": train, "xt": xt, "mt": mt}


@needs_cc
@pytest.mark.parametrize("params", [{}, {"direction_model": True}, {"per_device": False}],
                         ids=["per-device", "direction-model", "mixture-only"])
def test_the_c_function_matches_the_python_estimator(prior_data: dict, params: dict, tmp_path: Path) -> None:
    gp = GravityPrior(**params).fit(*prior_data["train"])
    gp.save(tmp_path / "prior.json")
    header = export_c_header(tmp_path / "prior.json", tmp_path / "include" / "prior.h", name="prior")
    exe = compile_harness(header, tmp_path / "build")
    xt, mt = prior_data["xt"], prior_data["mt"]
    index = device_indices(gp, mt["device"])
    assert index.tolist() == [0] * 20 + [1] * 20 + [2] * 20 + [3] * 20 + [-1] * 20
    bias, std, status, _ = run_harness(exe, xt, mt["g_local"].to_numpy(), index, tmp_path / "build")
    assert np.all(status == C_OK)
    py_bias, py_std = gp.predict(xt, mt), gp.predict_std(xt, mt)
    # float32 rounding: one device's posterior agrees to ~1e-6 m/s²; the mixture's to ~2e-5 m/s²
    # on biases of ~1 m/s² (its log weights, −innovation²/s ~ 10²…10³, keep a float32 ulp of
    # 1e-5…6e-5, which moves the mean by w(1 − w)·(μ_i − μ_j)); both well inside these bounds
    np.testing.assert_allclose(bias, py_bias, rtol=1e-4, atol=1e-5)
    np.testing.assert_allclose(std, py_std, rtol=1e-4, atol=1e-5)


@needs_cc
def test_the_c_function_reports_bad_arguments(prior_data: dict, tmp_path: Path) -> None:
    gp = GravityPrior().fit(*prior_data["train"])
    exe = compile_harness(export_c_header(gp, tmp_path, name="prior"), tmp_path)
    x = prior_data["xt"][:4].copy()
    x[3] = 0.0
    g = np.array([G, G, 0.0, G], dtype=np.float32)
    bias, std, status, _ = run_harness(exe, x, g, np.array([0, 4, 0, 0]), tmp_path)
    assert status.tolist() == [C_OK, C_EDEVICE, C_EINVAL, C_EWINDOW]
    assert np.all(np.isfinite(bias[0])) and np.all(std[0] > 0)


@needs_cc
def test_device_ids_survive_any_characters(prior_data: dict, tmp_path: Path) -> None:
    x, y, meta = prior_data["train"]
    names = {"d0": 'dut "A"\\1', "d1": "capteur-é", "d2": "x??=y", "d3": "*/ tab\t"}
    gp = GravityPrior().fit(x, y, meta.assign(device=meta["device"].map(names)))
    header = export_c_header(gp, tmp_path / "ids.h", name="ids")
    text = header.read_text(encoding="ascii")
    assert "#define OFBE_GP_N_DEVICES 4" in text and "#ifndef OFBE_GP_IDS_H" in text
    assert "malloc" not in text and '#define OFBE_GP_VERSION "' in text
    src = tmp_path / "ids.c"
    src.write_text('#include <stdio.h>\n#include "ids.h"\nint main(void) {\n    int i;\n'
                   '    for (i = 0; i < OFBE_GP_N_DEVICES; ++i) printf("%s\\n", ofbe_gp_device_ids[i]);\n'
                   "    return 0;\n}\n")
    compiler = find_c_compiler()
    subprocess.run([compiler, "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror",
                    "-o", str(tmp_path / "ids"), str(src), "-lm"], check=True, capture_output=True)
    shown = subprocess.run([str(tmp_path / "ids")], check=True, capture_output=True).stdout.decode("utf-8")
    assert shown.splitlines() == sorted(names.values())
    assert table_bytes(gp) == 4 * (1 + 4 * 25) + sum(len(n.encode()) + 1 for n in names.values()) + 4 * 4


def test_export_c_header_errors(prior_data: dict, tmp_path: Path) -> None:
    with pytest.raises(EstimatorError, match="expected a fitted gravity-prior"):
        export_c_header(GravityPrior(), tmp_path / "a.h")
    bad = tmp_path / "prior.json"
    bad.write_text('{"format": "something else"}')
    with pytest.raises(EstimatorError, match=r"prior\.json: format: expected 'ofbe-gravity-prior/1'"):
        export_c_header(bad, tmp_path / "a.h")
    gp = GravityPrior().fit(*prior_data["train"])
    with pytest.raises(EstimatorError, match="name: expected letters"):
        export_c_header(gp, tmp_path / "a.h", name="9 lives")
    assert not (tmp_path / "a.h").exists()
    assert header_text(gp, name="p") == header_text(gp, name="p")  # deterministic text


def test_ofbe_export_c_header_writes_what_export_c_header_writes(prior_data: dict, tmp_path: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    from ofbe_data.cli.export import main as export_main

    gp = GravityPrior().fit(*prior_data["train"])
    gp.save(tmp_path / "prior.json")
    assert export_main(["c-header", str(tmp_path / "prior.json"), "--out", f"{tmp_path / 'out'}/"]) == 0
    direct = export_c_header(tmp_path / "prior.json", tmp_path / "direct" / "prior.h", name="prior")
    assert (tmp_path / "out" / "prior.h").read_bytes() == direct.read_bytes()
    assert capsys.readouterr().err == "ofbe-export: c-header: 1 result file written\n"


def test_ofbe_export_tflite_needs_the_training_windows(net: dict, tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    from ofbe_data.cli.export import main as export_main

    model = tmp_path / "tiny.keras"
    net["est"].save(model)
    assert export_main(["tflite", str(model), "--out", str(tmp_path / "out")]) == 2
    assert "tflite needs --dataset DIR" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
