"""A walk plan: footsteps, ZMP reference, CoM and foot trajectories, and how it is replanned.

:func:`initial_plan` stands still at the start (feet where they are, the ZMP reference moving from
the CoM's projection to the mid-point of the feet). :func:`replan` at time ``t`` for a new command
keeps every step already lifted off (a swinging foot lands where it was going), plans the next
ones from the walking frame after them, and replans the CoM with ``ZmpPlanner`` from the previous
plan's CoM state at ``t``: position and velocity are continuous across a replan. The reference
ZMP starts from the previous reference's value at ``t``. With a leg-mass model
(:class:`~.multibody_zmp.LegMasses`) the CoM is planned for the reference minus the legs' ZMP
error, so that the ZMP of the whole body's planned motion, not the pendulum's, follows the reference
(:func:`corrected_com`).

Commands (:class:`WalkCommand`): a velocity ``(vx, vy, ω)`` (walk on, the plan extended a few
steps ahead as time goes; zero: the feet close up and the robot stands), or a list of step
displacements ``(dx, dy, dθ)`` of the walking frame (then the feet close up and it stands).

Bad input is refused (:class:`~sotdrake.exceptions.InvalidInput`, naming the argument) before
anything is planned: a command outside ``PatternGenerator.setVelocity``'s and ``setSteps``' ranges
(when it is made, the steps' lengths when it is planned for a gait), a time that is not a finite
number in ``[plan.planned_at, MAX_TIME]``, an ``input_cost`` outside the planner's range
(:func:`~.com_planner.check_input_cost`), a gait whose ZMP reference segments are too long for the
CoM's height (:func:`check_segments`), arguments of the wrong kind.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from ..exceptions import InvalidInput, check_finite, check_number, check_type
from .com_planner import GRAVITY, INPUT_COST, MAX_OMEGA_T, ComPlan, check_input_cost, longest_segment, planned_com
from .footsteps import Footstep, closing_steps, first_side, other, steps_from, velocity_displacement
from .gait import GaitParameters, check_steps, velocity_vector
from .multibody_zmp import PASSES, LegMasses
from .support import support_polygon
from .swing import foot_trajectory
from .zmp_reference import HOLD, segment_durations, zmp_reference

#: The latest time (s) a plan is made for (about 11 days; later, a step's duration is lost in round-off).
MAX_TIME = 1e6


@dataclass(frozen=True)
class WalkCommand:
    """``velocity`` ``(vx, vy, ω)`` (m/s, m/s, rad/s, walking frame) or ``steps``, a tuple of
    displacements ``(dx, dy, dθ)`` (m, m, rad); at most one of them non-zero. Checked when made
    (:class:`~sotdrake.exceptions.InvalidInput` naming the field): finite, ``|vx|, |vy| ≤ 0.2``,
    ``|ω| ≤ 0.4`` (``PatternGenerator.setVelocity``'s range), at most ``MAX_STEPS`` steps with
    ``|dθ| ≤ 0.4``; the steps' ``|dx|, |dy|`` are checked against the gait by :func:`replan`.
    Lists and numpy numbers are accepted, kept as tuples of floats."""

    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    steps: tuple[tuple[float, float, float], ...] = ()

    def __post_init__(self) -> None:
        velocity = velocity_vector("WalkCommand.velocity", self.velocity, "WalkCommand.velocity (vx, vy, ω)")
        steps = check_steps("WalkCommand.steps", self.steps, low=0)
        if steps and velocity.any():
            raise InvalidInput(f"WalkCommand: give a velocity or steps, not both; got velocity={self.velocity!r:.80} "
                               f"and {len(steps)} steps")
        object.__setattr__(self, "velocity", tuple(float(v) for v in velocity))
        object.__setattr__(self, "steps", steps)

    @property
    def walking(self) -> bool:
        """True when the command walks on indefinitely (a non-zero velocity)."""
        return any(self.velocity) and not self.steps


@dataclass(frozen=True)
class Start:
    """Where the walk starts: sole poses ``X_WS`` of both feet (``"left"`` and ``"right"``), the CoM
    ``p_WCm`` (finite, above the ground z = 0: its height is the pendulum's) and the waist pose;
    anything else is refused (:class:`~sotdrake.exceptions.InvalidInput`) when it is made."""

    feet: dict  # side → RigidTransform
    com: np.ndarray
    waist: RigidTransform

    def __post_init__(self) -> None:
        if not isinstance(self.feet, dict) or sorted(self.feet) != ["left", "right"]:
            raise InvalidInput(f"Start: feet must be a dict of the 'left' and 'right' sole poses, got {self.feet!r:.100}")
        for side, pose in [*self.feet.items(), ("waist", self.waist)]:
            if not isinstance(pose, RigidTransform) or not np.all(np.isfinite(pose.GetAsMatrix34())):
                raise InvalidInput(f"Start: the {side} pose must be a finite RigidTransform, got {pose!r:.100}")
        com = check_finite("Start: com (m, world)", self.com, (3,), 1e3)
        if not com[2] > 0:
            raise InvalidInput(f"Start: the CoM must be above the ground (z > 0: its height is the pendulum's), got z = {com[2]:g} m")
        object.__setattr__(self, "com", com)

    def foot(self, side: str) -> tuple[float, float, float]:
        """``(x, y, yaw)`` of a sole at the start: the left sole's yaw in [−π, π], the right one's
        within π of it (feet turned about ±π read as −3.12 and 3.12 rad are 0.04 rad apart, and
        their mean yaw is π, not 0)."""
        X = self.feet[side]
        yaw = RollPitchYaw(X.rotation()).yaw_angle()
        if side == "right":
            left = RollPitchYaw(self.feet["left"].rotation()).yaw_angle()
            yaw = left + float(np.angle(np.exp(1j * (yaw - left))))
        return (X.translation()[0], X.translation()[1], yaw)

    @property
    def body(self) -> tuple[float, float, float]:
        """The walking frame at the start: the mid-point of the soles, their mean yaw."""
        left, right = self.foot("left"), self.foot("right")
        return tuple(0.5 * (np.array(left) + np.array(right)))


@dataclass(frozen=True)
class References:
    """Everything the pattern generator outputs at one time (world frame; m, m/s, rad)."""

    com: np.ndarray  # (3,)
    com_velocity: np.ndarray
    com_acceleration: np.ndarray
    zmp: np.ndarray  # (2,), the reference
    feet: dict  # side → (x, y, z, yaw)
    feet_velocity: dict  # side → (ẋ, ẏ, ż, yaw rate)
    feet_acceleration: dict  # side → (ẍ, ÿ, z̈, yaw acceleration)
    support: int  # 0 double support, 1 left foot only, -1 right foot only


@dataclass(frozen=True)
class WalkPlan:
    command: WalkCommand | None  # None: not yet planned for any command
    planned_at: float
    start: Start
    steps: tuple[Footstep, ...]
    zmp: Any  # PiecewisePolynomial (2 rows)
    com: ComPlan
    feet: dict = field(default_factory=dict)  # side → PiecewisePolynomial (x, y, z, yaw)
    feet_rate: dict = field(default_factory=dict)
    feet_acceleration: dict = field(default_factory=dict)
    lipm_zmp: Any = None  # PiecewisePolynomial: the reference the CoM was planned for (with a leg-mass model), else None

    def __deepcopy__(self, memo) -> WalkPlan:
        # Immutable (its trajectories are never modified): Drake's copies of the state share it.
        return self

    @property
    def end(self) -> float:
        return self.com.end

    def steps_ahead(self, t: float) -> int:
        return sum(1 for s in self.steps if s.liftoff > t)

    def needs_replan(self, command: WalkCommand, t: float, gait: GaitParameters) -> bool:
        """For a new command, or to extend the plan of a walking one."""
        return command != self.command or (command.walking and self.steps_ahead(t) < gait.replan_steps)

    def zmp_reference(self, t: float) -> np.ndarray:
        return self.zmp.value(min(max(t, self.zmp.start_time()), self.zmp.end_time())).ravel()

    def feet_at(self, t: float) -> dict:
        """Sole poses ``(x, y, yaw)`` at ``t`` as the ZMP reference sees them: a swinging foot
        where it lifted off."""
        feet = {side: self.start.foot(side) for side in ("left", "right")}
        for s in self.steps:
            if s.touchdown <= t:
                feet[s.side] = (s.x, s.y, s.yaw)
        return feet

    def swinging(self, t: float) -> str | None:
        for s in self.steps:
            if s.liftoff <= t < s.touchdown:
                return s.side
        return None

    def support_polygon(self, t: float, gait: GaitParameters) -> np.ndarray:
        """The footprints' hull of the feet on the ground at ``t``."""
        feet, swinging = self.feet_at(t), self.swinging(t)
        return support_polygon([p for side, p in feet.items() if side != swinging], gait)

    def references(self, t: float) -> References:
        com, com_velocity, com_acceleration = self.com.state(t)
        z = self.com.height
        feet, rates, accelerations = {}, {}, {}
        for side, trajectory in self.feet.items():
            tc = min(max(t, trajectory.start_time()), trajectory.end_time())
            feet[side] = trajectory.value(tc).ravel()
            rates[side] = self.feet_rate[side].value(tc).ravel()
            accelerations[side] = self.feet_acceleration[side].value(tc).ravel()
        swinging = self.swinging(t)
        support = 0 if swinging is None else (1 if swinging == "right" else -1)
        return References(np.append(com, z), np.append(com_velocity, 0.0), np.append(com_acceleration, 0.0),
                          self.zmp_reference(t), feet, rates, accelerations, support)


def _trajectories(start: Start, steps: list[Footstep], gait: GaitParameters, end: float) -> tuple[dict, dict, dict]:
    """Each foot's trajectory, its rate and its acceleration."""
    feet, rates, accelerations = {}, {}, {}
    for side in ("left", "right"):
        z0 = start.feet[side].translation()[2]
        feet[side] = foot_trajectory(start.foot(side), z0, steps, side, gait.swing_height, end,
                                     gait.landing_depth, gait.double_support, gait.swing_profile)
        rates[side] = feet[side].derivative(1)
        accelerations[side] = feet[side].derivative(2)
    return feet, rates, accelerations


def corrected_com(zmp, position, velocity, height: float, input_cost: float, t: float, feet: dict, accelerations: dict,
                  legs: LegMasses | None, passes: int = PASSES) -> tuple[ComPlan, Any]:
    """The CoM planned from ``(position, velocity)`` at ``t`` for the reference ``zmp``: by the
    pendulum alone without ``legs``; with them, ``passes`` times replanned for ``p_d − e``, ``e`` the
    legs' ZMP error along the previous pass (:meth:`LegMasses.lipm_reference`). Returns the plan and
    the reference it was planned for (None without ``legs``)."""
    x0 = np.concatenate([position, velocity])
    com = planned_com(zmp, x0, height, input_cost)
    lipm = None
    for _ in range(passes if legs is not None else 0):
        assert legs is not None
        lipm = legs.lipm_reference(zmp, com, feet, accelerations, t)
        com = planned_com(lipm, x0, height, input_cost)
    return com, lipm


def check_segments(what: str, gait: GaitParameters, height: float) -> None:
    """:class:`InvalidInput` naming ``what`` and the gait's duration if a segment of the ZMP reference
    it makes is longer than ``ZmpPlanner`` plans at the CoM ``height`` (m; see
    :func:`~.com_planner.longest_segment`: 20 s, the longest a gait takes, at heights from 0.18 m)."""
    limit = longest_segment(height)
    if HOLD > limit:
        raise InvalidInput(f"{what}: a CoM height of {height:g} m is too low for ZmpPlanner (its final {HOLD:g} s hold "
                           f"needs at least {GRAVITY * (HOLD / MAX_OMEGA_T) ** 2:.3g} m)")
    for name, duration in segment_durations(gait).items():
        if duration > limit:
            raise InvalidInput(f"{what}: GaitParameters' {name} makes ZMP reference segments of {duration:g} s, longer than "
                               f"ZmpPlanner plans at a CoM height of {height:g} m ({limit:.3g} s: ω·T ≤ {MAX_OMEGA_T:g}, "
                               f"ω = √(g/z)); give shorter durations")


def _check_model(what: str, gait: GaitParameters, input_cost: float, legs: LegMasses | None, height: float) -> float:
    """``input_cost`` as a float after checking ``gait`` (its segments at the CoM ``height``),
    ``input_cost`` and ``legs`` (InvalidInput naming them)."""
    check_type(f"{what}: gait", gait, GaitParameters, "GaitParameters")
    if legs is not None:
        check_type(f"{what}: legs", legs, LegMasses, "LegMasses (leg_masses()) or None")
    check_segments(what, gait, height)
    return check_input_cost(what, input_cost)


def initial_plan(start: Start, gait: GaitParameters, input_cost: float = INPUT_COST, legs: LegMasses | None = None) -> WalkPlan:
    """Standing at t = 0: the CoM at rest, the ZMP reference from under it to the feet's mid-point.
    A ``start`` that is not a :class:`Start`, a ``gait`` that is not :class:`GaitParameters`, an
    ``input_cost`` out of range: :class:`InvalidInput`."""
    check_type("initial_plan: start", start, Start, "Start (the soles, the CoM and the waist at t = 0: start_of)")
    input_cost = _check_model("initial_plan", gait, input_cost, legs, start.com[2])
    feet = {side: start.foot(side) for side in ("left", "right")}
    zmp = zmp_reference(0.0, start.com[:2], feet, [], gait)
    trajectories, rates, accelerations = _trajectories(start, [], gait, zmp.end_time())
    com, lipm = corrected_com(zmp, start.com[:2], np.zeros(2), start.com[2], input_cost, 0.0, trajectories, accelerations, legs)
    return WalkPlan(None, 0.0, start, (), zmp, com, trajectories, rates, accelerations, lipm)


def new_steps(plan: WalkPlan, command: WalkCommand, t: float, gait: GaitParameters) -> tuple[list[Footstep], list[Footstep]]:
    """``(kept, new)``: the steps lifted off by ``t``, and those ``command`` adds after them."""
    kept = [s for s in plan.steps if s.liftoff <= t]
    feet = {side: plan.start.foot(side) for side in ("left", "right")}
    for s in kept:
        feet[s.side] = (s.x, s.y, s.yaw)
    if kept:
        body, side = kept[-1].body, other(kept[-1].side)
        liftoff = kept[-1].touchdown + gait.double_support  # walking on: keep the rhythm
        if liftoff <= t:  # it had stopped: start again
            liftoff = t + gait.start_duration
    else:
        body, side = plan.start.body, first_side(command.steps[0] if command.steps else command.velocity)
        liftoff = t + gait.start_duration
    if command.steps:
        new = steps_from(body, side, liftoff, command.steps, gait)
        last = new[-1]
        new += closing_steps(last.body, other(last.side), last.liftoff + gait.step_duration,
                             {**feet, **{step.side: (step.x, step.y, step.yaw) for step in new}}, gait)
    elif command.walking:
        new, stepping, lift = [], side, liftoff
        for _ in range(gait.horizon_steps):
            step = steps_from(body, stepping, lift, [velocity_displacement(command.velocity, stepping, gait)], gait)[0]
            new.append(step)
            body, stepping, lift = step.body, other(stepping), lift + gait.step_duration
    elif kept:
        new = closing_steps(body, side, liftoff, feet, gait)
    else:
        new = []
    return kept, new


def replan(plan: WalkPlan, command: WalkCommand, t: float, gait: GaitParameters, input_cost: float = INPUT_COST,
           legs: LegMasses | None = None) -> WalkPlan:
    """The plan for ``command`` from time ``t`` (see the module docstring; what it refuses there)."""
    t, input_cost = _check_replan(plan, command, t, gait, input_cost, legs)
    kept, new = new_steps(plan, command, t, gait)
    steps = kept + new
    landed = {side: plan.start.foot(side) for side in ("left", "right")}
    for s in steps:
        if s.touchdown <= t:
            landed[s.side] = (s.x, s.y, s.yaw)
    ahead = [s for s in steps if s.touchdown > t]
    zmp = zmp_reference(t, plan.zmp_reference(t), landed, ahead, gait)
    position, velocity, _ = plan.com.state(t)
    trajectories, rates, accelerations = _trajectories(plan.start, steps, gait, zmp.end_time())
    com, lipm = corrected_com(zmp, position, velocity, plan.com.height, input_cost, t, trajectories, accelerations, legs)
    return WalkPlan(command, t, plan.start, tuple(steps), zmp, com, trajectories, rates, accelerations, lipm)


def _check_replan(plan: WalkPlan, command: WalkCommand, t: float, gait: GaitParameters, input_cost: float,
                  legs: LegMasses | None) -> tuple[float, float]:
    """``(t, input_cost)`` as floats once :func:`replan`'s arguments are checked (before Drake sees any)."""
    check_type("replan: plan", plan, WalkPlan, "WalkPlan (initial_plan() or replan())")
    check_type("replan: command", command, WalkCommand, "WalkCommand")
    input_cost = _check_model("replan", gait, input_cost, legs, plan.com.height)
    t = check_number("replan: t", t, -MAX_TIME, MAX_TIME, " s")
    if t < plan.planned_at:
        raise InvalidInput(f"replan: t = {t:g} s is before the plan's time {plan.planned_at:g} s: a plan is replanned forward")
    if command.steps:
        check_steps("replan: command.steps", command.steps, gait.step_duration)
    return t, input_cost


def foot_pose(reference, X_WS0: RigidTransform, yaw0: float) -> RigidTransform:
    """The sole pose for ``reference = (x, y, z, yaw)``: the start's tilt turned by ``yaw − yaw0``."""
    R = RotationMatrix.MakeZRotation(reference[3] - yaw0).multiply(X_WS0.rotation())
    return RigidTransform(R, reference[:3])

