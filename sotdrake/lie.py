"""SO(3) and SE(3) maths used by the features and the device.

Conventions: rotation vectors ``φ = θ u`` (radians, axis ``u`` unit); ``hat(a) b = a × b``.
``exp_so3(φ) = I + sin θ/θ [φ]× + (1 - cos θ)/θ² [φ]×²`` (Rodrigues), ``log_so3`` its inverse with
θ ∈ [0, π]. For a rotation ``R(t)`` with body angular velocity ``ω`` (``Ṙ = R [ω]×``) and
``φ = log(R)``: ``φ̇ = Jr⁻¹(φ) ω``, where the inverse right Jacobian is
``Jr⁻¹(φ) = I + ½[φ]× + (1/θ² - (1 + cos θ)/(2θ sin θ)) [φ]×²``; the inverse left Jacobian is
``Jl⁻¹(φ) = Jr⁻¹(-φ)`` (``φ̇ = Jl⁻¹(φ) ω_world`` for ``Ṙ = [ω_world]× R``).
SE(3) twists are body twists ``ξ = (v, ω)``: ``X(t) = X0 · exp(t ξ)`` for a constant ``ξ``, whose
rotation is ``exp_so3(ω t)`` and translation ``V(ω t) v t`` (:func:`se3_translation`).
"""

from __future__ import annotations

import math

import numpy as np

from .exceptions import InvalidInput, check_finite

_SMALL = 1e-8
#: A quaternion of a smaller norm is no rotation (refused where one is read: a base's, a tilt's).
MIN_QUATERNION_NORM = 1e-6


def check_base_quaternion(what: str, q: np.ndarray, start: int) -> None:
    """:class:`~sotdrake.exceptions.InvalidInput` naming ``what`` unless the floating base's
    quaternion ``q[start:start + 4]`` (``(qw, qx, qy, qz)``) has a norm of at least
    :data:`MIN_QUATERNION_NORM` (Drake normalises it; a zero one is no rotation, and Drake raises)."""
    quaternion = q[start : start + 4]
    if not (norm := float(np.linalg.norm(quaternion))) >= MIN_QUATERNION_NORM:
        raise InvalidInput(f"{what}: the floating base's quaternion q[{start}:{start + 4}] = {quaternion.tolist()} (norm "
                           f"{norm:g}) is no rotation; give a unit quaternion (qw, qx, qy, qz)")


def check_rotation(what: str, R: object) -> np.ndarray:
    """``R`` as a 3×3 float array if it is a rotation matrix (finite, ``RᵀR = I`` to 1e-6 and
    ``det R > 0``), else :class:`InvalidInput` naming ``what``: a ``RotationMatrix`` or
    ``RigidTransform`` built from any matrix is not checked by Drake in a release build."""
    matrix: np.ndarray = check_finite(what, R, (3, 3))
    if not np.allclose(matrix.T @ matrix, np.eye(3), rtol=0.0, atol=1e-6) or not np.linalg.det(matrix) > 0:
        raise InvalidInput(f"{what}: not a rotation matrix (orthonormal with determinant +1), got {matrix.tolist()} "
                           f"(determinant {np.linalg.det(matrix):g})")
    return matrix


def hat(a: np.ndarray) -> np.ndarray:
    """Skew-symmetric matrix ``[a]×`` such that ``hat(a) @ b == np.cross(a, b)``."""
    x, y, z = a.tolist() if isinstance(a, np.ndarray) else a
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def exp_so3(phi: np.ndarray) -> np.ndarray:
    """Rotation matrix ``exp([φ]×)``."""
    theta = float(np.linalg.norm(phi))
    K = hat(phi)
    if theta < _SMALL:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + (np.sin(theta) / theta) * K + ((1.0 - np.cos(theta)) / theta**2) * K @ K


