"""Gait parameters of the pattern generator, and the velocity command's accepted range.

Timing as the walkromeo generator's: a step lasts ``step_duration`` = 0.8 s, ``single_support``
= 0.7 s with one foot in the air then ``step_duration - single_support`` = 0.1 s of double support;
feet ``feet_distance`` = 0.2 m apart (sole origins, across the walking direction), swing apex
``swing_height`` = 5 cm above the ground; ``landing_depth`` (0 to 2 cm, default 0) makes the swing end
below the ground, for position servos that would otherwise stop short of it. The sole is a rectangle ``sole_length × sole_width``
centred at ``sole_centre`` in the sole frame (TALOS: the footprint of its foot, 0.211 × 0.124 m,
centre 5.4 mm behind the sole frame); the ZMP reference sits at that centre in single support.
``swing_profile``: ``'cubic'`` (default) or ``'quintic'`` (zero acceleration at the lift-off, apex
and touch-down; see :mod:`.swing`).
Units: m, s, rad. Lengths are at most 1 km; ``step_duration``, ``start_duration`` and
``stop_duration`` at most :data:`MAX_DURATION` (20 s): Drake's ``ZmpPlanner`` plans a CoM in closed
form whose exponentials overflow (a NaN plan) on a ZMP reference segment of ``T`` s once ``ω·T``
exceeds about 172 (``ω = √(g/z)``: 51 s at TALOS' CoM height of 0.87 m); the plans also check each
segment against the CoM's height (:func:`~.plan.check_segments`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..exceptions import InvalidInput, check_count, check_finite, check_number, finite_number

#: The seed's range of ``pg.setVelocity(x, y, θ)``: ``-0.2 ≤ x, y ≤ 0.2`` (m/s).
MAX_LINEAR_VELOCITY = 0.2
#: Accepted yaw rate (rad/s): one step then turns by at most 0.32 rad.
MAX_YAW_RATE = 0.4
#: Most steps one ``pg.setSteps`` plans (a few hours of walking).
MAX_STEPS = 10_000
#: The longest ``step_duration``, ``start_duration`` and ``stop_duration`` (s) of a gait (see the module docstring).
MAX_DURATION = 20.0


@dataclass(frozen=True)
class GaitParameters:
    step_duration: float = 0.8
    single_support: float = 0.7
    feet_distance: float = 0.2
    swing_height: float = 0.05
    start_duration: float = 0.8  # double support before the first lift-off: the CoM shifts onto the support foot
    stop_duration: float = 0.8  # after the last touch-down: the ZMP returns between the feet
    sole_length: float = 0.211
    sole_width: float = 0.124
    sole_centre: tuple[float, float] = (-0.0054, 0.0)
    horizon_steps: int = 6  # steps planned ahead when walking by velocity
    replan_steps: int = 3  # extend the plan when fewer steps than this remain ahead
    landing_depth: float = 0.0  # the swing ends this far below the ground, back on it over the double support
    swing_profile: str = "cubic"  # or "quintic": zero acceleration at the lift-off, apex and touch-down (see .swing)

    def __post_init__(self) -> None:
        for name in ("step_duration", "start_duration", "stop_duration"):
            value = getattr(self, name)
            if not (finite_number(value) and 0 < value <= MAX_DURATION):
                raise InvalidInput(f"GaitParameters.{name} must be a number in (0, {MAX_DURATION:g}] s (Drake's ZmpPlanner "
                                   f"overflows on longer segments), got {value!r:.100}")
        for name in ("feet_distance", "sole_length", "sole_width"):
            check_number(f"GaitParameters.{name}", getattr(self, name), 0.0, 1e3, " m")  # finite, at most 1 km
            if getattr(self, name) == 0:
                raise InvalidInput(f"GaitParameters.{name} must be > 0, got {getattr(self, name)!r}")
        check_number("GaitParameters.swing_height", self.swing_height, 0.0, 1e3, " m")
        check_number("GaitParameters.landing_depth", self.landing_depth, 0.0, 0.02, " m")
        if not check_number("GaitParameters.single_support", self.single_support, 0.0, MAX_DURATION, " s") > 0 \
                or not self.single_support < self.step_duration:
            raise InvalidInput(f"GaitParameters.single_support must be in (0, step_duration = {self.step_duration!r}) s, "
                               f"got {self.single_support!r}")
        check_finite("GaitParameters.sole_centre (x, y in the sole frame, m)", self.sole_centre, (2,), 1e3)
        horizon = check_count("GaitParameters.horizon_steps", self.horizon_steps, 2, MAX_STEPS)
        check_count("GaitParameters.replan_steps", self.replan_steps, 1, horizon - 1)
        if self.swing_profile not in ("cubic", "quintic"):
            raise InvalidInput(f"GaitParameters.swing_profile must be 'cubic' or 'quintic', got {self.swing_profile!r:.60}")

    @property
    def double_support(self) -> float:
        return self.step_duration - self.single_support


def check_velocity(x: float, y: float, theta: float, what: str = "pg.setVelocity") -> np.ndarray:
    """The command ``(x, y, θ)`` (m/s, m/s, rad/s, in the walking frame: x forward, y left, θ
    counter-clockwise) as an array, or :class:`InvalidInput` naming ``what``, the component and its
    range (``|x|, |y| ≤`` :data:`MAX_LINEAR_VELOCITY`, ``|θ| ≤`` :data:`MAX_YAW_RATE`)."""
    return velocity_vector(what, [x, y, theta], f"{what}(x, y, theta)")


def velocity_vector(what: str, value, label: str | None = None) -> np.ndarray:
    """``value``, three numbers ``(x, y, θ)``, checked as :func:`check_velocity` does; ``label``
    names the whole vector when it is not finite or not three numbers (default ``what``)."""
    v = check_finite(label or what, value, (3,))
    for name, component, limit in (("x", v[0], MAX_LINEAR_VELOCITY), ("y", v[1], MAX_LINEAR_VELOCITY),
                                   ("theta", v[2], MAX_YAW_RATE)):
        if abs(component) > limit:
            unit = "rad/s" if name == "theta" else "m/s"
            raise InvalidInput(f"{what}: {name} = {component} {unit} is out of range; accepted: -{limit} ≤ {name} ≤ {limit}")
    return v


def check_steps(what: str, steps, step_duration: float | None = None, low: int = 1) -> tuple[tuple[float, float, float], ...]:
    """``steps``, ``low`` to :data:`MAX_STEPS` displacements ``(dx, dy, dθ)`` (m, m, rad), as a
    tuple of float triples, or :class:`InvalidInput` naming ``what``: not finite, not triples,
    ``|dθ| > MAX_YAW_RATE`` (0.4 rad a step) or, given the gait's ``step_duration``, ``|dx|`` or
    ``|dy| > 2 · MAX_LINEAR_VELOCITY · step_duration`` (the distance ``setVelocity``'s fastest
    command moves the leading foot in a step)."""
    array = check_finite(what, steps)
    if array.shape == (0,) and low == 0:
        return ()
    if array.ndim != 2 or array.shape[1] != 3 or not low <= len(array) <= MAX_STEPS:
        raise InvalidInput(f"{what}: expected a list of {low} to {MAX_STEPS} (dx, dy, dθ), got shape {array.shape}")
    limit = np.inf if step_duration is None else 2 * MAX_LINEAR_VELOCITY * step_duration
    if np.abs(array[:, :2]).max() > limit or np.abs(array[:, 2]).max() > MAX_YAW_RATE:
        accepted = "" if step_duration is None else f"|dx|, |dy| ≤ {limit:g} m, "
        raise InvalidInput(f"{what}: accepted {accepted}|dθ| ≤ {MAX_YAW_RATE} rad; got {array.tolist()!s:.300}")
    return tuple((float(dx), float(dy), float(dtheta)) for dx, dy, dtheta in array)
