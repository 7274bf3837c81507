"""``SolverKine``: the stack solved as a hierarchical QP, with joint limits as hard constraints.

The same stack as :class:`~sotdrake.solvers.sot.SOT` (a :class:`~.stack.Stack`: same task inputs,
same stack commands, the stack in the Context), plus a ``position`` input (``q``, from the device)
for the joint limits, which become velocity bounds over one tick (:mod:`.limits`) above every task. Inequality tasks
(``TaskInequality``) mix freely with equality tasks in any level.

The stack is solved by the paths :data:`~sotdrake.hqp.stack_paths.KINEMATIC` declares: a stack of
equality tasks first at once, by one QR from the last tick's active limits, verified
(:mod:`~sotdrake.hqp.equality_stack`), or by the QR sweep from the same limits when a level has
more rows than what is left free (a posture task at the bottom,
:class:`~sotdrake.hqp.stack_paths.WarmQrSweep`); a stack with inequality rows whose equality rows
can all be met by the same QR on its equality rows and the inequality rows it has to hold at a
bound (:class:`~sotdrake.hqp.stack_paths.HeldRows`); then level by level when none applies or verifies.

``setAccelerationLimit(a_max)`` adds hard bounds ``|v − v_prev| ≤ a_max dt`` on each joint (the
last command ``v_prev`` kept in the Context), combined with the position and velocity limits and the
braking distance (:mod:`.acceleration_limits`).

Outputs: ``control`` (``v``), ``residuals`` (the optimal slack norm of each level) and
``diagnostics`` (:class:`HqpDiagnostics`). If a level cannot be solved the control is zero (the
device holds), ``diagnostics.failure`` says which level and why, and a warning is logged.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field, replace
from typing import cast

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, InputPort

from ..configuration import Layout
from ..exceptions import InvalidInput, SolverError, StackError, finite_number
from ..hqp import ACTIVE_SET, HierarchicalQP, HqpResult, check_solver
from ..hqp.stack_paths import KINEMATIC, StackProblem, solve_stack
from ..hqp.warm import WarmStart
from ..robots import RobotModel
from ..task import TaskLevel
from .acceleration_limits import MAX_ACCELERATION, AccelerationBounds
from .base_velocity import MAX_BASE_VELOCITY, default_base_velocity_limit
from .kinematic import KinematicSolver
from .limits import VelocityBounds
from .stack import StackSettings
from .step_limit import clip_bounds
from .unmet_rows import keep_met_rows, keyed_inequality

log = logging.getLogger("sotdrake.solver_kine")


@dataclass
class HqpSettings(StackSettings):
    position_margin: float = 1e-3  # rad (or m): joints stop this far from their position limits
    solver: str = ACTIVE_SET
    base_velocity_limit: tuple[float, float] | None = None  # (rad/s, m/s), see .base_velocity
    acceleration_limit: np.ndarray | None = None  # nv limits > 0 (inf: none; rad/s², m/s²), see .acceleration_limits


@dataclass
class HqpDiagnostics:
    """Per-level results of one tick: ``slack_norms``, ``active_rows`` (inequality rows at a bound),
    ``active_limits`` (velocity components at a joint-limit bound), ``level_solvers`` (per stage:
    "active-set", "<Drake solver>+polish", or the whole-stack path that answered: "active-bounds",
    "qr"), ``solve_time_s``, and ``failure`` (a message, or empty)."""

    tasks: list[str] = field(default_factory=list)
    slack_norms: np.ndarray = field(default_factory=lambda: np.zeros(0))
    active_rows: list[np.ndarray] = field(default_factory=list)
    active_limits: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    level_solvers: list[str] = field(default_factory=list)
    solve_time_s: float = 0.0
    max_iterations: int = 0  # active-set iterations of the stage that needed most (0: every guess held)
    fallbacks: list[str] = field(default_factory=list)  # paths that failed before another succeeded
    failure: str = ""


class SolverKine(KinematicSolver[HqpSettings]):
    """Hierarchical-QP kinematic solver (sot-dyninv ``SolverKine``).

    Inputs: one per task (a :class:`~sotdrake.task.TaskLevel` over ``v``) and ``position`` (``q``,
    nq, for the joint limits). Outputs: ``control`` (``v``, nv, rad/s and m/s), ``residuals`` (the
    optimal slack norm of each level), ``velocity_scale`` (always 1: the limits are hard bounds, not
    a scaling), ``step_bound`` (see :class:`.kinematic.KinematicSolver`) and ``diagnostics``
    (:class:`HqpDiagnostics`).
    """

    accepts_inequalities = True

    def __init__(
        self,
        name: str,
        model: RobotModel,
        dt: float,
        damping: float = 0.0,
        position_margin: float = 1e-3,
        solver: str = ACTIVE_SET,
    ):
        layout = Layout.of(model.plant)
        KinematicSolver.__init__(self, name, model.nv, HqpSettings(), damping=damping, dt=dt, layout=layout)
        self.setSolver(solver)
        self.setPositionMargin(position_margin)
        # The position port, period and layout, typed as never None here (q for the joint limits).
        self._position: InputPort = self.GetInputPort("position")
        self._period = float(dt)
        self._layout = layout
        if self._layout.base_v is not None:
            self.setBaseVelocityLimit(*default_base_velocity_limit(model))
        limits = model.joint_limits()
        self._bounds = VelocityBounds(limits["position_lower"], limits["position_upper"],
                                      limits["velocity_lower"], limits["velocity_upper"], layout)
        self._acceleration_bounds = AccelerationBounds(limits["position_lower"], limits["position_upper"], layout)
        plant = model.plant
        model_limit = np.minimum(-plant.GetAccelerationLowerLimits(), plant.GetAccelerationUpperLimits())
        if np.isfinite(model_limit[layout.joints_v]).any():  # the model's own limits (URDF drake:acceleration)
            self.setAccelerationLimit(np.where(np.isfinite(model_limit) & (model_limit > 0), model_limit, np.inf))
        self._hqp = HierarchicalQP(model.nv)  # its Drake programs are caches
        # The solve's warm starts (working sets, held bounds, back-off: which path answers), in the
        # Context: a cloned or reset Context replays a run bit for bit. The solve updates them in
        # place (the solution is not recomputed for them: they are left out of its prerequisites).
        self._warm_index = self.DeclareAbstractState(AbstractValue.Make(WarmStart(model.nv)))
        self.DeclareAbstractOutputPort(
            "diagnostics", lambda: AbstractValue.Make(HqpDiagnostics()),
            lambda c, o: o.set_value(self._solution.Eval(c).diagnostics),
        )

    def setDamping(self, damping: float, context: Context | None = None) -> None:
        """Damping μ of the last level (``‖w‖² + μ‖Δv‖²``), as sot-dyninv's ``SolverKine``."""
        KinematicSolver.setDamping(self, damping, context)

    def setPositionMargin(self, margin: float, context: Context | None = None) -> None:
        if not finite_number(margin) or not 0 <= margin <= 0.5:
            raise InvalidInput(f"position margin must be a number in [0, 0.5] (rad or m), got {margin!r}")
        self._command(context, lambda s: setattr(s, "position_margin", float(margin)))

    def setBaseVelocityLimit(self, angular: float, linear: float, context: Context | None = None) -> None:
        """Bound each component of the floating base's angular (rad/s) and linear (m/s) velocity,
        both in ``(0, 100]``; the default comes from the legs' limits (:mod:`.base_velocity`)."""
        for name, value in (("angular", angular), ("linear", linear)):
            if not finite_number(value) or not 0 < value <= MAX_BASE_VELOCITY:
                raise InvalidInput(
                    f"{self.name}.setBaseVelocityLimit: {name} must be a number in (0, {MAX_BASE_VELOCITY:g}], got {value!r}"
                )
        if self._layout.base_v is None:
            raise InvalidInput(f"{self.name}.setBaseVelocityLimit: the robot has no floating base")
        self._command(context, lambda s: setattr(s, "base_velocity_limit", (float(angular), float(linear))))

    def setAccelerationLimit(self, limit: float | np.ndarray | None, context: Context | None = None) -> None:
        """Bound each joint's acceleration between two commands, ``|v − v_prev| ≤ a_max dt``, as
        hard bounds combined with the position and velocity limits and the braking distance
        (:mod:`.acceleration_limits`). ``limit``: one number for every joint, or nv numbers (the
        floating base's entries inf), each in ``(0, 1e6]`` rad/s² (m/s²) or inf for none; ``None``:
        no limit (the default, unless the robot model has acceleration limits)."""
        value = None
        if limit is not None:
            try:
                value = np.array(limit, dtype=float).reshape(-1)
            except (TypeError, ValueError):
                value = np.full(1, np.nan)
            if isinstance(limit, (bool, str)):
                value = np.full(1, np.nan)
            if value.shape == (1,):
                value = np.full(self.nv, value[0])
                if self._layout.base_v is not None:
                    value[self._layout.base_v : self._layout.base_v + 6] = np.inf
            base = slice(self._layout.base_v, self._layout.base_v + 6) if self._layout.base_v is not None else slice(0, 0)
            if (value.shape != (self.nv,) or np.isnan(value).any() or not (value > 0).all()
                    or (value[np.isfinite(value)] > MAX_ACCELERATION).any() or np.isfinite(value[base]).any()):
                raise InvalidInput(f"{self.name}.setAccelerationLimit: a_max must be one number or {self.nv} numbers, each in "
                                   f"(0, {MAX_ACCELERATION:g}] rad/s² or inf (the floating base's entries inf), got {limit!r:.200}")
        self._command(context, lambda s: setattr(s, "acceleration_limit", value))

    def acceleration_limit(self, context: Context | None = None) -> np.ndarray | None:
        """The acceleration limits (nv, inf: none), or None without any."""
        limit = self.settings(context).acceleration_limit
        return None if limit is None else limit.copy()

    def _previous_velocity(self, context: Context) -> np.ndarray:
        """The last command ``v_prev`` (zero before the first tick: the robot starts at rest)."""
        kept = context.get_discrete_state(cast(int, self._last_velocity)).get_value()
        return kept[1:] if kept[0] == 1.0 else np.zeros(self.nv)

    def setThreshold(self, svd_threshold: float, context: Context | None = None) -> None:
        """Refused: the levels are solved exactly (hierarchical QP); its rank decisions take one
        threshold τ on unit rows (``HierarchicalQP``'s ``rank_threshold``, 1e-8), not an SVD
        truncation."""
        raise StackError(f"{self.name} is a SolverKine: its levels are solved exactly (hierarchical QP), it has no SVD "
                         "truncation threshold (setThreshold is the basic SOT's; the QP's rank threshold is 1e-8 on unit rows)")

    def setSolver(self, solver: str, context: Context | None = None) -> None:
        """How the levels are solved: ``'active-set'`` (default, exact), or a Drake solver
        (``'clarabel'``, ``'osqp'``, ``'snopt'``) polished by the active-set method."""
        check_solver(solver if isinstance(solver, str) else repr(solver))
        self._command(context, lambda s: setattr(s, "solver", solver))

    def _calc(self, context: Context, value: AbstractValue) -> None:
        s = self._settings_of(context)
        task_levels = self._levels(context, s, check=False)
        q = self._position.Eval(context)
        lower, upper = self._bounds(q, self._period, s.position_margin, s.control_selection, s.base_velocity_limit)
        cap = self._velocity_limit(s)  # setVelocityLimit and each tick's step within δ (.step_limit): hard bounds here
        if cap is not None:
            lower, upper = clip_bounds(lower, upper, cap)
        if s.acceleration_limit is not None:
            lower, upper = self._acceleration_bounds(lower, upper, q, self._previous_velocity(context), s.acceleration_limit,
                                                     self._period, s.position_margin)
        diagnostics = HqpDiagnostics(tasks=(["contacts"] if s.contacts else []) + list(s.tasks))
        warm = context.get_abstract_state(self._warm_index).get_value()
        # With acceleration limits, 0 may lie outside the bounds: the stages start inside them, so
        # that every bound holds (a start outside would relax the bound it violates).
        start = np.clip(0.0, lower, upper) if s.acceleration_limit is not None else None
        problem = StackProblem([(level.jacobian, level.lower, level.upper) for level in task_levels], lower, upper,
                               s.damping, s.solver, start=start, warm=warm)
        try:
            result = solve_stack(self._hqp, problem, KINEMATIC)
        except InvalidInput:
            # The stages check every level's shapes (LevelRows, and the columns against nv) and values
            # (finite A, ordered sides without NaN, finite values of equality rows); the levels are
            # checked again to name the task.
            self._levels(context, s)  # raises SolverError naming the task, if a task's values are wrong
            raise
        except SolverError as error:
            diagnostics.failure = f"t = {context.get_time():.4f} s: {error}"
            log.warning("%s: %s; the device holds", self.name, diagnostics.failure)
            value.set_value(_Solution(np.zeros(self.nv), np.full(len(task_levels), np.nan), diagnostics, task_levels.tasks))
            return
        if any(keyed_inequality(level) for level in task_levels):
            result = keep_met_rows(lambda levels: self._trial(levels, problem), task_levels, result, 0)
        diagnostics.slack_norms = result.slack_norms
        diagnostics.active_rows = result.active_rows
        diagnostics.active_limits = result.active_bounds
        diagnostics.level_solvers = result.level_solvers
        diagnostics.solve_time_s = result.solve_time_s
        diagnostics.max_iterations = max(result.iterations, default=0)
        diagnostics.fallbacks = result.fallbacks
        value.set_value(_Solution(result.x, result.slack_norms, diagnostics, task_levels.tasks))

    def _trial(self, levels: list[TaskLevel], problem: StackProblem) -> HqpResult | None:
        """``problem`` with these task levels (:func:`~.unmet_rows.keep_met_rows`' extra solves),
        solved cold (a fresh warm start: nothing carried from one tick to the next); None if it fails."""
        trial = replace(problem, levels=[(level.jacobian, level.lower, level.upper) for level in levels],
                        warm=WarmStart(self.nv))
        try:
            return solve_stack(self._hqp, trial, KINEMATIC)
        except SolverError:
            return None


@dataclass
class _Solution:
    """The solve's result: the fields the ``control``, ``residuals`` and ``diagnostics`` ports read,
    and what the last tick keeps."""

    velocity: np.ndarray
    residuals: np.ndarray
    diagnostics: HqpDiagnostics
    tasks: list[tuple[str, np.ndarray, np.ndarray | None]]  # each task's name, Jacobian and row keys (what the last tick keeps)
