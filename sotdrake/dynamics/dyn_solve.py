"""The solve of one tick's dynamic problem (:class:`.dyn_types.Problem`): pure, no Drake system.

Solved first with ``τ`` eliminated when ``B`` is a selection (:meth:`DynamicSolve.reduced`): the
actuated rows of the dynamics then only define ``τ``. If that optimum's ``τ`` is within the effort
limits and the contacts' wrench rows hold, it is the optimum of the full problem (after the damping
level ``x`` is unique, so the last minimum-norm stage changes nothing). Otherwise the hierarchy over
``(q̈, w, τ)`` is solved without the contacts' wrench inequalities, every level an equality (closed
forms, no program); if that optimum satisfies those rows it is the exact optimum of the full
hierarchy too (each level's optimal set with the rows is the one without them intersected with the
rows, and the optimum lies in it), else the full hierarchy is solved (:meth:`DynamicSolve.full`).
Each solve goes through the paths :data:`~sotdrake.hqp.stack_paths.DYNAMIC` declares. A failure is
rescued (:meth:`DynamicSolve.rescue`): never zero torque on a standing robot if avoidable.

The solvers it keeps, one per problem size, are caches: which path answers and how it starts
depend only on the warm starts it is handed (kept by :class:`.solver_dyn.SolverDyn` in its Context).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from dataclasses import replace

import numpy as np

from ..compiled import read_only
from ..exceptions import SolverError
from ..hqp import HierarchicalQP, HqpResult, LevelRows
from ..hqp.equality_hierarchy import StackedLevels
from ..hqp.stack_paths import DYNAMIC, StackProblem, solve_stack
from ..hqp.warm import WarmStart
from ..solvers.unmet_rows import keep_met_rows, keyed_inequality
from ..task import TaskLevel
from .dyn_types import _NO_INDICES, DynDiagnostics, DynSettings, Problem
from .formulation import (
    WRENCH_REGULARIZATION,
    Rows,
    _shear_weights,
    _wrench_rows_hold,
    actuated_rows,
    dynamic_levels,
    dynamic_rows,
    inside,
    unactuated_rows,
)
from .reduced_levels import StackedContacts, reduced_stack, torques_and_checks

log = logging.getLogger("sotdrake.solver_dyn")

Warm = Callable[[str, int], WarmStart]
"""The warm start of a problem ("full" or "reduced") of n variables."""


class DynamicSolve:
    """One tick's problem solved (see the module docstring) for a robot of ``nv`` velocities and
    ``na`` actuators with torque limits ``effort`` (N·m, N)."""

    def __init__(self, nv: int, na: int, effort: np.ndarray):
        self.nv, self.na = nv, na
        self._effort_held = effort * (1 + 1e-9)  # what the fast path's τ must stay within
        self._hqps: dict[int, HierarchicalQP] = {}  # the full problem's solver per size
        self._reduced_hqps: dict[int, HierarchicalQP] = {}  # the same, τ eliminated
        self._actuation: tuple[np.ndarray, np.ndarray | None, np.ndarray, np.ndarray] | None = None  # actuation()

    def solve(self, p: Problem, s: DynSettings, warm: Warm, held: tuple[Sequence[int], Sequence[int]],
              diagnostics: DynDiagnostics, time: float, name: str) -> tuple[HqpResult | None, list[np.ndarray] | None, int]:
        """``(result, world, count)``: the optimum (None: every attempt failed, zero torque), the
        contacts' world wrenches when the fast path computed them, and the number of levels of what
        was tried (the residuals' size). ``held``: the components held at their lower and upper
        bound at the last tick (the QR sweep's guess); ``time`` (s) and ``name``: for the failure's message."""
        n = len(p.lower)
        hqp = self._hqps.get(n)
        if hqp is None:
            hqp = self._hqps[n] = HierarchicalQP(n)
        tried: list[HqpResult] = []
        try:
            result, world = self.attempt(p, s, hqp, warm, held, diagnostics, tried)
        except SolverError as error:
            rescued, count = self.rescue(p, s, hqp, warm, error, tried, diagnostics, time, name)
            return rescued, None, count
        if any(keyed_inequality(task) for task in p.tasks):
            refined = self.keep_met_rows(p, s, hqp, warm, held, result, diagnostics)
            if refined is not result:
                result, world = refined, None
        return result, world, len(result.slack_norms)

    def attempt(self, p: Problem, s: DynSettings, hqp: HierarchicalQP, warm: Warm, held: tuple[Sequence[int], Sequence[int]],
                diagnostics: DynDiagnostics, tried: list[HqpResult]) -> tuple[HqpResult, list[np.ndarray] | None]:
        """The optimum and, from the fast path, the contacts' world wrenches: :meth:`reduced`, else
        :meth:`full` (whose relaxed optimum is appended to ``tried``). Raises :class:`SolverError`."""
        fast = self.reduced(p, s, warm, held)
        diagnostics.torques_eliminated = fast is not None
        if fast is not None:
            return fast
        return self.full(p, s, hqp, warm, held, tried), None

    def keep_met_rows(self, p: Problem, s: DynSettings, hqp: HierarchicalQP, warm: Warm,
                      held: tuple[Sequence[int], Sequence[int]], result: HqpResult, diagnostics: DynDiagnostics) -> HqpResult:
        """``result`` with each collision level's rows that can hold kept exact
        (:func:`~sotdrake.solvers.unmet_rows.keep_met_rows`); the extra solves warm-started from
        their own warm starts (``"split "`` + the problem's), so that the stack's are the same as
        without them."""
        eliminated: dict[int, bool] = {}

        def solve(tasks: list[TaskLevel]) -> HqpResult | None:
            scratch = DynDiagnostics()
            try:
                trial, _ = self.attempt(replace(p, tasks=tasks), s, hqp, lambda problem, n: warm("split " + problem, n),
                                        held, scratch, [])
            except SolverError:
                return None
            eliminated[id(trial.x)] = scratch.torques_eliminated
            return trial

        refined = keep_met_rows(solve, p.tasks, result, 2 if p.contacts else 1)
        if refined is not result:
            diagnostics.torques_eliminated = eliminated[id(refined.x)]
        return refined

    def reduced(self, p: Problem, s: DynSettings, warm: Warm, held: tuple[Sequence[int], Sequence[int]]
                ) -> tuple[HqpResult, list[np.ndarray]] | None:
        """The fast path, ``τ`` eliminated (a smaller problem, no ``τ`` bounds), when ``B`` is a
        selection; with every task an equality, assembled, stacked and checked by compiled code
        (:mod:`.reduced_levels`). Its result with ``τ`` appended and the contacts' world wrenches,
        or None when it does not hold (``τ`` beyond the limits, a wrench row violated)."""
        terms, contacts, tasks, loads, lower, upper = p.terms, p.contacts, p.tasks, p.loads, p.lower, p.upper
        actuated, compiled_actuated, passive = self.actuation(terms.B)
        if actuated is None:
            return None
        m = len(lower) - self.na
        small = self._reduced_hqps.get(m)
        if small is None:
            small = self._reduced_hqps[m] = HierarchicalQP(m)
        reduced_warm = warm("reduced", m)
        try:
            stacked = StackedContacts(contacts, self.nv)
            rows: list[Rows] | StackedLevels
            if all(task.lower is task.upper for task in tasks):  # the levels assembled and stacked compiled
                scales = [WRENCH_REGULARIZATION * weight for weight in _shear_weights(loads, len(contacts))]
                rows = reduced_stack(terms, stacked, tasks, s.damping_gain, scales, passive)
            else:
                rows, _ = dynamic_rows(terms, contacts, tasks, s.damping_gain, False, loads, actuated)
            fast = _solve(small, rows, lower[:m], upper[:m], s.solver, reduced_warm, held)
            tau, world, within, hold = torques_and_checks(terms, stacked, compiled_actuated, fast.x, self._effort_held)
        except SolverError:
            return None
        if not (within and hold):
            return None
        fast.x = np.concatenate([fast.x, tau])
        return fast, world

    def full(self, p: Problem, s: DynSettings, hqp: HierarchicalQP, warm: Warm, held: tuple[Sequence[int], Sequence[int]],
             tried: list[HqpResult]) -> HqpResult:
        """The hierarchy over ``(q̈, w, τ)``: relaxed (without the contacts' wrench rows; its
        optimum appended to ``tried``), then, if those rows do not hold there, in full."""
        terms, contacts, tasks, loads, lower, upper = p.terms, p.contacts, p.tasks, p.loads, p.lower, p.upper
        rows, _ = dynamic_rows(terms, contacts, tasks, s.damping_gain, with_inequalities=False, loads=loads)
        full_warm = warm("full", len(lower))
        relaxed = result = _solve(hqp, rows, lower, upper, s.solver, full_warm, held)
        tried.append(relaxed)
        if contacts and not _wrench_rows_hold(contacts, p.slices, result.x):
            levels, _ = dynamic_levels(terms, contacts, tasks, s.damping_gain, loads=loads)
            result = hqp.solve(levels, lower, upper, 0.0, s.solver, start=inside(lower, upper), warm=full_warm)
        return result

    def rescue(self, p: Problem, s: DynSettings, hqp: HierarchicalQP, warm: Warm, error: SolverError,
               tried: list[HqpResult], diagnostics: DynDiagnostics, time: float, name: str) -> tuple[HqpResult | None, int]:
        """The relaxed optimum (dynamics, contact accelerations and the stack exact; friction/CoP
        rows possibly violated), else the dynamics and contacts alone, else the dynamics alone (its
        best residual within the bounds); None (zero torque) if even that fails. Also the number of
        levels of what was tried (the residuals' size)."""
        terms, contacts, tasks, loads, lower, upper = p.terms, p.contacts, p.tasks, p.loads, p.lower, p.upper
        diagnostics.failure = f"t = {time:.4f} s: {error}"
        relaxed = tried[0] if tried else None
        levels: list[LevelRows] = []
        if relaxed is None:
            levels, _ = dynamic_levels(terms, contacts, [], s.damping_gain, with_inequalities=False, loads=loads)
            # The dynamics and contacts, else the dynamics alone (when the dynamics cannot be met under
            # the torque and joint bounds, the level below it held at that residual can fail).
            for kept, dropped in ((len(levels), "the stack"), (1, "the stack and the contacts")):
                try:
                    relaxed = hqp.solve(levels[:kept], lower, upper, 0.0, s.solver, start=inside(lower, upper),
                                        warm=warm("full", len(lower)))
                    diagnostics.failure += f"; {dropped} dropped for this tick"
                    levels = levels[:kept]
                    break
                except SolverError as second:
                    diagnostics.failure += f"; {second}"
            else:
                diagnostics.failure += "; zero torque"
        else:
            levels, _ = dynamic_levels(terms, contacts, tasks, s.damping_gain, with_inequalities=False, loads=loads)
            diagnostics.failure += "; the contacts' wrench rows are relaxed for this tick"
        log.warning("%s: %s", name, diagnostics.failure)
        return relaxed, len(levels)

    def actuation(self, B: np.ndarray) -> tuple[np.ndarray | None, np.ndarray, np.ndarray]:
        """:func:`.formulation.actuated_rows` (None: ``B`` is not a selection), and the actuated and
        unactuated velocity rows (:func:`.formulation.unactuated_rows`) as read-only int64 arrays,
        for the compiled fast path; kept for a read-only ``B`` (the dynamic entity's, the same array
        at every tick): a pure cache."""
        if self._actuation is not None and self._actuation[0] is B:
            return self._actuation[1:]
        rows = actuated_rows(B)
        if rows is None:
            compiled = _NO_INDICES, _NO_INDICES
        else:
            compiled = (read_only(rows.astype(np.int64)), read_only(np.arange(self.nv, dtype=np.int64)[unactuated_rows(self.nv, rows)]))
        if not B.flags.writeable:
            self._actuation = (B, rows, *compiled)
        return (rows, *compiled)


def _solve(hqp: HierarchicalQP, rows: list[Rows] | StackedLevels, lower: np.ndarray, upper: np.ndarray, solver: str,
           warm: WarmStart, held: tuple[Sequence[int], Sequence[int]]) -> HqpResult:
    """The hierarchy ``rows`` (or equality levels already stacked) by the paths
    :data:`~sotdrake.hqp.stack_paths.DYNAMIC` declares: the QR sweep when that is clear-cut (every
    level an equality, the bounds at the optimum held as equalities and certified by their
    multipliers, from those ``held`` at the last tick), else level by level (which checks the rows)."""
    levels, stacked = ([], rows) if isinstance(rows, StackedLevels) else (rows, None)
    problem = StackProblem(levels, lower, upper, 0.0, solver, start=inside(lower, upper), warm=warm, held=held,
                           stacked=stacked)
    return solve_stack(hqp, problem, DYNAMIC)
