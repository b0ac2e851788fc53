"""Issue 36: ``ofbe-predict`` applies ``ofbe-label``'s plausibility checks. A file whose x axis is
dead (exactly 0) got a bias from predict while label rejected it as ``saturated``; now every
recording label rejects (garbled, implausible norm, dead, stuck or clipped axes) is reported by
predict with label's reason and words, one line naming the file, and gets no bias.

Sessions are copies of raw/examples/tiny-gravity-aligned in tmp_path whose sparkfun-1 file is
rewritten through ``write_ofbe_logger`` with its counts edited; the model is a gravity-prior
fitted on synthetic z-up windows of both devices at 150 Hz (the example's domain).
"""

from __future__ import annotations

import json
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from ofbe_data.io.formats.ofbe_logger import read_ofbe_logger, write_ofbe_logger
from ofbe_data.io.gravity import G0
from ofbe_data.labelling.labels import LabelParams, label_session
from ofbe_model.cli.predict import main as predict_main
from ofbe_model.estimators.priors import GravityPrior
from tests.helpers.paths import ROOT

EXAMPLE = ROOT / "raw" / "examples" / "tiny-gravity-aligned" / "ga-pc001"
T = 1000

Edit = Callable[[np.ndarray], np.ndarray]


def _dead_x(c: np.ndarray) -> np.ndarray:
    c[:, 0] = 0
    return c


def _stuck_y(c: np.ndarray) -> np.ndarray:
    c[:, 1] = 37
    return c


def _clipped_z(c: np.ndarray) -> np.ndarray:
    c[:, 2] = np.minimum(c[:, 2], int(np.median(c[:, 2])))  # half the samples at the top
    return c


def _times_four(c: np.ndarray) -> np.ndarray:
    return c * 4


@pytest.fixture(scope="module")
def model(tmp_path_factory) -> Path:
    rng = np.random.default_rng(36)
    X = (np.array([0.0, 0.0, G0]) + rng.normal(0.0, 0.02, (40, T, 3))).astype(np.float32)
    y = rng.normal(0.0, 0.05, (40, 3))
    meta = pd.DataFrame({"device": ["sparkfun-1", "sparkfun-2"] * 20, "g_local": [9.7954] * 40,
                         "fs_hz": [150.0] * 40})
    path = tmp_path_factory.mktemp("model") / "gp.json"
    GravityPrior().fit(X, y, meta).save(path)
    return path


def _session(tmp_path: Path, edit: Edit | None = None,
             corrupt: Callable[[list[bytes]], list[bytes]] | None = None) -> tuple[Path, Path]:
    """A copy of the example session with sparkfun-1's counts edited; (session, edited file)."""
    session = tmp_path / "ga-pc001"
    shutil.copytree(EXAMPLE, session)
    path = session / "rec-01" / "sparkfun-1.csv"
    if edit is not None or corrupt is not None:
        rec = read_ofbe_logger(path)
        t_us = np.rint(rec.t * 1e6).astype(np.int64)
        counts = np.rint(rec.acc / G0 * float(rec.header["lsb_per_g"])).astype(np.int64)
        counts = counts if edit is None else edit(counts.copy())
        write_ofbe_logger(path, t_us, counts, rec.header, (), corrupt)
    return session, path


def _predict(capsys, model: Path, *args: str) -> tuple[int, dict, str]:
    code = predict_main([str(model), *args, "--window-length", str(T)])
    captured = capsys.readouterr()
    return code, json.loads(captured.out), captured.err


def _garble(lines: list[bytes]) -> list[bytes]:
    return [b"4294,x!" if i % 40 == 7 else line for i, line in enumerate(lines)]


@pytest.mark.parametrize(("edit", "corrupt", "reason"), [
    (_dead_x, None, "saturated"),
    (_stuck_y, None, "saturated"),
    (_clipped_z, None, "saturated"),
    (_times_four, None, "implausible-norm"),
    (None, _garble, "garbled"),
])
def test_predict_rejects_what_label_rejects_with_its_reason(tmp_path, capsys, model, edit, corrupt,
                                                            reason) -> None:
    session, path = _session(tmp_path, edit, corrupt)
    (rejection,) = label_session(session, LabelParams(min_samples=T)).rejections
    assert (rejection.device, rejection.reason) == ("sparkfun-1", reason)
    code, out, err = _predict(capsys, model, str(session))
    assert code == 1
    bad, good = out["results"]
    assert bad["file"] == str(path) and bad["error"] == f"{reason}: {rejection.detail}"
    assert "bias_m_s2" not in bad and len(good["bias_m_s2"]) == 3  # the other device still gets one
    assert [line for line in err.splitlines() if "error" in line] == [
        f"ofbe-predict: error: {path}: {reason}: {rejection.detail}"]


def test_dead_axis_exact_message_and_nothing_predicted_from_a_bare_file(tmp_path, capsys, model) -> None:
    _, path = _session(tmp_path, _dead_x)
    code, out, err = _predict(capsys, model, str(path), "--device", "sparkfun-1", "--g-local", "9.7954")
    detail = ("saturated: the x axis reads 0 m/s² on every sample of the stationary segment while the others "
              "vary: clipped at the logger's range, or stuck (record with a wider range)")
    assert code == 1
    assert [r.get("error") for r in out["results"]] == [detail]
    assert "bias_m_s2" not in out["results"][0]
    assert f"ofbe-predict: error: {path}: {detail}\n" in err


def test_an_axis_stuck_only_in_the_models_window_is_refused(tmp_path, capsys, model) -> None:
    """Label judges the whole still run, where the stuck value is no extreme (and accepts it); the
    model would see only the stuck part."""
    session, path = _session(tmp_path, _stuck_first)
    assert label_session(session, LabelParams(min_samples=T)).rejections == []
    code, out, _ = _predict(capsys, model, str(path), "--device", "sparkfun-1", "--g-local", "9.7954")
    assert code == 1
    assert out["results"][0]["error"] == (
        f"saturated: the x axis reads {4 / 256 * G0:.5g} m/s² on every sample of the window the model sees "
        "while the others vary: clipped at the logger's range, or stuck (record with a wider range)")


def _stuck_first(c: np.ndarray) -> np.ndarray:
    c[:T + 100, 0] = 4  # the mode of x (1 to 7 counts): the first window's worth, then it varies again
    return c


def test_the_untouched_example_is_predicted(tmp_path, capsys, model) -> None:
    session, _ = _session(tmp_path)
    assert label_session(session, LabelParams(min_samples=T)).rejections == []
    code, out, err = _predict(capsys, model, str(session))
    assert code == 0 and "error" not in err
    assert [len(r["bias_m_s2"]) for r in out["results"]] == [3, 3]
