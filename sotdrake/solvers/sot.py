"""The ``SOT`` entity: the stack of tasks and the basic cascade solver around it.

Input ports: one per task known to the solver, named after the task, carrying its
:class:`~sotdrake.task.TaskLevel`. Only the tasks in the stack are evaluated. The stack (task names,
highest priority first), the contacts, the SVD threshold and the damping are the entity's settings,
held in the Context (see :mod:`sotdrake.entity`); ``push`` appends at the lowest priority, as in
sot-core. Contacts (``addContact``/``rmContact``, sot-dyninv) are tasks solved together as one level
above the whole stack; the last contact cannot be removed (the robot would lose its support).
``addContact(task, priority="bottom")`` is sot-dyninv's kinematic ``addContact`` instead: ``keep()``
then ``push``, the contact an ordinary task at the bottom of the stack.

Outputs: ``control`` (``v``, size nv, Drake generalized velocities) and ``residuals`` (per level,
``‖J_i v - ė_i*‖``). An empty stack gives ``v = 0``: the robot holds still.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, InputPort, ValueProducer

from ..configuration import Layout
from ..entity import Entity
from ..exceptions import InvalidInput, SolverError, StackError, TaskNotFound
from ..task import Task, TaskLevel
from ..task_weight import TaskWeight
from .cascade import CascadeResult, cascade_factorization, cascade_residuals
from .second_order import curvature_correction
from .step_limit import DEFAULT_STEP_LIMIT, check_step_limit
from .velocity_scaling import scale_to_limits, velocity_scale

log = logging.getLogger("sotdrake.sot")


class _Levels(list):
    """The levels a solver solves (a list of :class:`TaskLevel`), and ``tasks``: each task's name
    and Jacobian, in the order of the contacts, then the stack (the contacts are one level)."""

    tasks: list[tuple[str, np.ndarray]]


class _CascadeSolution:
    """The cascade's velocity, ranks and the uniform scale applied to fit the velocity limits (1: none);
    the residuals are computed when the ``residuals`` output is read (most ticks only need the
    velocity). ``tasks``: each task's name and Jacobian (what the last tick keeps)."""

    def __init__(self, velocity: np.ndarray, ranks: np.ndarray, levels: list[tuple[np.ndarray, np.ndarray]],
                 scale: float = 1.0, tasks: list[tuple[str, np.ndarray]] | None = None):
        self.velocity, self.ranks, self._levels = velocity, ranks, levels
        self._residuals: np.ndarray | None = None
        self.scale = scale
        self.tasks = tasks or []

    @property
    def residuals(self) -> np.ndarray:
        if self._residuals is None:
            self._residuals = cascade_residuals(self._levels, self.velocity)
        return self._residuals


#: Accepted ranges: the SVD threshold (a singular value, unit of the Jacobian) and the damping δ.
MAX_SVD_THRESHOLD = 1.0
MAX_DAMPING = 1e4


def _real(value) -> bool:
    return isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool) and bool(np.isfinite(value))


@dataclass
class StackSettings:
    tasks: list[str] = field(default_factory=list)
    contacts: list[str] = field(default_factory=list)
    svd_threshold: float = 1e-4
    damping: float = 0.0
    control_selection: np.ndarray | None = None  # nv booleans; None: every component
    velocity_limit: np.ndarray | None = None  # nv limits > 0 (inf: none); None: no scaling
    step_limit: float = DEFAULT_STEP_LIMIT  # rad or m per tick (inf: none), see .step_limit


