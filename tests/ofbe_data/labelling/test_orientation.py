"""Rodrigues' rotation against scipy, the paper's label against its closed form."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from ofbe_data.labelling.orientation import (
    VERTICAL,
    apparent_bias,
    nearest_axis,
    rodrigues,
    rodrigues_label,
    roll_pitch,
    rotation_to_vertical,
)
from ofbe_data.simulator.physics import plate_direction

unit_vectors = st.lists(st.floats(-1, 1), min_size=3, max_size=3).map(np.array).filter(
    lambda v: np.linalg.norm(v) > 0.1)


@given(axis=unit_vectors, angle=st.floats(-np.pi, np.pi))
def test_rodrigues_formula_equals_scipy_rotation_vector(axis, angle):
    k = axis / np.linalg.norm(axis)
    expected = Rotation.from_rotvec(k * angle).as_matrix()
    np.testing.assert_allclose(rodrigues(axis, angle), expected, atol=1e-12)


@pytest.mark.slow
@given(u=unit_vectors)
def test_rotation_to_vertical_takes_u_up_by_the_smallest_rotation(u):
    R = rotation_to_vertical(u)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    np.testing.assert_allclose(R @ (u / np.linalg.norm(u)), VERTICAL, atol=1e-12)
    if np.allclose(u / np.linalg.norm(u), -VERTICAL):
        return  # any half turn is minimal there; scipy and we pick different axes
    # scipy finds the same (minimal) rotation aligning u with the vertical
    expected, _ = Rotation.align_vectors([VERTICAL], [u])
    np.testing.assert_allclose(R, expected.as_matrix(), atol=1e-9)


def test_rotation_to_vertical_special_cases():
    np.testing.assert_array_equal(rotation_to_vertical(np.array([0, 0, 2.0])), np.eye(3))
    R = rotation_to_vertical(np.array([0, 0, -1.0]))
    np.testing.assert_allclose(R @ [0, 0, -1.0], VERTICAL, atol=1e-15)
    with pytest.raises(ValueError, match="cannot normalise a zero-length vector"):
        rotation_to_vertical(np.zeros(3))


@settings(max_examples=50)
@given(u=unit_vectors, b=st.lists(st.floats(-0.5, 0.5), min_size=3, max_size=3),
       perm=st.sampled_from([np.eye(3), np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1.0]]),
                             np.array([[0, 0, 1], [0, -1, 0], [1, 0, 0.0]])]))
def test_rodrigues_label_is_mean_minus_g_times_reference_direction(u, b, perm):
    g = 9.7946
    u_ref = u / np.linalg.norm(u)
    dut_mean = g * perm @ u_ref + np.asarray(b)
    bias, u_used = rodrigues_label(dut_mean, 3.7 * u_ref, perm, g)
    np.testing.assert_allclose(u_used, perm @ u_ref, atol=1e-12)
    # a direction within 1e-12 rad of the vertical is taken as vertical (rotation_to_vertical),
    # which moves the label by up to g·1e-12 ≈ 1e-11 m/s²
    np.testing.assert_allclose(bias, b, atol=2e-11)
    np.testing.assert_allclose(bias, apparent_bias(dut_mean, perm @ u_ref, g), atol=1e-12)


@given(roll=st.floats(-179, 180), pitch=st.floats(-89, 89))
def test_roll_pitch_inverts_the_plate_direction(roll, pitch):
    assert roll_pitch(plate_direction(roll, pitch)) == pytest.approx((roll, pitch), abs=1e-9)


def test_nearest_axis_takes_sign_from_the_data():
    np.testing.assert_array_equal(nearest_axis(np.array([0.1, -9.7, 0.3])), [0, -1, 0])
    np.testing.assert_array_equal(nearest_axis(np.array([0.1, 0.2, 9.8])), [0, 0, 1])
