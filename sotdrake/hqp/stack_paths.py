"""The ways a whole stack is solved, declared once, and which solver tries which, in order.

A *stack path* takes every level at once. The closed forms answer only when they apply and their
answer verifies, and that answer is then the one the level-by-level stages would give (to the
tolerances); otherwise they give None and the next path is tried. The stages always answer or raise
:class:`~sotdrake.exceptions.SolverError`, so a list that ends with them always decides:

* :data:`CASCADE`: the damped pseudo-inverse cascade of sot-core's ``SOT`` (:mod:`.cascade`). It
  applies to equality levels without bounds. Without damping its answer is the stages'
  minimum-norm point of the hierarchy when every rank decision is clear; with damping ``δ > 0`` it
  is the seed's damped inverse of every level (not a strict QP any more, as in sot-core).
* :data:`QR_SWEEP`: equality levels under bounds, by one pivoted-QR sweep per guess of the bounds
  held at the optimum, certified by their multipliers (:mod:`.equality_hierarchy`). The guess is
  the bounds held at the last tick.
* :data:`ACTIVE_BOUNDS`: equality levels under bounds, by one QR of all the levels with the bounds
  held at the last call, certified by the minimum-norm stage's KKT conditions
  (:mod:`.equality_stack`), with a back-off after failures kept in the warm start.
* :data:`INACTIVE_ROWS`: a stack with inequality rows, by the active bounds on its equality rows
  alone, when every inequality row holds at that answer (:class:`InactiveRows`: then it is the
  whole stack's optimum), with its own back-off after failures kept in the warm start.
* :data:`STAGES`: level by level, each stage's own paths tried in the order of :mod:`.paths`
  (:meth:`.solve.HierarchicalQP.solve`). It takes inequality rows and Drake's solvers.

What each solver tries, in order:

=========================  ==================================
``SOT`` (basic)            :data:`BASIC` = (cascade,)
``SolverKine``             :data:`KINEMATIC` = (active bounds, inactive rows, stages)
``SolverDyn``              :data:`DYNAMIC` = (QR sweep, stages)
=========================  ==================================

The closed forms are tried only with the default solver (``"active-set"``): a chosen Drake solver
goes to the stages at once.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..exceptions import SolverError
from .cascade import CascadeFactorization, cascade_factorization
from .equality_hierarchy import StackedLevels, solve_equality_hierarchy, solve_stacked
from .problem import ACTIVE_SET, NO_ACTIVE_ROWS, HqpResult, LevelRows, result_of
from .solve import HierarchicalQP
from .tolerances import VERIFIED
from .warm import WarmStart, back_off

CASCADE_NAME = "cascade"


@dataclass
class StackProblem:
    """One stack to solve: ``levels`` ``[(A_k, lower_k, upper_k), …]``, highest first (an equality
    level has ``lower_k is upper_k``), or the same levels already ``stacked`` (equalities only),
    the bounds ``x_lower ≤ x ≤ x_upper``, the damping ``μ`` of the last level, the solver's name,
    the stages' start (None: 0), the warm start of the call, and ``held``: the components expected
    at their lower and at their upper bound (the QR sweep's first guess)."""

    levels: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]]
    x_lower: np.ndarray
    x_upper: np.ndarray
    damping: float = 0.0
    solver: str = ACTIVE_SET
    start: np.ndarray | None = None
    warm: WarmStart | None = None
    held: tuple[Sequence[int], Sequence[int]] = ((), ())
    stacked: StackedLevels | None = None

    @property
    def equalities_only(self) -> bool:
        """Every level an equality (a level without rows, e.g. a collision level with no pair in
        range, counts as one)."""
        return self.stacked is not None or all(lower is upper or len(lower) == 0 for _, lower, upper in self.levels)


class StackPath:
    """A way to solve a whole stack: :meth:`attempt` gives the answer, or None when it does not
    apply or does not verify."""

    name: str

    def attempt(self, qp: HierarchicalQP, problem: StackProblem) -> HqpResult | None:
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"<stack path {self.name!r}>"


