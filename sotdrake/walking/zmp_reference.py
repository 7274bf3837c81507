"""The ZMP reference: piecewise linear, inside the support polygon.

In single support the reference rests at the centre of the support sole's footprint; in each
double support it moves in a straight line to the next support sole's centre (a segment between
two footprints lies in their hull). Before the first lift-off from standing it holds, then shifts
onto the first support foot during the last half of ``start_duration``; after the last touch-down it returns to the
mid-point of the feet during ``stop_duration`` and holds (the stationary end ``ZmpPlanner`` needs).
"""

from __future__ import annotations

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from .footsteps import Footstep, other
from .gait import GaitParameters
from .support import centre_of

#: How long the reference holds at its end (s): the plan's stationary tail.
HOLD = 1.0
#: Part of ``start_duration`` during which the reference shifts onto the first support foot (it
#: holds before: the CoM, at rest, starts moving ahead of the reference without a jump of its ZMP).
SHIFT = 0.5


def segment_durations(gait: GaitParameters) -> dict[str, float]:
    """The longest reference segment (s) each of the gait's durations makes (its name → the
    duration): single and double supports, the start's hold and shift, the stop; the final hold is
    :data:`HOLD`."""
    return {"single_support": gait.single_support, "step_duration - single_support": gait.double_support,
            "start_duration": max(SHIFT, 1 - SHIFT) * gait.start_duration, "stop_duration": gait.stop_duration}


def zmp_knots(t: float, zmp0, feet: dict, steps: list[Footstep], gait: GaitParameters) -> tuple[np.ndarray, np.ndarray]:
    """Knot times (k,) and points (2×k) of the reference from time ``t``, where it is ``zmp0``.

    ``feet``: the sole poses ``(x, y, yaw)`` at ``t`` (a swinging foot: where it lifted off);
    ``steps``: those not yet landed at ``t``, in order.
    """
    feet = dict(feet)
    times, points = [t], [np.asarray(zmp0, dtype=float)]

    def add(time: float, point) -> None:
        if time > times[-1] + 1e-9:
            times.append(time)
            points.append(np.asarray(point, dtype=float))

    for i, step in enumerate(steps):
        support = centre_of(feet[other(step.side)], gait)
        if step.liftoff > t:
            if i == 0 and step.liftoff - t > gait.double_support + 1e-9:  # from standing
                add(step.liftoff - SHIFT * gait.start_duration, points[-1])
            add(step.liftoff, support)
        add(step.touchdown, support)
        feet[step.side] = (step.x, step.y, step.yaw)
    middle = 0.5 * (centre_of(feet["left"], gait) + centre_of(feet["right"], gait))
    add(times[-1] + gait.stop_duration, middle)
    add(times[-1] + HOLD, middle)
    return np.array(times), np.array(points).T


def zmp_reference(t: float, zmp0, feet: dict, steps: list[Footstep], gait: GaitParameters) -> PiecewisePolynomial:
    """The reference as a first-order-hold ``PiecewisePolynomial`` (2 rows: x, y; world; m)."""
    times, points = zmp_knots(t, zmp0, feet, steps, gait)
    return PiecewisePolynomial.FirstOrderHold(times, points)
