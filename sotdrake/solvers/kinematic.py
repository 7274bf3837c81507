"""What the two kinematic solvers (``SOT`` and ``SolverKine``) share besides their :class:`.stack.Stack`:
the control period and the last tick kept in the Context (for the curvature correction of
:mod:`.second_order`), the levels read from the task inputs, the kinematic settings and contacts,
and the ports ``control`` / ``residuals`` / ``velocity_scale`` / ``step_bound``. Each solver brings its own solve
(``_calc``, the ``solution`` cache entry's calc)."""

from __future__ import annotations

from typing import Any

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, ValueProducer

from ..configuration import Layout
from ..exceptions import InvalidInput, SolverError, finite_number
from ..hqp.cascade import CascadeResult
from ..task import TaskLevel
from .second_order import corrected_bounds, curvature_correction, keyed_curvature_correction
from .stack import S, Stack, StackSettings, StackSolver


class _Levels(list):
    """The levels a solver solves (a list of :class:`TaskLevel`), and ``tasks``: each task's name
    and Jacobian, in the order of the contacts, then the stack (the contacts are one level);
    ``plain``: each level's ``lower`` before the curvature correction (the same array when none)."""

    tasks: list[tuple[str, np.ndarray, np.ndarray | None]]
    plain: list[np.ndarray]