class Cascade(StackPath):
    """The damped pseudo-inverse cascade (:mod:`.cascade`) of equality levels without bounds."""

    name = CASCADE_NAME

    def factorize(self, levels: Sequence[tuple[np.ndarray, np.ndarray]], n: int, threshold: float,
                  damping: float | Sequence[float] = 0.0, selection: np.ndarray | None = None) -> CascadeFactorization:
        """The cascade of ``levels`` ``[(J_k, ė*_k), …]`` kept for other references (what ``SOT``
        uses: it scales the references to its velocity limits and solves again)."""
        return cascade_factorization(levels, n, threshold, damping, selection)

    def attempt(self, qp: HierarchicalQP, problem: StackProblem) -> HqpResult | None:
        p = problem
        if (p.solver != ACTIVE_SET or not p.equalities_only or np.isfinite(p.x_lower).any()
                or np.isfinite(p.x_upper).any()):
            return None
        levels = [(A, b) for A, b, _ in p.levels] if p.stacked is None else [(level.A, level.lower) for level in p.stacked.levels()]
        try:
            x = self.factorize(levels, qp.n, qp.rank_threshold, p.damping).velocity
        except (SolverError, ValueError, np.linalg.LinAlgError):
            return None
        if not np.isfinite(x).all():
            return None
        slacks = [A @ x - b for A, b in levels]
        count = len(levels)
        return HqpResult(x=x, slacks=slacks, slack_norms=np.array([np.linalg.norm(s) for s in slacks]),
                         active_rows=[NO_ACTIVE_ROWS] * count, active_bounds=np.zeros(0, dtype=int),
                         level_solvers=[CASCADE_NAME] * count, iterations=[0] * count)


class QrSweep(StackPath):
    """Equality levels under bounds by the QR sweep (:mod:`.equality_hierarchy`)."""

    name = "qr-sweep"

    def attempt(self, qp: HierarchicalQP, problem: StackProblem) -> HqpResult | None:
        p = problem
        if p.solver != ACTIVE_SET:
            return None
        if p.stacked is not None:
            return solve_stacked(p.stacked, p.x_lower, p.x_upper, *p.held)
        if not p.equalities_only:
            return None
        return solve_equality_hierarchy([(A, b) for A, b, _ in p.levels], p.x_lower, p.x_upper, *p.held)


class ActiveBounds(StackPath):
    """Equality levels under bounds from the bounds held at the last call (:mod:`.equality_stack`)."""

    name = "active-bounds"

    def attempt(self, qp: HierarchicalQP, problem: StackProblem) -> HqpResult | None:
        p = problem
        if p.solver != ACTIVE_SET or p.stacked is not None or not p.equalities_only:
            return None
        return qp.solve_equalities([A for A, _, _ in p.levels], [b for _, b, _ in p.levels], p.x_lower, p.x_upper,
                                   p.damping, warm=p.warm)


