"""``TaskCollision``: the collision pairs in range as inequality rows of one level (velocity damper).

For each pair closer than the influence distance ``d_i`` (:mod:`.distance`), one row

    J_d v ≥ −ξ (d − d_t) / (d_i − d_t),   d_t = d_s + a     (the velocity damper; upper side +inf)

with ``d`` the signed distance (m), ``d_s`` the safety distance (m), ``ξ`` the damper's speed
(m/s) and ``a`` = :data:`TICK_ALLOWANCE` (1 mm): a pair entering the influence zone may approach at
most at ``ξ``, and that bound falls linearly to 0 at ``d_t``, so ``d − d_t`` decays at most
exponentially at the rate ``λ = ξ/(d_i − d_t)`` (1/s) and does not cross 0 while the level is
satisfied, to first order. The step of a tick also has a part the rows do not see: the distance has
kinks where the closest features of two hulls change, and a link sliding fast past an edge of
another's hull (or of a box) can end a tick a fraction of a millimetre closer than the rows
predicted; the allowance ``a`` keeps those ticks outside ``d_s``. A pair inside ``d_t`` gets a
positive lower bound, the larger of ``ξ (d_t − d)/(d_i − d_t)`` and ``min((d_t − d)/dt, ξ)``: a
small shortfall is undone in the next tick, a large one at the speed ``ξ``. Over one device tick
``dt`` the integrated step keeps ``d − d_t ≥ (1 − λ dt)(d_k − d_t)``, so ``λ dt < 1`` is required
(``setMargins`` refuses a damper that could cross ``d_t`` in one tick).

**Acceleration level** (``acceleration=True``, for ``SolverDyn``, whose variable is ``q̈``): a
second-order damper. With ``h = d − d_t``, ``λ = ξ/(d_i − d_t)`` and ``e = ḋ + λ h`` (how much
faster than the damper's ``ḋ_min = −λ h`` the pair approaches, negated: ``e ≥ 0`` inside the
damper's set), each row asks ``ė ≥ −e/T``, i.e. with ``ḋ = J_d v`` and ``d̈ = J_d q̈ + J̇_d v``:

    J_d q̈ ≥ −λ ḋ − (ḋ + λ (d − d_t))/T − J̇_d v,    T = max(RECOVERY_TIME, dt)

A pair that enters with ``e ≥ 0`` keeps it (``e(t) ≥ e(0) e^(−t/T)``), so ``ḋ ≥ −λ h`` and ``h``
stays positive; a pair found outside that set is brought back in ``T`` (10 ms) with accelerations
of ``|e|/T`` rather than the ``|e|/dt`` of a one-tick target, which no torque could give and whose
slack would spill onto the level's other rows. The set has no edge at ``d_i``: a pair is taken in
range as soon as it may approach faster than the damper allows, within ``d_t + s/λ`` for ``s`` a
bound of its approach speed (the speeds of the two bodies' bounding spheres,
:meth:`~.schedule.PairSchedule.approach_bound`), or ``d_i`` if that is farther. ``J̇_d v`` is taken
with the witness points fixed in their bodies, the rotation of the normal left out
(:func:`~.distance.pair_distances`). The task then reads ``velocity`` (``v``) too.

**Pairs the solver cannot move.** With ``controlled`` (the solver's control selection, nv
booleans), a pair whose ``J_d`` is zero over the controlled velocities (two links of a gripper the
solver does not drive, say) gets no row: nothing the solver commands changes its distance, so its
row could only be infeasible (a pair resting just inside ``d_t`` would ask a recovery of ``ξ`` it
cannot give, and the level would carry that slack at every tick). It is still measured
(``distances``, ``min_distance``).

The number of rows is the number of pairs in range at that tick (0 to all of them): the level is a
:class:`~sotdrake.task.TaskLevel` of any size, which ``SolverKine`` takes as it comes. The basic
``SOT`` refuses it at ``push`` (it has no inequality rows).

Ports: inputs ``position`` (``q``, nq) and, at the acceleration level, ``velocity`` (``v``, nv). Outputs ``task`` (the rows, a
:class:`~sotdrake.task.TaskLevel`, ``error = d − d_s`` per row, m), ``distances``
(:class:`~.distance.PairDistances` of the pairs in range) and ``min_distance`` (1, m: the smallest
signed distance in range, ``+inf`` when no pair is within ``d_i``).
"""

from __future__ import annotations

import copy
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, ValueProducer

