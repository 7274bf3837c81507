"""The CoM from the ZMP reference, by Drake's ``ZmpPlanner`` (linear inverted pendulum).

With the CoM at constant height ``z`` over flat ground, the LIPM is ``ẍ = g/z (x − p)`` per
horizontal axis, ``p`` the ZMP. ``ZmpPlanner`` minimises ``∫ (p − p_d)ᵀ Q_y (p − p_d) + ẍᵀ R ẍ dt``
along the reference ``p_d`` from the state ``(x0, ẋ0)`` (Tedrake et al., Humanoids 2015) and returns
the optimal CoM trajectory in closed form. ``R = r I``: Drake's default ``r = 0.1`` (s⁴, with
``Q_y = I``) lets the realised ZMP ``p = x − z/g ẍ`` stray centimetres from the reference; the
pattern generator uses ``INPUT_COST`` (see the README for the measured margins). ``r`` must lie in
[:data:`MIN_INPUT_COST`, :data:`MAX_INPUT_COST`]: outside, the planner's Riccati equation fails (too
small, for a high CoM) or the CoM hardly moves (too large); anything else is an :class:`InvalidInput`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from pydrake.planning import ZmpPlanner
from pydrake.trajectories import PiecewisePolynomial

from ..exceptions import InvalidInput, check_number

GRAVITY = 9.81
#: ``r`` of ``R = r I``, tuned: the realised ZMP stays within a few millimetres of the reference.
INPUT_COST = 1e-6
#: The range of ``r`` accepted (s⁴): the Riccati equation is solved for CoM heights up to 1 km.
MIN_INPUT_COST, MAX_INPUT_COST = 1e-10, 1e6


def check_input_cost(what: str, input_cost) -> float:
    """``input_cost`` as a float if it is a number in [:data:`MIN_INPUT_COST`, :data:`MAX_INPUT_COST`],
    else :class:`InvalidInput` naming ``what``."""
    return check_number(f"{what}: input_cost", input_cost, MIN_INPUT_COST, MAX_INPUT_COST, " s⁴")


@dataclass(frozen=True)
class ComPlan:
    """CoM trajectories (x, y; world; m, m/s, m/s²) valid on ``[start, end]``, held outside."""

    position: Any  # PiecewisePolynomial (2 rows)
    velocity: Any
    acceleration: Any
    height: float
    start: float
    end: float

    def _clamp(self, t: float) -> float:
        return min(max(t, self.start), self.end)

    def state(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(x, ẋ, ẍ)`` at ``t`` (2 each); after ``end`` the CoM is at rest at its final point."""
        tc = self._clamp(t)
        x = self.position.value(tc).ravel()
        if t > self.end:
            return x, np.zeros(2), np.zeros(2)
        return x, self.velocity.value(tc).ravel(), self.acceleration.value(tc).ravel()

    def zmp(self, t: float) -> np.ndarray:
        """The realised ZMP of the planned CoM, ``x − z/g ẍ``."""
        x, _, a = self.state(t)
        return x - self.height / GRAVITY * a


def plan_com(zmp_d: PiecewisePolynomial, position, velocity, height: float, input_cost: float = INPUT_COST) -> ComPlan:
    """The optimal CoM following ``zmp_d`` from ``(position, velocity)`` (xy) at its start time."""
    planner = ZmpPlanner()
    x0 = np.concatenate([position, velocity])
    try:
        planner.Plan(zmp_d, x0, height, GRAVITY, np.eye(2), input_cost * np.eye(2))
    except RuntimeError as error:  # (the Riccati equation has no solution for these numbers)
        raise InvalidInput(f"plan_com: no CoM plan for input_cost = {input_cost:g} s⁴ at a CoM height of {height:g} m "
                           f"({error}); give an input_cost in [{MIN_INPUT_COST:g}, {MAX_INPUT_COST:g}]") from None
    return ComPlan(planner.get_nominal_com(), planner.get_nominal_comd(), planner.get_nominal_comdd(),
                   float(height), zmp_d.start_time(), zmp_d.end_time())
