"""The CoM from the ZMP reference, by Drake's ``ZmpPlanner`` (linear inverted pendulum).

With the CoM at constant height ``z`` over flat ground, the LIPM is ``ẍ = g/z (x − p)`` per
horizontal axis, ``p`` the ZMP. ``ZmpPlanner`` minimises ``∫ (p − p_d)ᵀ Q_y (p − p_d) + ẍᵀ R ẍ dt``
along the reference ``p_d`` from the state ``(x0, ẋ0)`` (Tedrake et al., Humanoids 2015) and returns
the optimal CoM trajectory in closed form. ``R = r I``: Drake's default ``r = 0.1`` (s⁴, with
``Q_y = I``) lets the realised ZMP ``p = x − z/g ẍ`` stray centimetres from the reference; the
pattern generator uses ``INPUT_COST`` (see the README for the measured margins). ``r`` must lie in
[:data:`MIN_INPUT_COST`, :data:`MAX_INPUT_COST`]: outside, the planner's Riccati equation fails (too
small, for a high CoM) or the CoM hardly moves (too large); anything else is an :class:`InvalidInput`.

``ZmpPlanner``'s closed form has exponentials of ``ω·T`` (``ω = √(g/z)``, ``T`` a segment's
duration) that overflow, a NaN plan from its start, once ``ω·T`` exceeds about 172 (measured with
``input_cost`` from 1e-10 to 1e-6 s⁴, later with larger ones: segments of 51 s at a CoM height of
0.87 m; below that the plan is as accurate as on short segments). :func:`plan_com` refuses a plan
that is not finite; the walk plans keep ``ω·T ≤`` :data:`MAX_OMEGA_T` for every segment a gait
makes (:func:`~.plan.check_segments`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from pydrake.planning import ZmpPlanner
from pydrake.trajectories import PiecewisePolynomial

from ..exceptions import InvalidInput, check_finite, check_number, check_type, finite_number

GRAVITY = 9.81
#: ``r`` of ``R = r I``, tuned: the realised ZMP stays within a few millimetres of the reference.
INPUT_COST = 1e-6
#: The range of ``r`` accepted (s⁴): the Riccati equation is solved for CoM heights up to 1 km.
MIN_INPUT_COST, MAX_INPUT_COST = 1e-10, 1e6
#: The largest ``ω·T`` of a reference segment the walk plans give ``ZmpPlanner`` (it overflows from about 172).
MAX_OMEGA_T = 150.0
#: The highest CoM (m) a plan takes, as the start's.
MAX_HEIGHT = 1e3


def longest_segment(height: float) -> float:
    """The longest reference segment (s) the walk plans give ``ZmpPlanner`` at a CoM ``height`` (m):
    :data:`MAX_OMEGA_T` ``/ ω``, ``ω = √(g/z)``."""
    return MAX_OMEGA_T / float(np.sqrt(GRAVITY / height))


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
    """The optimal CoM following ``zmp_d`` (a ``PiecewisePolynomial`` of 2 rows, 1 column, finite:
    the ZMP reference, xy) from ``(position, velocity)`` (xy, finite) at its start time, at the CoM
    ``height`` (m, in (0, :data:`MAX_HEIGHT`]). Anything else, an ``input_cost`` out of range, or a
    plan ``ZmpPlanner`` cannot make finite (a segment too long for the height, see the module
    docstring): :class:`InvalidInput` naming the argument, before Drake sees it."""
    check_type("plan_com: zmp_d", zmp_d, PiecewisePolynomial, "PiecewisePolynomial (the ZMP reference, xy)")
    if (zmp_d.rows(), zmp_d.cols()) != (2, 1):
        raise InvalidInput(f"plan_com: zmp_d must have 2 rows (x, y) and 1 column, got {zmp_d.rows()}×{zmp_d.cols()}")
    breaks = np.asarray(zmp_d.get_segment_times())
    check_finite("plan_com: zmp_d (its values at its breaks, m)", zmp_d.vector_values(breaks))
    x0 = np.concatenate([check_finite("plan_com: position (xy, m)", position, (2,)),
                         check_finite("plan_com: velocity (xy, m/s)", velocity, (2,))])
    if not (finite_number(height) and 0 < height <= MAX_HEIGHT):
        raise InvalidInput(f"plan_com: height (the CoM's) must be a number in (0, {MAX_HEIGHT:g}] m, got {height!r:.60}")
    height = float(height)
    return planned_com(zmp_d, x0, height, check_input_cost("plan_com", input_cost))


def planned_com(zmp_d: PiecewisePolynomial, x0: np.ndarray, height: float, input_cost: float) -> ComPlan:
    """:func:`plan_com` from the state ``x0 = (position, velocity)`` for arguments already checked
    (the walk plans' own); a plan that is not finite is still refused."""
    planner = ZmpPlanner()
    try:
        planner.Plan(zmp_d, x0, height, GRAVITY, np.eye(2), input_cost * np.eye(2))
    except RuntimeError as error:  # (the Riccati equation has no solution for these numbers)
        raise InvalidInput(f"plan_com: no CoM plan for input_cost = {input_cost:g} s⁴ at a CoM height of {height:g} m "
                           f"({error}); give an input_cost in [{MIN_INPUT_COST:g}, {MAX_INPUT_COST:g}]") from None
    plan = ComPlan(planner.get_nominal_com(), planner.get_nominal_comd(), planner.get_nominal_comdd(),
                   float(height), zmp_d.start_time(), zmp_d.end_time())
    _check_plan(plan, np.asarray(zmp_d.get_segment_times()))
    return plan


def _check_plan(plan: ComPlan, breaks: np.ndarray) -> None:
    """:class:`InvalidInput` if ``plan`` is not finite at the reference's ``breaks`` (an overflow
    makes every segment before it NaN, the velocity and acceleration with the position)."""
    if np.all(np.isfinite(plan.position.vector_values(breaks))):
        return
    durations = np.diff(breaks)
    longest = int(np.argmax(durations))
    raise InvalidInput(
        f"plan_com: ZmpPlanner's CoM plan is not finite: zmp_d's longest segment, {durations[longest]:g} s from "
        f"t = {breaks[longest]:g} s, is too long for a CoM height of {plan.height:g} m (its exponentials overflow once "
        f"ω·T > about 172, ω = √(g/z) = {np.sqrt(GRAVITY / plan.height):.3g} /s); shorten it (a gait's step_duration, "
        f"single_support, start_duration or stop_duration), or give smaller values")
