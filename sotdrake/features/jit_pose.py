"""The 6D feature's error and Jacobian, compiled with numba: :func:`pose_error`.

The same formulas as :func:`.feature6d.python_pose_error_and_jacobian` (see :mod:`.feature6d`),
operation for operation: ``e``, ``M`` (the 6×6 map of the error's frame, ``J = M S J_WOp`` with
``S`` the shift to ``F``) and ``ė_ref``, then the selected rows. In Python the feature's hot path
was a few dozen products on 3-vectors, each a Python call (about 12 µs a feature, three of them in
a tick with both feet and a hand); compiled, one call of about 2–4 µs.

The arguments are :func:`~sotdrake.compiled.compiled_input` arrays (C-ordered, writeable): the
transposes of the 4×4 homogeneous matrices ``X_WOp``, ``X_WFd`` and ``X_OpF`` (the identity when
``shifted`` is False) and of ``J_WOp`` (6 × nv), ``V_WFd`` (6, zeros for a fixed target) and the selected ``rows`` (int64,
increasing, at least one; an index outside 0–5 raises ``ValueError``). The rotations are orthonormal, as Drake's poses are.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def _log(R, out):
    """``out ← log(R)`` (the branches of :func:`sotdrake.lie.log_so3_list`)."""
    cos_theta = min(1.0, max(-1.0, 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)))
    wx, wy, wz = 0.5 * (R[2, 1] - R[1, 2]), 0.5 * (R[0, 2] - R[2, 0]), 0.5 * (R[1, 0] - R[0, 1])
    sin_theta = math.sqrt(wx * wx + wy * wy + wz * wz)
    theta = math.atan2(sin_theta, cos_theta)
    if theta < 1e-6:
        k = 1.0 + theta * theta / 6.0
        out[0], out[1], out[2] = wx * k, wy * k, wz * k
        return
    if math.pi - theta > 1e-4:
        k = theta / sin_theta
        out[0], out[1], out[2] = wx * k, wy * k, wz * k
        return
    # Near π: the axis from the symmetric part, R + Rᵀ = 2 cos θ I + 2 (1 - cos θ) u uᵀ.
    B = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            B[i, j] = 0.5 * (R[i, j] + R[j, i]) - (cos_theta if i == j else 0.0)
    k = 0
    for i in range(1, 3):
        if B[i, i] > B[k, k]:
            k = i
    scale = math.sqrt(max(B[k, k] * (1.0 - cos_theta), 1e-300))
    u0, u1, u2 = B[0, k] / scale, B[1, k] / scale, B[2, k] / scale
    size = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    sign = -1.0 if u0 * wx + u1 * wy + u2 * wz < 0.0 else 1.0
    out[0], out[1], out[2] = sign * theta * u0 / size, sign * theta * u1 / size, sign * theta * u2 / size


@njit(cache=True)
def _jr_inverse(x, y, z, out):
    """``out ← Jr⁻¹(φ)``, ``φ = (x, y, z)`` (:func:`sotdrake.lie.right_jacobian_inverse_list`)."""
    t2 = x * x + y * y + z * z
    theta = math.sqrt(t2)
    if theta < 1e-4:
        c = 1.0 / 12.0 + theta**2 / 720.0
    else:
        c = 1.0 / theta**2 - (1.0 + math.cos(theta)) / (2.0 * theta * math.sin(theta))
    d = 1.0 - c * t2
    out[0, 0], out[0, 1], out[0, 2] = d + c * x * x, c * x * y - 0.5 * z, c * x * z + 0.5 * y
    out[1, 0], out[1, 1], out[1, 2] = c * x * y + 0.5 * z, d + c * y * y, c * y * z - 0.5 * x
    out[2, 0], out[2, 1], out[2, 2] = c * x * z - 0.5 * y, c * y * z + 0.5 * x, d + c * z * z


@njit(cache=True)
def _product(A, B, out):
    """``out ← A B`` (3×3)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@njit(cache=True)
def _apply(A, x, out):
    """``out ← A x`` (3×3, 3)."""
    for i in range(3):
        out[i] = A[i, 0] * x[0] + A[i, 1] * x[1] + A[i, 2] * x[2]


@njit(cache=True)
def _hat(a, out):
    """``out ← [a]×``."""
    out[0, 0], out[0, 1], out[0, 2] = 0.0, -a[2], a[1]
    out[1, 0], out[1, 1], out[1, 2] = a[2], 0.0, -a[0]
    out[2, 0], out[2, 1], out[2, 2] = -a[1], a[0], 0.0