class SOT(Entity[StackSettings]):
    """Strict-priority kinematic solver (sot-core ``SOT``)."""

    accepts_inequalities = False

    def __init__(
        self,
        name: str,
        nv: int,
        svd_threshold: float = 1e-4,
        damping: float = 0.0,
        settings: StackSettings | None = None,
        dt: float | None = None,
        layout: Layout | None = None,
    ):
        """``dt`` (the control period, s): with it, the solver corrects each level for the curvature
        of the tick (:mod:`.second_order`), its last command ``v`` and each level's ``J v`` kept in
        the Context (discrete state, updated every ``dt``). ``layout`` (of the robot's ``q``): for a
        solver that reads ``q`` on a ``position`` input (``SolverKine``'s joint limits)."""
        Entity.__init__(self, name, settings or StackSettings())
        self.nv = nv
        self.dt = dt
        if dt is not None:
            if not (isinstance(dt, (int, float)) and np.isfinite(dt) and dt > 0):
                raise InvalidInput(f"{name}: dt must be a number > 0 (s), got {dt!r}")
        self.layout = layout
        self.position = None
        if layout is not None:
            self.position = self.DeclareVectorInputPort("position", layout.nq)
        # The last tick (discrete state): [1, v] (or [0, …] before the first tick), and per task
        # [rows, J v] (rows -1: not in the stack, or more rows than nv).
        self._last_velocity: int | None = None
        self._last_task_velocity: dict[str, int] = {}
        if dt is not None:
            self._last_velocity = int(self.DeclareDiscreteState(np.zeros(1 + nv)))
            self.DeclarePeriodicDiscreteUpdateEvent(dt, 0.0, self._remember)
        self.setThreshold(svd_threshold)
        self.setDamping(damping)
        self._task_ports: dict[str, InputPort] = {}
        self._task_systems: dict[str, object] = {}  # the task system behind each port (its identity)
        self._inequality_tasks: set[str] = set()
        self._groups: dict[str, tuple[str, ...]] = {}  # weighted levels (TaskWeight): their members
        empty = CascadeResult(np.zeros(nv), np.zeros(0), np.zeros(0, dtype=int))
        # The solution depends on the inputs, the settings and the last tick; the last tick is
        # left out of the prerequisites: it changes only in the update that also moves the
        # device (so the inputs change with it), and the solve a publisher asked for after a tick
        # is the one the next tick uses. (A tick with v = 0 exactly leaves q, hence the cached
        # solution, as they were.)
        self._solution = self.DeclareCacheEntry(
            "solution",
            ValueProducer(allocate=lambda: AbstractValue.Make(empty), calc=self._calc),
            prerequisites_of_calc=self._solution_prerequisites(),
        )
        self.DeclareVectorOutputPort("control", nv, lambda c, o: o.SetFromVector(self._solution.Eval(c).velocity))
        self.DeclareAbstractOutputPort(
            "residuals", lambda: AbstractValue.Make(np.zeros(0)), lambda c, o: o.set_value(self._solution.Eval(c).residuals)
        )
        # s of the velocity scaling (1: the stack's solution was within the limits).
        self.DeclareVectorOutputPort(
            "velocity_scale", 1, lambda c, o: o.SetAtIndex(0, getattr(self._solution.Eval(c), "scale", 1.0))
        )
        self._warned_scaling = False  # logging only: warn once per solver, results never depend on it

    def _solution_prerequisites(self) -> set:
        """Every source of the solution but time (the references reach it through the inputs) and,
        with ``dt``, the last tick: the inputs, the parameters, the settings, and the numeric state
        of a solver without ``dt`` (``SolverDyn``'s contact ramps)."""
        tickets = {self.all_input_ports_ticket(), self.all_parameters_ticket(), self.xc_ticket(),
                   self.abstract_state_ticket(self._settings_index)}
        return tickets if self.dt is not None else tickets | {self.xd_ticket()}

    # --- wiring (build time) ---------------------------------------------------------------
    def declare_task_input(self, task: Task | TaskWeight) -> InputPort:
        """The input port for ``task`` (a task, or a :class:`~sotdrake.task_weight.TaskWeight`
        group; created once); connect ``task.task`` to it."""
        if task.nv != self.nv:
            raise InvalidInput(f"task {task.name} has nv = {task.nv}, solver {self.name} has nv = {self.nv}")
        if task.name not in self._task_ports:
            self._task_systems[task.name] = task
            self._task_ports[task.name] = self.DeclareAbstractInputPort(
                task.name, AbstractValue.Make(TaskLevel(np.zeros((0, self.nv)), np.zeros(0), np.zeros(0), np.zeros(0)))
            )
            if task.is_inequality:
                self._inequality_tasks.add(task.name)
            if isinstance(task, TaskWeight):
                self._groups[task.name] = task.members
            if self._last_velocity is not None:
                self._last_task_velocity[task.name] = int(self.DeclareDiscreteState(np.full(1 + self.nv, -1.0)))
        return self._task_ports[task.name]

    @property
    def known_tasks(self) -> list[str]:
        return list(self._task_ports)

    def _known(self, name: object) -> str:
        if not isinstance(name, str):
            raise TaskNotFound(f"{name!r:.80}", list(self._task_ports)).but(
                f"{self.name} expects a task name (str), a task or a meta task, got a {type(name).__name__}")
        if name not in self._task_ports:
            raise TaskNotFound(name, list(self._task_ports))
        return name

    def _task_name(self, task: object) -> str:
        """The known task name of a name, a ``Task`` or a meta task (its ``.task``); a task object
        must be the one this solver reads (not another robot's task of the same name)."""
        system = getattr(task, "task", task)
        name = self._known(getattr(system, "name", task))
        if not isinstance(task, str) and self._task_systems.get(name) is not system:
            raise StackError(f"{self.name}: the task {name!r} given is not the one this solver reads (a task of another "
                             "robot or diagram?): give this robot's task, or its name")
        return name

    # --- stack commands (sot-core names) ---------------------------------------------------
    def push(self, name: object, context: Context | None = None) -> None:
        """Append ``name`` (a task name, a task or a meta task) at the bottom (lowest priority) of
        the stack."""
        name = self._task_name(name)
        self._check_solvable(name)
        if context is not None:
            self._check_connected(name, context)

        def change(s: StackSettings) -> None:
            if name in s.tasks or name in s.contacts:
                raise StackError(f"{self.name}.push: {name!r} is already in the stack {s.tasks} or contacts {s.contacts}")
            s.tasks.append(name)

        self._command(context, change)

    def _check_solvable(self, name: str) -> None:
        if name in self._inequality_tasks and not self.accepts_inequalities:
            raise StackError(
                f"{self.name} is a {type(self).__name__}, which cannot solve the inequality task {name!r}: "
                "the solvers that take inequality rows are SolverKine (the hierarchical QP: add_sot(robot, solver='hqp')) "
                "and SolverDyn"
            )

    def _check_connected(self, name: str, context: Context) -> None:
        """Into a running stack (a ``context`` given), a task that cannot be evaluated (no gain, no
        feature) is refused now, by the task's own :class:`StackError`; any other problem is the
        run's to report."""
        port = self._task_ports[name]
        try:
            connected = port.HasValue(self.own_context(context))  # evaluates the task
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
        name = self._task_name(name)

        def change(s: StackSettings) -> None:
            if name not in s.tasks:
                raise StackError(f"{self.name}: {name!r} is not in the stack {s.tasks}")
            i = s.tasks.index(name)
            j = i + step
            if not 0 <= j < len(s.tasks):
                raise StackError(f"{self.name}: {name!r} is already at the {'top' if step < 0 else 'bottom'} of the stack")
            s.tasks[i], s.tasks[j] = s.tasks[j], s.tasks[i]

        self._command(context, change)

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
        name = self._task_name(task)
        if priority == "bottom":
            current = self.settings(context)
            if name in current.contacts or name in current.tasks:
                raise StackError(f"{self.name}.addContact: {name!r} is already a contact or in the stack")
            self._check_solvable(name)
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
        name = self._task_name(task)

        def change(s: StackSettings) -> None:
            if name not in s.contacts:
                raise StackError(f"{self.name}.rmContact: {name!r} is not a contact {s.contacts}")
            if len(s.contacts) == 1:
                raise StackError(f"{self.name}.rmContact: {name!r} is the last contact; the robot would lose its support")
            s.contacts.remove(name)

        self._command(context, change)

    def contacts(self, context: Context | None = None) -> list[str]:
        return list(self.settings(context).contacts)

    def pop(self, context: Context | None = None) -> None:
        """Remove the lowest-priority task."""

        def change(s: StackSettings) -> None:
            if not s.tasks:
                raise StackError(f"{self.name}.pop: the stack is empty")
            s.tasks.pop()

        self._command(context, change)

    def remove(self, name: object, context: Context | None = None) -> None:
        """Remove ``name`` (a task name, a task or a meta task) from the stack."""
        name = self._task_name(name)

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
        groups = self._groups
        if not groups:
            return tuple(settings.tasks)
        return tuple(n for name in settings.tasks for n in (name, *groups.get(name, ())))

    def setThreshold(self, svd_threshold: float, context: Context | None = None) -> None:
        """Singular values of ``J_i P_{i-1}`` at or below this are treated as zero (rank)."""
        if not _real(svd_threshold) or not 0 <= svd_threshold <= MAX_SVD_THRESHOLD:
            raise InvalidInput(f"svd_threshold must be a number in [0, {MAX_SVD_THRESHOLD:g}], got {svd_threshold!r}")
        self._command(context, lambda s: setattr(s, "svd_threshold", float(svd_threshold)))

    def setDamping(self, damping: float, context: Context | None = None) -> None:
        """True damping δ (``min ‖A x - r‖² + δ‖x‖²`` at each level); 0 for the pseudo-inverse."""
        if not _real(damping) or not 0 <= damping <= MAX_DAMPING:
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
                value = np.asarray(limit, dtype=float).copy()
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

    def _velocity_limit(self, s: StackSettings) -> np.ndarray | None:
        """The bound of the command: the velocity limit and the step limit's ``δ / dt``, or None."""
        if self.dt is None or s.step_limit == np.inf:
            return s.velocity_limit
        cap = s.step_limit / self.dt
        if s.velocity_limit is None:
            return np.full(self.nv, cap)
        return np.minimum(s.velocity_limit, cap)

    # --- solve -----------------------------------------------------------------------------
    def _remember(self, context: Context, discrete_state) -> None:
        """Keep this tick's command ``v`` and each level's ``J v`` (see :mod:`.second_order`). Drake
        computes every discrete update of a tick from the same context, so the device moves with
        the ``v`` kept here."""
        solution = self._solution.Eval(context)
        v = solution.velocity
        discrete_state.set_value(self._last_velocity, np.concatenate(([1.0], v)))
        indices = self._last_task_velocity
        kept_rows = dict.fromkeys(indices, -1)  # -1: not in the stack (or more rows than nv)
        for name, J in solution.tasks:
            if J.shape[0] <= self.nv:
                y = J @ v
                kept = discrete_state.get_mutable_value(indices[name])
                kept[0], kept[1 : 1 + y.size] = y.size, y
                kept_rows[name] = y.size
        for name, rows in kept_rows.items():
            if rows < 0:
                discrete_state.get_mutable_value(indices[name])[0] = -1.0

    def _last_tick(self, context: Context, names: list[str]) -> tuple[np.ndarray, dict[str, np.ndarray]] | None:
        """``(v_{k-1}, {task: J_{k-1} v_{k-1}})`` of the last tick for the tasks ``names``, or None
        before the first."""
        state = context.get_discrete_state()
        kept = state.get_value(self._last_velocity)
        if kept[0] != 1.0:
            return None
        task_velocities = {}
        indices = self._last_task_velocity
        for name in names:
            y = state.get_value(indices[name])
            if y[0] >= 0:
                task_velocities[name] = y[1 : 1 + int(y[0])]
        return kept[1:], task_velocities

    def _levels(self, context: Context, settings: StackSettings, check: bool = True, correct: bool = True) -> _Levels:
        """The levels, highest first (the contacts stacked as one level, then the stack), checked
        (with ``check``): sizes fit nv, no NaN (±inf only as inequality bounds); with ``dt`` and
        ``correct``, each level's reference corrected for the curvature of the tick (:mod:`.second_order`)."""
        levels = _Levels()
        levels.tasks = []
        names = [*settings.contacts, *settings.tasks] if settings.contacts else settings.tasks
        last_tick = None
        if correct and self._last_velocity is not None:
            last_tick = self._last_tick(context, names)
        ports = self._task_ports
        for name in names:
            level = ports[name].Eval(context)
            J = level.jacobian
            levels.tasks.append((name, J))
            if check:
                if J.ndim != 2 or J.shape[1] != self.nv or level.lower.shape != (J.shape[0],) or level.upper.shape != (J.shape[0],):
                    raise SolverError(f"task {name}: jacobian {J.shape} and bounds {level.lower.shape} do not fit nv = {self.nv}")
                if not np.isfinite(J).all() or np.isnan(level.lower).any() or np.isnan(level.upper).any():
                    raise SolverError(f"task {name}: non-finite jacobian or reference at t = {context.get_time()}")
                if level.is_equality and not np.isfinite(level.lower).all():
                    raise SolverError(f"task {name}: non-finite reference at t = {context.get_time()}")
            if last_tick is not None:
                correction = curvature_correction(J, last_tick[0], last_tick[1].get(name))
                if correction is not None:
                    lower = level.lower - correction
                    upper = lower if level.upper is level.lower else level.upper - correction
                    level = TaskLevel(J, lower, upper, level.error)
            levels.append(level)
        if settings.contacts:
            count = len(settings.contacts)
            contacts = levels[:count]
            J = np.vstack([c.jacobian for c in contacts])
            lower = np.concatenate([c.lower for c in contacts])
            upper = lower if all(c.is_equality for c in contacts) else np.concatenate([c.upper for c in contacts])
            levels[:count] = [TaskLevel(J, lower, upper, np.concatenate([c.error for c in contacts]))]
        return levels

    def _calc(self, context: Context, value: AbstractValue) -> None:
        s = self._settings_of(context)
        # The checks of every level's values run only when the solve goes wrong (to name the
        # task); the shapes and the equality of each level are checked on every tick.
        levels = self._levels(context, s, check=False)
        nv = self.nv
        for level in levels:
            J = level.jacobian
            if J.ndim != 2 or J.shape[1] != nv or level.lower.shape != (J.shape[0],) or level.upper.shape != (J.shape[0],):
                self._levels(context, s)  # raises, naming the task
            if not level.is_equality:
                self._levels(context, s)  # a NaN makes unequal bounds: named first
                raise SolverError(f"{self.name} cannot solve inequality rows: use the hierarchical QP")
        pairs = [(level.jacobian, level.reference) for level in levels]
        try:
            result = cascade_factorization(pairs, nv, s.svd_threshold, s.damping, s.control_selection)
        except (SolverError, ValueError, np.linalg.LinAlgError):
            result = None
        if result is None or not math.isfinite(result.velocity.sum() + sum(r.sum() for _, r in pairs)):
            self._levels(context, s)  # a non-finite level: raises, naming the task
            raise SolverError(f"{self.name}: the cascade gave a non-finite control at t = {context.get_time()}")
        velocity, scale = result.velocity, 1.0
        limit = self._velocity_limit(s)
        if limit is not None:
            scale = velocity_scale(velocity, limit)
            if scale < 1.0:
                # The cascade is linear in the references (for its rank decisions, which depend on
                # the Jacobians only): scale the tasks' ė* but not the curvature correction c (its
                # size is the one of the scaled motion), i.e. solve the same factorisation for
                # s·ė* - c = s·(ė* - c) - (1 - s)·c, then keep within the limits.
                plain = [level.reference for level in self._levels(context, s, check=False, correct=False)]
                pairs = [(J, scale * r - (1.0 - scale) * (p - r)) for (J, r), p in zip(pairs, plain, strict=False)]
                velocity, second = scale_to_limits(result.solve([r for _, r in pairs]), limit)
                scale *= second
                if not self._warned_scaling:
                    self._warned_scaling = True
                    log.warning("%s: t = %.3f s: the stack asks more than the velocity (or step) limits; the command is "
                                "scaled by %.3g (warned once)", self.name, context.get_time(), scale)
        value.set_value(_CascadeSolution(velocity, result.ranks, pairs, scale, levels.tasks))
