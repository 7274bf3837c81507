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
  (:mod:`.equality_stack`), with a back-off after failures kept in the warm start. Every level must
  be of full row rank in what the levels above leave free.
* :data:`WARM_QR_SWEEP`: the QR sweep from the bounds held at the last answer (the warm start's),
  for the equality stacks the active bounds cannot certify: a level with more rows than the levels
  above leave free (a posture task at the bottom) or of lower rank, which the sweep's
  least-squares steps take; with its own back-off.
* :data:`HELD_ROWS`: a stack with inequality rows whose equality rows can all be met exactly: its
  equality rows and the inequality rows it has to hold at a bound, by the active bounds
  (:class:`HeldRows`: then it is the whole stack's optimum), with its own back-off after failures
  kept in the warm start.
* :data:`INACTIVE_ROWS`: a stack with inequality rows that all hold at the answer of its equality
  rows alone (by the active bounds or the warm QR sweep): that answer (:class:`InactiveRows`), with
  its own back-off. It takes what the held rows cannot: a level whose equality rows cannot all be
  met, as a posture task below a collision level whose pairs are in range but not about to touch.
* :data:`STAGES`: level by level, each stage's own paths tried in the order of :mod:`.paths`
  (:meth:`.solve.HierarchicalQP.solve`). It takes inequality rows and Drake's solvers.

What each solver tries, in order:

=========================  ==================================
``SOT`` (basic)            :data:`BASIC` = (cascade,)
``SolverKine``             :data:`KINEMATIC` = (active bounds, warm QR sweep, held rows, inactive rows, stages)
``SolverDyn``              :data:`DYNAMIC` = (QR sweep, stages)
=========================  ==================================

The closed forms are tried only with the default solver (``"active-set"``): a chosen Drake solver
goes to the stages at once.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from ..exceptions import InvalidInput, SolverError
from .cascade import CascadeFactorization, cascade_factorization
from .equality_hierarchy import solve_equality_hierarchy, solve_stacked
from .equality_stack import bound_guess, default_stages, solve_held_rows, start_inside
from .problem import ACTIVE_SET, NO_ACTIVE_ROWS, HqpResult, LevelRows, result_of
from .solve import HierarchicalQP
from .stack_problem import StackProblem, check_sizes, what_is_wrong
from .tolerances import FEASIBILITY, RANK_THRESHOLD, VERIFIED

CASCADE_NAME = "cascade"


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
                  damping: float | Sequence[float] = 0.0, selection: np.ndarray | None = None,
                  extra: Sequence[np.ndarray] | None = None) -> CascadeFactorization:
        """The cascade of ``levels`` ``[(J_k, ė*_k), …]``, and solved for the ``extra`` references
        in the same pass (what ``SOT`` uses: it scales the references to its velocity limits)."""
        return cascade_factorization(levels, n, threshold, damping, selection, extra)

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
    """Equality levels under bounds by the QR sweep (:mod:`.equality_hierarchy`): no damping (the
    sweep's answer is the undamped hierarchy's) and the start, if given, inside the bounds."""

    name = "qr-sweep"

    def attempt(self, qp: HierarchicalQP, problem: StackProblem) -> HqpResult | None:
        p = problem
        if p.solver != ACTIVE_SET or p.damping != 0.0:  # (damped: the stages' damped last level decides)
            return None
        if p.start is not None:  # a start outside a bound relaxes that bound in the stages: theirs to answer
            with np.errstate(invalid="ignore"):
                if not start_inside(p.x_lower, p.x_upper, p.x_lower == p.x_upper, p.start):
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


class WarmQrSweep(StackPath):
    """Equality levels under bounds by the QR sweep (:mod:`.equality_hierarchy`), its first guess
    the bounds held at the last answer (the warm start's), for the kinematic solver: it answers the
    equality stacks the active bounds cannot certify (a level of more rows than the levels above
    leave free, as a posture task at the bottom, or of lower rank: the sweep's least-squares steps
    take them), when its rank decisions are clear-cut. It stands for the default stages only: no
    damping, the default tolerances, the start inside the bounds (no bound relaxed to it). After f
    failures in a row the next 2^(f−1) calls, at most 16, skip it (the warm start's
    ``sweep_failures``/``sweep_skips``): a stack it cannot decide costs a sixteenth of a sweep a tick."""

    name = "warm-qr-sweep"

    def attempt(self, qp: HierarchicalQP, problem: StackProblem) -> HqpResult | None:
        p = problem
        if (p.solver != ACTIVE_SET or p.stacked is not None or not p.levels or not p.equalities_only or p.damping != 0.0
                or not default_stages(qp) or qp.rank_threshold != RANK_THRESHOLD
                or qp.feasibility_tolerance != FEASIBILITY or qp.hold_tolerance != 0.0):
            return None
        x_lower, x_upper = np.asarray(p.x_lower, dtype=float), np.asarray(p.x_upper, dtype=float)
        with np.errstate(invalid="ignore"):  # (±∞ bounds)
            if not start_inside(x_lower, x_upper, x_lower == x_upper, 0.0 if p.start is None else p.start):
                return None
            qp._use(p.warm)
            if qp.warm.skipped("sweep"):
                return None
            sides = bound_guess(qp, x_lower, x_upper)
        result = solve_equality_hierarchy([(A, b) for A, b, _ in p.levels], x_lower, x_upper,
                                          np.flatnonzero(sides < 0).tolist(), np.flatnonzero(sides > 0).tolist())
        qp.warm.record("sweep", result is not None)
        if result is not None:  # (as the stages leave it: the active bounds' next guess)
            qp.warm.bound_sides = (result.x, x_lower, x_upper)
        return result


class HeldRows(StackPath):
    """A stack with inequality rows whose equality rows can all be met exactly, with its violated
    inequality rows held at their bounds (:func:`.equality_stack.solve_held_rows`).

    Every level's equality rows, and the inequality rows held (at first those the last answer held,
    when the rows keep their places; each round holds one violated and releases those whose
    multiplier has the wrong sign), are solved at once under the bounds held at the last call
    (:mod:`.active_bounds`). A point that meets every equality row, holds every inequality row and
    satisfies the KKT conditions of ``min ½‖x‖²`` over all the rows and bounds is the stack's
    answer: each level's objective (its residual, its violation) is 0 there, its least value, so
    every level's optimal set is the part of the one above where the level's rows are met, the last
    one is the polyhedron of all the rows, and the answer is its minimum-norm point. When no row is
    held this is the equality rows' answer holding every inequality row (a collision level while no
    pair is about to touch); when one is, a level that the rows keep from its target (the hand
    pushed against the torso) makes the rows dependent and the path gives None: the stages decide.
    After f failures in a row the next 2^(f−1) calls, at most 16, skip the path (the warm start's
    ``row_failures``/``row_skips``)."""

    name = "held-rows"

    def attempt(self, qp: HierarchicalQP, problem: StackProblem) -> HqpResult | None:
        p = problem
        if (p.solver != ACTIVE_SET or p.stacked is not None or p.equalities_only or p.damping != 0.0
                or not default_stages(qp)):
            return None
        qp._use(p.warm)
        if qp.warm.skipped("row"):
            return None
        began = time.perf_counter()
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            result = solve_held_rows(qp, p.levels, np.asarray(p.x_lower, dtype=float), np.asarray(p.x_upper, dtype=float),
                                     began)
        qp.warm.record("row", result is not None)
        return result


class InactiveRows(StackPath):
    """A stack with inequality rows that all hold at the answer ``x*`` of its equality rows alone
    (each level's equality rows, solved by :data:`ACTIVE_BOUNDS` or :data:`WARM_QR_SWEEP`, which
    take a level that cannot be met, as a posture task at the bottom): ``x*`` is then the whole
    stack's answer. A level's objective over what the levels above leave optimal is at least its
    equality rows' own least value, which ``x*`` reaches with no violation, so each level's optimal
    set is the equality rows' one cut by the inequality rows held so far, ``x*`` is in all of them,
    and the minimum-norm point of the last one (a subset of the equality rows' last set, ``x*`` its
    minimum-norm point) is ``x*``. An inequality row passed by more than the compiled paths' check
    (1e-10, relative above 1) leaves the stack to the stages; after f such failures in a row the next
    2^(f−1) calls, at most 16, skip the path (the warm start's ``inactive_failures``/``inactive_skips``)."""

    name = "inactive-rows"

    def attempt(self, qp: HierarchicalQP, problem: StackProblem) -> HqpResult | None:
        p = problem
        if p.solver != ACTIVE_SET or p.stacked is not None or p.equalities_only or p.damping != 0.0:
            return None
        qp._use(p.warm)
        warm = qp.warm
        if warm.skipped("inactive"):
            return None
        began = time.perf_counter()
        try:
            levels = [LevelRows(A, lower, upper) for A, lower, upper in p.levels]
        except (InvalidInput, ValueError, TypeError):  # (the stages say what is wrong with the rows)
            return None
        equalities = []
        for level in levels:
            values = level.lower[level.equality]
            equalities.append((level.A[level.equality], values, values))
        sub = StackProblem(equalities, p.x_lower, p.x_upper, start=p.start, warm=warm)
        answer = ACTIVE_BOUNDS.attempt(qp, sub) or WARM_QR_SWEEP.attempt(qp, sub)
        if answer is None:
            return None
        x = answer.x
        for level in levels:
            if level.all_equality:
                continue
            value = level.A_in @ x
            margin = VERIFIED * np.maximum(1.0, np.abs(value))
            if not (np.all(value >= level.lower_in - margin) and np.all(value <= level.upper_in + margin)):
                warm.record("inactive", False)
                return None
        warm.record("inactive", True)
        x_lower, x_upper = np.asarray(p.x_lower, dtype=float), np.asarray(p.x_upper, dtype=float)
        result = result_of(levels, x, x_lower, x_upper, x_lower == x_upper, [self.name] * (len(levels) + 1))
        result.iterations = [0] * (len(levels) + 1)
        result.solve_time_s = time.perf_counter() - began
        return result


class Stages(StackPath):
    """Level by level (:meth:`.solve.HierarchicalQP.solve`): answers or raises."""

    name = "stages"

    def attempt(self, qp: HierarchicalQP, problem: StackProblem) -> HqpResult | None:
        p = problem
        levels = p.stacked.levels() if p.stacked is not None else [LevelRows(*level) for level in p.levels]
        return qp.solve(levels, p.x_lower, p.x_upper, p.damping, p.solver, start=p.start, warm=p.warm)


CASCADE, QR_SWEEP, ACTIVE_BOUNDS, HELD_ROWS, STAGES = Cascade(), QrSweep(), ActiveBounds(), HeldRows(), Stages()
WARM_QR_SWEEP, INACTIVE_ROWS = WarmQrSweep(), InactiveRows()
BASIC: tuple[StackPath, ...] = (CASCADE,)
KINEMATIC: tuple[StackPath, ...] = (ACTIVE_BOUNDS, WARM_QR_SWEEP, HELD_ROWS, INACTIVE_ROWS, STAGES)
DYNAMIC: tuple[StackPath, ...] = (QR_SWEEP, STAGES)


def solve_stack(qp: HierarchicalQP, problem: StackProblem, paths: Sequence[StackPath]) -> HqpResult:
    """The first answer of ``paths`` tried in order; :class:`SolverError` when none answers. The
    problem's sizes against ``qp.n`` are checked first (:func:`.stack_problem.check_sizes`), whatever
    the paths: a start of another size raises :class:`InvalidInput`."""
    check_sizes(problem, qp.n)
    for path in paths:
        result = path.attempt(qp, problem)
        if result is not None:
            return result
    wrong = what_is_wrong(problem, qp.n)
    if wrong is not None:
        raise InvalidInput(f"solve_stack: {wrong}")
    raise SolverError(f"no path answered ({', '.join(path.name for path in paths)})")

