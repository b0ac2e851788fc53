"""Label fidelity: labels against the simulator's truth files (simulated campaigns only).

The simulator writes, beside each simulated campaign, ``_truth/<session>.json`` with the
apparent bias and zero-g offset of every (recording, device) (:mod:`ofbe_data.simulator`).
This module compares label rows with them; labelling itself never opens those files. The
result goes on dataset cards and into the pipeline's summary.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from ofbe_data.core.errors import OfbeError

MG = 9.80665e-3
"""One milligravity, m/s²."""
AXES = ("x", "y", "z")


TRUTH_FOLDER = "_truth"
"""Name of the truth folder inside a simulated campaign folder."""


def truth_dir_of(raw_dir: str | Path) -> Path | None:
    """The truth folder of a raw campaign folder, or None when it has none (real data)."""
    path = Path(raw_dir) / TRUTH_FOLDER
    return path if path.is_dir() else None


class TruthError(OfbeError):
    """A truth file is missing or lacks a labelled recording."""


def truth_table(truth_dir: str | Path, labels: pd.DataFrame) -> pd.DataFrame:
    """True apparent bias and offset of every label row, (n, 6) as a frame.

    Parameters
    ----------
    truth_dir
        The campaign's ``_truth`` folder.
    labels
        Label rows (``session``, ``recording``, ``device``).

    Returns
    -------
    pandas.DataFrame
        ``true_bias_x/y/z`` and ``true_offset_x/y/z`` (m/s²), index of ``labels``.

    Raises
    ------
    TruthError
        A session's truth file is missing, or it does not hold a labelled recording.
    """
    truth_dir = Path(truth_dir)
    cache: dict[str, dict[str, Any]] = {}
    out = []
    for r in labels.itertuples():
        if r.session not in cache:
            path = truth_dir / f"{r.session}.json"
            try:
                cache[r.session] = json.loads(path.read_text(encoding="utf-8"))
            except (OSError, json.JSONDecodeError) as exc:
                raise TruthError(f"{path}: expected the simulator's truth file for session {r.session}, "
                                 f"found {exc}") from None
        try:
            d = cache[r.session]["recordings"][r.recording]["devices"][r.device]
        except (KeyError, TypeError):
            raise TruthError(f"{truth_dir / (r.session + '.json')}: expected recording {r.recording}, device "
                             f"{r.device}, found no such entry") from None
        out.append([*d["apparent_bias"], *d["offset"]])
    cols = [f"true_bias_{a}" for a in AXES] + [f"true_offset_{a}" for a in AXES]
    return pd.DataFrame(np.array(out, dtype=np.float64).reshape(-1, 6), columns=cols, index=labels.index)


def label_fidelity(labels: pd.DataFrame, truth_dir: str | Path) -> dict[str, Any]:
    """RMS and largest label errors against the truth, in mg.

    Returns
    -------
    dict
        ``n``; ``bias_rms_mg`` and ``bias_max_mg`` per axis (apparent bias, the paper's
        label); ``offset_rms_mg`` / ``offset_max_mg`` per axis and ``n_offsets`` when some
        rows carry a zero-g offset.
    """
    truth = truth_table(truth_dir, labels)
    out: dict[str, Any] = {"n": len(labels)}
    for name in ("bias", "offset"):
        est = labels[[f"{name}_{a}" for a in AXES]].to_numpy(dtype=np.float64)
        tru = truth[[f"true_{name}_{a}" for a in AXES]].to_numpy()
        ok = np.all(np.isfinite(est), axis=1)
        if not ok.any():
            continue
        err = (est[ok] - tru[ok]) / MG
        if name == "offset":
            out["n_offsets"] = int(ok.sum())
        rms = np.sqrt(np.mean(err**2, axis=0))
        big = np.max(np.abs(err), axis=0)
        out[f"{name}_rms_mg"] = {a: round(float(rms[i]), 4) for i, a in enumerate(AXES)}
        out[f"{name}_max_mg"] = {a: round(float(big[i]), 4) for i, a in enumerate(AXES)}
    return out
