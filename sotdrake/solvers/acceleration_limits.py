"""Joint acceleration limits at the velocity level: hard bounds ``|v − v_prev| ≤ a_max dt``.

``SolverKine`` commands a velocity ``v`` every tick ``dt``; the previous command ``v_prev`` is kept
in its Context. With an acceleration limit ``a`` (rad/s², m/s² for a prismatic joint) on a joint,
its velocity bounds ``[l, u]`` (the position and velocity limits of :mod:`.limits`) are narrowed to

* the acceleration window ``v_prev − a dt ≤ v ≤ v_prev + a dt``;
* the braking bounds: a joint moving at ``v`` towards its upper limit, ``d = q_max − m − q`` away
  (``m`` the position margin), must still be able to stop before it at deceleration ``a`` after
  this tick: ``v dt + v²/(2a) ≤ d``, i.e. ``v ≤ v_brake(d) = −a dt + √((a dt)² + 2 a d)`` (0 for
  ``d ≤ 0``); symmetrically ``v ≥ −v_brake(q − q_min − m)``. (The discrete braking from ``v`` in
  steps of ``a dt`` covers ``v²/(2a) + θ v dt`` with ``θ ≤ ½``: the bound is conservative, and a
  joint that satisfies it at one tick can satisfy it at the next with ``v − a dt``, so the set
  stays feasible tick after tick.)

Precedence when they cannot all hold (a start at speed next to a limit, a limit changed at run
time, a new control selection): the position and velocity limits first (``[l, u]`` is kept), then
the acceleration window (the velocity of ``[l, u]`` nearest to ``v_prev``), then the braking bounds
(the greatest deceleration the window allows). The bounds stay ordered: ``lower ≤ upper``. Joints
without a limit (``a = inf``) and the floating base keep ``[l, u]``.
"""

from __future__ import annotations

import numpy as np

from ..configuration import Layout

#: Largest finite acceleration limit accepted (rad/s² or m/s²).
MAX_ACCELERATION = 1e6


def braking_velocity(distance: np.ndarray, a_max: np.ndarray, dt: float) -> np.ndarray:
    """``v_brake(d) = −a dt + √((a dt)² + 2 a d)`` for ``d ≥ 0`` (0 for ``d ≤ 0``; inf where
    ``a`` or ``d`` is inf): the largest speed towards a limit ``d`` away (m or rad) from which the
    joint can still stop before it, moving this tick then decelerating at ``a``."""
    d = np.maximum(np.asarray(distance, dtype=float), 0.0)
    a = np.asarray(a_max, dtype=float)
    with np.errstate(invalid="ignore"):
        step = a * dt
        out = np.sqrt(step * step + 2.0 * a * d) - step
    return np.where(np.isinf(a) | np.isinf(d), np.inf, out)


def acceleration_bounds(lower: np.ndarray, upper: np.ndarray, v_prev: np.ndarray, a_max: np.ndarray, dt: float,
                        brake_lower: np.ndarray, brake_upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``[lower, upper]`` (velocity bounds, ordered) narrowed by the acceleration window
    ``v_prev ± a_max dt`` and the braking bounds ``[brake_lower, brake_upper]``, with the
    precedence of the module docstring. All arrays of one size (``a_max`` inf: no window)."""
    step = a_max * dt
    with np.errstate(invalid="ignore"):  # inf − inf does not occur: v_prev is finite
        lo = np.maximum(lower, v_prev - step)
        up = np.minimum(upper, v_prev + step)
    crossed = lo > up  # the window misses [lower, upper]: its nearest velocity
    if crossed.any():
        nearest = np.clip(v_prev, lower, upper)
        lo = np.where(crossed, nearest, lo)
        up = np.where(crossed, nearest, up)
    up2 = np.maximum(np.minimum(up, brake_upper), lo)
    lo2 = np.minimum(np.maximum(lo, brake_lower), up2)
    return lo2, up2


class AccelerationBounds:
    """:func:`acceleration_bounds` for one robot: the joints' coordinates and position limits read
    once (``position_lower``, ``position_upper``: nq, as the plant gives them)."""

    def __init__(self, position_lower: np.ndarray, position_upper: np.ndarray, layout: Layout):
        self._iq = np.asarray(layout.joints_q, dtype=int)
        self._iv = np.asarray(layout.joints_v, dtype=int)
        self._q_lower = np.asarray(position_lower, dtype=float)[self._iq]
        self._q_upper = np.asarray(position_upper, dtype=float)[self._iq]
        self.nv = layout.nv

    def __call__(self, lower: np.ndarray, upper: np.ndarray, q: np.ndarray, v_prev: np.ndarray, a_max: np.ndarray,
                 dt: float, margin: float) -> tuple[np.ndarray, np.ndarray]:
        """The bounds on ``v`` (nv) at ``q`` after a command ``v_prev``, with ``a_max`` (nv; inf:
        none) and the position margin ``margin``."""
        iv = self._iv
        qj = q[self._iq]
        a = a_max[iv]
        lo, up = lower.copy(), upper.copy()
        brake_up = braking_velocity(self._q_upper - margin - qj, a, dt)
        brake_lo = -braking_velocity(qj - self._q_lower - margin, a, dt)
        lo[iv], up[iv] = acceleration_bounds(lower[iv], upper[iv], v_prev[iv], a, dt, brake_lo, brake_up)
        return lo, up
