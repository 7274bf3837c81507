"""Foot trajectories (stance and swing) as Drake ``PiecewisePolynomial`` s.

One trajectory per foot over the whole walk, rows ``(x, y, z, yaw)`` of its sole (world; m, rad):
constant in stance; during a swing ``[t_l, t_d]`` a cubic with zero end velocities for ``x, y,
yaw`` (``s(τ) = 3τ² − 2τ³``, ``τ = (t − t_l)/(t_d − t_l)``) and, for ``z``, two cubics rising to
``z0 + h`` at mid-swing with zero vertical velocity there and at both ends (cubic Hermite knots);
optionally (``landing_depth``, for position servos) the swing ends a little below the ground and
the sole comes back to ``z0`` during the double support.
The mid-swing knot of ``x, y, yaw`` takes the cubic's own value and slope (half-way, ``1.5 Δ/T``),
so the two Hermite pieces are exactly the single cubic.

``profile="quintic"`` (minimum jerk): the same knots with zero acceleration at the lift-off, the
apex and the touch-down, each piece a quintic Hermite (value, slope and acceleration at both ends);
``x, y, yaw`` then follow ``s(τ) = 10τ³ − 15τ⁴ + 6τ⁵`` (mid-swing slope ``1.875 Δ/T``). The cubic's
acceleration jumps to ``6 Δ/T²`` at the lift-off (4.9 m/s² for TALOS' 0.4 m swing in 0.7 s): under
torque control the stance sole then takes that jump of the swing leg's inertial wrench (a yaw
torque and a forward shift of the CoP) in one tick. The quintic starts from zero acceleration
(its peak, ``5.77 Δ/T²``, comes 0.21 T after the lift-off).
"""

from __future__ import annotations

import numpy as np
from pydrake.polynomial import Polynomial
from pydrake.trajectories import PiecewisePolynomial

from ..exceptions import InvalidInput
from .footsteps import Footstep

#: Swing profiles: ``'cubic'`` (C¹, the default) or ``'quintic'`` (C², minimum jerk).
SWING_PROFILES = ("cubic", "quintic")


def quintic_hermite(times, values, slopes, accelerations) -> PiecewisePolynomial:
    """The C² piecewise quintic through knots ``times`` (k,) with ``values``, ``slopes`` and
    ``accelerations`` (each rows × k): on ``[t_i, t_i+1]``, with ``h = t_i+1 − t_i`` and ``u = t − t_i``,
    the quintic matching the value, slope and acceleration at both ends."""
    times = np.asarray(times, dtype=float)
    values, slopes, accelerations = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (values, slopes, accelerations))
    rows = values.shape[0]
    pieces = []
    for i in range(len(times) - 1):
        h = times[i + 1] - times[i]
        p0, v0, a0 = values[:, i], slopes[:, i], accelerations[:, i]
        p1, v1, a1 = values[:, i + 1], slopes[:, i + 1], accelerations[:, i + 1]
        # The coefficients of u³, u⁴, u⁵ from the end conditions (value, slope, acceleration at u = h).
        d0 = p1 - p0 - v0 * h - 0.5 * a0 * h**2
        d1 = v1 - v0 - a0 * h
        d2 = a1 - a0
        c3 = (10 * d0 - 4 * d1 * h + 0.5 * d2 * h**2) / h**3
        c4 = (-15 * d0 + 7 * d1 * h - d2 * h**2) / h**4
        c5 = (6 * d0 - 3 * d1 * h + 0.5 * d2 * h**2) / h**5
        coefficients = np.stack([p0, v0, 0.5 * a0, c3, c4, c5], axis=1)
        pieces.append(np.array([[Polynomial(coefficients[r])] for r in range(rows)]))
    return PiecewisePolynomial(pieces, list(times))


def foot_trajectory(start, z0: float, steps: list[Footstep], side: str, swing_height: float, end: float,
                    landing_depth: float = 0.0, settle: float = 0.0, profile: str = "cubic") -> PiecewisePolynomial:
    """The trajectory of ``side`` from pose ``start = (x, y, yaw)`` at t = 0 through its ``steps``
    (others' are ignored), held until ``end``. With ``landing_depth`` d > 0 the swing ends at
    ``z0 − d`` (below the ground: on position-controlled servos the sole presses onto it instead of
    stopping short) and returns to ``z0`` over the next ``settle`` seconds (cubic, zero slopes).
    ``profile``: ``'cubic'`` or ``'quintic'`` (see the module docstring)."""
    if profile not in SWING_PROFILES:
        raise InvalidInput(f"foot_trajectory: profile is one of {SWING_PROFILES}, got {profile!r}")
    quintic = profile == "quintic"
    pose = np.array([start[0], start[1], z0, start[2]])
    times, values, slopes = [0.0], [pose], [np.zeros(4)]
    for step in steps:
        if step.side != side:
            continue
        target = np.array([step.x, step.y, z0, step.yaw])
        duration = step.touchdown - step.liftoff
        middle = 0.5 * (pose + target)
        middle[2] = z0 + swing_height
        slope = (1.875 if quintic else 1.5) * (target - pose) / duration
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
    if quintic:  # zero acceleration at every knot: at the ends, at the apex (z) and at mid-swing (x, y, yaw: s''(½) = 0)
        return quintic_hermite(np.array(times), np.array(values).T, np.array(slopes).T, np.zeros((4, len(times))))
    return PiecewisePolynomial.CubicHermite(np.array(times), np.array(values).T, np.array(slopes).T)
