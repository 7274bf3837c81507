"""``SolverDyn``'s fast path compiled with numba: the levels with ``τ`` eliminated, stacked, and the
checks of their optimum (see :mod:`.reduced_levels`, the Python front).

The same numbers as the Python reference (:func:`.formulation.dynamic_rows` with ``actuated``,
:func:`.formulation.torques_of`, :func:`.formulation.variable_bounds`), in three calls instead of
about a hundred numpy operations a tick, whose overhead, not their arithmetic, was their cost.

The contacts come stacked and transposed (Drake's matrices are column-major: their transposes are
C-ordered views): ``JT`` their Jacobians side by side (nv × Σk; contact c's rows of ``J`` are
columns ``offsets[c]:offsets[c] + sizes[c]``, 6, or 3 for a point contact, whose wrench is the
force alone), ``RT`` their rotations ``R_WCᵀ`` side by side (3 × 3c); contact c's wrench is at
``x[nv + offsets[c] :]``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..hqp.kernels.lapack import row_norms


@njit(cache=True)
def reduced_stack(M, h, passive, JT, RT, sizes, acceleration, centres, scales, task_J, task_rhs, task_sizes, v, damping_gain):
    """``(A, b, norms, starts)``: the levels over ``x = (q̈, w…)`` stacked, each level's rows at
    ``starts[k]:starts[k + 1]`` (``norms``: the rows' norms, 0 → 1):

    0. the dynamics' ``passive`` rows: ``[M_p, −(J_cᵀ diag(R_c, R_c))_p …] x = −h_p``;
    1. (with contacts) ``[J_c 0] x = acceleration``;
    2. … the tasks (``task_sizes`` rows each): ``[J_t 0] x = rhs``;
    last. ``[I 0] x = −K_d v`` and each contact's regularization rows times ``scales[c]``
       (``n_x − y_c f_z, n_y + x_c f_z, n_z, f_x, f_y`` with ``(x_c, y_c) = centres[c]``; a point
       contact: ``f_x, f_y``), target 0."""
    nv = M.shape[0]
    p = passive.size
    count = sizes.size
    n_w = JT.shape[1]
    n = nv + n_w
    m_t = task_J.shape[0]
    regularization = 0
    for c in range(count):
        regularization += sizes[c] - 1
    rows = p + n_w + m_t + nv + regularization
    A = np.zeros((rows, n))
    b = np.zeros(rows)
    for i in range(p):
        A[i, :nv] = M[passive[i]]
        b[i] = -h[passive[i]]
    offset = 0
    for c in range(count):
        for block in range(sizes[c] // 3):
            first = offset + 3 * block  # this block's rows of J, and its columns in x after q̈
            for j in range(3):
                for i in range(p):
                    column = 0.0  # (J_bᵀ R)[passive[i], j]
                    for k in range(3):
                        column += RT[j, 3 * c + k] * JT[passive[i], first + k]
                    A[i, nv + first + j] = -column
        offset += sizes[c]
    row = p
    for i in range(n_w):
        A[row + i, :nv] = JT[:, i]
        b[row + i] = acceleration[i]
    row += n_w
    for i in range(m_t):
        A[row + i, :nv] = task_J[i]
        b[row + i] = task_rhs[i]
    row += m_t
    for i in range(nv):
        A[row + i, i] = 1.0
        b[row + i] = -damping_gain * v[i]
    row += nv
    offset = 0
    for c in range(count):
        s, column = scales[c], nv + offset
        if sizes[c] == 6:
            A[row, column], A[row, column + 5] = s, -centres[c, 1] * s
            A[row + 1, column + 1], A[row + 1, column + 5] = s, centres[c, 0] * s
            for k in range(2, 5):
                A[row + k, column + k] = s
            row += 5
        else:
            A[row, column], A[row + 1, column + 1] = s, s
            row += 2
        offset += sizes[c]
    levels = 2 + task_sizes.size + (1 if count else 0)
    starts = np.zeros(levels + 1, np.int64)
    starts[1] = p
    k = 1
    if count:
        starts[k + 1] = starts[k] + n_w
        k += 1
    for size in task_sizes:
        starts[k + 1] = starts[k] + size
        k += 1
    starts[k + 1] = rows
    return A, b, row_norms(A), starts


@njit(cache=True)
def world_wrenches(RT, sizes, x, nv):
    """Each contact's world wrench ``diag(R_c, R_c) w_c`` (``R_c f_c`` for a point contact), stacked."""
    out = np.empty(x.size - nv)
    offset = 0
    for c in range(sizes.size):
        for block in range(sizes[c] // 3):
            first = offset + 3 * block
            for k in range(3):
                value = 0.0
                for j in range(3):
                    value += RT[j, 3 * c + k] * x[nv + first + j]
                out[first + k] = value
        offset += sizes[c]
    return out


@njit(cache=True)
def torques_and_checks(M, h, actuated, JT, RT, sizes, x, effort, wrench_rows, row_counts, tolerance):
    """``(τ, W, within, hold)`` at ``x = (q̈, w…)``: ``τ`` the ``actuated`` rows of
    ``M q̈ + h − Σ_c J_cᵀ W_c``, ``W`` the world wrenches (:func:`world_wrenches`); ``within``:
    ``|τ| ≤ effort`` (NaN counts as within, as the comparison says); ``hold``: every contact's
    wrench rows (``row_counts[c]`` rows of ``wrench_rows``, stacked, ``sizes[c]`` columns used)
    give ``A w ≤ tolerance · max(1, max |w|)``."""
    nv = M.shape[0]
    world = world_wrenches(RT, sizes, x, nv)
    tau = np.empty(actuated.size)
    within = True
    for a in range(actuated.size):
        r = actuated[a]
        value = 0.0
        for j in range(nv):
            value += M[r, j] * x[j]
        value += h[r]
        for i in range(world.size):
            value -= JT[r, i] * world[i]
        tau[a] = value
        if abs(value) > effort[a]:
            within = False
    hold = True
    offset, first_row = 0, 0
    for c in range(sizes.size):
        k = sizes[c]
        largest = 1.0
        for j in range(k):
            largest = max(largest, abs(x[nv + offset + j]))
        for i in range(first_row, first_row + row_counts[c]):
            value = 0.0
            for j in range(k):
                value += wrench_rows[i, j] * x[nv + offset + j]
            if value > tolerance * largest:
                hold = False
        offset += k
        first_row += row_counts[c]
    return tau, world, within, hold


@njit(cache=True)
def _min(a, b):
    return a if a <= b or math.isnan(a) else b  # np.minimum (NaN kept)


@njit(cache=True)
def _max(a, b):
    return a if a >= b or math.isnan(a) else b  # np.maximum (NaN kept)


@njit(cache=True)
def _side_bounds(q, v, position_upper, velocity_upper, horizon, margin, dt, braking):
    """:func:`.terms.side_acceleration_bounds` of one joint (the same operations, in the same order)."""
    rate = velocity_upper / horizon
    brake = _min(rate, braking)
    stretched = velocity_upper / brake if brake < rate and math.isfinite(velocity_upper) else horizon
    reach = q + v * stretched
    limit = position_upper - margin
    if q > limit:  # inside the margin: min(0, q_max − reach), as np.minimum (NaN kept)
        inside = position_upper - reach
        up = inside if inside < 0.0 or math.isnan(inside) else 0.0
    else:
        up = limit - reach
    up *= 2
    up /= stretched * stretched
    speed_rate = (velocity_upper - v) / horizon
    room = position_upper - q
    speed = 0.0  # (.terms.stopping_speed)
    if room > 0.0 and brake > 0.0:
        speed = math.inf if math.isinf(room) else 2 * room / (dt + math.sqrt(dt * dt + 2 * room / brake))
    return _min(up, speed_rate), _max((speed - v) / dt, -brake)


@njit(cache=True)
def dynamic_bounds(lower_template, upper_template, q, v, joints_q, joints_v, position_limits, velocity_limits, horizon,
                   margin, dt, braking, selection, normal, normal_lower, normal_upper):
    """The bounds on ``x`` (copies of the templates: free wrenches, ``±effort``): the joints' rows
    ``joints_v`` from :func:`.terms.mirrored_acceleration_bounds` (the same operations, ``braking``
    over the joints), the components out of the control ``selection`` (a mask over the first
    ``selection.size`` ones) fixed at 0, the components ``normal`` between ``normal_lower`` and ``normal_upper``."""
    lower, upper = lower_template.copy(), upper_template.copy()
    for k in range(joints_v.size):
        qk, vk = q[joints_q[k]], v[joints_v[k]]
        shaping_up, stop_up = _side_bounds(qk, vk, position_limits[0, k], velocity_limits[0, k], horizon, margin, dt, braking[k])
        shaping_down, stop_down = _side_bounds(-qk, -vk, position_limits[1, k], velocity_limits[1, k], horizon, margin, dt,
                                               braking[k])
        high = _min(_max(_min(shaping_up, stop_up), -stop_down), stop_up)
        mirrored = _min(_max(_min(shaping_down, stop_down), -stop_up), stop_down)  # the mirrored joint's upper bound
        upper[joints_v[k]] = high
        lower[joints_v[k]] = _min(-mirrored, high)
    for i in range(selection.size):
        if not selection[i]:
            lower[i] = upper[i] = 0.0
    for i in range(normal.size):
        lower[normal[i]], upper[normal[i]] = normal_lower[i], normal_upper[i]
    return lower, upper
