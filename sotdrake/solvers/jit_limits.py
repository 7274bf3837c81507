"""The joint limits' velocity bounds of :mod:`.limits`, compiled with numba: :func:`bounds`.

The same arithmetic as ``velocity_bounds`` of ``tests/oracles.py``, one joint at a time (in numpy,
about fifteen calls of a microsecond each, every tick). ``np.maximum``/``np.minimum`` on scalars
keep numpy's rule: a NaN on either side gives NaN.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def bounds(q, joints_q, joints_v, q_lower, q_upper, v_lower, v_upper, outside_lower, outside_upper, dt, margin, unselected):
    """``(lower, upper)`` bounds on ``v`` at ``q`` (see :mod:`.limits`): joint ``k`` at ``q[joints_q[k]]``
    with limits ``q_lower[k]``, ``q_upper[k]``, ``v_lower[k]``, ``v_upper[k]`` bounds ``v[joints_v[k]]``;
    the other components keep ``outside_lower``/``outside_upper``; the components where
    ``unselected`` (nv booleans, or none) is True get ``[0, 0]``."""
    lower, upper = outside_lower.copy(), outside_upper.copy()
    for k in range(joints_q.size):
        qj, lo, hi = q[joints_q[k]], q_lower[k], q_upper[k]
        up = np.maximum((hi - margin - qj) / dt, np.minimum(0.0, (hi - qj) / dt))
        down = np.minimum((lo + margin - qj) / dt, np.maximum(0.0, (lo - qj) / dt))
        up = np.minimum(np.maximum(up, v_lower[k]), v_upper[k])
        down = np.minimum(np.maximum(down, v_lower[k]), v_upper[k])
        upper[joints_v[k]] = up
        lower[joints_v[k]] = np.minimum(down, up)
    for i in range(unselected.size):
        if unselected[i]:
            lower[i] = upper[i] = 0.0
    return lower, upper
