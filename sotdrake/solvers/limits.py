"""Joint limits as velocity bounds over one tick: the hard constraints above every task.

For a joint with position limits ``[q_min, q_max]``, velocity limits ``[v_min, v_max]``, tick
``dt`` and margin ``m`` (rad or m), the upper bound on its velocity is

* ``(q_max - m - q)/dt`` while the joint is farther than ``m`` from its limit;
* ``0`` inside the margin (it may stay, it is not pushed out: a start on the boundary is fine);
* ``(q_max - q)/dt < 0`` if it is beyond the limit (brought back in one tick),

then capped by ``v_max``; the lower bound is symmetric. Where the two would cross (a violated limit
faster than the velocity limit allows to fix), the position side wins within the velocity limit.
The floating base's velocity is bounded only when ``base_velocity = (ω̄, v̄)`` is given: each
component of its angular velocity in ``[-ω̄, ω̄]`` (rad/s), of its linear velocity in ``[-v̄, v̄]``
(m/s) (default of the solvers: :mod:`.base_velocity`). Coordinates excluded by a control selection
get ``[0, 0]``.
"""

from __future__ import annotations

import numpy as np

from ..configuration import Layout


def velocity_bounds(
    q: np.ndarray,
    position_lower: np.ndarray,
    position_upper: np.ndarray,
    velocity_lower: np.ndarray,
    velocity_upper: np.ndarray,
    dt: float,
    margin: float,
    layout: Layout,
    control_selection: np.ndarray | None = None,
    base_velocity: tuple[float, float] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``(lower, upper)`` bounds on ``v`` (size nv); see the module docstring."""
    nv = len(velocity_lower)
    lower, upper = np.full(nv, -np.inf), np.full(nv, np.inf)
    iq, iv = layout.joints_q, layout.joints_v
    qj, lo, hi = q[iq], position_lower[iq], position_upper[iq]
    with np.errstate(invalid="ignore"):  # infinite position limits give ±inf bounds
        up = np.maximum((hi - margin - qj) / dt, np.minimum(0.0, (hi - qj) / dt))
        down = np.minimum((lo + margin - qj) / dt, np.maximum(0.0, (lo - qj) / dt))
    v_lo, v_hi = velocity_lower[iv], velocity_upper[iv]
    up = np.minimum(np.maximum(up, v_lo), v_hi)  # np.clip, without its wrapper's cost
    down = np.minimum(np.maximum(down, v_lo), v_hi)
    upper[iv], lower[iv] = up, np.minimum(down, up)
    if base_velocity is not None and layout.base_v is not None:
        b = layout.base_v
        angular, linear = base_velocity
        lower[b : b + 3], upper[b : b + 3] = -angular, angular
        lower[b + 3 : b + 6], upper[b + 3 : b + 6] = -linear, linear
    if control_selection is not None:
        lower[~control_selection] = upper[~control_selection] = 0.0
    return lower, upper
