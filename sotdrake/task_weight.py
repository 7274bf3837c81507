"""``TaskWeight`` (sot-dyninv): several tasks weighted inside one level of the stack.

Each member ``i`` gives rows ``lower_i ≤ J_i x ≤ upper_i`` (a :class:`~sotdrake.task.TaskLevel`,
over ``v`` for the kinematic solvers, over ``q̈`` for ``SolverDyn``) and has a weight ``w_i ≥ 0``.
The level is the members' rows stacked, each scaled by ``√w_i``::

    √w_i J_i x = √w_i ė_i*             (equality rows)
    √w_i lower_i ≤ √w_i J_i x ≤ √w_i upper_i   (inequality rows; ±inf stay ±inf)

so that the solver's least-squares slack of the level is ``Σ_i w_i ‖J_i x − ė_i*‖²`` (plus the
inequality rows' violations, weighted the same way): a compromise between the members, solved in
the null space of the levels above and strictly above the levels below. Only the ratios of the
weights matter to an equality level; a member of weight 0 is left out of the level (its rows are
not solved). The level's ``error`` is the members' errors scaled the same way (``Σ w_i ‖e_i‖²`` is
its squared norm).

Ports: one input per member, named after it, carrying its ``TaskLevel`` (connect the member's
``task`` output; :func:`add_task_weight` does). Outputs ``task`` (the weighted level, a
:class:`~sotdrake.task.TaskLevel`, for any solver's input of the group's name), ``weights`` (the
members' weights, in the order of ``members``, dimensionless) and ``error_norm`` (the weighted
error's norm). The members are fixed at construction; the weights are settings in the Context
(``setWeight``, ``setWeights``), checked before anything changes: each a finite number in
``[0, MAX_WEIGHT]``, not all zero.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, InputPort

from .entity import Entity
from .exceptions import InvalidInput, StackError, TaskNotFound, finite_number
from .task import _UNCONNECTED, TaskLevel, unconnected_input_message

#: Largest weight of a member (dimensionless; rows scaled by at most √MAX_WEIGHT = 1e4).
MAX_WEIGHT = 1e8


def weighted_level(levels: Sequence[TaskLevel], weights: Sequence[float] | np.ndarray) -> TaskLevel:
    """The level of ``levels`` weighted by ``weights``: each member's Jacobian, bounds and error
    scaled by ``√w_i`` and stacked, members of weight 0 left out. An equality level (every member
    an equality) keeps ``lower is upper``. ``weights`` are not checked here (see
    :func:`check_weights`)."""
    if len(levels) != len(weights):
        raise InvalidInput(f"weighted_level: {len(levels)} levels and {len(weights)} weights")
    kept = [(level, math.sqrt(float(w))) for level, w in zip(levels, weights, strict=True) if w > 0]
    nv = levels[0].jacobian.shape[1] if levels else 0
    if not kept:
        return TaskLevel(np.zeros((0, nv)), np.zeros(0), np.zeros(0), np.zeros(0))
    jacobian = np.vstack([s * level.jacobian for level, s in kept])
    error = np.concatenate([s * level.error for level, s in kept])
    lower = np.concatenate([s * level.lower for level, s in kept])
    if all(level.is_equality for level, _ in kept):
        return TaskLevel(jacobian, lower, lower, error)
    upper = np.concatenate([s * level.upper for level, s in kept])
    return TaskLevel(jacobian, lower, upper, error)


def check_weight(name: str, member: str, weight: Any) -> float:
    """``weight`` as a float if it is one finite number in ``[0, MAX_WEIGHT]`` (a numpy scalar
    too), else :class:`InvalidInput` naming the group, the member and the value given."""
    if not (finite_number(weight) and 0 <= weight <= MAX_WEIGHT):
        raise InvalidInput(f"{name}: the weight of {member!r} must be a finite number in [0, {MAX_WEIGHT:g}], got {weight!r:.100}")
    return float(weight)


def check_weights(name: str, members: Sequence[str], weights: Any) -> np.ndarray:
    """``weights`` as an array of ``len(members)`` floats, each finite in ``[0, MAX_WEIGHT]``, not
    all zero; else :class:`InvalidInput` naming the group and the member."""
    items = list(np.ravel(weights)) if isinstance(weights, np.ndarray) else weights
    if not isinstance(items, (list, tuple)) or len(items) != len(members):
        raise InvalidInput(f"{name}: weights must be {len(members)} numbers (one per member {members}), got {weights!r:.100}")
    for member, w in zip(members, items, strict=True):
        check_weight(name, member, w)
    values = np.array([float(w) for w in items])
    if not values.any():
        raise InvalidInput(f"{name}: every weight is 0, the level would ask nothing: give at least one member a weight > 0")
    return values


@dataclass
class WeightSettings:
    weights: np.ndarray = field(default_factory=lambda: np.zeros(0))


class TaskWeight(Entity[WeightSettings]):
    """Several tasks in one level, weighted (see the module docstring). ``members``: the tasks
    (kinematic ``Task``, ``TaskPD``, ``TaskInequality``, or ``TaskDynPD`` for ``SolverDyn``), at
    least one, each once, of the same ``nv``; ``weights``: one per member (default 1 each).

    Inputs: one per member (named after it, its :class:`~sotdrake.task.TaskLevel`). Outputs:
    ``task`` (the weighted level), ``weights`` (each member's weight) and ``error_norm`` (the
    weighted error's norm).
    """

    def __init__(self, name: str, nv: int, members: Sequence[Any], weights: Sequence[float] | None = None):
        if not isinstance(members, Sequence) or not members:
            raise InvalidInput(f"{name}: a weighted level needs at least one task (members), got {members!r:.100}")
        names: list[str] = []
        for member in members:
            member_name = getattr(member, "name", None)
            if not isinstance(member_name, str) or not hasattr(member, "is_inequality") or getattr(member, "nv", None) != nv:
                raise InvalidInput(f"{name}: each member must be a task of nv = {nv} (Task, TaskPD, TaskInequality, TaskDynPD), "
                                   f"got {member!r:.100}")
            names.append(member_name)
        if len(set(names)) != len(names):
            raise InvalidInput(f"{name}: a task appears twice in members {names}")
        if name in names:
            raise InvalidInput(f"{name}: the group cannot have the name of one of its members {names}")
        values = check_weights(name, names, np.ones(len(names)) if weights is None else weights)
        Entity.__init__(self, name, WeightSettings(values))
        self.nv = nv
        self.members: tuple[str, ...] = tuple(names)
        self._tasks = dict(zip(names, members, strict=True))  # build-time structure (the members' systems)
        self.is_inequality = any(bool(member.is_inequality) for member in members)
        empty = TaskLevel(np.zeros((0, nv)), np.zeros(0), np.zeros(0), np.zeros(0))
        self._ports: dict[str, InputPort] = {m: self.DeclareAbstractInputPort(m, AbstractValue.Make(empty)) for m in names}
        self._task_output = self.DeclareAbstractOutputPort("task", lambda: AbstractValue.Make(empty), self._calc)
        self.DeclareVectorOutputPort("weights", len(names), lambda c, o: o.SetFromVector(self._settings_of(c).weights))
        self.DeclareVectorOutputPort(
            "error_norm", 1, lambda c, o: o.SetAtIndex(0, float(np.linalg.norm(self._task_output.Eval(c).error))),
            prerequisites_of_calc={self.cache_entry_ticket(self._task_output.cache_entry().cache_index())},
        )

    def member_port(self, member: Any) -> InputPort:
        """The input of ``member`` (a task, a meta task, or its name)."""
        return self._ports[self._member(member)]

    def _member(self, member: Any) -> str:
        name = getattr(getattr(member, "task", member), "name", member)
        if not isinstance(name, str) or name not in self._ports:
            raise TaskNotFound(f"{name!r:.80}", list(self.members)).but(f"{self.name}: not a member of this weighted level")
        return name

    # --- settings ------------------------------------------------------------------------------
    def weights(self, context: Context | None = None) -> dict[str, float]:
        """Each member's weight (in ``context``, else the defaults)."""
        return dict(zip(self.members, (float(w) for w in self.settings(context).weights), strict=True))

    def setWeights(self, weights: Sequence[float] | Mapping[str, float], context: Context | None = None) -> None:
        """Every weight at once: one number per member (in the order of ``members``) or a mapping
        from member names to weights (members not named keep theirs as they are when the change
        applies: inside ``attime``, at its time; not all 0 then)."""
        if not isinstance(weights, Mapping):
            values = check_weights(self.name, self.members, weights)
            self._command(context, lambda s: setattr(s, "weights", values.copy()))
            return
        named = {}
        for member, w in weights.items():
            key = self._member(member)
            named[self.members.index(key)] = check_weight(self.name, key, w)

        def change(s: WeightSettings) -> None:
            values = s.weights.copy()
            for index, w in named.items():
                values[index] = w
            s.weights = check_weights(self.name, self.members, values)

        self._command(context, change)

    def setWeight(self, member: Any, weight: float, context: Context | None = None) -> None:
        """The weight of one member (a task, a meta task, or its name)."""
        self.setWeights({self._member(member): weight}, context)

    # --- checks and calc -----------------------------------------------------------------------
    def member_tasks(self) -> list[Any]:
        """The members' task systems, in order."""
        return [self._tasks[m] for m in self.members]

    def missing_inputs(self, context: Context) -> str | None:
        """What keeps this level from being evaluated in the root ``context``: a member's own
        missing input (its gain, its feature), or a member not connected to the group; None when
        it can be evaluated."""
        own = self.GetMyContextFromRoot(context)
        for member, task in zip(self.members, self.member_tasks(), strict=True):
            check = getattr(task, "missing_inputs", None)
            missing = check(context) if check is not None else None
            if missing is not None:
                return f"in the weighted level {self.name!r}: {missing}"
            try:
                connected = self._ports[member].HasValue(own)
            except Exception:  # another problem: the run reports it itself, from its own state
                continue
            if not connected:
                return f"weighted level {self.name!r}: its member {member!r} is not connected to its input {member!r}"
        return None

    def _calc(self, context: Context, value: AbstractValue) -> None:
        levels, weights = [], []
        for member, w in zip(self.members, self._settings_of(context).weights, strict=True):
            if w == 0:  # left out: not even evaluated
                continue
            try:
                level = self._ports[member].Eval(context)
            except RuntimeError as error:
                match = _UNCONNECTED.search(str(error))
                if match is not None and match.group(2).rsplit("::", 1)[-1] == self.name:
                    raise StackError(f"weighted level {self.name!r}: its member {member!r} is not connected to its input "
                                     f"{member!r}") from None
                missing = unconnected_input_message(member, error)
                if missing is not None:
                    raise StackError(missing) from None
                raise
            if level.jacobian.ndim != 2 or level.jacobian.shape[1] != self.nv:
                raise InvalidInput(f"{self.name}: member {member!r} gives a Jacobian {level.jacobian.shape}, expected (rows, {self.nv})")
            levels.append(level)
            weights.append(w)
        value.set_value(weighted_level(levels, weights) if levels else TaskLevel(np.zeros((0, self.nv)), np.zeros(0), np.zeros(0),
                                                                                 np.zeros(0)))


def add_task_weight(robot: Any, name: str, members: Sequence[Any], weights: Sequence[float] | None = None) -> TaskWeight:
    """Add a :class:`TaskWeight` named ``name`` over ``members`` (tasks or meta tasks already added
    to ``robot``, a :class:`~sotdrake.robot.Robot` or a
    :class:`~sotdrake.dynamics.robot_dyn.RobotDyn`) to ``robot``'s builder, connect each member's
    ``task`` output to it and the group to the robot's solver; then ``sot.push(group)`` puts the
    weighted level in the stack. Everything is checked before anything is added."""
    tasks = [getattr(member, "task", member) for member in members] if isinstance(members, Sequence) else members
    group = TaskWeight(name, robot.dimension, tasks, weights)
    for task in group.member_tasks():
        if robot.tasks.get(task.name) is not task:
            raise InvalidInput(f"{name}: the member {task.name!r} is not a task of this robot (add it first, e.g. with a meta task)")
    solver = getattr(robot, "solver", None) or getattr(robot, "sot", None)
    if solver is not None:
        solver.check_task_input(group)
    robot.add(group)
    for task in group.member_tasks():
        robot.builder.Connect(task.GetOutputPort("task"), group.member_port(task))
    robot.tasks[name] = group
    if solver is not None:
        robot.builder.Connect(group.GetOutputPort("task"), solver.declare_task_input(group))
    return group
