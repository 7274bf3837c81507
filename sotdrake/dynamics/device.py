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
from ..exceptions import InvalidInput, SolverError, check_finite


def integrate_acceleration(q: np.ndarray, v: np.ndarray, a: np.ndarray, dt: float, layout: Layout) -> tuple[np.ndarray, np.ndarray]:
    """One semi-implicit Euler step: ``(q ⊕ v' dt, v')`` with ``v' = v + a dt``."""
    v_next = v + a * dt
    return integrate(q, v_next, dt, layout), v_next


class RobotDynSimu(LeafSystem):
    """Input ``control`` (``q̈``); discrete state and output ``state`` (``(q, v)``); period ``dt``."""

    def __init__(self, plant: MultibodyPlant, dt: float, q0: np.ndarray, v0: np.ndarray | None = None, name: str = "device"):
        LeafSystem.__init__(self)
        self.set_name(name)
        if not (np.isfinite(dt) and dt > 0):
            raise InvalidInput(f"dt must be > 0, got {dt}")
        self.dt = float(dt)
        self.nq, self.nv = plant.num_positions(), plant.num_velocities()
        self.layout = Layout.of(plant)
        q0 = check_finite("q0", q0, (self.nq,))
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