def log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vector ``φ`` with ``exp_so3(φ) = R`` and ``|φ| ≤ π`` (robust near 0 and π)."""
    return np.array(log_so3_list(R.tolist() if isinstance(R, np.ndarray) else R))


def log_so3_list(R) -> list[float]:
    """:func:`log_so3` of a rotation given as rows of Python floats, on Python floats (the hot
    path of the features: cheaper than numpy for a 3×3)."""
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R
    cos_theta = min(1.0, max(-1.0, 0.5 * (r00 + r11 + r22 - 1.0)))
    wx, wy, wz = 0.5 * (r21 - r12), 0.5 * (r02 - r20), 0.5 * (r10 - r01)  # sin θ · u
    sin_theta = math.sqrt(wx * wx + wy * wy + wz * wz)
    # θ from both (not acos alone, whose error grows as 1/sin θ towards π), and θ / sin θ from the
    # sin θ that w holds: the result is θ times a unit vector to the last bits, up to the π branch.
    theta = math.atan2(sin_theta, cos_theta)
    if theta < 1e-6:
        k = 1.0 + theta * theta / 6.0  # sin θ ≈ θ (1 - θ²/6)
        return [wx * k, wy * k, wz * k]
    if math.pi - theta > 1e-4:
        k = theta / sin_theta
        return [wx * k, wy * k, wz * k]
    # Near π: the axis from the symmetric part, R + Rᵀ = 2 cos θ I + 2 (1 - cos θ) u uᵀ.
    R = np.array(R, dtype=float)
    B = 0.5 * (R + R.T) - cos_theta * np.eye(3)
    k = int(np.argmax(np.diag(B)))
    u = B[:, k] / np.sqrt(max(B[k, k] * (1.0 - cos_theta), 1e-300))
    u /= np.linalg.norm(u)
    if u @ np.array([wx, wy, wz]) < 0.0:
        u = -u
    return (theta * u).tolist()


def _jacobian_coefficient(theta: float) -> float:
    """``1/θ² - (1 + cos θ)/(2θ sin θ)``, with its series ``1/12 + θ²/720`` near 0."""
    if theta < 1e-4:
        return 1.0 / 12.0 + theta**2 / 720.0
    return 1.0 / theta**2 - (1.0 + math.cos(theta)) / (2.0 * theta * math.sin(theta))


def right_jacobian_inverse_so3(phi: np.ndarray) -> np.ndarray:
    """``Jr⁻¹(φ)``: maps a body angular velocity to ``d/dt log(R)``."""
    return np.array(right_jacobian_inverse_list(phi.tolist() if isinstance(phi, np.ndarray) else phi))


def right_jacobian_inverse_list(phi) -> list[list[float]]:
    """:func:`right_jacobian_inverse_so3` on Python floats (rows): ``Jr⁻¹ = I + ½[φ]× + c(θ)[φ]×²``
    with ``[φ]×² = φφᵀ - θ² I``, written out entry by entry."""
    x, y, z = phi
    t2 = x * x + y * y + z * z
    c = _jacobian_coefficient(math.sqrt(t2))
    d = 1.0 - c * t2
    return [
        [d + c * x * x, c * x * y - 0.5 * z, c * x * z + 0.5 * y],
        [c * x * y + 0.5 * z, d + c * y * y, c * y * z - 0.5 * x],
        [c * x * z - 0.5 * y, c * y * z + 0.5 * x, d + c * z * z],
    ]


def left_jacobian_inverse_so3(phi: np.ndarray) -> np.ndarray:
    """``Jl⁻¹(φ) = Jr⁻¹(-φ)``: maps a world angular velocity to ``d/dt log(R)``."""
    return right_jacobian_inverse_so3(-np.asarray(phi))


def se3_translation(v: np.ndarray, omega: np.ndarray) -> np.ndarray:
    """Translation ``V(ω) v`` of the SE(3) exponential of the body twist ``(v, ω)``, with
    ``V = I + (1-cos θ)/θ² [ω]× + (θ - sin θ)/θ³ [ω]×²``."""
    theta = math.sqrt(omega @ omega)
    w_v = _cross(omega, v)
    w_w_v = _cross(omega, w_v)
    if theta < 1e-6:
        return v + 0.5 * w_v + w_w_v / 6.0
    return v + ((1.0 - math.cos(theta)) / theta**2) * w_v + ((theta - math.sin(theta)) / theta**3) * w_w_v


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def quaternion_wxyz_to_rotation(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of the unit quaternion ``(w, x, y, z)`` (Drake's floating-base order)."""
    w, x, y, z = q / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quaternion_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a ⊗ b`` of quaternions ``(w, x, y, z)``."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ])


def quaternion_exp(phi: np.ndarray) -> np.ndarray:
    """Unit quaternion ``(cos θ/2, sin θ/2 · u)`` of the rotation vector ``φ = θ u``."""
    theta = float(np.linalg.norm(phi))
    if theta < 1e-8:
        return np.concatenate([[1.0 - theta**2 / 8], 0.5 * phi])
    return np.concatenate([[np.cos(theta / 2)], (np.sin(theta / 2) / theta) * phi])


# --- the same on Python floats (the device's hot path; cheaper than numpy for 3- and 4-vectors) ---


def se3_translation_list(v, omega) -> list[float]:
    """:func:`se3_translation` on Python floats."""
    theta = math.sqrt(omega[0] * omega[0] + omega[1] * omega[1] + omega[2] * omega[2])
    w_v = _cross_list(omega, v)
    w_w_v = _cross_list(omega, w_v)
    if theta < 1e-6:
        a, b = 0.5, 1.0 / 6.0
    else:
        a, b = (1.0 - math.cos(theta)) / theta**2, (theta - math.sin(theta)) / theta**3
    return [v[i] + a * w_v[i] + b * w_w_v[i] for i in range(3)]


def _cross_list(a, b) -> list[float]:
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def quaternion_wxyz_to_rotation_list(w: float, x: float, y: float, z: float) -> list[list[float]]:
    """:func:`quaternion_wxyz_to_rotation` of a unit quaternion, rows of Python floats."""
    return [
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ]


def quaternion_multiply_list(a, b) -> list[float]:
    """:func:`quaternion_multiply` on Python floats."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return [
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ]


def quaternion_exp_list(phi) -> list[float]:
    """:func:`quaternion_exp` on Python floats."""
    theta = math.sqrt(phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2])
    if theta < 1e-8:
        return [1.0 - theta**2 / 8, 0.5 * phi[0], 0.5 * phi[1], 0.5 * phi[2]]
    k = math.sin(theta / 2) / theta
    return [math.cos(theta / 2), k * phi[0], k * phi[1], k * phi[2]]