class KinematicSolver(StackSolver[S]):
    """A kinematic solver of the stack: ``v`` (Drake generalized velocities, nv) from the levels.
    See :class:`~.sot.SOT` and :class:`~.solver_kine.SolverKine`.

    Inputs: one per task (named after it, a :class:`~sotdrake.task.TaskLevel` over ``v``) and,
    with a ``layout``, ``position`` (``q``, nq, Drake's positions). Outputs: ``control`` (``v``, nv,
    rad/s and m/s), ``residuals`` (per level, the norm of what it misses, unit/s of its task) and
    ``velocity_scale`` (1-vector: the uniform scale the command was given to fit the velocity and
    step limits, 1 when none) and ``step_bound`` (nv: the largest ``|v_j| dt`` the settings allow,
    rad or m, inf for none: what a collision level reads).
    """

    accepts_inequalities = False

    def __init__(self, name: str, nv: int, settings: S, svd_threshold: float = 1e-4, damping: float = 0.0,
                 dt: float | None = None, layout: Layout | None = None):
        """``dt`` (the control period, s): with it, the solver corrects each level for the curvature
        of the tick (:mod:`.second_order`), its last command ``v`` and each level's ``J v`` kept in
        the Context (discrete state, updated every ``dt``). ``layout`` (of the robot's ``q``): for a
        solver that reads ``q`` on a ``position`` input (``SolverKine``'s joint limits)."""
        StackSolver.__init__(self, name, settings)
        self.nv = nv
        self.dt = dt
        if dt is not None:
            if not (finite_number(dt) and dt > 0):
                raise InvalidInput(f"{name}: dt must be a number > 0 (s), got {dt!r}")
        self.layout = layout
        self.position = None
        if layout is not None:
            self.position = self.DeclareVectorInputPort("position", layout.nq)
        # The last tick (discrete state): [1, v] (or [0, …] before the first tick), and per task
        # [rows, J v, the rows' keys] (rows -1: not in the stack, or more rows than nv; keys -1: fixed rows).
        self._last_velocity: int | None = None
        self._last_task_velocity: dict[str, int] = {}
        if dt is not None:
            self._last_velocity = int(self.DeclareDiscreteState(np.zeros(1 + nv)))
            self.DeclarePeriodicDiscreteUpdateEvent(dt, 0.0, self._remember)
        self.stack_of_tasks = Stack(self, nv, self.accepts_inequalities, self._declare_task_memory)
        self.stack_of_tasks.setThreshold(svd_threshold)  # (SolverKine refuses the command: no SVD truncation)
        self.setDamping(damping)
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
        # The largest |v_j| dt a tick may command (rad or m; inf: no bound), from the settings alone:
        # what a collision level needs to know which pairs one tick can bring within reach.
        self.DeclareVectorOutputPort("step_bound", nv, self._calc_step_bound,
                                     prerequisites_of_calc={self.abstract_state_ticket(self._settings_index)})

    def _calc(self, context: Context, value: AbstractValue) -> None:
        raise NotImplementedError

    def _solution_prerequisites(self) -> set:
        """Every source of the solution but time (the references reach it through the inputs) and,
        with ``dt``, the last tick: the inputs, the parameters, the settings, and the numeric state."""
        tickets = {self.all_input_ports_ticket(), self.all_parameters_ticket(), self.xc_ticket(),
                   self.abstract_state_ticket(self._settings_index)}
        return tickets if self.dt is not None else tickets | {self.xd_ticket()}

    def _declare_task_memory(self, name: str) -> None:
        if self._last_velocity is not None:
            self._last_task_velocity[name] = int(self.DeclareDiscreteState(np.full(1 + 2 * self.nv, -1.0)))

    # --- contacts and settings (the stack's) ---------------------------------------------------
    def addContact(self, task, context: Context | None = None, priority: str = "top") -> None:
        """Add a contact (a task or meta task): see :meth:`.stack.Stack.addContact` (``priority``
        ``"top"``: the contact level above the stack; ``"bottom"``: ``keep()`` then ``push``)."""
        self.stack_of_tasks.addContact(task, context, priority)

    def rmContact(self, task, context: Context | None = None) -> None:
        """Remove a contact; removing the last one is refused."""
        self.stack_of_tasks.rmContact(task, context)

    def contacts(self, context: Context | None = None) -> list[str]:
        """The contacts' task names."""
        return self.stack_of_tasks.contacts(context)

    def setThreshold(self, svd_threshold: float, context: Context | None = None) -> None:
        """Singular values of ``J_i P_{i-1}`` at or below this are treated as zero (rank)."""
        self.stack_of_tasks.setThreshold(svd_threshold, context)

    def setDamping(self, damping: float, context: Context | None = None) -> None:
        """True damping δ (``min ‖A x - r‖² + δ‖x‖²`` at each level); 0 for the pseudo-inverse."""
        self.stack_of_tasks.setDamping(damping, context)

    def setVelocityLimit(self, limit, context: Context | None = None) -> None:
        """Bound the command by ``limit`` (nv values > 0, ``inf`` for none; rad/s, m/s); ``None``: no
        bound. See :meth:`.stack.Stack.setVelocityLimit`."""
        self.stack_of_tasks.setVelocityLimit(limit, context)

    def setStepLimit(self, step: float, context: Context | None = None) -> None:
        """Bound each component of the command by ``step / dt`` (rad or m per tick, in ``(0, 1]``,
        or ``inf`` for none). See :meth:`.stack.Stack.setStepLimit`."""
        self.stack_of_tasks.setStepLimit(step, context)

    def _calc_step_bound(self, context: Context, output) -> None:
        limit = self._velocity_limit(self._settings_of(context))
        if limit is None or self.dt is None:
            output.SetFromVector(np.full(self.nv, np.inf))
        else:
            output.SetFromVector(np.asarray(limit) * self.dt)

    def _velocity_limit(self, s: StackSettings) -> np.ndarray | None:
        """The bound of the command: the velocity limit and the step limit's ``δ / dt``, or None."""
        if self.dt is None or s.step_limit == np.inf:
            return s.velocity_limit
        cap = s.step_limit / self.dt
        if s.velocity_limit is None:
            return np.full(self.nv, cap)
        return np.minimum(s.velocity_limit, cap)

    # --- the last tick and the levels ----------------------------------------------------------
    def _remember(self, context: Context, discrete_state) -> None:
        """Keep this tick's command ``v`` and each level's ``J v`` and row keys (see :mod:`.second_order`). Drake
        computes every discrete update of a tick from the same context, so the device moves with
        the ``v`` kept here."""
        solution = self._solution.Eval(context)
        v = solution.velocity
        discrete_state.set_value(self._last_velocity, np.concatenate(([1.0], v)))
        indices = self._last_task_velocity
        kept_rows = dict.fromkeys(indices, -1)  # -1: not in the stack (or more rows than nv)
        nv = self.nv
        for name, J, keys in solution.tasks:
            if J.shape[0] <= nv:
                y = J @ v
                kept = discrete_state.get_mutable_value(indices[name])
                kept[0], kept[1 : 1 + y.size] = y.size, y
                kept[1 + nv : 1 + nv + y.size] = -1.0 if keys is None else keys
                kept_rows[name] = y.size
        for name, rows in kept_rows.items():
            if rows < 0:
                discrete_state.get_mutable_value(indices[name])[0] = -1.0

    def _last_tick(self, context: Context, names: list[str]) -> tuple[np.ndarray, dict[str, tuple[np.ndarray, np.ndarray]]] | None:
        """``(v_{k-1}, {task: (J_{k-1} v_{k-1}, its rows' keys)})`` of the last tick for the tasks
        ``names`` (keys -1: a task's fixed rows), or None before the first."""
        state = context.get_discrete_state()
        kept = state.get_value(self._last_velocity)
        if kept[0] != 1.0:
            return None
        task_velocities = {}
        indices = self._last_task_velocity
        for name in names:
            y = state.get_value(indices[name])
            if y[0] >= 0:
                rows = int(y[0])
                task_velocities[name] = (y[1 : 1 + rows], y[1 + self.nv : 1 + self.nv + rows])
        return kept[1:], task_velocities

    def _levels(self, context: Context, settings: StackSettings, check: bool = True, correct: bool = True) -> _Levels:
        """The levels, highest first (the contacts stacked as one level, then the stack), checked
        (with ``check``): sizes fit nv, no NaN (±inf only as inequality bounds); with ``dt`` and
        ``correct``, each level's reference corrected for the curvature of the tick (:mod:`.second_order`)."""
        levels = _Levels()
        levels.tasks = []
        levels.plain = plain = []
        names = [*settings.contacts, *settings.tasks] if settings.contacts else settings.tasks
        last_tick = None
        if correct and self._last_velocity is not None:
            last_tick = self._last_tick(context, names)
        ports = self.stack_of_tasks.task_ports
        for name in names:
            level = ports[name].Eval(context)
            J = level.jacobian
            levels.tasks.append((name, J, level.row_keys))
            if check:
                _check_level(name, level, self.nv, context)
            plain.append(level.lower)
            if last_tick is not None:
                previous = last_tick[1].get(name)
                if level.row_keys is None:
                    correction = curvature_correction(J, last_tick[0], None if previous is None else previous[0])
                else:  # (rows that come and go: each matched with its own row of the last tick)
                    correction = keyed_curvature_correction(J, level.row_keys, last_tick[0], previous)
                if correction is not None:
                    lower, upper = corrected_bounds(level.lower, level.upper, correction)
                    level = TaskLevel(J, lower, upper, level.error, level.row_keys)
            levels.append(level)
        if settings.contacts:
            count = len(settings.contacts)
            contacts = levels[:count]
            J = np.vstack([c.jacobian for c in contacts])
            lower = np.concatenate([c.lower for c in contacts])
            upper = lower if all(c.is_equality for c in contacts) else np.concatenate([c.upper for c in contacts])
            levels[:count] = [TaskLevel(J, lower, upper, np.concatenate([c.error for c in contacts]))]
            plain[:count] = [np.concatenate(plain[:count])]
        return levels


def _check_level(name: str, level: Any, nv: int, context: Context) -> None:
    """Refuse (:class:`SolverError`, naming the task) a level whose sizes do not fit nv or whose
    values are not finite (±inf only as inequality bounds)."""
    J = level.jacobian
    if J.ndim != 2 or J.shape[1] != nv or level.lower.shape != (J.shape[0],) or level.upper.shape != (J.shape[0],):
        raise SolverError(f"task {name}: jacobian {J.shape} and bounds {level.lower.shape} do not fit nv = {nv}")
    if not np.isfinite(J).all() or np.isnan(level.lower).any() or np.isnan(level.upper).any():
        raise SolverError(f"task {name}: non-finite jacobian or reference at t = {context.get_time()}")
    if level.is_equality and not np.isfinite(level.lower).all():
        raise SolverError(f"task {name}: non-finite reference at t = {context.get_time()}")
