"""Where a rotated label's error comes from (issue 26): the reference's own bias and scale tilt
the gravity direction a label is made with. ``label_fidelity`` computes that share from the
truth alone; with a perfect reference it is zero, and what is left (the labeller's own
error) is small either way."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ofbe_data.dataset.fidelity import label_fidelity
from ofbe_data.labelling.batch import expand_sessions, label_sessions
from ofbe_data.labelling.labels import LabelParams
from ofbe_data.labelling.store import read_labels
from ofbe_data.simulator import load_config, simulate_campaign

PERFECT = {"bias_sigma_mg": 0.0, "scale_sigma": 0.0, "cross_axis_sigma_deg": 0.0}


def _fidelity(tmp: Path, reference: dict[str, float] | None) -> dict:
    overrides = {"sessions": 4, "stationary_s": [23.5, 24.5],
                 **({"reference_model": reference} if reference is not None else {})}
    simulate_campaign(load_config("rotated", overrides), tmp / "raw", seed=8, jobs=2, progress=False)
    outcomes = label_sessions(expand_sessions([tmp / "raw"]), LabelParams(min_samples=2000), tmp / "labels",
                              jobs=2, progress=False)
    assert [o.error for o in outcomes if o.error] == []
    return label_fidelity(read_labels(tmp / "labels" / "raw"), tmp / "raw" / "_truth")


@pytest.mark.slow
@pytest.mark.parametrize("reference", [None, PERFECT], ids=["paper-reference", "perfect-reference"])
def test_the_references_share_of_a_rotated_labels_error(tmp_path: Path, reference) -> None:
    fid = _fidelity(tmp_path, reference)
    assert fid["n"] == 24
    error, share, own = (np.array(list(fid[k].values())) for k in ("bias_rms_mg", "reference_rms_mg",
                                                                    "bias_own_rms_mg"))
    assert np.all(own < 0.1), fid  # the labeller's own error: sync, noise, convergence
    if reference is None:
        assert np.all(share > 0.15) and np.all(error > 2 * own), fid  # the reference's error dominates
        # the share explains the error: what is left is not larger than the share's own size
        assert np.all(np.abs(error - share) < own + 0.02), fid
    else:
        assert np.all(share == 0.0) and np.array_equal(error, own), fid
    assert "bias_sensor_frame_rms_mg" not in fid  # rotated labels are in the nominal mount's axes
