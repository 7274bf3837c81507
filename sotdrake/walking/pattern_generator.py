"""``PatternGenerator``: the seed's ``pg``, commanded by velocity (``pg.setVelocity(x, y, θ)``) or
by a list of steps (``pg.setSteps([(dx, dy, dθ), …])``).

The command is the entity's setting, in its Context (set at build time, with ``context=`` between
``AdvanceTo`` calls, or from ``attime``); the plan (:class:`~.plan.WalkPlan`) is abstract state.
An update every ``dt`` replans when the command has changed (a command issued at time T, e.g.
by ``attime``, is planned from the tick after T) (or, walking by velocity, to extend
the plan ahead): see :func:`~.plan.replan`. Outputs, at the Context's time (world frame; m, m/s,
m/s², rad):

* ``com``, ``com_velocity``, ``com_acceleration`` (3): the planned CoM (constant height);
* ``zmp_reference`` (2): the reference ZMP;
* ``left_foot_pose``, ``right_foot_pose`` (``RigidTransform``, sole frames ``X_WS``) and
  ``left_foot_velocity``, ``right_foot_velocity`` (6: ``(ω, ṗ)``), ``left_foot_acceleration``,
  ``right_foot_acceleration`` (6: ``(ω̇, p̈)``);
* ``waist_pose`` (``RigidTransform``: the start's waist height and tilt, turned by the mean yaw of
  the feet, above the planned CoM) and ``waist_velocity`` (6);
* ``support_phase`` (1): 0 in double support, 1 on the left foot only, −1 on the right only;
* ``feet`` (8: ``x, y, z, yaw`` of the left sole then the right one) and ``velocity_command`` (3),
  for tracing.

Plans are made up to :data:`~.plan.MAX_TIME` (10⁶ s, about 11.6 days of simulated time): a command
given with a ``context=`` whose time is later is refused (:class:`~sotdrake.exceptions.InvalidInput`,
nothing changed), one scheduled later by ``attime`` is refused at its time (its settings unchanged,
kept in ``refused_commands``), and a walk by velocity cannot be extended past it (the update raises).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import Context, ValueProducer

from ..entity import Entity
from ..exceptions import InvalidInput, check_name, check_type, finite_number
from .com_planner import INPUT_COST, check_input_cost
from .gait import GaitParameters, check_steps, check_velocity
from .multibody_zmp import LegMasses
from .plan import MAX_TIME, References, Start, WalkCommand, WalkPlan, foot_pose, initial_plan, replan

SIDES = ("left", "right")
#: The longest replanning period (s) a pattern generator takes.
MAX_DT = 1.0


@dataclass
class PatternGeneratorSettings:
    command: WalkCommand = field(default_factory=WalkCommand)


class PatternGenerator(Entity[PatternGeneratorSettings]):
    """See the module docstring. ``start``: the robot's sole poses, CoM and waist pose at t = 0;
    ``legs``: a leg-mass model (:func:`~.multibody_zmp.leg_masses`) puts the legs' momentum in the
    CoM plan (the multibody ZMP correction), None the pendulum alone. A ``dt`` not in (0, 1] s, a
    ``gait`` that is not :class:`GaitParameters` (or None: the defaults), an ``input_cost`` out of
    :func:`~.com_planner.check_input_cost`'s range: :class:`InvalidInput`, before anything is planned.

    Outputs (see the module docstring): each sole's ``<side>_foot_pose`` and the ``waist_pose``
    (``RigidTransform``, world).
    """

    def __init__(self, start: Start, dt: float, gait: GaitParameters | None = None,
                 input_cost: float = INPUT_COST, name: str = "pg", legs: LegMasses | None = None):
        Entity.__init__(self, name, PatternGeneratorSettings())
        if not (finite_number(dt) and 0 < dt <= MAX_DT):
            raise InvalidInput(f"{name}: dt must be a number in (0, {MAX_DT:g}] s, got {dt!r:.60}")
        input_cost = check_input_cost(name, input_cost)
        if not isinstance(start, Start):
            raise InvalidInput(f"{name}: start must be a Start (the soles, the CoM and the waist at t = 0: start_of), "
                               f"got {type(start).__name__}")
        if gait is not None:
            check_type(f"{name}: gait", gait, GaitParameters, "GaitParameters or None")
        if legs is not None:
            check_type(f"{name}: legs", legs, LegMasses, "LegMasses (leg_masses()) or None")
        self.gait = gait or GaitParameters()
        self.start, self.dt, self.input_cost, self.legs = start, float(dt), input_cost, legs
        self._yaw0 = {side: start.foot(side)[2] for side in SIDES}
        self._plan = self.DeclareAbstractState(AbstractValue.Make(initial_plan(start, self.gait, input_cost, legs)))
        self.DeclareInitializationUnrestrictedUpdateEvent(self._initialize)
        self.DeclarePeriodicUnrestrictedUpdateEvent(self.dt, 0.0, self._update)
        self._references = self.DeclareCacheEntry(
            "references", ValueProducer(allocate=lambda: AbstractValue.Make(object()), calc=self._calc_references),
            prerequisites_of_calc={self.time_ticket(), self.abstract_state_ticket(self._plan)})
        vector = self.DeclareVectorOutputPort
        vector("com", 3, lambda c, o: o.SetFromVector(self._refs(c).com))
        vector("com_velocity", 3, lambda c, o: o.SetFromVector(self._refs(c).com_velocity))
        vector("com_acceleration", 3, lambda c, o: o.SetFromVector(self._refs(c).com_acceleration))
        vector("zmp_reference", 2, lambda c, o: o.SetFromVector(self._refs(c).zmp))
        for side in SIDES:
            self.DeclareAbstractOutputPort(f"{side}_foot_pose", lambda: AbstractValue.Make(RigidTransform()),
                                           lambda c, o, s=side: o.set_value(self._foot_pose(c, s)))
            vector(f"{side}_foot_velocity", 6, lambda c, o, s=side: o.SetFromVector(self._foot_velocity(c, s)))
            vector(f"{side}_foot_acceleration", 6, lambda c, o, s=side: o.SetFromVector(self._foot_acceleration(c, s)))
        self.DeclareAbstractOutputPort("waist_pose", lambda: AbstractValue.Make(RigidTransform()), self._waist_pose)
        vector("waist_velocity", 6, self._waist_velocity)
        vector("support_phase", 1, lambda c, o: o.SetAtIndex(0, self._refs(c).support))
        vector("feet", 8, lambda c, o: o.SetFromVector(np.concatenate([self._refs(c).feet[s] for s in SIDES])))
        vector("velocity_command", 3, lambda c, o: o.SetFromVector(np.asarray(self._settings_of(c).command.velocity)))

    # --- commands ---------------------------------------------------------------------------
    def setVelocity(self, x: float, y: float, theta: float, context: Context | None = None) -> None:
        """Walk at ``(x, y, θ)`` (m/s, m/s, rad/s; x forward, y left, θ counter-clockwise, in the
        walking frame): ``|x|, |y| ≤ 0.2``, ``|θ| ≤ 0.4``; ``(0, 0, 0)`` closes the feet and stops."""
        vx, vy, w = (float(a) for a in check_velocity(x, y, theta))
        v = (vx, vy, w)
        self._check_time(f"{self.name}.setVelocity", context)
        self._command(context, lambda s: setattr(s, "command", WalkCommand(velocity=v)))

    def setSteps(self, steps, context: Context | None = None) -> None:
        """Walk the steps ``[(dx, dy, dθ), …]`` (displacements of the walking frame per step, m and
        rad, each ``|dx|, |dy| ≤ 2 · 0.2 m/s · step duration`` (0.32 m with the default 0.8 s),
        ``|dθ| ≤ 0.4``), then close the feet and stop. Each step's foot lands at its rest place in
        the moved frame: a sideways displacement towards the foot that stays (``dy > 0`` on a right
        step) of the feet's distance or more crosses the feet; give it to the foot on its side, as
        ``setVelocity`` does."""
        command = WalkCommand(steps=check_steps(f"{self.name}.setSteps", steps, self.gait.step_duration))
        self._check_time(f"{self.name}.setSteps", context)
        self._command(context, lambda s: setattr(s, "command", command))

    def _check_time(self, what: str, context: Context | None) -> None:
        """:class:`InvalidInput` if ``context``'s time is past :data:`~.plan.MAX_TIME` (the command could not be planned)."""
        if context is not None:
            check_type(f"{what}: context", context, Context, "a Context of the diagram (simulator.get_mutable_context())")
            if context.get_time() > MAX_TIME:
                raise InvalidInput(f"{what}: the context's time {context.get_time():.10g} s is past the latest time a walk is "
                                   f"planned for ({MAX_TIME:g} s): the command could not be planned")

    def _declare_timed_change(self, time: float, changes: list) -> None:
        """``attime``'s command at ``time``, refused at its time (settings unchanged) past :data:`~.plan.MAX_TIME`."""
        if time > MAX_TIME:
            def refuse(_settings) -> None:
                raise InvalidInput(f"{self.name}: a command at t = {time:.10g} s is past the latest time a walk is planned for "
                                   f"({MAX_TIME:g} s)")

            changes = [refuse, *changes]
        super()._declare_timed_change(time, changes)

    def plan(self, context: Context) -> WalkPlan:
        """The current plan in ``context`` (read-only)."""
        return self.own_context(context).get_abstract_state(self._plan).get_value()

    # --- calc -------------------------------------------------------------------------------
    def _initialize(self, context: Context, state) -> None:
        """At a tick (t = 0, or a context cloned at one): :meth:`_update`. Between two ticks (a context
        cloned after a command) nothing: the next tick plans, as it did in the run it was cloned from."""
        ticks = context.get_time() / self.dt
        if abs(ticks - round(ticks)) <= 1e-9 * max(1.0, ticks):
            self._update(context, state)

    def _update(self, context: Context, state) -> None:
        plan = context.get_abstract_state(self._plan).get_value()
        command, t = self._settings_of(context).command, context.get_time()
        if plan.needs_replan(command, t, self.gait):
            state.get_mutable_abstract_state(self._plan).set_value(replan(plan, command, t, self.gait, self.input_cost, self.legs))

    def _calc_references(self, context: Context, value: AbstractValue) -> None:
        value.set_value(context.get_abstract_state(self._plan).get_value().references(context.get_time()))

    def _refs(self, context: Context) -> References:
        return self._references.Eval(context)

    def _foot_pose(self, context: Context, side: str) -> RigidTransform:
        return foot_pose(self._refs(context).feet[side], self.start.feet[side], self._yaw0[side])

    def _foot_velocity(self, context: Context, side: str) -> np.ndarray:
        rate = self._refs(context).feet_velocity[side]
        return np.array([0.0, 0.0, rate[3], rate[0], rate[1], rate[2]])

    def _foot_acceleration(self, context: Context, side: str) -> np.ndarray:
        a = self._refs(context).feet_acceleration[side]
        return np.array([0.0, 0.0, a[3], a[0], a[1], a[2]])

    def _waist_pose(self, context: Context, output: AbstractValue) -> None:
        refs = self._refs(context)
        yaw = 0.5 * sum(refs.feet[s][3] - self._yaw0[s] for s in SIDES)
        R = RotationMatrix.MakeZRotation(yaw).multiply(self.start.waist.rotation())
        output.set_value(RigidTransform(R, [refs.com[0], refs.com[1], self.start.waist.translation()[2]]))

    def _waist_velocity(self, context: Context, output) -> None:
        refs = self._refs(context)
        yaw_rate = 0.5 * sum(refs.feet_velocity[s][3] for s in SIDES)
        output.SetFromVector([0.0, 0.0, yaw_rate, refs.com_velocity[0], refs.com_velocity[1], 0.0])


def start_of(dynamic, q0: np.ndarray, feet=("left-sole", "right-sole"), waist: str = "waist") -> Start:
    """The :class:`Start` of a robot at ``q0`` from its ``dynamic`` entity (op points or frames):
    ``feet`` names the left sole then the right one."""
    if isinstance(feet, str) or not isinstance(feet, (list, tuple)) or len(feet) != 2 \
            or not all(isinstance(name, str) and name for name in feet) or feet[0] == feet[1]:
        raise InvalidInput(f"start_of: feet must be two names, the left sole's then the right one's (not the same), got {feet!r:.100}")
    check_name("start_of: waist", waist)
    return Start({side: dynamic.pose_at(name, q0) for side, name in zip(SIDES, feet, strict=True)},
                 dynamic.com_at(q0), dynamic.pose_at(waist, q0))


__all__ = ["PatternGenerator", "PatternGeneratorSettings", "start_of"]
