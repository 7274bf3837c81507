"""``q ⊕ v·dt`` of :mod:`.configuration`, compiled with numba: :func:`integrate`.

The same operations as :func:`.configuration.python_integrate`, in one call (in Python, the base's
quaternion on floats and the joints in numpy cost about six microseconds a tick).
"""

from __future__ import annotations

import math

from numba import njit


@njit(cache=True)
def integrate(q, v, dt, base_q, base_v, joints_q, joints_v):
    """``q ⊕ v·dt``: joint ``k`` at ``q[joints_q[k]]`` moves by ``v[joints_v[k]]·dt``; a floating base
    (``base_q``, ``base_v`` ≥ 0: where its 7 positions and 6 velocities start; -1: none) turns by
    ``exp(ω_W dt) ⊗ q_B`` (re-normalised) and moves by ``v_WBo dt``. ``q`` is not modified."""
    out = q.copy()
    for j in range(joints_q.size):
        out[joints_q[j]] = q[joints_q[j]] + dt * v[joints_v[j]]
    if base_q >= 0:
        px, py, pz = v[base_v] * dt, v[base_v + 1] * dt, v[base_v + 2] * dt
        theta = math.sqrt(px * px + py * py + pz * pz)
        if theta < 1e-8:
            ew, scale = 1.0 - theta**2 / 8, 0.5
        else:
            ew, scale = math.cos(theta / 2), math.sin(theta / 2) / theta
        ex, ey, ez = scale * px, scale * py, scale * pz
        bw, bx, by, bz = q[base_q], q[base_q + 1], q[base_q + 2], q[base_q + 3]
        w = ew * bw - ex * bx - ey * by - ez * bz
        x = ew * bx + ex * bw + ey * bz - ez * by
        y = ew * by - ex * bz + ey * bw + ez * bx
        z = ew * bz + ex * by - ey * bx + ez * bw
        n = math.sqrt(w * w + x * x + y * y + z * z)
        out[base_q], out[base_q + 1], out[base_q + 2], out[base_q + 3] = w / n, x / n, y / n, z / n
        for i in range(3):
            out[base_q + 4 + i] = q[base_q + 4 + i] + v[base_v + 3 + i] * dt
    return out
