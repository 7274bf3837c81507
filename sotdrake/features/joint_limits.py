"""Joint-limit centring feature (sot-core ``FeatureJointLimits``).

For each selected joint with finite limits ``[l, u]``: ``e = 2(q - l)/(u - l) - 1``, which is 0 at
the middle of the range and ±1 on the limits; Jacobian ``2/(u - l)`` on the joint's velocity.
(sot-core's Jacobian is ``1/(u - l)``, half the derivative; this one is exact.) A task on it with a
low priority keeps joints away from their limits; as an inequality (``-1 + δ ≤ e ≤ 1 - δ``) it is a
soft joint-limit avoidance. Input ``state`` (``q``). Components are the joints with finite limits,
in the plant's order (``joint_names``); all are selected by default.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import Context

from ..configuration import Layout, position_names
from .base import Feature


class FeatureJointLimits(Feature):
    """``e = 2(q - l)/(u - l) - 1`` per joint with finite limits (dimensionless, ±1 on the limits):
    see the module docstring. Input ``state`` (``q``, nq); outputs ``signals``, ``error``,
    ``jacobian``, ``errordot``; ``joint_names`` lists the rows' joints."""

    def __init__(self, name: str, plant):
        layout = Layout.of(plant)
        lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
        finite = np.isfinite(lower[layout.joints_q]) & np.isfinite(upper[layout.joints_q])
        finite &= upper[layout.joints_q] > lower[layout.joints_q]
        self._q = layout.joints_q[finite]
        self._v = layout.joints_v[finite]
        self._lower, self._width = lower[self._q], (upper - lower)[self._q]
        Feature.__init__(self, name, len(self._q), plant.num_velocities())
        names = position_names(plant)
        self.joint_names = [names[i] for i in self._q]
        self.state = self.DeclareVectorInputPort("state", plant.num_positions())
        self._declare_outputs()

    def _compute(self, context: Context, settings, rows):
        return joint_limits_error_and_jacobian(self.state.Eval(context), self._q, self._v, self._lower, self._width, self.nv)


def joint_limits_error_and_jacobian(
    q: np.ndarray, q_index: np.ndarray, v_index: np.ndarray, lower: np.ndarray, width: np.ndarray, nv: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``e = 2(q - l)/(u - l) - 1`` of the coordinates ``q_index`` (limits ``lower``, ``width = u - l``),
    Jacobian ``2/(u - l)`` on the velocities ``v_index``, ``ė_ref = 0``."""
    e = 2.0 * (q[q_index] - lower) / width - 1.0
    J = np.zeros((e.size, nv))
    J[np.arange(e.size), v_index] = 2.0 / width
    return e, J, np.zeros(e.size)

