"""Foot trajectories (stance and swing) as Drake ``PiecewisePolynomial`` s.

One trajectory per foot over the whole walk, rows ``(x, y, z, yaw)`` of its sole (world; m, rad):
constant in stance; during a swing ``[t_l, t_d]`` a cubic with zero end velocities for ``x, y,
yaw`` (``s(τ) = 3τ² − 2τ³``, ``τ = (t − t_l)/(t_d − t_l)``) and, for ``z``, two cubics rising to
``z0 + h`` at mid-swing with zero vertical velocity there and at both ends (cubic Hermite knots);
optionally (``landing_depth``, for position servos) the swing ends a little below the ground and
the sole comes back to ``z0`` during the double support.
The mid-swing knot of ``x, y, yaw`` takes the cubic's own value and slope (half-way, ``1.5 Δ/T``),
so the two Hermite pieces are exactly the single cubic.
"""

from __future__ import annotations

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from .footsteps import Footstep


def foot_trajectory(start, z0: float, steps: list[Footstep], side: str, swing_height: float, end: float,
                    landing_depth: float = 0.0, settle: float = 0.0) -> PiecewisePolynomial:
    """The trajectory of ``side`` from pose ``start = (x, y, yaw)`` at t = 0 through its ``steps``
    (others' are ignored), held until ``end``. With ``landing_depth`` d > 0 the swing ends at
    ``z0 − d`` (below the ground: on position-controlled servos the sole presses onto it instead of
    stopping short) and returns to ``z0`` over the next ``settle`` seconds (cubic, zero slopes)."""
    pose = np.array([start[0], start[1], z0, start[2]])
    times, values, slopes = [0.0], [pose], [np.zeros(4)]
    for step in steps:
        if step.side != side:
            continue
        target = np.array([step.x, step.y, z0, step.yaw])
        duration = step.touchdown - step.liftoff
        middle = 0.5 * (pose + target)
        middle[2] = z0 + swing_height
        slope = 1.5 * (target - pose) / duration
        slope[2] = 0.0
        knots = [(step.liftoff, pose, np.zeros(4)), (step.liftoff + duration / 2, middle, slope)]
        if landing_depth > 0 and settle > 0:
            pressed = target.copy()
            pressed[2] = z0 - landing_depth
            knots += [(step.touchdown, pressed, np.zeros(4)), (step.touchdown + settle, target, np.zeros(4))]
        else:
            knots.append((step.touchdown, target, np.zeros(4)))
        for t, value, derivative in knots:
            if t > times[-1] + 1e-9:
                times.append(t)
                values.append(value)
                slopes.append(derivative)
        pose = target
    times.append(max(end, times[-1]) + 1.0)
    values.append(pose)
    slopes.append(np.zeros(4))
    return PiecewisePolynomial.CubicHermite(np.array(times), np.array(values).T, np.array(slopes).T)
