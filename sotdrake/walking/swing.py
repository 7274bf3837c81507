"""Foot trajectories (stance and swing) as Drake ``PiecewisePolynomial`` s.

One trajectory per foot over the whole walk, rows ``(x, y, z, yaw)`` of its sole (world; m, rad):
constant in stance; during a swing ``[t_l, t_d]`` a cubic with zero end velocities for ``x, y,
yaw`` (``s(τ) = 3τ² − 2τ³``, ``τ = (t − t_l)/(t_d − t_l)``) and, for ``z``, two cubics rising to
``z0 + h`` at mid-swing with zero vertical velocity there and at both ends (cubic Hermite knots).
The mid-swing knot of ``x, y, yaw`` takes the cubic's own value and slope (half-way, ``1.5 Δ/T``),
so the two Hermite pieces are exactly the single cubic.
"""

from __future__ import annotations

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from .footsteps import Footstep


def foot_trajectory(start, z0: float, steps: list[Footstep], side: str, swing_height: float, end: float) -> PiecewisePolynomial:
    """The trajectory of ``side`` from pose ``start = (x, y, yaw)`` at t = 0 through its ``steps``
    (others' are ignored), held until ``end``."""
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
        for t, value, derivative in ((step.liftoff, pose, np.zeros(4)), (step.liftoff + duration / 2, middle, slope),
                                     (step.touchdown, target, np.zeros(4))):
            if t > times[-1] + 1e-9:
                times.append(t)
                values.append(value)
                slopes.append(derivative)
        pose = target
    times.append(max(end, times[-1]) + 1.0)
    values.append(pose)
    slopes.append(np.zeros(4))
    return PiecewisePolynomial.CubicHermite(np.array(times), np.array(values).T, np.array(slopes).T)
