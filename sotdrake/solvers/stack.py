"""The stack of tasks, one object that every solver system holds (:class:`Stack`).

A ``Stack`` is the part of a solver that the seed's commands change: the task inputs it knows
(one port per task, named after the task, carrying its :class:`~sotdrake.task.TaskLevel`), the
order of the stack (task names, highest priority first: ``push`` appends at the lowest priority,
as in sot-core; ``up``/``down``/``remove``/``pop``/``clear``), the contacts (``addContact`` /
``rmContact``: tasks solved together as one level above the whole stack) and the settings of the
solve (SVD threshold, damping, control selection, velocity and step limits). The stack's state is
the system's settings, held in its Context (:mod:`sotdrake.entity`): a ``Stack`` keeps none of it,
it only declares the system's task ports and changes the settings through the system's commands.

:class:`StackSolver` is the command surface every solver (``SOT``, ``SolverKine``, ``SolverDyn``)
exposes under the seed's names (``sot.push(...)``): each command is its stack's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, InputPort

from ..entity import Entity
from ..exceptions import InvalidInput, StackError, TaskNotFound, all_numbers, finite_number
from ..task import Task, TaskLevel
from ..task_weight import TaskWeight
from .step_limit import DEFAULT_STEP_LIMIT, check_step_limit

#: Accepted ranges: the SVD threshold (a singular value, unit of the Jacobian) and the damping δ.
MAX_SVD_THRESHOLD = 1.0
MAX_DAMPING = 1e4


@dataclass
class StackSettings:
    """The stack's settings, held in the solver's Context: the stack (task names, highest priority
    first), the contacts, the SVD threshold, the damping, the control selection (nv booleans), the
    velocity limit (nv values, rad/s or m/s) and the step limit (rad or m per tick)."""

    tasks: list[str] = field(default_factory=list)
    contacts: list[str] = field(default_factory=list)
    svd_threshold: float = 1e-4
    damping: float = 0.0
    control_selection: np.ndarray | None = None  # nv booleans; None: every component
    velocity_limit: np.ndarray | None = None  # nv limits > 0 (inf: none); None: no scaling
    step_limit: float = DEFAULT_STEP_LIMIT  # rad or m per tick (inf: none), see .step_limit


S = TypeVar("S", bound=StackSettings)
_Change = Callable[[Any], None]


class Stack:
    """The stack of tasks of one solver system (see the module docstring): its task inputs and the
    commands that change its settings in the system's Context. ``accepts_inequalities``: whether
    the solver takes inequality tasks (the cascade does not); ``on_new_task(name)``: called once
    per new task input (a solver that keeps something per task declares it there)."""

    def __init__(self, system: Entity[Any], nv: int, accepts_inequalities: bool,
                 on_new_task: Callable[[str], None] | None = None):
        self.system, self.nv, self.accepts_inequalities = system, nv, accepts_inequalities
        self._on_new_task = on_new_task
        self.task_ports: dict[str, InputPort] = {}
        self._task_systems: dict[str, object] = {}  # the task system behind each port (its identity)
        self._inequality_tasks: set[str] = set()
        self.groups: dict[str, tuple[str, ...]] = {}  # weighted levels (TaskWeight): their members

    @property
    def name(self) -> str:
        return self.system.name

    def _command(self, context: Context | None, change: _Change) -> None:
        self.system._command(context, change)

    def settings(self, context: Context | None = None) -> StackSettings:
        return self.system.settings(context)

    # --- wiring (build time) ---------------------------------------------------------------
    def check_task_input(self, task: Task | TaskWeight) -> None:
        """:class:`InvalidInput` if :meth:`declare_task_input` would refuse ``task`` (another size,
        or a name one of the solver's own inputs has): for a caller that checks before adding."""
        if task.nv != self.nv:
            raise InvalidInput(f"task {task.name} has nv = {task.nv}, solver {self.name} has nv = {self.nv}")
        if task.name not in self.task_ports and self.system.HasInputPort(task.name):
            raise InvalidInput(f"{task.name!r}: the solver {self.name} has an input of that name (its own): give the task "
                               "or weighted level another name")

    def declare_task_input(self, task: Task | TaskWeight) -> InputPort:
        """The input port for ``task`` (a task, or a :class:`~sotdrake.task_weight.TaskWeight`
        group; created once); connect ``task.task`` to it."""
        self.check_task_input(task)
        if task.name not in self.task_ports:
            self._task_systems[task.name] = task
            self.task_ports[task.name] = self.system.DeclareAbstractInputPort(
                task.name, AbstractValue.Make(TaskLevel(np.zeros((0, self.nv)), np.zeros(0), np.zeros(0), np.zeros(0)))
            )
            if task.is_inequality:
                self._inequality_tasks.add(task.name)
            if isinstance(task, TaskWeight):
                self.groups[task.name] = task.members
            if self._on_new_task is not None:
                self._on_new_task(task.name)
        return self.task_ports[task.name]

    @property
    def known_tasks(self) -> list[str]:
        return list(self.task_ports)

    def _known(self, name: object) -> str:
        if not isinstance(name, str):
            raise TaskNotFound(f"{name!r:.80}", list(self.task_ports)).but(
                f"{self.name} expects a task name (str), a task or a meta task, got a {type(name).__name__}")
        if name not in self.task_ports:
            raise TaskNotFound(name, list(self.task_ports))
        return name

    def task_name(self, task: object) -> str:
        """The known task name of a name, a ``Task`` or a meta task (its ``.task``); a task object
        must be the one this solver reads (not another robot's task of the same name)."""
        system = getattr(task, "task", task)
        name = self._known(getattr(system, "name", task))
        if not isinstance(task, str) and self._task_systems.get(name) is not system:
            raise StackError(f"{self.name}: the task {name!r} given is not the one this solver reads (a task of another "
                             "robot or diagram?): give this robot's task, or its name")
        return name

    # --- the order of the stack ------------------------------------------------------------
    def push(self, name: object, context: Context | None = None) -> None:
        """Append ``name`` (a task name, a task or a meta task) at the bottom (lowest priority) of
        the stack."""
        name = self.task_name(name)
        self.check_solvable(name)
        if context is not None:
            self._check_connected(name, context)

        def change(s: StackSettings) -> None:
            if name in s.tasks or name in s.contacts:
                raise StackError(f"{self.name}.push: {name!r} is already in the stack {s.tasks} or contacts {s.contacts}")
            s.tasks.append(name)

        self._command(context, change)

    def check_solvable(self, name: str) -> None:
        if name in self._inequality_tasks and not self.accepts_inequalities:
            raise StackError(
                f"{self.name} is a {type(self.system).__name__}, which cannot solve the inequality task {name!r}: "
                "the solvers that take inequality rows are SolverKine (the hierarchical QP: add_sot(robot, solver='hqp')) "
                "and SolverDyn"
            )

    def _check_connected(self, name: str, context: Context) -> None:
        """Into a running stack (a ``context`` given), a task that cannot be evaluated (no gain, no
        feature) is refused now, by the task's own :class:`StackError`; any other problem is the
        run's to report."""
        port = self.task_ports[name]
        try:
            connected = port.HasValue(self.system.own_context(context))  # evaluates the task
        except StackError:
            raise
        except Exception:  # another problem: the run reports it itself, from its own state
            return
        if not connected:
            raise StackError(f"{self.name}.push: the task {name!r} is not connected to the solver's input {name!r}")

    def up(self, name: object, context: Context | None = None) -> None:
        """Raise ``name`` (a task name, a task or a meta task) one level (swap with the task above it)."""
        self._move(name, -1, context)

    def down(self, name: object, context: Context | None = None) -> None:
        """Lower ``name`` (a task name, a task or a meta task) one level (swap with the task below it)."""
        self._move(name, +1, context)

    def _move(self, name: object, step: int, context: Context | None) -> None:
        name = self.task_name(name)

        def change(s: StackSettings) -> None:
            if name not in s.tasks:
                raise StackError(f"{self.name}: {name!r} is not in the stack {s.tasks}")
            i = s.tasks.index(name)
            j = i + step
            if not 0 <= j < len(s.tasks):
                raise StackError(f"{self.name}: {name!r} is already at the {'top' if step < 0 else 'bottom'} of the stack")
            s.tasks[i], s.tasks[j] = s.tasks[j], s.tasks[i]

        self._command(context, change)

    def pop(self, context: Context | None = None) -> None:
        """Remove the lowest-priority task."""

        def change(s: StackSettings) -> None:
            if not s.tasks:
                raise StackError(f"{self.name}.pop: the stack is empty")
            s.tasks.pop()

        self._command(context, change)

    def remove(self, name: object, context: Context | None = None) -> None:
        """Remove ``name`` (a task name, a task or a meta task) from the stack."""
        name = self.task_name(name)

        def change(s: StackSettings) -> None:
            if name not in s.tasks:
                raise StackError(f"{self.name}.remove: {name!r} is not in the stack {s.tasks}")
            s.tasks.remove(name)

        self._command(context, change)

    def clear(self, context: Context | None = None) -> None:
        """Empty the stack (the contacts stay)."""
        self._command(context, lambda s: s.tasks.clear())

    def stack(self, context: Context | None = None) -> list[str]:
        """Task names, highest priority first."""
        return list(self.settings(context).tasks)

    def solved_tasks(self, settings: StackSettings) -> tuple[str, ...]:
        """The names of the tasks ``settings``' stack solves: each task of the stack and, for a
        weighted level (:class:`~sotdrake.task_weight.TaskWeight`), each of its members."""
        groups = self.groups
        if not groups:
            return tuple(settings.tasks)
        return tuple(n for name in settings.tasks for n in (name, *groups.get(name, ())))

    # --- contacts (tasks solved as one level above the stack) -------------------------------
    def addContact(self, task, context: Context | None = None, priority: str = "top") -> None:
        """Add a contact: a task (or meta task).

        ``priority="top"`` (the default): the contact joins the contact level, solved above the whole
        stack, whatever is pushed before or after it (as the dynamic SoT's contacts, which are
        constraints); ``rmContact`` removes it. ``priority="bottom"``: sot-dyninv's kinematic
        ``SolverKine.addContact``, i.e. the meta task's ``keep()`` (its target ← where the op point is
        now) then ``push``: the contact is an ordinary task at the bottom of the stack, below every
        task pushed before it (a hand pushed first may then pull the feet); ``remove`` removes it.
        Given a task or a name, not a meta task, nothing is kept (the target stays as it is); the
        ``keep()`` reads the current pose, so ``"bottom"`` is refused inside ``attime``."""
        if priority not in ("top", "bottom"):
            raise InvalidInput(f"{self.name}.addContact: priority must be 'top' (the contact level, above the stack) "
                               f"or 'bottom' (keep() then push, the seed's SolverKine.addContact), got {priority!r}")
        name = self.task_name(task)
        self.check_solvable(name)
        if priority == "bottom":
            current = self.settings(context)
            if name in current.contacts or name in current.tasks:
                raise StackError(f"{self.name}.addContact: {name!r} is already a contact or in the stack")
            keep = getattr(task, "keep", None)
            if callable(keep):
                keep(context)
            self.push(name, context)
            return

        def change(s: StackSettings) -> None:
            if name in s.contacts or name in s.tasks:
                raise StackError(f"{self.name}.addContact: {name!r} is already a contact or in the stack")
            s.contacts.append(name)

        self._command(context, change)

    def rmContact(self, task, context: Context | None = None) -> None:
        """Remove a contact; removing the last one is refused."""
        name = self.task_name(task)

        def change(s: StackSettings) -> None:
            if name not in s.contacts:
                raise StackError(f"{self.name}.rmContact: {name!r} is not a contact {s.contacts}")
            if len(s.contacts) == 1:
                raise StackError(f"{self.name}.rmContact: {name!r} is the last contact; the robot would lose its support")
            s.contacts.remove(name)

        self._command(context, change)

    def contacts(self, context: Context | None = None) -> list[str]:
        return list(self.settings(context).contacts)

    # --- settings of the solve ---------------------------------------------------------------
    def setThreshold(self, svd_threshold: float, context: Context | None = None) -> None:
        """Singular values of ``J_i P_{i-1}`` at or below this are treated as zero (rank)."""
        if not finite_number(svd_threshold) or not 0 <= svd_threshold <= MAX_SVD_THRESHOLD:
            raise InvalidInput(f"svd_threshold must be a number in [0, {MAX_SVD_THRESHOLD:g}], got {svd_threshold!r}")
        self._command(context, lambda s: setattr(s, "svd_threshold", float(svd_threshold)))

    def setDamping(self, damping: float, context: Context | None = None) -> None:
        """True damping δ (``min ‖A x - r‖² + δ‖x‖²`` at each level); 0 for the pseudo-inverse."""
        if not finite_number(damping) or not 0 <= damping <= MAX_DAMPING:
            raise InvalidInput(f"damping must be a number in [0, {MAX_DAMPING:g}], got {damping!r}")
        self._command(context, lambda s: setattr(s, "damping", float(damping)))

    def setControlSelection(self, selection, context: Context | None = None) -> None:
        """Velocity components the solver may use (sot-core ``controlSelec``): nv booleans, or
        ``None`` for all. See :meth:`sotdrake.robot.Robot.velocity_selection`."""
        mask = None
        if selection is not None:
            mask = np.asarray(selection)
            if mask.dtype != bool or mask.shape != (self.nv,) or not mask.any():
                raise InvalidInput(f"control selection: expected {self.nv} booleans, at least one True, got {mask.dtype} {mask.shape}")
            mask = mask.copy()
        self._command(context, lambda s: setattr(s, "control_selection", mask))

    def setVelocityLimit(self, limit, context: Context | None = None) -> None:
        """Bound the command by ``limit`` (nv values > 0, ``inf`` for none; rad/s, m/s), scaling the
        whole solution uniformly when it exceeds them (:mod:`.velocity_scaling`); ``None``: no
        bound. ``add_sot`` sets the robot's joint limits and the base bound of :mod:`.base_velocity`."""
        value = None
        if limit is not None:
            try:
                value = np.asarray(limit, dtype=float).copy() if all_numbers(limit) else np.full(0, np.nan)
            except (TypeError, ValueError):
                value = np.full(0, np.nan)
            if value.shape != (self.nv,) or np.isnan(value).any() or not (value > 0).all():
                raise InvalidInput(f"{self.name}.setVelocityLimit: expected {self.nv} numbers > 0 (inf for none), got {limit!r:.200}")
        self._command(context, lambda s: setattr(s, "velocity_limit", value))

    def setStepLimit(self, step: float, context: Context | None = None) -> None:
        """Bound each component of the command by ``step / dt`` (``step`` in rad or m per tick, in
        ``(0, 1]``, or ``inf`` for none; default 7e-3): the linearised tasks then hold over a tick,
        held contacts within 0.1 mm at any control period (:mod:`.step_limit`). A solver without
        ``dt`` has no tick and ignores it."""
        value = check_step_limit(self.name, step)
        self._command(context, lambda s: setattr(s, "step_limit", value))


class StackSolver(Entity[S], Generic[S]):
    """A solver system with a :class:`Stack` (``stack_of_tasks``): the seed's stack commands under
    their names (``push``, ``up``, ``down``, ``remove``, ``pop``, ``clear``, ``stack``), each its
    stack's. Each solver adds the commands of its own contacts and settings."""

    stack_of_tasks: Stack

    @property
    def _task_ports(self) -> dict[str, InputPort]:
        return self.stack_of_tasks.task_ports

    def declare_task_input(self, task: Task | TaskWeight) -> InputPort:
        """The input port for ``task`` (a task, or a :class:`~sotdrake.task_weight.TaskWeight`
        group; created once); connect ``task.task`` to it."""
        return self.stack_of_tasks.declare_task_input(task)

    def check_task_input(self, task: Task | TaskWeight) -> None:
        """Whether :meth:`declare_task_input` would take ``task`` (:class:`InvalidInput` if not)."""
        self.stack_of_tasks.check_task_input(task)

    @property
    def known_tasks(self) -> list[str]:
        """The tasks this solver has an input for."""
        return self.stack_of_tasks.known_tasks

    def push(self, name: object, context: Context | None = None) -> None:
        """Append ``name`` (a task name, a task or a meta task) at the bottom (lowest priority) of
        the stack."""
        self.stack_of_tasks.push(name, context)

    def up(self, name: object, context: Context | None = None) -> None:
        """Raise ``name`` (a task name, a task or a meta task) one level (swap with the task above it)."""
        self.stack_of_tasks.up(name, context)

    def down(self, name: object, context: Context | None = None) -> None:
        """Lower ``name`` (a task name, a task or a meta task) one level (swap with the task below it)."""
        self.stack_of_tasks.down(name, context)

    def pop(self, context: Context | None = None) -> None:
        """Remove the lowest-priority task."""
        self.stack_of_tasks.pop(context)

    def remove(self, name: object, context: Context | None = None) -> None:
        """Remove ``name`` (a task name, a task or a meta task) from the stack."""
        self.stack_of_tasks.remove(name, context)

    def rm(self, name: object, context: Context | None = None) -> None:
        """:meth:`remove` under sot-dyninv's name (its scripts' ``sot.rm(task.name)``)."""
        self.stack_of_tasks.remove(name, context)

    def clear(self, context: Context | None = None) -> None:
        """Empty the stack (the contacts stay)."""
        self.stack_of_tasks.clear(context)

    def stack(self, context: Context | None = None) -> list[str]:
        """Task names, highest priority first."""
        return self.stack_of_tasks.stack(context)

    def solved_tasks(self, settings: StackSettings) -> tuple[str, ...]:
        """The tasks ``settings``' stack solves, the members of a weighted level included."""
        return self.stack_of_tasks.solved_tasks(settings)

    def setControlSelection(self, selection, context: Context | None = None) -> None:
        """Velocity components the solver may use (sot-core ``controlSelec``): nv booleans, or
        ``None`` for all. See :meth:`sotdrake.robot.Robot.velocity_selection`."""
        self.stack_of_tasks.setControlSelection(selection, context)
