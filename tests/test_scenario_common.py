"""The scenarios' shared measures (sotdrake.scenarios.common) on poses whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from sotdrake.scenarios.common import (
    floating_base_fall,
    point_drift,
    point_on,
    rotation_drift,
    support_drift,
    translation_drift,
)


def yawed(angles: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Poses (T × 4 × 4) rotated by ``angles`` (rad) about z, at ``positions`` (T × 3, m)."""
    poses = np.tile(np.eye(4), (len(angles), 1, 1))
    c, s = np.cos(angles), np.sin(angles)
    poses[:, 0, 0], poses[:, 0, 1], poses[:, 1, 0], poses[:, 1, 1] = c, -s, s, c
    poses[:, :3, 3] = positions
    return poses


def test_drifts_of_a_frame_moving_and_turning():
    positions = np.array([[1.0, 2.0, 3.0], [1.3, 2.4, 3.0], [1.0, 2.0, 4.0]])
    poses = yawed(np.array([0.0, 0.2, -0.5]), positions)
    assert translation_drift(poses) == pytest.approx([0.0, 0.5, 1.0])
    assert translation_drift(poses, 2) == pytest.approx([0.0, 0.5, 0.0])
    assert rotation_drift(poses) == pytest.approx([0.0, 0.2, 0.5], abs=1e-7)
    assert point_drift(positions, 2) == pytest.approx([0.0, 0.5, 0.0])


def test_point_on_a_frame_is_rotated_then_translated():
    poses = yawed(np.array([np.pi / 2]), np.array([[1.0, 0.0, 0.0]]))
    assert point_on(poses, (0.1, 0.0, 0.0)) == pytest.approx(np.array([[1.0, 0.1, 0.0]]))


def test_support_drift_takes_the_largest_over_feet_and_ticks():
    still = yawed(np.zeros(3), np.zeros((3, 3)))
    moved = yawed(np.array([0.0, 0.1, 0.0]), np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.02, 0.0]]))
    com = np.array([[0.0, 0.0, 0.9], [0.003, 0.004, 0.9], [0.0, 0.0, 0.8]])
    drift = support_drift({"LF": still, "RF": moved, "com": com})
    assert drift["max_foot_drift_m"] == pytest.approx(0.02)
    assert drift["max_foot_rotation_drift_rad"] == pytest.approx(0.1, abs=1e-7)
    assert drift["max_com_drift_m"] == pytest.approx(0.1)
    assert drift["max_com_xy_drift_m"] == pytest.approx(0.005)


def test_a_floating_base_fall_standing_and_with_a_non_finite_state():
    t = np.linspace(0.0, 1.0, 11)
    state = np.zeros((11, 8))
    state[:, 0], state[:, 6] = 1.0, 1.0  # upright, the base 1 m high
    assert not floating_base_fall(t, state, np.zeros(11))["fell"]
    state[7, 3] = np.nan
    fall = floating_base_fall(t, state, np.zeros(11))
    assert fall["fell"] and fall["fell_at_s"] == pytest.approx(0.7) and fall["fall_reason"] == "non-finite"