from ..entity import Entity
from ..exceptions import InvalidInput, check_number, finite_number
from ..task import TaskLevel
from .distance import PairDistances
from .schedule import PairSchedule, ScheduleMemory, ScheduleState, ScheduleStep
from .world import CollisionWorld

log = logging.getLogger(__name__)

#: Defaults: safety distance (m), influence distance (m), damper speed (m/s).
SAFETY_DISTANCE, INFLUENCE_DISTANCE, DAMPER_SPEED = 0.01, 0.05, 0.5
#: The rows aim this far (m) beyond the safety distance: the part of a tick's step they do not see.
TICK_ALLOWANCE = 1e-3
#: At the acceleration level, the time (s) in which a pair's approach speed is brought back within
#: the damper's bound (longer: gentler accelerations; see the module docstring).
RECOVERY_TIME = 0.01
#: A pair whose ``J_d`` entries over the controlled velocities are all below this (m per unit of
#: ``v``) cannot be moved by the solver and gets no row.
MOVABLE_TOLERANCE = 1e-9
#: Largest influence distance (m) and damper speed (m/s) accepted.
MAX_INFLUENCE, MAX_DAMPER_SPEED = 1.0, 10.0


@dataclass
class CollisionMargins:
    """``safety`` ``d_s`` (m), ``influence`` ``d_i`` (m), ``xi`` ``ξ`` (m/s): see the module docstring."""

    safety: float = SAFETY_DISTANCE
    influence: float = INFLUENCE_DISTANCE
    xi: float = DAMPER_SPEED


def check_margins(safety: object, influence: object, xi: object, dt: float, where: str = "margins") -> CollisionMargins:
    """The margins if ``0 ≤ d_s``, ``d_s + a < d_i ≤ 1 m`` (``a`` = :data:`TICK_ALLOWANCE`),
    ``0 < ξ ≤ 10 m/s`` and ``ξ dt < d_i − d_s − a`` (the damper cannot cross ``d_s + a`` in one tick
    ``dt``, a number > 0 s); else :class:`~sotdrake.exceptions.InvalidInput` naming the argument."""
    if not (finite_number(dt) and dt > 0):
        raise InvalidInput(f"{where}: dt (the tick) must be a number > 0 s, got {dt!r:.40}")
    d_s = check_number(f"{where}: safety (the safety distance d_s)", safety, 0.0, MAX_INFLUENCE, " m")
    d_i = check_number(f"{where}: influence (the influence distance d_i)", influence, 0.0, MAX_INFLUENCE, " m")
    if not d_i > d_s + TICK_ALLOWANCE:
        raise InvalidInput(f"{where}: influence (d_i = {d_i:g} m) must be larger than safety (d_s = {d_s:g} m) "
                           f"+ {TICK_ALLOWANCE:g} m (the rows aim that far beyond d_s)")
    speed = check_number(f"{where}: xi (the damper speed ξ)", xi, 0.0, MAX_DAMPER_SPEED, " m/s")
    if speed <= 0:
        raise InvalidInput(f"{where}: xi (the damper speed ξ) must be > 0 m/s, got {xi!r}")
    room = d_i - d_s - TICK_ALLOWANCE
    if speed * dt >= room:
        raise InvalidInput(
            f"{where}: xi = {speed:g} m/s is too stiff for a tick of {dt:g} s: one tick could cross d_s "
            f"(ξ·dt = {speed * dt:g} m ≥ d_i − d_s − {TICK_ALLOWANCE:g} m = {room:g} m); take xi < {room / dt:g} m/s")
    return CollisionMargins(d_s, d_i, speed)


def target_distance(margins: CollisionMargins) -> float:
    """The distance ``d_t = d_s + a`` (m) the rows aim at (``a`` = :data:`TICK_ALLOWANCE`)."""
    return margins.safety + TICK_ALLOWANCE


def damper_rate(margins: CollisionMargins) -> float:
    """The damper's rate ``λ = ξ/(d_i − d_t)`` (1/s)."""
    return margins.xi / (margins.influence - margins.safety - TICK_ALLOWANCE)


def damper_rows(distances: PairDistances, margins: CollisionMargins, dt: float) -> TaskLevel:
    """The velocity-damper rows ``J_d v ≥ −ξ (d − d_t)/(d_i − d_t)`` of the pairs in range, with the
    recovery of a pair inside ``d_t = d_s + a`` (see the module docstring; ``dt`` the device's tick, s)."""
    d = distances.distance
    if not len(d):  # no pair in range: no row
        return TaskLevel(distances.jacobian, d, d, d)
    xi, d_t = margins.xi, target_distance(margins)
    lower = -damper_rate(margins) * (d - d_t)
    inside = d < d_t
    if inside.any():
        lower[inside] = np.maximum(lower[inside], np.minimum((d_t - d[inside]) / dt, xi))
    return TaskLevel(distances.jacobian, lower, np.full(lower.shape, np.inf), distances.distance - margins.safety)