class InactiveRows(StackPath):
    """A stack with inequality rows whose rows all hold at the answer of its equality rows alone.

    The equality rows of every level (a level of inequality rows alone keeps none) are solved by
    the active bounds (:class:`ActiveBounds`, under the same bounds on ``x``); if that answer ``x*``
    holds every inequality row (on unit rows, to :data:`~.tolerances.VERIFIED` relative above 1),
    it is the lexicographic optimum of the whole stack, and the minimum-norm one. Proof, by
    induction over the levels: let ``S_k`` be the optimal set of the levels ``≤ k`` with their
    inequality rows and ``S'_k`` without them, ``G_k`` the points that hold the inequality rows of
    the levels ``≤ k``, and assume ``S_(k−1) = S'_(k−1) ∩ G_(k−1)`` with ``x* ∈ S_(k−1)``. On
    ``S_(k−1) ⊆ S'_(k−1)`` the equality residual of level ``k`` is at least its minimum over
    ``S'_(k−1)``, which ``x*`` attains, and the inequality slack is at least 0, which ``x*``
    attains: so ``x* ∈ S_k`` and ``S_k = S'_k ∩ G_k``. The minimum-norm point of ``S'_K`` lies in
    ``S_K ⊆ S'_K``, so it is also ``S_K``'s. Otherwise (a row is violated: it will be active) the
    path gives None and the stages decide; after f failures in a row the next 2^(f−1) calls, at
    most 16, skip the path (the warm start's ``row_failures``/``row_skips``), so that a stack that
    keeps a row active does not pay for the equality solve at every call."""

    name = "inactive-rows"

    def attempt(self, qp: HierarchicalQP, problem: StackProblem) -> HqpResult | None:
        p = problem
        if p.solver != ACTIVE_SET or p.stacked is not None or p.equalities_only or p.damping != 0.0:
            return None
        qp._use(p.warm)
        warm = qp.warm
        if warm.row_skips:
            warm.row_skips -= 1
            return None
        levels = [LevelRows(*level) for level in p.levels]  # (the split, and the checks the stages make)
        result = qp.solve_equalities([level.A_eq for level in levels], [level.b_eq for level in levels], p.x_lower,
                                     p.x_upper, 0.0, warm=p.warm)
        if result is None:
            return None
        tolerance = min(VERIFIED, qp.feasibility_tolerance)
        if not all(_inequalities_hold(level, result.x, tolerance) for level in levels if not level.all_equality):
            warm.row_failures += 1
            warm.row_skips = back_off(warm.row_failures)
            return None
        warm.row_failures = 0
        answer = result_of(levels, result.x, p.x_lower, p.x_upper, p.x_lower == p.x_upper, result.level_solvers)
        answer.iterations, answer.solve_time_s = result.iterations, result.solve_time_s
        return answer


def _inequalities_hold(level: LevelRows, x: np.ndarray, tolerance: float) -> bool:
    """Whether the level's inequality rows ``lower ≤ A x ≤ upper`` hold at ``x`` on unit rows (their
    reference norms, :attr:`~.problem.LevelRows.in_norms`) to ``tolerance`` relative above 1."""
    norms = level.in_norms
    value = (level.A_in @ x) / norms
    margin = tolerance * np.maximum(1.0, np.abs(value))
    return bool(np.all(value >= level.lower_in / norms - margin) and np.all(value <= level.upper_in / norms + margin))


class Stages(StackPath):
    """Level by level (:meth:`.solve.HierarchicalQP.solve`): answers or raises."""

    name = "stages"

    def attempt(self, qp: HierarchicalQP, problem: StackProblem) -> HqpResult | None:
        p = problem
        levels = p.stacked.levels() if p.stacked is not None else [LevelRows(*level) for level in p.levels]
        return qp.solve(levels, p.x_lower, p.x_upper, p.damping, p.solver, start=p.start, warm=p.warm)


CASCADE, QR_SWEEP, ACTIVE_BOUNDS, INACTIVE_ROWS, STAGES = Cascade(), QrSweep(), ActiveBounds(), InactiveRows(), Stages()
BASIC: tuple[StackPath, ...] = (CASCADE,)
KINEMATIC: tuple[StackPath, ...] = (ACTIVE_BOUNDS, INACTIVE_ROWS, STAGES)
DYNAMIC: tuple[StackPath, ...] = (QR_SWEEP, STAGES)


def solve_stack(qp: HierarchicalQP, problem: StackProblem, paths: Sequence[StackPath]) -> HqpResult:
    """The first answer of ``paths`` tried in order; :class:`SolverError` when none answers."""
    for path in paths:
        result = path.attempt(qp, problem)
        if result is not None:
            return result
    raise SolverError(f"no path answered ({', '.join(path.name for path in paths)})")
