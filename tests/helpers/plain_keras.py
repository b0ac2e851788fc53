"""Run ofbe's saved models in a fresh interpreter with plain Keras 3, never importing ofbe.

What a user of another tool does with ``final.keras`` or a fold model: ``keras.saving.load_model``
in safe mode (the default), no custom objects, then predict. The tests compare the result with
``OFBENet.load(path).predict`` in the parent process.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

#: The child's program: keras and numpy only; it fails when anything of ofbe got imported.
PLAIN_KERAS = """\
import sys

import keras
import numpy as np

model = keras.saving.load_model(sys.argv[1])  # safe_mode=True, the default; no custom_objects
x = np.load(sys.argv[2])
batch, predicted = model.predict_on_batch(x), model.predict(x, verbose=0)
np.save(sys.argv[3], np.stack([np.asarray(batch), np.asarray(predicted)]))
ofbe = sorted(m for m in sys.modules if m.split(".")[0] in ("ofbe_data", "ofbe_model"))
assert not ofbe, f"ofbe was imported: {ofbe}"
print("PLAIN-KERAS-OK", keras.__version__)
"""


def plain_keras_predict(model: Path, windows: np.ndarray, tmp: Path) -> np.ndarray:
    """Predictions of ``model`` by plain Keras in a fresh ``python -c`` (``sys.executable``).

    Parameters
    ----------
    model
        A ``.keras`` file.
    windows
        (N, T, 3) float32 m/s², N ≤ 32 (one batch for ``predict_on_batch`` and for ``predict``).
    tmp
        A scratch folder; also the child's working directory (so the repository is not on its path).

    Returns
    -------
    np.ndarray
        (2, N, 3) float32: ``predict_on_batch`` and ``predict``.
    """
    assert windows.shape[0] <= 32
    tmp.mkdir(parents=True, exist_ok=True)
    np.save(tmp / "windows.npy", np.asarray(windows, dtype=np.float32))
    env = {**os.environ, "TF_CPP_MIN_LOG_LEVEL": "3"}
    proc = subprocess.run([sys.executable, "-c", PLAIN_KERAS, str(Path(model).resolve()),
                           str(tmp / "windows.npy"), str(tmp / "plain.npy")],
                          capture_output=True, text=True, env=env, cwd=tmp, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "PLAIN-KERAS-OK" in proc.stdout
    return np.load(tmp / "plain.npy")
