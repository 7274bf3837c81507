"""The collision wing's compiled kernels (numba): the pairs' rows from their bodies' kinematics
(:func:`cover`, :func:`assemble`), the support gaps of pairs along given directions (:func:`gaps`)
and the schedule's bounds after a motion (:func:`lowered`).

**The rows.** For pair ``i``, with side A's body (slot ``a``: its pose ``X_WB``, bias spatial
acceleration ``(α; a_Bo)`` and angular velocity ``ω``, world frame) and the witness point ``p_GC``
in A's geometry frame G (pose ``X_BG`` in the body), ``r = R_WB p_BC`` (``p_BC = X_BG p_GC``) is
the point from the body's origin and ``p_WC = p_WBo + r``. With ``J = (J_ω; J_v)`` the spatial
Jacobian of the point of the body at the world's origin (world frame), the point's velocity is
``v_WO + ω × p_WC``, so ``n̂ᵀ v_WC = (n̂ᵀ J_v + (p_WC × n̂)ᵀ J_ω) v``; its bias acceleration, fixed
in the body, is ``a_Bo + α × r + ω × (ω × r)``. ``J`` is that of the body's leaf (:func:`cover`)
on the columns of the body's own joints (``columns``): at a point fixed in the world, a joint's
column is the same for every body downstream of it. ``J_d`` adds A's row and subtracts B's (the
module docstring of :mod:`.distance`); a side of slot -1 is an obstacle (the world body: ``X_BG``
is then the geometry's pose in the world; no velocity).

One compiled call per tick instead of a few dozen numpy calls on ``k × 3`` arrays (about 0.3 ms
for 36 pairs).

**The gaps.** For two convex shapes A and B and a unit direction ``n̂`` (world frame, from B to A),
the gap ``min_{a∈A} n̂ᵀa − max_{b∈B} n̂ᵀb`` is at most their signed distance: a plane normal to
``n̂`` lies between them when it is positive, and their overlap along ``n̂`` is at least their
penetration depth when it is not. Each side's extreme point comes from its support function in its
own frame (``X_WG = (R, p)``: ``max_{g∈G} uᵀg = uᵀp + h_G(Rᵀu)``), by kind
(:data:`~sotdrake.collision.shapes.SUPPORT_KINDS`): the largest ``uᵀv`` over a hull's vertices
(a mesh's convex hull, a box's corners), ``‖(a u_x, b u_y, c u_z)‖`` for an ellipsoid (a sphere),
``r ‖(u_x, u_y)‖ + h |u_z|`` for a cylinder (radius ``r``, half-length ``h``) and
``r ‖u‖ + h |u_z|`` for a capsule.
:func:`sotdrake.collision.schedule.support` is the same function in plain Python, the reference
the tests hold the kernel to.

Arguments: :func:`~sotdrake.compiled.compiled_input` arrays.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def cover(bodies, depth, ancestors, needed, slots, leaves, leaf_of):
    """The moving bodies of the pairs and their leaves. ``bodies`` (2×k int64: each side's body
    index, -1 for an obstacle) gives ``needed[:m]`` (the distinct ones, increasing) and ``slots``
    (2×k: each side's place in ``needed``, -1 for an obstacle). Then, deepest first (``depth`` by
    body index), a needed body on no chosen leaf's way to the world (``ancestors[L, b]``) becomes a
    leaf: ``leaves[:count]`` (places in ``needed``) and ``leaf_of[:m]`` (the leaf, a number in
    ``0 … count − 1``, whose way holds each body). Returns ``(m, count)``."""
    seen = np.full(ancestors.shape[0], -1)
    for side in range(2):
        for i in range(bodies.shape[1]):
            if bodies[side, i] >= 0:
                seen[bodies[side, i]] = 0
    m = 0
    for body in range(seen.shape[0]):
        if seen[body] == 0:
            seen[body] = m
            needed[m] = body
            m += 1
    for side in range(2):
        for i in range(bodies.shape[1]):
            slots[side, i] = seen[bodies[side, i]] if bodies[side, i] >= 0 else -1
    order = np.argsort(-depth[needed[:m]], kind="mergesort")
    count = 0
    for o in order:
        body = needed[o]
        found = -1
        for leaf in range(count):
            if ancestors[needed[leaves[leaf]], body]:
                found = leaf
                break
        if found < 0:
            leaves[count] = o
            found = count
            count += 1
        leaf_of[o] = found
    return m, count


@njit(cache=True)
def assemble(X_WB, J, leaf_of, columns, A_bias, omega, slots, X_BG, p_GC, normal, with_bias, jacobian, bias, points):
    """Fill ``jacobian`` (k×nv, zeroed here), ``bias`` (k) and ``points`` (2×k×3: ``p_WCa``, ``p_WCb``)
    for ``slots`` (2×k int64: each side's body slot, -1 for an obstacle), ``X_BG`` (2×k×4×4), ``p_GC``
    (2×k×3) and ``normal`` (k×3, ``n̂_BA_W``); the per-slot ``X_WB`` (m×4×4), ``leaf_of`` (m),
    ``columns`` (m×nv bool), ``A_bias`` (m×6, ``(α; a)``) and ``omega`` (m×3); the per-leaf ``J``
    (6×nv, the point at the world's origin); ``bias`` only when ``with_bias``."""
    k, nv = normal.shape[0], J.shape[2]
    for i in range(k):
        bias[i] = 0.0
        for c in range(nv):
            jacobian[i, c] = 0.0
    for side in range(2):
        sign = 1.0 if side == 0 else -1.0
        for i in range(k):
            G = X_BG[side, i]
            px, py, pz = p_GC[side, i, 0], p_GC[side, i, 1], p_GC[side, i, 2]
            bx = G[0, 0] * px + G[0, 1] * py + G[0, 2] * pz + G[0, 3]
            by = G[1, 0] * px + G[1, 1] * py + G[1, 2] * pz + G[1, 3]
            bz = G[2, 0] * px + G[2, 1] * py + G[2, 2] * pz + G[2, 3]
            s = slots[side, i]
            if s < 0:  # an obstacle: the world body
                points[side, i, 0], points[side, i, 1], points[side, i, 2] = bx, by, bz
                continue
            X = X_WB[s]
            rx = X[0, 0] * bx + X[0, 1] * by + X[0, 2] * bz
            ry = X[1, 0] * bx + X[1, 1] * by + X[1, 2] * bz
            rz = X[2, 0] * bx + X[2, 1] * by + X[2, 2] * bz
            wx, wy, wz = X[0, 3] + rx, X[1, 3] + ry, X[2, 3] + rz  # p_WC
            points[side, i, 0], points[side, i, 1], points[side, i, 2] = wx, wy, wz
            nx, ny, nz = normal[i, 0], normal[i, 1], normal[i, 2]
            cx, cy, cz = wy * nz - wz * ny, wz * nx - wx * nz, wx * ny - wy * nx  # p_WC × n̂
            Js, mask = J[leaf_of[s]], columns[s]
            for c in range(nv):
                if mask[c]:
                    jacobian[i, c] += sign * (nx * Js[3, c] + ny * Js[4, c] + nz * Js[5, c]
                                              + cx * Js[0, c] + cy * Js[1, c] + cz * Js[2, c])
            if with_bias:
                A, w = A_bias[s], omega[s]
                ax = A[3] + (A[1] * rz - A[2] * ry)  # a_Bo + α × r
                ay = A[4] + (A[2] * rx - A[0] * rz)
                az = A[5] + (A[0] * ry - A[1] * rx)
                ux, uy, uz = w[1] * rz - w[2] * ry, w[2] * rx - w[0] * rz, w[0] * ry - w[1] * rx  # ω × r
                ax += w[1] * uz - w[2] * uy  # + ω × (ω × r)
                ay += w[2] * ux - w[0] * uz
                az += w[0] * uy - w[1] * ux
                bias[i] += sign * (nx * ax + ny * ay + nz * az)


@njit(cache=True)
def _support(kind, points, params, ux, uy, uz):
    """``max uᵀg`` over the shape (its frame): ``points`` its hull's vertices (kind 0) or
    ``params`` its sizes (1: semi-axes; 2, 3: radius, half-length)."""
    if kind == 0:
        best = -math.inf
        for i in range(points.shape[0]):
            value = ux * points[i, 0] + uy * points[i, 1] + uz * points[i, 2]
            if value > best:
                best = value
        return best
    if kind == 1:
        return math.sqrt((params[0] * ux) ** 2 + (params[1] * uy) ** 2 + (params[2] * uz) ** 2)
    radial = math.sqrt(ux * ux + uy * uy) if kind == 2 else math.sqrt(ux * ux + uy * uy + uz * uz)
    return params[0] * radial + params[1] * abs(uz)


@njit(cache=True)
def gaps(pairs, normal, X_WB, X_BG, kinds, params, offsets, points, out):
    """Fill ``out`` (k) with the gap of each pair ``(pairs[i, 0], pairs[i, 1])`` (k×2 int64: A's and
    B's shape index) along ``normal[i]`` (k×3, unit, world, from B to A): ``X_WB`` (k×2×4×4) the
    poses of the two shapes' bodies (the identity for an obstacle's world body); per shape index
    ``s``, its pose in its body ``X_BG[s]`` (4×4), ``kinds[s]`` (:data:`~.shapes.SUPPORT_KINDS`),
    ``params[s]`` (3) and its vertices ``points[offsets[s]:offsets[s + 1]]``."""
    for i in range(pairs.shape[0]):
        nx, ny, nz = normal[i, 0], normal[i, 1], normal[i, 2]
        value = 0.0
        for side in range(2):
            s = pairs[i, side]
            B, G = X_WB[i, side], X_BG[s]
            # n̂ in the body frame (R_WBᵀ n̂), then in the shape's (R_BGᵀ ·), and n̂ᵀ p_WGo
            bx = B[0, 0] * nx + B[1, 0] * ny + B[2, 0] * nz
            by = B[0, 1] * nx + B[1, 1] * ny + B[2, 1] * nz
            bz = B[0, 2] * nx + B[1, 2] * ny + B[2, 2] * nz
            centre = nx * B[0, 3] + ny * B[1, 3] + nz * B[2, 3] + bx * G[0, 3] + by * G[1, 3] + bz * G[2, 3]
            sign = -1.0 if side == 0 else 1.0  # A: min n̂ᵀa = −max (−n̂)ᵀa; B: max n̂ᵀb
            ux = sign * (G[0, 0] * bx + G[1, 0] * by + G[2, 0] * bz)
            uy = sign * (G[0, 1] * bx + G[1, 1] * by + G[2, 1] * bz)
            uz = sign * (G[0, 2] * bx + G[1, 2] * by + G[2, 2] * bz)
            extreme = _support(kinds[s], points[offsets[s]:offsets[s + 1]], params[s], ux, uy, uz)
            value += centre - extreme if side == 0 else -(centre + extreme)
        out[i] = value


@njit(cache=True)
def lowered(lower, coefficients, q0, q1, one_dof_q, floating_q, quaternion, bounding):
    """``lower − coefficients · m``, ``m`` the motion vector from ``q0`` to ``q1`` of
    :meth:`~.schedule.PairSchedule.motion` (its reference in plain Python): ``|Δq|`` of the one-dof
    joints at ``one_dof_q``, then per floating joint starting at ``floating_q[k]`` (a quaternion
    ``(w, x, y, z)`` then the position, when ``quaternion[k]``; else roll-pitch-yaw then the
    position) ``|Δp|`` and a bound of its rotation's angle, zeros when ``bounding[k]`` is False."""
    u = one_dof_q.size
    motion = np.zeros(u + 2 * floating_q.size)
    for j in range(u):
        motion[j] = abs(q1[one_dof_q[j]] - q0[one_dof_q[j]])
    for k in range(floating_q.size):
        if not bounding[k]:
            continue
        s = floating_q[k]
        if quaternion[k]:
            aw, ax, ay, az = q0[s], q0[s + 1], q0[s + 2], q0[s + 3]
            bw, bx, by, bz = q1[s], q1[s + 1], q1[s + 2], q1[s + 3]
            w = aw * bw + ax * bx + ay * by + az * bz
            vx = aw * bx - bw * ax - (ay * bz - az * by)  # the vector part of conj(a)·b
            vy = aw * by - bw * ay - (az * bx - ax * bz)
            vz = aw * bz - bw * az - (ax * by - ay * bx)
            angle = 2.0 * math.atan2(math.sqrt(vx * vx + vy * vy + vz * vz), abs(w))
            position = s + 4
        else:  # each angle's change bounds its rotation; the sum bounds theirs
            angle = abs(q1[s] - q0[s]) + abs(q1[s + 1] - q0[s + 1]) + abs(q1[s + 2] - q0[s + 2])
            position = s + 3
        dx, dy, dz = q1[position] - q0[position], q1[position + 1] - q0[position + 1], q1[position + 2] - q0[position + 2]
        motion[u + 2 * k] = math.sqrt(dx * dx + dy * dy + dz * dz)
        motion[u + 2 * k + 1] = angle
    return lower - np.dot(coefficients, motion)
