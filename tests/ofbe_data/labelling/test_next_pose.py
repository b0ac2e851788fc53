"""The next pose to record (methods.md §8): the full model's expected standard errors from the
poses found, and the cube orientations that determine it or shrink its largest error; and what
``ofbe-session check`` prints for a simulated multi-position session: the label's own model,
standard errors and reason, then the next poses.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ofbe_data.labelling.conventions import matrix_from_imutk
from ofbe_data.labelling.multiposition._advice import ladder_fit, report_lines
from ofbe_data.labelling.multiposition._fit import fit_poses, parameter_names
from ofbe_data.labelling.multiposition._ladder import choose_fit
from ofbe_data.labelling.multiposition._next_pose import (
    MG,
    cube_directions,
    describe_direction,
    expectation_from_jacobian,
    expected_covariance,
    linearisation_point,
    next_poses,
    pose_jacobian,
)

G = 9.79538
S_TRUE = np.array([1.012, 0.991, 1.004])
ANGLES_TRUE = np.array([0.002, -0.003, 0.0015])
B_TRUE = np.array([0.05, -0.11, 0.08])
A_TRUE = matrix_from_imutk(S_TRUE, ANGLES_TRUE)
X_TRUE = np.concatenate([B_TRUE, S_TRUE, ANGLES_TRUE])


def _means(u: np.ndarray, sigma: float = 0.0, rng: np.random.Generator | None = None) -> np.ndarray:
    """Pose means with specific force along the unit rows of ``u`` (true A, b), plus noise."""
    m = G * np.asarray(u) @ A_TRUE.T + B_TRUE
    return m if rng is None else m + rng.normal(0.0, sigma, m.shape)


def _faces() -> np.ndarray:
    return np.vstack([np.eye(3), -np.eye(3)])


def test_cube_directions_are_26_distinct_symmetric_unit_vectors() -> None:
    u = cube_directions()
    assert u.shape == (26, 3)
    np.testing.assert_allclose(np.linalg.norm(u, axis=1), 1.0, rtol=0, atol=1e-15)
    assert len({tuple(np.round(r, 12)) for r in u}) == 26
    as_set = {tuple(np.round(r, 12)) for r in u}
    assert {tuple(np.round(-r, 12)) for r in u} == as_set  # symmetric under u → −u
    for perm in ([1, 0, 2], [2, 1, 0], [0, 2, 1]):  # and under swapping axes
        assert {tuple(np.round(r[perm], 12)) for r in u} == as_set
    nonzero = np.count_nonzero(np.abs(u) > 1e-12, axis=1)
    assert list(np.bincount(nonzero)) == [0, 6, 12, 8]
    assert np.array_equal(cube_directions(), u)  # fixed order


def test_describe_direction_names_the_axes_that_point_up() -> None:
    assert describe_direction(np.array([1.0, 1.0, 0.0])) == "+x+y (x up 45°, y up 45°, z level)"
    assert describe_direction(np.array([0.0, 0.0, -1.0])) == "-z (z straight down, x level, y level)"
    assert describe_direction(np.array([1.0, -1.0, 1.0])) == "+x-y+z (x up 35°, y down 35°, z up 35°)"


def test_six_faces_leave_the_full_model_undetermined_and_the_suggestions_fix_it() -> None:
    rng = np.random.default_rng(7)
    faces = np.vstack([_faces(), _faces()])  # each face twice: 12 poses, enough for the full model's count
    means = _means(faces)
    x, source = linearisation_point(means, G)
    assert source == "scale-offset"  # the full fit is not determined: its fallback
    e = expectation_from_jacobian(pose_jacobian(means, G, x), 1e-3)
    assert not e.determined
    names = parameter_names("full")
    undetermined = {n for n, u in zip(names, e.undetermined, strict=True) if u}
    # faces fix b and s_x; s_y trades off against mis_yz, s_z against mis_zy and mis_zx
    assert undetermined == {"imutk_s_y", "imutk_s_z", "imutk_mis_yz", "imutk_mis_zy", "imutk_mis_zx"}
    assert np.all(np.isfinite(e.se[:4])) and np.all(e.se[:3] < 1e-3)
    assert np.all(np.isinf(np.diag(expected_covariance(means, G, x, sigma=1e-3))[4:]))
    # check says what the label writes (the ladder's choice: here the six-face fit), never the
    # norms' "undetermined" for parameters the label fits (issue 33)
    lines = report_lines("dut", means, G, 1e-3)
    choice = choose_fit(means, G)
    assert lines[0].startswith(f"dut: the label fits {choice.fit.model} from 12 poses, standard errors ")
    # (noise-free poses: the reason's test statistics are rounding noise, compare its start)
    assert lines[1].startswith(f"dut: why: {choice.reason.split(';')[0]};")
    assert "inf" not in lines[0]

    picks = next_poses(means, G, x, sigma=1e-3, n=3)
    assert len(picks) == 3
    dirs = np.array([u for u, _ in picks])
    assert max(np.count_nonzero(np.abs(u) > 1e-12) for u in dirs) >= 2  # off-axis information
    assert not any(np.count_nonzero(np.abs(u) > 1e-12) == 1 for u in dirs)  # no axis face again
    assert np.isfinite(picks[-1][1]) and picks[-1][1] < 5e-3  # determined after all three (σ = 1e-3)
    assert next_poses(means, G, x, sigma=1e-3, n=3)[0][0].tolist() == dirs[0].tolist()  # deterministic

    before = fit_poses(_means(faces, 1e-3, rng), G, "full", 1000)
    assert not before.determined
    after = fit_poses(_means(np.vstack([faces, dirs]), 1e-3, rng), G, "full", 1000)
    assert after.determined, after.reason
    np.testing.assert_allclose(after.offset, B_TRUE, atol=5e-3)


@pytest.mark.slow
def test_expected_se_matches_the_scatter_of_repeated_fits() -> None:
    rng = np.random.default_rng(2024)
    u = rng.normal(size=(24, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    sigma = 2e-3
    expected = np.sqrt(np.diag(expected_covariance(_means(u), G, X_TRUE, sigma=sigma)))
    fits = [fit_poses(_means(u, sigma, rng), G, "full", 1000) for _ in range(200)]
    assert all(f.determined for f in fits)
    params = np.array([f.params for f in fits])
    empirical = params.std(axis=0, ddof=1)
    np.testing.assert_allclose(empirical[:3], expected[:3], rtol=0.2)  # the offsets
    np.testing.assert_allclose(empirical, expected, rtol=0.25)  # and every other parameter
    # and the fit's own covariance agrees with the prediction at the truth
    np.testing.assert_allclose(np.sqrt(np.diag(fits[0].covariance)) / expected, 1.0, atol=0.35)


def test_a_determined_set_is_linearised_at_its_full_fit() -> None:
    rng = np.random.default_rng(3)
    u = cube_directions()[6:]  # edges and corners
    means = _means(u, 1e-3, rng)
    x, source = linearisation_point(means, G)
    assert source == "full"
    np.testing.assert_allclose(x, X_TRUE, atol=3e-3)
    e = expectation_from_jacobian(pose_jacobian(means, G, x), 1e-3)
    assert e.determined and not e.undetermined.any()
    lines = report_lines("dut", means, G, float("nan"))  # NaN residual: σ = 1 mm/s² for the planning
    assert len(lines) == 3 and lines[0].startswith("dut: the label fits full from 20 poses, standard errors")
    assert "angles not fitted" not in lines[0] and lines[1].startswith("dut: why: full: 20 poses")
    # the label fits full now: its own largest standard error beside the one expected (issue 36)
    now_label = ladder_fit(means, G).largest(G)
    assert lines[2].endswith(f" mg after each); the label states {now_label / MG:.3g} mg now"), lines[2]
    picks = next_poses(means, G, x, 1e-3)
    worst = [w for _, w in picks]
    now = float(np.max(e.se * np.array([1, 1, 1, G, G, G, G, G, G])))
    assert now > worst[0] >= worst[1] >= worst[2]  # each pose lowers the largest error


@pytest.mark.slow
def test_check_prints_expected_se_and_next_poses(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from ofbe_data.cli.session import main
    from ofbe_data.io.manifest import load_manifest
    from ofbe_data.labelling.labels import label_params_from, label_session
    from ofbe_data.simulator import load_config, simulate_campaign

    simulate_campaign(load_config("tiny-multi-position"), tmp_path / "mp", seed=1, jobs=1, progress=False)
    folder = sorted(p for p in (tmp_path / "mp").iterdir() if (p / "session.yaml").exists())[0]
    params = tmp_path / "params.yaml"
    params.write_text("label:\n  min_samples: 500\n", encoding="utf-8")
    assert main(["check", str(folder), "--params", str(params)]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    summary = next(i for i, line in enumerate(lines) if line.startswith("  → would label"))
    labels = label_session(folder, label_params_from({"min_samples": 500}, "test"))
    for dev in load_manifest(folder).duts:
        row = next(r for r in labels.rows if r["device"] == dev.id)
        se = next(i for i, line in enumerate(lines) if line.startswith(f"  {dev.id}: the label fits "))
        nxt = next(i for i, line in enumerate(lines) if line.startswith(f"  {dev.id}: next poses to record"))
        assert se < nxt < summary
        assert lines[se].startswith(f"  {dev.id}: the label fits {row['fit_model']} from ")
        assert f"offset x, y, z {row['offset_x_se'] / MG:.3g}, " in lines[se]  # the label's own numbers
        assert lines[se + 1] == f"  {dev.id}: why: {row['fit_model_reason']}"
        assert "1. " in lines[nxt] and "3. " in lines[nxt] and " up " in lines[nxt]
        assert "with them the label's full model is expected to state a largest standard error" in lines[nxt]
        assert "inf" not in lines[nxt]
    assert main(["check", str(folder), "--params", str(params)]) == 0
    assert capsys.readouterr().out == out  # deterministic
    assert MG == pytest.approx(9.80665e-3)