def acceleration_rows(distances: PairDistances, margins: CollisionMargins, dt: float, v: np.ndarray) -> TaskLevel:
    """The acceleration-level rows ``J_d q̈ ≥ −λ ḋ − (ḋ + λ (d − d_t))/T − J̇_d v`` with ``ḋ = J_d v``
    and ``T`` = max(:data:`RECOVERY_TIME`, ``dt``) (see the module docstring)."""
    lam = damper_rate(margins)
    d_t = target_distance(margins)
    rate = distances.jacobian @ v
    excess = rate + lam * (distances.distance - d_t)  # ḋ − ḋ_min(d): ≥ 0 inside the damper's set
    lower = -lam * rate - excess / max(RECOVERY_TIME, dt) - distances.bias
    return TaskLevel(distances.jacobian, lower, np.full(lower.shape, np.inf), distances.distance - margins.safety)


def speed_aware_influence(margins: CollisionMargins, approach: np.ndarray) -> np.ndarray:
    """Per pair, the distance (m) within which the acceleration level needs its row: ``d_i``, or
    farther for a pair that may approach at ``approach`` (m/s, a bound of ``−ḋ``) faster than the
    damper allows there, ``d_t + approach/λ``."""
    return np.maximum(margins.influence, target_distance(margins) + approach / damper_rate(margins))


def one_tick_influence(margins: CollisionMargins, approach: np.ndarray) -> np.ndarray:
    """Per pair, the distance (m) within which the velocity level needs its row: ``d_i``, or farther
    for a pair that one tick may bring ``approach`` (m) closer, ``d_t + approach`` (a pair farther
    than that stays beyond ``d_t`` whatever the command, within the solver's step bound)."""
    return np.maximum(margins.influence, target_distance(margins) + approach)


class _WorldContext:
    """The collision diagram's context as the value of a cache entry (a copy gets a context of its
    own, at the same configuration), and the pairs' approach speed bound at its positions and
    velocities (``approach``, m/s, taken at most once per configuration: None until then)."""

    def __init__(self, world: CollisionWorld):
        self.world = world
        self.context = world.new_context()
        self.approach: np.ndarray | None = None

    def __deepcopy__(self, memo: dict) -> _WorldContext:
        clone = _WorldContext(self.world)
        clone.context.SetTimeStateAndParametersFrom(self.context)  # (a cloned cache entry stays valid)
        return clone


