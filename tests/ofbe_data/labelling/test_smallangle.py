import math

import numpy as np
import pytest

from ofbe_data.labelling.orientation import roll_pitch
from ofbe_data.labelling.smallangle import (
    analyse,
    gravity_direction,
    leak_g,
    leak_surface,
    symmetric_grid,
    threshold_angle,
)

ASIN_50MG = math.degrees(math.asin(0.05))


def test_gravity_direction_level_and_quarter_turns():
    np.testing.assert_allclose(gravity_direction(0.0, 0.0), [0.0, 0.0, 1.0])
    np.testing.assert_allclose(gravity_direction(90.0, 0.0), [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(gravity_direction(0.0, 90.0), [-1.0, 0.0, 0.0], atol=1e-15)


def test_gravity_direction_broadcasts_to_unit_vectors():
    u = gravity_direction(np.zeros((4, 1)), np.linspace(-30.0, 30.0, 5))
    assert u.shape == (4, 5, 3)
    np.testing.assert_allclose(np.linalg.norm(u, axis=-1), 1.0, rtol=1e-15)


def test_round_trip_with_roll_pitch():
    rng = np.random.default_rng(7)
    roll = rng.uniform(-179.9, 179.9, 500)
    pitch = rng.uniform(-89.9, 89.9, 500)
    u = gravity_direction(roll, pitch)
    back = np.array([roll_pitch(v) for v in u])
    np.testing.assert_allclose(back[:, 0], roll, atol=1e-9)
    np.testing.assert_allclose(back[:, 1], pitch, atol=1e-9)


@pytest.mark.parametrize("direction", ["pitch", "roll", "combined"])
def test_threshold_is_asin_of_the_limit(direction):
    # max-axis: a tilt α leaks sin α on the tangential axis; with equal roll and pitch the
    # x leak is still sin α, so every direction gives asin(0.05) = 2.8660°
    assert threshold_angle(0.05, direction) == pytest.approx(ASIN_50MG, abs=1e-6)
    assert ASIN_50MG == pytest.approx(2.8660, abs=5e-5)


def test_threshold_scales_with_the_limit():
    assert threshold_angle(0.2, "pitch") == pytest.approx(math.degrees(math.asin(0.2)), abs=1e-9)
    assert threshold_angle(0.01, "roll") == pytest.approx(math.degrees(math.asin(0.01)), abs=1e-9)


def test_norm_thresholds_closed_forms():
    # ‖u − e_z‖ = 2 sin(γ/2), γ the total tilt, cos γ = cos φ cos θ
    single = 2.0 * math.degrees(math.asin(0.025))
    assert threshold_angle(0.05, "pitch", "norm") == pytest.approx(single, abs=1e-9)
    gamma = 2.0 * math.asin(0.025)
    combined = math.degrees(math.acos(math.sqrt(math.cos(gamma))))
    assert threshold_angle(0.05, "combined", "norm") == pytest.approx(combined, abs=1e-9)
    assert combined < single


def test_threshold_rejects_bad_arguments():
    with pytest.raises(ValueError, match="limit_g"):
        threshold_angle(1.5, "pitch")  # max-axis leak never exceeds 1 g
    with pytest.raises(ValueError, match="limit_g"):
        threshold_angle(0.0)
    with pytest.raises(ValueError, match="direction"):
        threshold_angle(0.05, "yaw")
    with pytest.raises(ValueError, match="measure"):
        threshold_angle(0.05, "pitch", "rms")


def test_surface_shape_zero_at_level_and_symmetric():
    roll = np.linspace(-10.0, 10.0, 41)
    pitch = np.linspace(-8.0, 8.0, 33)
    for measure in ("max-axis", "norm"):
        s = leak_surface(roll, pitch, measure)
        assert s.shape == (33, 41)
        assert s[16, 20] == 0.0
        np.testing.assert_array_equal(s, leak_surface(-roll, pitch, measure))
        np.testing.assert_array_equal(s, leak_surface(roll, -pitch, measure))
        assert np.all(s[16, :20] > 0) and np.all(s[:16, 20] > 0)


def test_surface_layout_is_pitch_by_roll():
    s = leak_surface(np.array([0.0, 5.0]), np.array([0.0, 1.0, 2.0]))
    np.testing.assert_allclose(s[:, 0], np.sin(np.radians([0.0, 1.0, 2.0])), atol=1e-15)
    np.testing.assert_allclose(s[0, :], np.sin(np.radians([0.0, 5.0])), atol=1e-15)


def test_norm_is_never_smaller_than_max_axis():
    g = np.linspace(-45.0, 45.0, 91)
    max_axis = leak_surface(g, g, "max-axis")
    norm = leak_surface(g, g, "norm")
    assert np.all(norm >= max_axis)
    assert np.all(norm <= math.sqrt(3.0) * max_axis + 1e-15)


def test_leak_single_axis_is_sin():
    tilt = np.linspace(0.0, 80.0, 17)
    np.testing.assert_allclose(leak_g(0.0, tilt), np.sin(np.radians(tilt)), rtol=1e-14, atol=1e-16)


def test_symmetric_grid_and_analyse():
    grid = symmetric_grid(10.0, 0.05)
    assert grid.size == 401 and grid[0] == -10.0 and grid[-1] == 10.0 and grid[200] == 0.0
    np.testing.assert_array_equal(grid, -grid[::-1])
    with pytest.raises(ValueError, match="step_deg"):
        symmetric_grid(10.0, -1.0)
    res = analyse(range_deg=5.0, step_deg=0.5)
    assert res.surface_g.shape == (21, 21)
    assert res.asin_limit_deg == pytest.approx(ASIN_50MG, abs=1e-12)
    assert set(res.threshold_deg) == {"pitch", "roll", "combined"}
