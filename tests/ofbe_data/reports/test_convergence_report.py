"""The convergence report on the default gravity-aligned campaign (acceptance: mean on x in
4000–5000 samples, and the report says so), its files, determinism and bad inputs."""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest

from ofbe_data.cli import convergence as convergence_cli
from ofbe_data.core.errors import OfbeError
from ofbe_data.labelling.batch import expand_sessions
from ofbe_data.labelling.convergence import convergence_index, read_recommendation
from ofbe_data.labelling.labels import LabelParams, label_session
from ofbe_data.reports import convergence as cr
from ofbe_data.reports.convergence import ConvergenceParams, analyse, write_report
from ofbe_data.simulator import load_config, simulate_campaign

pytestmark = pytest.mark.slow
"""Slow: a campaign or model fixture shared by the module (``-m "not slow"`` leaves it out)."""

FILES = ("convergence.json", "convergence.md", "convergence_histogram.png", "convergence_example.png",
         "convergence_indices.csv", "allan.csv")


@pytest.fixture(scope="module")
def default_ga(tmp_path_factory) -> tuple[Path, cr.Analysis, dict]:
    """The default gravity-aligned campaign (seed 1, as params.yaml), analysed and reported."""
    tmp = tmp_path_factory.mktemp("conv")
    simulate_campaign(load_config("gravity-aligned"), tmp / "raw", seed=1, jobs=2, progress=False)
    analysis = analyse(expand_sessions([tmp / "raw"]), LabelParams(), jobs=2, progress=False)
    doc = write_report(analysis, tmp / "report", ConvergenceParams(), LabelParams())
    return tmp, analysis, doc


def test_default_campaign_converges_in_the_papers_band(default_ga) -> None:
    tmp, analysis, doc = default_ga
    x = doc["axes"]["x"]
    assert doc["n_recordings"] == 400 and x["n_not_converged"] == 0
    assert 4000 <= x["mean"] <= 5000
    assert doc["x_mean_within_paper_band"] is True
    assert doc["recommended_label_start"] == int(np.ceil(x["mean"] / 100) * 100)
    md = (tmp / "report" / "convergence.md").read_text()
    assert f"converges after {x['mean']:.0f} ± {x['std']:.0f} samples" in md
    assert "inside the paper's 4000–5000 band" in md
    # z is noisier, so it converges later (datasheet 430 vs 290 µg/√Hz)
    assert doc["axes"]["z"]["mean"] > 1.2 * x["mean"]


def test_indices_are_the_labellers(default_ga) -> None:
    """The report's indices are those ofbe-label writes (same code, same segment)."""
    tmp, analysis, doc = default_ga
    session = tmp / "raw" / "ga-pc007"
    labels = label_session(session, LabelParams())
    report = {(r["session"], r["recording"], r["device"]): r for r in doc["recordings"]}
    assert labels.rows
    for row in labels.rows:
        got = report[(row["session"], row["recording"], row["device"])]
        assert [got[f"convergence_{a}"] for a in "xyz"] == [row[f"convergence_{a}"] for a in "xyz"]


def test_example_and_allan(default_ga) -> None:
    tmp, analysis, doc = default_ga
    ex = doc["example"]
    assert abs(ex["index"] - doc["axes"]["x"]["mean"]) < 100
    # the Allan white-noise level is the simulator's: 3.5 mg noise and 3.9 mg/LSB quantisation
    expected = np.hypot(3.5, 3.9 / np.sqrt(12))
    for dev, a in doc["allan"].items():
        assert a["recordings"] == 100, dev
        assert a["white_noise_rms_mg"]["x"] == pytest.approx(expected, rel=0.03)
        assert a["white_noise_rms_mg"]["z"] == pytest.approx(np.hypot(5.2, 3.9 / np.sqrt(12)), rel=0.03)
    for name in FILES + tuple(f"allan_{d}.png" for d in doc["allan"]):
        assert (tmp / "report" / name).stat().st_size > 1000, name
    img = mpimg.imread(tmp / "report" / "convergence_histogram.png")
    assert img.shape[1] >= 1200


def test_report_is_deterministic(default_ga, tmp_path) -> None:
    tmp, analysis, doc = default_ga
    write_report(analysis, tmp_path / "again", ConvergenceParams(), LabelParams())
    for name in sorted(p.name for p in (tmp / "report").iterdir()):
        assert (tmp_path / "again" / name).read_bytes() == (tmp / "report" / name).read_bytes(), name


def test_recommendation_rules(default_ga, tmp_path) -> None:
    tmp, analysis, doc = default_ga
    z = write_report(analysis, tmp_path / "z", ConvergenceParams(axis="z", statistic="p95", round_to=500),
                     LabelParams())
    assert z["recommended_label_start"] == int(np.ceil(z["axes"]["z"]["p95"] / 500) * 500)
    assert z["recommended_label_start"] > doc["recommended_label_start"]
    assert read_recommendation(tmp_path / "z" / "convergence.json") == z["recommended_label_start"]


def test_read_recommendation_errors(tmp_path) -> None:
    with pytest.raises(OfbeError, match="expected a convergence report .*found no such file"):
        read_recommendation(tmp_path / "none.json")
    bad = tmp_path / "bad.json"
    bad.write_text("[1, 2")
    with pytest.raises(OfbeError, match="bad.json: expected a convergence report in JSON"):
        read_recommendation(bad)
    bad.write_text(json.dumps({"format": "other", "recommended_label_start": 4500}))
    with pytest.raises(OfbeError, match="found format 'other'"):
        read_recommendation(bad)


def test_cli_on_the_tiny_example(examples, tmp_path, capsys) -> None:
    out = tmp_path / "rep"
    assert convergence_cli.main([str(examples / "tiny-gravity-aligned"), "--out", str(out), "--quiet"]) == 0
    doc = json.loads((out / "convergence.json").read_text())
    assert doc["campaigns"] == ["tiny-gravity-aligned"]
    # tiny recordings are too short for the Allan curves; the rest of the report is there
    assert doc["allan"] == {}
    for r in doc["recordings"]:
        assert r["convergence_x"] == -1 or 1 <= r["convergence_x"] <= r["n_samples"]


def test_cli_bad_inputs(examples, tmp_path, capsys) -> None:
    assert convergence_cli.main([str(tmp_path / "missing"), "--out", str(tmp_path / "o")]) == 2
    assert "missing: expected a session or campaign folder" in capsys.readouterr().err
    params = tmp_path / "p.yaml"
    params.write_text("convergence:\n  axis: w\n")
    assert convergence_cli.main([str(examples / "tiny-gravity-aligned"), "--params", str(params),
                    "--out", str(tmp_path / "o")]) == 2
    assert "convergence.axis: expected x, y or z, found 'w'" in capsys.readouterr().err
    assert convergence_cli.main([str(examples / "tiny-gravity-aligned"), "--example", "no/such/row",
                                 "--quiet", "--out", str(tmp_path / "o")]) == 1
    assert "--example: expected SESSION/RECORDING/DEVICE" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_convergence_index_agrees_with_step_average() -> None:
    from ofbe_data.labelling.convergence import step_average

    x = np.random.default_rng(3).normal(0.0, 0.034, 9000)
    k = convergence_index(x)
    avg = step_average(x)
    assert k > 0 and avg[k - 1] < 5e-6 and np.all(~(avg[: k - 1] < 5e-6))