@njit(cache=True)
def pose_error(XT_WOp, JT_WOp, XT_WFd, current, V_WFd, XT_OpF, shifted, rows):
    """``(e, J, ė_ref)`` of the selected ``rows`` (see the module docstring); ``current``: the error
    in the current frame (``frame('current')``), else in the desired one. The matrices come
    transposed (``XT_WOp = X_WOpᵀ``, ``JT_WOp = J_WOpᵀ``, nv × 6): Drake's are column-major, their
    transposes C-ordered views."""
    for i in range(rows.size):
        if rows[i] < 0 or rows[i] > 5:
            raise ValueError("rows: indices of the six components (0 to 5) expected")
    R = np.empty((3, 3))
    p = np.empty(3)
    r = np.zeros(3)  # p_OpF in world axes
    Rd, pd = np.empty((3, 3)), np.empty(3)
    for i in range(3):
        p[i], pd[i] = XT_WOp[3, i], XT_WFd[3, i]
        for j in range(3):
            R[i, j], Rd[i, j] = XT_WOp[j, i], XT_WFd[j, i]
    if shifted:
        for i in range(3):
            r[i] = R[i, 0] * XT_OpF[3, 0] + R[i, 1] * XT_OpF[3, 1] + R[i, 2] * XT_OpF[3, 2]
            p[i] += r[i]
        R_Op = R.copy()
        _product(R_Op, XT_OpF[:3, :3].T.copy(), R)
    RT, RdT = R.T.copy(), Rd.T.copy()
    rotation = rows[rows.size - 1] >= 3
    moving = False
    for i in range(6):
        moving = moving or V_WFd[i] != 0.0
    e, e_dot, M = np.zeros(6), np.zeros(6), np.zeros((6, 6))
    a, b, phi, w = np.empty((3, 3)), np.empty((3, 3)), np.empty(3), np.empty(3)
    if not current:  # e = (R*ᵀ(p − p*), log(R*ᵀ R))
        _apply(RdT, p - pd, e[:3])
        M[:3, 3:] = RdT
        if shifted:
            _hat(-r, a)
            _product(RdT, a, b)
            M[:3, :3] = b
        if rotation:
            _product(RdT, R, a)
            _log(a, phi)
            e[3:] = phi
            _jr_inverse(phi[0], phi[1], phi[2], a)
            _product(a, RT, b)
            M[3:, :3] = b
        if moving:
            _apply(RdT, V_WFd[:3], w)  # ω* in F*
            _apply(RdT, V_WFd[3:], phi)
            e_dot[0] = e[1] * w[2] - e[2] * w[1] - phi[0]
            e_dot[1] = e[2] * w[0] - e[0] * w[2] - phi[1]
            e_dot[2] = e[0] * w[1] - e[1] * w[0] - phi[2]
            if rotation:
                _jr_inverse(-e[3], -e[4], -e[5], a)
                _apply(a, w, phi)
                e_dot[3:] = -phi
    else:  # e = (Rᵀ(p* − p), log(Rᵀ R*))
        _apply(RT, pd - p, e[:3])
        _hat(e[:3], a)
        _product(a, RT, b)
        if shifted:
            _hat(r, a)
            c = np.empty((3, 3))
            _product(RT, a, c)
            b += c
        M[:3, :3] = b
        M[:3, 3:] = -RT
        if rotation:
            _product(RT, Rd, a)
            _log(a, phi)
            e[3:] = phi
            _jr_inverse(-phi[0], -phi[1], -phi[2], a)
            _product(a, RT, b)
            M[3:, :3] = -b
        if moving:
            _apply(RT, V_WFd[3:], phi)
            e_dot[:3] = phi
            if rotation:
                _apply(RdT, V_WFd[:3], w)
                _jr_inverse(e[3], e[4], e[5], a)
                _apply(a, w, phi)
                e_dot[3:] = phi
    k, nv = rows.size, JT_WOp.shape[0]
    J = np.zeros((k, nv))
    e_rows, e_dot_rows = np.empty(k), np.empty(k)
    for i in range(k):
        row = rows[i]
        e_rows[i], e_dot_rows[i] = e[row], e_dot[row]
        for m in range(6):
            coefficient = M[row, m]
            for j in range(nv):
                J[i, j] += coefficient * JT_WOp[j, m]
    return e_rows, J, e_dot_rows
