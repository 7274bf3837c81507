"""The kinematic ``Device`` (sot-core ``Device``/``RobotSimu``): integrates the velocity command.

Discrete state ``q`` (Drake positions), updated every ``dt`` seconds by ``q ← q ⊕ v·dt`` with ``v``
the ``control`` input (Drake generalized velocities) evaluated at the start of the tick. Output
``state`` is ``q``.

``⊕`` is :func:`sotdrake.configuration.integrate`: exact for Drake's generalized velocity ``v``
held constant over the tick (see there).

Joint limits are *not* enforced here (nothing is silently clamped): the solvers own limits. The
device logs a warning each time a joint crosses one of its position limits, and the diagrams report
the smallest limit margin seen.
"""

from __future__ import annotations

import logging
import math

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from .configuration import Layout, check_base_quaternion, integrate, position_names
from .entity import own_context
from .exceptions import SolverError, SotError, check_finite, check_number
from .ranges import MAX_JOINT_TARGET

log = logging.getLogger("sotdrake.device")


class Device(LeafSystem):
    """Input ``control`` (nv); discrete state and output ``state`` (q); period ``dt`` (s)."""

    def __init__(self, plant: MultibodyPlant, dt: float, q0: np.ndarray, name: str = "device"):
        LeafSystem.__init__(self)
        self.set_name(name)
        self.dt = check_number("dt (the control period)", dt, 1e-6, 1.0, " s")
        self.layout = Layout.of(plant)
        self.nq, self.nv = plant.num_positions(), plant.num_velocities()
        self._lower, self._upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
        self._coordinate_names = position_names(plant)
        self.initial_position = self._checked_position("q0", q0)
        self.initial_position.flags.writeable = False
        self._q = self.DeclareDiscreteState(self.initial_position)
        self.control = self.DeclareVectorInputPort("control", self.nv)
        self.DeclareStateOutputPort("state", self._q)
        self.DeclarePeriodicDiscreteUpdateEvent(self.dt, 0.0, self._update)

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        v = self.control.Eval(context)
        if not math.isfinite(v.sum()):
            raise SolverError(f"{self.get_name()}: non-finite control at t = {context.get_time()}: {v}")
        # The update's own copy of the state (writeable: integrate takes it without a copy; not modified).
        q = discrete_state.get_mutable_value(self._q)
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
        from .entity import recording

        if recording():
            raise SotError(f"{self.get_name()}.set_position changes the state now: it cannot be recorded by attime")
        own_context(self, context).SetDiscreteState(self._q, self._checked_position(f"{self.get_name()}.set_position: q", q))

    def _checked_position(self, label: str, q: np.ndarray) -> np.ndarray:
        """``q`` as a new array: nq finite numbers within :data:`~sotdrake.ranges.MAX_JOINT_TARGET`,
        the base quaternion (if any) of norm 1 ± 1e-3."""
        q = check_finite(f"{label} (rad, m)", q, (self.nq,), MAX_JOINT_TARGET).copy()
        check_base_quaternion(label, q, self.layout)
        return q

    def position(self, context: Context) -> np.ndarray:
        return own_context(self, context).get_discrete_state(self._q).get_value().copy()
