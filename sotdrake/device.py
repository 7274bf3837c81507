"""The kinematic ``Device`` (sot-core ``Device``/``RobotSimu``): integrates the velocity command.

Discrete state ``q`` (Drake positions), updated every ``dt`` seconds by ``q ← q ⊕ v·dt`` with ``v``
the ``control`` input (Drake generalized velocities) evaluated at the start of the tick. Output
``state`` is ``q``.

``⊕`` is exact for a velocity held constant over the tick in the SoT sense:

* revolute/prismatic coordinates: ``q_j ← q_j + v_j dt``;
* the floating base ``X_WB = (R, p)`` with Drake's ``v_B = (ω_W, v_WBo)`` (world frame): the body
  twist ``ξ = (Rᵀ v_WBo, Rᵀ ω_W)`` is integrated on SE(3), ``X_WB ← X_WB · exp(ξ dt)``; the
  quaternion as ``q ← q ⊗ exp(ω_B dt)`` (continuous, no sign flips), re-normalised each tick.

Joint limits are *not* enforced here (nothing is silently clamped): the solvers own limits. The
device logs a warning each time a joint crosses one of its position limits, and the diagrams report
the smallest limit margin seen.
"""

from __future__ import annotations

import logging
import math
from typing import NamedTuple

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from .entity import own_context
from .exceptions import InvalidInput, SolverError, check_finite
from .lie import quaternion_exp_list, quaternion_multiply_list, quaternion_wxyz_to_rotation_list, se3_translation_list

log = logging.getLogger("sotdrake.device")


class Layout(NamedTuple):
    """Where the floating base sits in ``q`` and ``v`` (None: fixed base), and the joint indices."""

    base_q: int | None
    base_v: int | None
    joints_q: np.ndarray
    joints_v: np.ndarray
    joints_q_slice: slice | None = None  # the same indices as a slice, when contiguous
    joints_v_slice: slice | None = None

    @staticmethod
    def of(plant: MultibodyPlant) -> "Layout":
        bases = list(plant.GetFloatingBaseBodies())
        if len(bases) > 1:
            raise InvalidInput("the device handles at most one floating base")
        base_q = base_v = None
        joints_q, joints_v = np.arange(plant.num_positions()), np.arange(plant.num_velocities())
        if bases:
            body = plant.get_body(bases[0])
            base_q, base_v = body.floating_positions_start(), body.floating_velocities_start_in_v()
            joints_q = np.setdiff1d(joints_q, np.arange(base_q, base_q + 7))
            joints_v = np.setdiff1d(joints_v, np.arange(base_v, base_v + 6))
        if joints_q.size != joints_v.size:
            raise InvalidInput("every joint but the floating base must have as many positions as velocities")
        return Layout(base_q, base_v, joints_q, joints_v, _as_slice(joints_q), _as_slice(joints_v))


def _as_slice(indices: np.ndarray) -> slice | None:
    """``indices`` as a slice if they are contiguous and increasing (None otherwise)."""
    if indices.size and np.array_equal(indices, np.arange(indices[0], indices[0] + indices.size)):
        return slice(int(indices[0]), int(indices[0]) + indices.size)
    return None


def _coordinate_names(plant: MultibodyPlant) -> list[str]:
    names = [""] * plant.num_positions()
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        for k in range(joint.num_positions()):
            names[joint.position_start() + k] = joint.name() if joint.num_positions() == 1 else f"{joint.name()}[{k}]"
    return names


def integrate(q: np.ndarray, v: np.ndarray, dt: float, layout: Layout) -> np.ndarray:
    """``q ⊕ v·dt`` (see the module docstring). The floating base's 3-vectors and quaternion are
    handled on Python floats (cheaper than numpy at this size)."""
    out = q.copy()
    if layout.joints_q_slice is not None and layout.joints_v_slice is not None:
        out[layout.joints_q_slice] += dt * v[layout.joints_v_slice]
    else:
        out[layout.joints_q] += dt * v[layout.joints_v]
    if layout.base_q is not None:
        iq, iv = layout.base_q, layout.base_v
        w, x, y, z = q[iq : iq + 4].tolist()
        n = math.sqrt(w * w + x * x + y * y + z * z)
        w, x, y, z = w / n, x / n, y / n, z / n
        R = quaternion_wxyz_to_rotation_list(w, x, y, z)
        twist = v[iv : iv + 6].tolist()
        omega_B = [dt * (R[0][i] * twist[0] + R[1][i] * twist[1] + R[2][i] * twist[2]) for i in range(3)]
        v_B = [dt * (R[0][i] * twist[3] + R[1][i] * twist[4] + R[2][i] * twist[5]) for i in range(3)]
        dp = se3_translation_list(v_B, omega_B)
        quaternion = quaternion_multiply_list((w, x, y, z), quaternion_exp_list(omega_B))
        n = math.sqrt(sum(c * c for c in quaternion))
        out[iq : iq + 4] = [c / n for c in quaternion]
        p = q[iq + 4 : iq + 7].tolist()
        out[iq + 4 : iq + 7] = [p[i] + R[i][0] * dp[0] + R[i][1] * dp[1] + R[i][2] * dp[2] for i in range(3)]
    return out


class Device(LeafSystem):
    """Input ``control`` (nv); discrete state and output ``state`` (q); period ``dt`` (s)."""

    def __init__(self, plant: MultibodyPlant, dt: float, q0: np.ndarray, name: str = "device"):
        LeafSystem.__init__(self)
        self.set_name(name)
        if not (np.isfinite(dt) and dt > 0):
            raise InvalidInput(f"dt must be > 0, got {dt}")
        self.dt = float(dt)
        self.nq, self.nv = plant.num_positions(), plant.num_velocities()
        self.layout = Layout.of(plant)
        self._lower, self._upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
        self._coordinate_names = _coordinate_names(plant)
        self.initial_position = check_finite("q0", q0, (self.nq,)).copy()
        self.initial_position.flags.writeable = False
        self._q = self.DeclareDiscreteState(self.initial_position)
        self.control = self.DeclareVectorInputPort("control", self.nv)
        self.DeclareStateOutputPort("state", self._q)
        self.DeclarePeriodicDiscreteUpdateEvent(self.dt, 0.0, self._update)

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        v = self.control.Eval(context)
        if not math.isfinite(v.sum()):
            raise SolverError(f"{self.get_name()}: non-finite control at t = {context.get_time()}: {v}")
        q = context.get_discrete_state(self._q).get_value()
        q_next = integrate(q, v, self.dt, self.layout)
        outside = (q_next < self._lower) | (q_next > self._upper)
        if np.count_nonzero(outside):
            crossed = outside & (q >= self._lower) & (q <= self._upper)
            for i in np.flatnonzero(crossed):
                log.warning("t = %.3f s: %s left its limits [%g, %g]: %g", context.get_time(),
                            self._coordinate_names[i], self._lower[i], self._upper[i], q_next[i])
        discrete_state.set_value(self._q, q_next)

    def set_position(self, context: Context, q: np.ndarray) -> None:
        """Set ``q`` in ``context`` (the root diagram context or the device's own)."""
        own_context(self, context).SetDiscreteState(self._q, check_finite("q", q, (self.nq,)))

    def position(self, context: Context) -> np.ndarray:
        return own_context(self, context).get_discrete_state(self._q).get_value().copy()
