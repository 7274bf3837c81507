import numpy as np
import pytest

from sotdrake.lie import (
    exp_so3,
    hat,
    left_jacobian_inverse_so3,
    log_so3,
    right_jacobian_inverse_so3,
    se3_translation,
)


def expm(A: np.ndarray) -> np.ndarray:
    """Matrix exponential by scaling and squaring of a Taylor series (independent of lie.py)."""
    s = max(0, int(np.ceil(np.log2(max(np.linalg.norm(A, 1), 1e-16)))) + 1)
    B, term, out = A / 2**s, np.eye(len(A)), np.eye(len(A))
    for k in range(1, 25):
        term = term @ B / k
        out = out + term
    for _ in range(s):
        out = out @ out
    return out


@pytest.mark.parametrize("theta", [0.0, 1e-9, 1e-5, 0.3, 2.0, np.pi - 1e-3, np.pi - 1e-7])
def test_exp_log_round_trip(theta, rng):
    axis = rng.normal(size=3)
    phi = theta * axis / np.linalg.norm(axis)
    R = exp_so3(phi)
    np.testing.assert_allclose(R, expm(hat(phi)), atol=1e-12)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    np.testing.assert_allclose(log_so3(R), phi, atol=1e-6 if theta > 3 else 1e-12)


@pytest.mark.parametrize("gap", [1e-2, 1e-3, 3e-4, 1.01e-4, 9.9e-5, 1e-6])
def test_log_is_accurate_towards_pi(gap, rng):
    """Against Drake's angle-axis (from the quaternion): from acos alone the angle's round-off grew
    as 1/sin θ, 7e-8 rad at π − 1e-4; the compiled 6D error takes the same branches."""
    from pydrake.math import RotationMatrix

    from sotdrake.features.feature6d import pose_error_and_jacobian

    for _ in range(5):
        axis, R0 = rng.normal(size=3), exp_so3(rng.normal(size=3))
        Rd = R0 @ expm(hat((np.pi - gap) * axis / np.linalg.norm(axis)))
        R = Rd.T @ R0  # (a product, as the feature forms it: its trace carries the products' round-off)
        angle_axis = RotationMatrix(R).ToAngleAxis()
        reference = angle_axis.angle() * angle_axis.axis()
        np.testing.assert_allclose(log_so3(R), reference, rtol=0, atol=1e-10)
        X, Xd = np.eye(4), np.eye(4)
        X[:3, :3], Xd[:3, :3] = R0, Rd
        np.testing.assert_allclose(pose_error_and_jacobian(X, np.zeros((6, 1)), Xd)[0][3:], reference, rtol=0, atol=1e-10)


@pytest.mark.parametrize("theta", [1e-7, 0.4, 2.5])
def test_log_jacobians_by_finite_differences(theta, rng):
    axis = rng.normal(size=3)
    phi = theta * axis / np.linalg.norm(axis)
    R, h = exp_so3(phi), 1e-6
    for k in range(3):
        w = np.eye(3)[k]
        body = (log_so3(R @ exp_so3(h * w)) - log_so3(R @ exp_so3(-h * w))) / (2 * h)
        world = (log_so3(exp_so3(h * w) @ R) - log_so3(exp_so3(-h * w) @ R)) / (2 * h)
        np.testing.assert_allclose(right_jacobian_inverse_so3(phi) @ w, body, atol=1e-8)
        np.testing.assert_allclose(left_jacobian_inverse_so3(phi) @ w, world, atol=1e-8)


@pytest.mark.parametrize("scale", [1e-8, 0.1, 2.0])
def test_se3_exponential_matches_matrix_exponential(scale, rng):
    v, w = scale * rng.normal(size=3), scale * rng.normal(size=3)
    twist = np.zeros((4, 4))
    twist[:3, :3], twist[:3, 3] = hat(w), v
    X = expm(twist)
    np.testing.assert_allclose(exp_so3(w), X[:3, :3], atol=1e-12)
    np.testing.assert_allclose(se3_translation(v, w), X[:3, 3], atol=1e-12)