class TaskCollision(Entity[CollisionMargins]):
    """Collision-avoidance level (see the module docstring): ``world`` the robot's
    :class:`~.world.CollisionWorld`, ``nv`` the solver's size, ``dt`` the device's tick (s),
    ``pairs`` None (every pair the world checks) or a list of ``(link, link)`` / ``(link,
    obstacle)`` names; ``controlled``: the solver's control selection (nv booleans, None for all;
    see the module docstring).

    Inputs: ``position`` (the world plant's ``q``); at the acceleration level ``velocity`` (``v``,
    nv); at the velocity level, optional, ``step_bound`` (nv: the largest ``|v_j| dt`` the solver
    allows, rad or m; the kinematic solvers' output of that name, connected by the robot): a pair
    that one such tick may bring within ``d_t`` has its row from farther than ``d_i``
    (:func:`one_tick_influence`). Outputs: ``task`` (inequality rows over ``v``, m/s, or ``q̈``, m/s²),
    ``distances`` (each pair's signed distance, m, and its Jacobian) and ``min_distance`` (the
    smallest signed distance, m; inf without pairs).
    """

    is_inequality = True
    stack = None  # (RobotDyn.add_task: no previous Jacobian kept)

    def __init__(self, name: str, world: CollisionWorld, nv: int, dt: float,
                 pairs: Sequence[tuple[str, str]] | None = None, margins: CollisionMargins | None = None,
                 acceleration: bool = False, controlled: np.ndarray | None = None):
        if controlled is not None:
            controlled = np.asarray(controlled)
            if controlled.dtype != bool or controlled.shape != (nv,) or not controlled.any():
                raise InvalidInput(f"{name}: controlled must be {nv} booleans, at least one True, "
                                   f"got {controlled.dtype} {controlled.shape}")
            controlled = controlled.copy()
        self.controlled = controlled
        if isinstance(nv, bool) or not isinstance(nv, (int, np.integer)) or nv != world.plant.num_velocities():
            raise InvalidInput(f"{name}: nv = {nv!r:.40}, the collision model has {world.plant.num_velocities()} velocities")
        if margins is not None and not isinstance(margins, CollisionMargins):
            raise InvalidInput(f"{name}: margins must be CollisionMargins(safety, influence, xi), got {margins!r:.60}")
        margins = margins or CollisionMargins()
        margins = check_margins(margins.safety, margins.influence, margins.xi, dt, name)
        self.pairs = None if pairs is None else world.check_pairs(pairs)
        Entity.__init__(self, name, margins)
        self.world, self.nv, self.dt = world, nv, float(dt)
        self._geometry_pairs = None if self.pairs is None else world.geometry_pairs(self.pairs)
        self.acceleration = bool(acceleration)
        self._position = self.DeclareVectorInputPort("position", world.plant.num_positions())
        position = {self.input_port_ticket(self._position.get_index())}
        self._velocity = None
        self._step_bound = None
        if self.acceleration:
            self._velocity = self.DeclareVectorInputPort("velocity", nv)
            position.add(self.input_port_ticket(self._velocity.get_index()))
        else:
            self._step_bound = self.DeclareVectorInputPort("step_bound", nv)
            position.add(self.input_port_ticket(self._step_bound.get_index()))
        self._approach: tuple[bytes, np.ndarray] | None = None  # (a memo of tick_approach: a pure function of the bound)
        self._world_context = self.DeclareCacheEntry(
            "collision_context",
            ValueProducer(allocate=lambda: AbstractValue.Make(_WorldContext(world)), calc=self._set_positions),
            prerequisites_of_calc=position,
        )
        settings = {self.abstract_state_ticket(self._settings_index)}
        # Which pairs are queried at a tick (.schedule): the bounds, a warm start in the Context that
        # the step replaces in place (left out of its prerequisites: the pairs in range never depend on it).
        self._pair_schedule: PairSchedule | None = None  # made at the first tick (obstacles are in by then)
        self._warned_inside = False  # logging only (a pair inside d_s, warned once per task): results never depend on it
        self._schedule_index = self.DeclareAbstractState(AbstractValue.Make(ScheduleMemory()))
        self._step = self.DeclareCacheEntry(
            "pair_schedule", ValueProducer(allocate=lambda: AbstractValue.Make(ScheduleStep(ScheduleState(), [], 0)),
                                           calc=self._calc_step),
            prerequisites_of_calc=position | settings)
        self._distances = self.DeclareCacheEntry(
            "distances",
            ValueProducer(allocate=lambda: AbstractValue.Make(PairDistances(jacobian=np.zeros((0, nv)))),
                          calc=self._calc_distances),
            prerequisites_of_calc={self.cache_entry_ticket(self._step.cache_index())} | position,
        )
        distances = {self.cache_entry_ticket(self._distances.cache_index())}
        empty = TaskLevel(np.zeros((0, nv)), np.zeros(0), np.zeros(0), np.zeros(0))
        self.DeclareAbstractOutputPort("task", lambda: AbstractValue.Make(empty), self._calc_rows,
                                       prerequisites_of_calc=distances | settings | position)
        self.DeclareAbstractOutputPort("distances", lambda: AbstractValue.Make(PairDistances(jacobian=np.zeros((0, nv)))),
                                       lambda c, o: o.set_value(copy.copy(self._distances.Eval(c))),
                                       prerequisites_of_calc=distances)
        self.DeclareVectorOutputPort("min_distance", 1, self._calc_minimum, prerequisites_of_calc=distances)

    @property
    def name(self) -> str:
        return self.get_name()

    def setMargins(self, safety: float, influence: float, xi: float, context: Context | None = None) -> None:
        """Safety distance ``d_s`` (m), influence distance ``d_i`` (m) and damper speed ``ξ`` (m/s),
        all checked (:func:`check_margins`) before any is changed."""
        margins = check_margins(safety, influence, xi, self.dt, f"{self.name}.setMargins")
        def change(s: CollisionMargins) -> None:
            s.safety, s.influence, s.xi = margins.safety, margins.influence, margins.xi

        self._command(context, change)

    def missing_inputs(self, context: Context) -> str | None:
        """A sentence when the ``position`` input is not connected, else None."""
        try:
            own = self.GetMyContextFromRoot(context)
        except RuntimeError:
            own = context
        if not self._position.HasValue(own):
            return f"collision task {self.name!r} has no 'position' input: connect the device's 'state' (q) to it"
        return None

    def _set_positions(self, context: Context, value: AbstractValue) -> None:
        q = self._position.Eval(context)
        if not math.isfinite(q.sum()):  # Drake would abort the process
            raise InvalidInput(f"{self.name}: non-finite position at t = {context.get_time()}: {q}")
        holder = value.get_mutable_value()
        holder.approach = None
        plant_context = self.world.plant_context(holder.context)
        self.world.plant.SetPositions(plant_context, q)
        if self._velocity is not None:
            v = self._velocity.Eval(context)
            if not math.isfinite(v.sum()):
                raise InvalidInput(f"{self.name}: non-finite velocity at t = {context.get_time()}: {v}")
            self.world.plant.SetVelocities(plant_context, v)

    def _calc_rows(self, context: Context, output: AbstractValue) -> None:
        distances, margins = self._distances.Eval(context), self._settings_of(context)
        if not self._warned_inside and distances.minimum < margins.safety - 1e-4:
            self._warn_inside(distances, margins.safety, context.get_time())
        if self._velocity is None:
            rows = damper_rows(distances, margins, self.dt)
        else:
            rows = acceleration_rows(distances, margins, self.dt, self._velocity.Eval(context))
        keys = self._step.Eval(context).state.in_range_pairs  # (the rows' pairs: which row is which from tick to tick)
        if self.controlled is not None and len(rows.lower):
            movable = np.abs(rows.jacobian[:, self.controlled]).max(axis=1) > MOVABLE_TOLERANCE
            if not movable.all():
                rows, keys = TaskLevel(rows.jacobian[movable], rows.lower[movable], rows.upper[movable], rows.error[movable]), keys[movable]
        output.set_value(rows._replace(row_keys=keys))

    def _warn_inside(self, distances: PairDistances, safety: float, t: float) -> None:
        """Warn once: pairs inside the safety distance (a robot that starts in collision, an obstacle
        through it): their rows ask them to part, which the robot may not be able to do."""
        self._warned_inside = True
        inside = [f"{a}–{b} {1e3 * d:.1f} mm" for (a, b), d in zip(distances.names, distances.distance, strict=True)
                  if d < safety - 1e-4]
        log.warning("%s: t = %.3f s: %d pair(s) inside the safety distance d_s = %.1f mm (%s%s): their rows ask them to "
                    "part, which the robot may not be able to do (a start in collision? an obstacle through the robot?)",
                    self.name, t, len(inside), 1e3 * safety, ", ".join(inside[:5]), ", …" if len(inside) > 5 else "")

    def _calc_step(self, context: Context, value: AbstractValue) -> None:
        holder = self._world_context.Eval(context)
        if self._pair_schedule is None:
            self._pair_schedule = PairSchedule(self.world, self._geometry_pairs)
        memory = context.get_abstract_state(self._schedule_index).get_value()
        q, margins = self._position.Eval(context), self._settings_of(context)
        influence: float | np.ndarray = margins.influence
        if self._velocity is not None:  # a pair faster than the damper allows is taken in range before d_i
            if holder.approach is None:  # (once per configuration)
                holder.approach = self._pair_schedule.approach_bound(holder.context)
            influence = speed_aware_influence(margins, holder.approach)
        elif self._step_bound is not None and self._step_bound.HasValue(context):  # one tick may bring a pair from beyond d_i
            influence = one_tick_influence(margins, self._tick_approach(self._step_bound.Eval(context)))
        step = self._pair_schedule.step(memory.state, holder.context, q, influence)
        memory.state = step.state
        value.set_value(step)

    def _tick_approach(self, step: np.ndarray) -> np.ndarray:
        key = step.tobytes()
        if self._approach is None or self._approach[0] != key:
            self._approach = key, self._pair_schedule.tick_approach(step)  # type: ignore[union-attr]
        return self._approach[1]

    def _calc_distances(self, context: Context, value: AbstractValue) -> None:
        holder = self._world_context.Eval(context)
        step = self._step.Eval(context)
        value.set_value(self._pair_schedule.table.distances(self.world, holder.context, step.in_range,  # type: ignore[union-attr]
                                                            step.state.in_range_pairs, self.acceleration))

    def _calc_minimum(self, context: Context, output: BasicVector) -> None:
        output.SetAtIndex(0, self._distances.Eval(context).minimum)

