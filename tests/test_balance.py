"""The proprioceptive centre-of-mass-over-feet estimate used by the G1 key frames' balance feedback."""

from __future__ import annotations

import numpy as np

from frbench.policies.balance import ComOverFeet, roll_pitch_quaternion
from frbench.robots import get_robot
from frbench.tasks.observations import projected_gravity


def test_the_yaw_free_orientation_reproduces_the_measured_gravity():
    rng = np.random.default_rng(3)
    g = rng.normal(size=(20, 3))
    g /= np.linalg.norm(g, axis=1, keepdims=True)
    quats = roll_pitch_quaternion(g)
    assert np.allclose(projected_gravity(quats), g, atol=1e-12)
    assert np.allclose(roll_pitch_quaternion(np.array([[0.0, 0.0, -1.0]])), [[1.0, 0.0, 0.0, 0.0]])


def test_standing_g1_has_its_centre_of_mass_just_ahead_of_the_ankles_and_leaning_moves_it():
    spec = get_robot("g1")
    lean = 0.1  # rad
    gravity = np.array([[0.0, 0.0, -1.0], [np.sin(lean), 0.0, -np.cos(lean)], [-np.sin(lean), 0.0, -np.cos(lean)],
                        [0.0, np.sin(lean), -np.cos(lean)]])
    offset = ComOverFeet(spec).offset(gravity, np.tile(spec.default_pose, (4, 1)))
    assert 0.0 < offset[0] < 0.06  # the ankle joints sit behind the middle of the G1's feet
    # pitching forward by 0.1 rad about the pelvis moves a CoM ≈ 0.65 m above the ankles ≈ 6.5 cm forward
    assert 0.05 < offset[1] - offset[0] < 0.08 and 0.05 < offset[0] - offset[2] < 0.08
    assert abs(offset[3] - offset[0]) < 0.005  # a roll does not move it forwards
