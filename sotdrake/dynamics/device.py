"""``RobotDynSimu`` (sot-dyninv): the seed's dynamic device, no physics: it integrates ``q̈``.

Discrete state ``(q, v)``, updated every ``dt`` seconds with the ``control`` input ``q̈`` (nv)
evaluated at the start of the tick, semi-implicitly::

    v ← v + q̈ dt,     q ← q ⊕ v dt

where ``⊕`` is the kinematic device's integration on SE(3) × joints
(:func:`sotdrake.device.integrate`). Output ``state`` ``(q, v)``.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context, DiscreteValues, LeafSystem

from ..configuration import Layout, check_base_quaternion, integrate
from ..exceptions import SolverError, check_finite, check_name, check_number
from ..ranges import MAX_JOINT_TARGET


def integrate_acceleration(q: np.ndarray, v: np.ndarray, a: np.ndarray, dt: float, layout: Layout) -> tuple[np.ndarray, np.ndarray]:
    """One semi-implicit Euler step: ``(q ⊕ v' dt, v')`` with ``v' = v + a dt``."""
    v_next = v + a * dt
    return integrate(q, v_next, dt, layout), v_next


class RobotDynSimu(LeafSystem):
    """Input ``control`` (``q̈``); discrete state and output ``state`` (``(q, v)``); period ``dt``.

    Checked as the kinematic ``Device`` checks its own (:class:`InvalidInput` naming the argument):
    ``dt`` a number in [1e-6, 1] s (not a bool), ``q0`` the plant's nq finite positions within
    ``|q| ≤`` :data:`~sotdrake.ranges.MAX_JOINT_TARGET`, its base quaternion of norm 1 ± 1e-3,
    ``v0`` (None: zero) nv finite velocities, ``name`` a non-empty string."""

    def __init__(self, plant: MultibodyPlant, dt: float, q0: np.ndarray, v0: np.ndarray | None = None, name: str = "device"):
        LeafSystem.__init__(self)
        self.set_name(check_name("RobotDynSimu: name", name))
        self.dt = check_number("dt (the control period)", dt, 1e-6, 1.0, " s")
        self.layout = Layout.of(plant)
        self.nq, self.nv = plant.num_positions(), plant.num_velocities()
        q0 = check_finite("q0 (rad, m)", q0, (self.nq,), MAX_JOINT_TARGET)
        check_base_quaternion("q0", q0, self.layout)
        v0 = np.zeros(self.nv) if v0 is None else check_finite("v0", v0, (self.nv,))
        self.initial_state = np.concatenate([q0, v0])
        self._x = self.DeclareDiscreteState(self.initial_state)
        self.control = self.DeclareVectorInputPort("control", self.nv)
        self.DeclareStateOutputPort("state", self._x)
        self.DeclarePeriodicDiscreteUpdateEvent(self.dt, 0.0, self._update)

    @property
    def initial_position(self) -> np.ndarray:
        return self.initial_state[: self.nq].copy()

    def _update(self, context: Context, discrete_state: DiscreteValues) -> None:
        a = self.control.Eval(context)
        if not math.isfinite(a @ a) and not np.isfinite(a).all():  # ‖a‖² first: finite unless a is not, or it overflows
            raise SolverError(f"{self.get_name()}: non-finite acceleration at t = {context.get_time()}")
        x = discrete_state.get_mutable_value(self._x)  # initialized to the current state: updated in place
        x[: self.nq], x[self.nq :] = integrate_acceleration(x[: self.nq], x[self.nq :], a, self.dt, self.layout)
