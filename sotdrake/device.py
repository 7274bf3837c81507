"""The kinematic ``Device`` (sot-core ``Device``/``RobotSimu``): integrates the velocity command.

Discrete state ``q`` (Drake positions), updated every ``dt`` seconds by ``q ← q ⊕ v·dt`` with ``v``
the ``control`` input (Drake generalized velocities) evaluated at the start of the tick. Output
``state`` is ``q``.

``⊕`` is exact for Drake's generalized velocity ``v`` held constant over the tick (the flow of
``q̇ = N(q) v``, the meaning of ``v`` the solvers' Jacobians are taken with respect to):

* revolute/prismatic coordinates: ``q_j ← q_j + v_j dt``;
* the floating base ``X_WB = (R, p)`` with Drake's ``(ω_W, v_WBo)`` (both in the world frame):
  ``R ← exp([ω_W]× dt) R`` (the quaternion as ``q ← exp(ω_W dt) ⊗ q``, continuous, re-normalised
  each tick) and ``p ← p + v_WBo dt``.

(Integrating instead the body twist ``(Rᵀω_W, Rᵀv_WBo)`` on SE(3), as pinocchio's ``integrate``
does with its body-frame ``v``, bends the base's path by ``½ ω × v dt²`` per tick, a second-order
term no Drake Jacobian accounts for: TALOS' feet drifted by 8 µm in 0.3 s that way while reaching
at the velocity limits. :func:`difference` is the inverse of ``⊕``.)

Joint limits are *not* enforced here (nothing is silently clamped): the solvers own limits. The
device logs a warning each time a joint crosses one of its position limits, and the diagrams report
the smallest limit margin seen.
"""

from __future__ import annotations

import logging
from typing import NamedTuple

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from .entity import own_context
from .exceptions import InvalidInput, SolverError, SotError, check_finite
from .ranges import MAX_JOINT_TARGET
from .lie import log_so3, quaternion_exp, quaternion_multiply, quaternion_wxyz_to_rotation

log = logging.getLogger("sotdrake.device")


class Layout(NamedTuple):
    """Where the floating base sits in ``q`` and ``v`` (None: fixed base), and the joint indices."""

    base_q: int | None
    base_v: int | None
    joints_q: np.ndarray
    joints_v: np.ndarray

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
        return Layout(base_q, base_v, joints_q, joints_v)


def _coordinate_names(plant: MultibodyPlant) -> list[str]:
    names = [""] * plant.num_positions()
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        for k in range(joint.num_positions()):
            names[joint.position_start() + k] = joint.name() if joint.num_positions() == 1 else f"{joint.name()}[{k}]"
    return names


def integrate(q: np.ndarray, v: np.ndarray, dt: float, layout: Layout) -> np.ndarray:
    """``q ⊕ v·dt`` (see the module docstring)."""
    out = q.copy()
    out[layout.joints_q] += dt * v[layout.joints_v]
    if layout.base_q is not None:
        iq, iv = layout.base_q, layout.base_v
        quaternion = quaternion_multiply(quaternion_exp(v[iv : iv + 3] * dt), q[iq : iq + 4])
        out[iq : iq + 4] = quaternion / np.linalg.norm(quaternion)
        out[iq + 4 : iq + 7] = q[iq + 4 : iq + 7] + dt * v[iv + 3 : iv + 6]
    return out


def difference(q: np.ndarray, q_previous: np.ndarray, layout: Layout) -> np.ndarray:
    """``Δ`` (size nv) with ``q = q_previous ⊕ Δ`` (a velocity times ``dt``): joints ``q - q_prev``;
    the base ``(log(R R_prevᵀ), p - p_prev)``, world frame."""
    out = np.empty(len(layout.joints_v) + (6 if layout.base_v is not None else 0))
    out[layout.joints_v] = q[layout.joints_q] - q_previous[layout.joints_q]
    if layout.base_q is not None:
        iq, iv = layout.base_q, layout.base_v
        R = quaternion_wxyz_to_rotation(q[iq : iq + 4])
        R_previous = quaternion_wxyz_to_rotation(q_previous[iq : iq + 4])
        out[iv : iv + 3] = log_so3(R @ R_previous.T)
        out[iv + 3 : iv + 6] = q[iq + 4 : iq + 7] - q_previous[iq + 4 : iq + 7]
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
        if not np.all(np.isfinite(v)):
            raise SolverError(f"{self.get_name()}: non-finite control at t = {context.get_time()}: {v}")
        q = context.get_discrete_state(self._q).get_value()
        q_next = integrate(q, v, self.dt, self.layout)
        outside = (q_next < self._lower) | (q_next > self._upper)
        if outside.any():
            crossed = outside & (q >= self._lower) & (q <= self._upper)
            for i in np.flatnonzero(crossed):
                log.warning("t = %.3f s: %s left its limits [%g, %g]: %g", context.get_time(),
                            self._coordinate_names[i], self._lower[i], self._upper[i], q_next[i])
        discrete_state.set_value(self._q, q_next)

    def set_position(self, context: Context, q: np.ndarray) -> None:
        """Set ``q`` in ``context`` (the root diagram context or the device's own)."""
        from .entity import recording

        if recording():
            raise SotError(f"{self.get_name()}.set_position changes the state now: it cannot be recorded by attime")
        q = check_finite("q (rad, m)", q, (self.nq,), MAX_JOINT_TARGET)
        if self.layout.base_q is not None:
            norm = np.linalg.norm(q[self.layout.base_q : self.layout.base_q + 4])
            if abs(norm - 1.0) > 1e-3:
                raise InvalidInput(f"{self.get_name()}.set_position: the base quaternion must have norm 1 (± 1e-3), got {norm:g}")
        own_context(self, context).SetDiscreteState(self._q, q)

    def position(self, context: Context) -> np.ndarray:
        return own_context(self, context).get_discrete_state(self._q).get_value().copy()
