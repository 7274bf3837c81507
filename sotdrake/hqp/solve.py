"""Hierarchical QP (soth / sot-dyninv ``SolverKine``): strict priority, hard bounds, exact levels.

Variables ``x`` (size n). Hard constraints above every level: ``x_min ≤ x ≤ x_max``. Level k holds
rows ``lo_k ≤ A_k x ≤ hi_k`` (an equality row has ``lo = hi = b``) and solves::

    min_{x, w}  ‖w‖² (+ μ‖x - x_{k-1}‖² on the damped last level)
    s.t.        x_min ≤ x ≤ x_max
                every higher level j held at its optimum:
                    equality rows    A_j x = A_j x_j           (their optimal residual w_j*)
                    inequality rows  lo_j - w_j* ≤ A_j x ≤ hi_j + w_j*   (w_j* ≥ 0: optimal violation)
                lo_k - w ≤ A_k x ≤ hi_k + w

which is the LSE/LSI hierarchy (for an equality row the optimal ``|w|`` is ``|A x - b|``, for an
inequality row its violation). ``w*`` of a level is unique, the objective being strictly convex in
``w``. Last, unless ``regularize=False`` or the last level is damped (μ > 0: its optimum, strictly convex
in the free directions ``y``, is one point already), the minimum-norm ``x`` of the whole optimal set is taken.

How a level is solved:

* held equality rows and fixed bounds (``x_min = x_max``) are eliminated: ``x = x_{k-1} + Z y`` with
  ``Z`` an orthonormal basis of their null space, so they hold exactly and no solver ever sees a
  degenerate equality. The level's equality rows enter the objective, its inequality rows become
  constraints ``lo ≤ a y - w ≤ hi`` with one slack ``w`` each, and the bounds and held inequality
  rows are constraints on ``y``;
* the default path (``"active-set"``) is the exact primal active-set method of :mod:`.active_set`,
  started from the previous level's point (``y = 0``, feasible), and warm-started by a guess of the
  working set: the one this level had at the previous call with the same sizes (a cache: the answer
  is a function of the final working set only), else the active set of Goldfarb-Idnani's dual
  method on the level made strictly convex (DAQP's, or quadprog's on a level whose row weights spread beyond 10⁶), else
  (both refusing) the sides of the bounds and held rows active at the end of the level above. An equality-only level
  with no bound in the way is one least-squares step (from the factorisation, QR or SVD, that also gives the next ``Z``),
  checked against the bounds and held rows in ``x`` before any stage is built; the minimum-norm stage likewise tries its
  unconstrained point first when its previous call ended with an empty working set;
* before any stage, a stack of equality levels (no inequality row, no extension, no damping, the
  start inside the bounds) is tried at once from the bounds held at the previous answer
  (:mod:`.active_bounds`, reported as ``"active-bounds"`` for every stage): those bounds fixed, one
  QR of all the levels' unit rows gives the minimum-norm solution; it is kept only if every level is
  certified of full row rank (σ ≥ 10³ τ, so every level is met exactly) and the KKT conditions of
  the minimum-norm stage hold (the other bounds, the signs of the held bounds' multipliers), which
  make it the point the stages return. Up to three rounds release wrong-signed bounds and hold
  violated ones; otherwise the stages decide (after failures in a row the next calls skip the try:
  a back-off). :meth:`HierarchicalQP.solve_equalities` takes such a stack as plain arrays;
* a Drake solver (``"clarabel"``, ``"osqp"``, ``"snopt"``) can be chosen instead, for every level or
  per level: the level is then a ``MathematicalProgram`` in ``(y, w)``, and the solver's answer is
  *polished*: its active set is tried as the working-set guess of the same active-set method, which
  returns the exact optimum (from that guess if it satisfies the KKT conditions, else by iterating).
  A level whose rows carry an ``extend`` callback (a user's extra costs or constraints) goes through
  its ``MathematicalProgram`` and keeps the solver's answer (it is not a least-squares level any
  more); so do the stages below it, which receive the callback again with ``own=False`` to add
  the constraints that must keep holding (not the costs);
* nothing fails silently: if a path fails (no convergence, a non-finite point, a point outside the
  bounds by more than ``feasibility_tolerance``) the next one is tried: the active set warm, then
  cold (from the dual method's guess), then Clarabel polished, then OSQP polished; each failure is
  reported in :attr:`HqpResult.fallbacks`. If every path ended outside a hard row, a path's point
  that holds each hard row to the feasibility tolerance relative to the size of the row's terms
  (a point so large, 1e14 on some random stacks, that doubles cannot verify it closer to the bound)
  is the answer, said in the fallbacks (:data:`ROUND_OFF_LIMITED`); otherwise a :class:`SolverError`
  means all failed.

**The one threshold.** Every rank decision (the null space ``Z`` of the held equality rows, the
least-squares steps, the working-set matrices, which projected rows are constant) compares singular
values of matrices whose rows are scaled to unit norm (the norm of the row *before* projection, so
that a task already fixed by the levels above projects to round-off and is seen as zero) with one
absolute threshold τ, ``rank_threshold`` (default :data:`~.tolerances.RANK_THRESHOLD` = 1e-8). No
library default cutoff is used.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from ..compiled import compiled_input, kernels
from ..exceptions import InvalidInput, SolverError, check_flag, check_number
from . import equality_stack, rescue
from . import paths as declared
from .drake_program import DrakePrograms
from .equality_stack import _active_bounds_path
from .linalg import all_true, any_true
from .problem import (
    ACTIVE_BOUNDS,
    ACTIVE_SET,
    KEPT_LAST_LEVEL,
    MAX_MAGNITUDE,
    ROUND_OFF_LIMITED,
    SOLVERS,
    Extension,
    HqpResult,
    LevelRows,
    Stage,
    _EqualityFactors,
    check_damping,
    check_solver,
    checked_bounds,
    checked_solvers,
    float_arrays,
    floats,
    least_norm,
    null_space,
    result_of,
)
from .tolerances import DEGENERATE_RETRY, FEASIBILITY, HELD_SIDE, RANK_THRESHOLD
from .warm import WarmStart

_Stage = Stage  # the name the stage had here
__all__ = ["ACTIVE_BOUNDS", "ACTIVE_SET", "DEGENERATE_RETRY", "KEPT_LAST_LEVEL", "ROUND_OFF_LIMITED", "SOLVERS",
           "Extension", "HierarchicalQP", "HqpResult", "LevelRows", "check_solver", "least_norm", "null_space"]

_FREE_MINIMUM_NORM = "free minimum-norm stage"
_NO_LEVEL = (np.zeros((0, 0)), *[np.zeros(0)] * 2, np.zeros((0, 0)), *[np.zeros(0)] * 3)
"""The level's arrays given to :func:`.kernels.stage.build` for the minimum-norm stage (not read)."""


_jit_stage = kernels(".kernels.stage", __package__, "build", "the hierarchical QP's stage assembly", "about ten seconds")

#: The most variables a :class:`HierarchicalQP` takes (its dense n × n matrices).
MAX_VARIABLES = 10_000


class HierarchicalQP:
    """Solve stacks of :class:`LevelRows` in strict priority (see the module docstring).

    ``solver``: ``"active-set"`` (default) or a Drake solver of :data:`SOLVERS`; ``level_solvers`` overrides it per
    level; ``rank_threshold``: the τ of every rank decision; ``hold_tolerance``: a relative band added to the held
    optimal violation of inequality rows (0: held exactly); ``feasibility_tolerance``: the bound violation (on unit
    rows, relative above 1) beyond which a path's point is refused and the next path tried; ``regularize``: end with
    the minimum-norm stage (not after a damped last level: it would leave the damped optimum, see the module docstring)."""

    def __init__(
        self,
        n: int,
        solver: str = ACTIVE_SET,
        level_solvers: Sequence[str] | None = None,
        hold_tolerance: float = 0.0,
        rank_threshold: float = RANK_THRESHOLD,
        regularize: bool = True,
        feasibility_tolerance: float = FEASIBILITY,
    ):
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 0 <= n <= MAX_VARIABLES:
            raise InvalidInput(f"HierarchicalQP: n (the number of variables) must be an integer in [0, {MAX_VARIABLES}], got {n!r:.60}")
        n = int(n)
        names = checked_solvers(solver, level_solvers)
        rank_threshold = check_number("rank_threshold", rank_threshold, 1e-300, 1.0)
        hold_tolerance = check_number("hold_tolerance", hold_tolerance, 0.0, 1e6)
        feasibility_tolerance = check_number("feasibility_tolerance", feasibility_tolerance, 1e-300, 1e-2)
        regularize = check_flag("regularize", regularize)
        self.n, self.solver, self.level_solvers = n, solver, names
        self.hold_tolerance, self.rank_threshold, self.regularize = hold_tolerance, rank_threshold, regularize
        self.feasibility_tolerance = feasibility_tolerance
        self.programs = DrakePrograms(n)  # Drake's programs and solvers, cached: results never depend on them
        self._identity = np.eye(n)  # a constant (never written to)
        self._all_components = np.arange(n)  # the bound rows' indices when every component is bounded
        # The warm starts (see .warm): the call's ``warm``, else this object's own.
        self._own_warm = self.warm = WarmStart(n)

    def forget_warm_starts(self) -> None:
        """Drop every warm start of this object's own (the working sets, the held bounds' guess, the
        back-off), so that the next call without ``warm`` is solved cold. Results never depend on
        them to the tolerances; timings and the last bits do."""
        self._own_warm.clear()

    def _use(self, warm: WarmStart | None) -> None:
        if warm is None:
            self.warm = self._own_warm
        elif isinstance(warm, WarmStart) and warm.n == self.n:
            self.warm = warm
        else:
            raise InvalidInput(f"warm must be a WarmStart of {self.n} variables, got {warm!r:.80}")

    def solve(
        self,
        levels: Sequence[LevelRows],
        x_lower: np.ndarray,
        x_upper: np.ndarray,
        damping: float = 0.0,
        solver: str | None = None,
        start: np.ndarray | None = None,
        warm: WarmStart | None = None,
    ) -> HqpResult:
        """Solve in strict priority; ``damping`` μ applies to the last level; ``solver`` overrides
        the default path for this call. Raises :class:`SolverError` naming the stage if every path
        fails (which the tests have never seen with consistent bounds).

        ``start`` (n real numbers, an array or a list; default 0): the point the first level starts
        from. Each stage relaxes a hard bound that its starting point violates to that point (a joint
        already past its limit may stay there rather than be pushed off at once), so a bound that
        excludes the start is not enforced: give a start inside the bounds (e.g. ``clip(0, x_lower,
        x_upper)``) to have every bound hold.

        ``warm``: the warm-start state to read and update (:class:`~.warm.WarmStart` of ``n``
        variables, e.g. kept in a system's Context); default: this object's own."""
        solver = self.solver if solver is None else check_solver(solver)
        n = self.n
        if (isinstance(levels, (str, bytes)) or not isinstance(levels, Sequence)
                or not all(isinstance(level, LevelRows) for level in levels)):
            raise InvalidInput(f"levels: a sequence of LevelRows (highest priority first), got {levels!r:.100}")
        check_damping(damping)
        x_lower, x_upper = checked_bounds(n, x_lower, x_upper)
        fixed = x_lower == x_upper
        for level in levels:
            if level.A.shape[1] != n:
                raise InvalidInput(f"a level has {level.A.shape[1]} columns, expected {n}")
        if start is not None:
            start = floats("start", start)
            if start.shape != (n,) or not all_true(np.abs(start) <= MAX_MAGNITUDE):
                raise InvalidInput(f"start must be {n} finite numbers within ±{MAX_MAGNITUDE:g}")
        self._use(warm)
        began = time.perf_counter()
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # ±∞ bounds: once here, not per operation
            if solver == ACTIVE_SET and self._equalities_only(levels, x_lower, x_upper, fixed, damping, start):
                result = equality_stack.try_active_bounds(self, [level.A for level in levels], [level.lower for level in levels],
                                                 x_lower, x_upper, began)
                if result is not None:
                    return result
            try:
                result = self._solve_stages(levels, x_lower, x_upper, damping, solver, began, start)
            except SolverError as error:
                result = rescue.cold_again(self, error, lambda: self._solve_stages(levels, x_lower, x_upper, damping, solver,
                                                                                   began, start))
            self.warm.bound_sides = (result.x, x_lower, x_upper)
            return result

    def _equalities_only(self, levels, x_lower, x_upper, fixed, damping, start) -> bool:
        """Whether the active bounds path applies (:func:`.equality_stack.equalities_only`)."""
        return equality_stack.equalities_only(self, levels, x_lower, x_upper, fixed, damping, start)

    def solve_equalities(
        self,
        jacobians: Sequence[np.ndarray],
        values: Sequence[np.ndarray],
        x_lower: np.ndarray,
        x_upper: np.ndarray,
        damping: float = 0.0,
        warm: WarmStart | None = None,
    ) -> HqpResult | None:
        """The stack of equality levels ``jacobians[k] x = values[k]`` (highest first) by the active
        bounds alone (:mod:`.active_bounds`), without building :class:`LevelRows`: the answer of
        :meth:`solve` on the default path, or None when that path does not apply (another solver,
        damping, no minimum-norm stage, 0 outside the bounds) or does not verify; then :meth:`solve`
        decides. Lists are taken; what is not real numbers, and a damping not ≥ 0, raise :class:`InvalidInput`;
        a NaN or an infinite value makes the path fail (:meth:`solve` names it), shapes that do not fit give
        None. ``warm``: as :meth:`solve`'s."""
        n = self.n
        jacobians, values = float_arrays("jacobians", jacobians), float_arrays("values", values)
        x_lower, x_upper = floats("x_lower", x_lower), floats("x_upper", x_upper)
        check_damping(damping)
        self._use(warm)
        if (self.solver != ACTIVE_SET or not equality_stack.default_stages(self)
                or (damping != 0.0 and len(jacobians)) or len(values) != len(jacobians)):
            return None
        if x_lower.shape != (n,) or x_upper.shape != (n,):
            return None
        for J, value in zip(jacobians, values, strict=True):
            if J.ndim != 2 or J.shape[1] != n or value.shape != (J.shape[0],):
                return None
        return equality_stack.try_active_bounds(self, jacobians, values, x_lower, x_upper, time.perf_counter())

    def _solve_stages(self, levels, x_lower, x_upper, damping, solver, began, start=None) -> HqpResult:
        n = self.n
        fixed = x_lower == x_upper
        origin = 0.0 if start is None else start
        if any_true(fixed):
            x = np.where(fixed, x_lower, origin)
            Z = self._identity[:, ~fixed]
        elif start is None:
            x, Z = np.zeros(n), self._identity  # (read only: every later Z is a new array)
        else:
            x, Z = start.copy(), self._identity
        free = (~fixed & (np.isfinite(x_lower) | np.isfinite(x_upper))).nonzero()[0]  # bound rows that can bind
        # The hard rows, in x, with the side each was left at: the bounds of the free components (unit
        # rows, kept as indices), then the held inequality rows (their matrix: held).
        held, hard_lower, hard_upper = np.zeros((0, n)), x_lower[free], x_upper[free]
        hard_norms = np.ones(len(free))  # reference norms of the hard rows
        hard_side = np.zeros(len(free), dtype=int)
        if len(free) == n:  # every component bounded: its rows are read as views, not copied
            free = slice(None)
        used: list[str] = []
        iterations: list[int] = []
        carried: list[Extension] = []
        fallbacks: list[str] = []
        stages = list(levels) + ([None] if self.regularize and not (damping > 0.0 and levels) else [])
        for k, level in enumerate(stages):
            mu = damping if k == len(levels) - 1 else 0.0
            name = self.level_solvers[k] if k < len(self.level_solvers) and level is not None else solver
            hard = (free, hard_norms, held, hard_lower, hard_upper, hard_side)
            # One factorisation of the level's (unit-row) projected equality rows: its null space is the
            # next levels' Z, and an equality-only level may be solved by its least-squares step alone.
            eq_factors = None
            if level is not None and level.any_equality and Z.shape[1]:
                norms = level.eq_norms
                eq_factors = _EqualityFactors(level.A_eq @ Z / norms[:, None], norms, self.rank_threshold)
            x, side, how, count = self._stage(k, level, x, Z, hard, mu, name, carried, fallbacks, eq_factors)
            if level is not None and level.extend is not None:
                carried.append(level.extend)
            used.append(how)
            iterations.append(count)
            if level is None:
                break
            hard_side = side
            if eq_factors is not None:  # = null_space(A_eq Z / ‖rows of A_eq‖), the same factorisation
                Z = Z @ eq_factors.null
            elif level.any_equality:
                Z = Z[:, :0]
            if not level.all_equality:
                A_in, lo, hi = level.A_in, level.lower_in, level.upper_in
                value = A_in @ x
                slack = np.maximum(np.maximum(lo - value, value - hi), 0.0)
                magnitude = np.maximum(1.0, np.abs(value))
                row_side = np.where(value >= hi - HELD_SIDE * magnitude, 1, np.where(value <= lo + HELD_SIDE * magnitude, -1, 0))
                held = np.concatenate([held, A_in])
                hard_norms = np.concatenate([hard_norms, level.in_norms])
                if self.hold_tolerance:
                    slack = slack + self.hold_tolerance * magnitude
                hard_lower = np.concatenate([hard_lower, lo - slack])
                hard_upper = np.concatenate([hard_upper, hi + slack])
                hard_side = np.concatenate([hard_side, row_side])
        result = result_of(levels, self._onto_bounds(x, x_lower, x_upper), x_lower, x_upper, fixed, used)
        result.iterations = iterations
        result.fallbacks = fallbacks
        result.solve_time_s = time.perf_counter() - began
        return result

    # --- one stage --------------------------------------------------------------------------
    def _build(self, level, x0, Z, hard, mu) -> _Stage:
        """The stage in ``z = (y, w)`` (see :class:`_Stage` and :mod:`.kernels.stage`), rows scaled to unit
        norm, assembled by compiled code."""
        free, reference, held, hard_lower, hard_upper, hard_side = hard
        compiled, given = _jit_stage(), compiled_input
        if isinstance(free, slice):  # every component bounded
            free = self._all_components
        rows = _NO_LEVEL if level is None else (
            given(level.A_eq), given(level.b_eq), given(level.eq_norms), given(level.A_in), given(level.lower_in),
            given(level.upper_in), given(level.in_norms))
        M, t, m_scale, G, lower, upper, z0, kept, all_kept, guess, m_hard, identity, uniform = compiled.build(
            level is not None, *rows, given(x0), given(Z), given(free, np.int64), given(reference), given(held),
            given(hard_lower), given(hard_upper), given(hard_side, np.int64), float(mu), float(self.rank_threshold))
        return _Stage(M, t, m_scale, G, lower, upper, z0, Z.shape[1], None if all_kept else kept, guess, m_hard,
                      (identity, uniform))

    def _stage(self, k, level, x0, Z, hard, mu, name, carried, fallbacks, eq_factors=None):
        """One level (or the minimum-norm stage when ``level`` is None): x, the sides of the hard
        rows at the end, how it was solved, the active-set iterations. ``eq_factors``: the
        :class:`_EqualityFactors` of the level's unit-row projected equality rows, if it has some.
        The shortcuts first (no stage built), then the stage built, its declared paths tried in
        order (:mod:`.paths`) and the first accepted point kept, else the rescues decide."""
        if Z.shape[1] == 0:
            return x0, hard[5].copy(), ACTIVE_SET, 0
        x = self._shortcut(level, x0, Z, hard, mu, name, carried, eq_factors)
        if x is not None:
            return x, np.zeros(len(hard[5]), dtype=int), ACTIVE_SET, 0
        stage = self._build(level, x0, Z, hard, mu)
        what = "the minimum-norm stage" if level is None else f"level {k}"
        if (level is not None and level.extend is not None) or carried:
            return self._extended(level, x0, Z, hard, mu, name, carried, stage, what)
        key = (k, level is None, stage.G.shape, stage.M.shape)
        attempt = declared.Attempt(self, level, x0, Z, hard, mu, stage, self.warm.working_sets.get(key))
        for path in declared.stage_paths(name, attempt.cached is not None):
            found = path.attempt(attempt)
            if found is None:
                continue
            solution, label = found
            y = rescue.accepted(self, attempt, path.name, solution, label)
            if y is None:
                continue
            self.warm.working_sets[key] = solution.side
            if level is None:
                self.warm.working_sets[_FREE_MINIMUM_NORM] = not any_true(solution.side)
            fallbacks += [f"{what}: {failure}" for failure in attempt.failures]
            return x0 + Z @ y, self._hard_sides(hard[5], stage, solution.side), label, solution.iterations
        x, side, label, count = rescue.after_every_path(attempt, fallbacks, what)
        if level is not None:
            self.warm.working_sets[key] = side
        return x, (side if level is None else self._hard_sides(hard[5], stage, side)), label, count

    def _shortcut(self, level, x0, Z, hard, mu, name, carried, eq_factors) -> np.ndarray | None:
        """A stage's point without building it, or None: an equality-only level's least-squares
        step, or the minimum-norm stage's unconstrained point, if it holds the hard rows."""
        if (eq_factors is not None and name == ACTIVE_SET and mu == 0.0 and level.extend is None and not carried
                and level.all_equality):
            return declared.least_squares_level(self, level, x0, Z, hard, eq_factors)
        if level is None and name == ACTIVE_SET and not carried and self.warm.working_sets.get(_FREE_MINIMUM_NORM, False):
            # The minimum-norm stage's unconstrained point y = -Zᵀx0 (x0's component in range(Z)
            # removed), tried while the last such stage ended with an empty working set (a warm
            # start: a cold solve, where it rarely holds, does not try it).
            return declared.free_step(self, x0, Z, hard, -(Z.T @ x0))
        return None

    def _extended(self, level, x0, Z, hard, mu, name, carried, stage, what):
        """A stage whose levels add rows to Drake's program: Drake's programs alone
        (:func:`.paths.extended_paths`), the first whose point holds the hard rows."""
        failures: list[str] = []
        r = Z.shape[1]
        for attempt in declared.extended_paths(name, SOLVERS):
            x, message = self.programs.solve(level, x0, Z, hard, mu, attempt, carried)
            if x is not None and rescue.bounds_hold(self, stage, Z.T @ (x - x0)):
                side = declared.sides(stage, np.concatenate([Z.T @ (x - x0), np.zeros(len(stage.z0) - r)]))
                return x, self._hard_sides(hard[5], stage, side), attempt, 0
            failures.append(f"{attempt}: {message}")
        raise SolverError(f"hierarchical QP: no solution on {what} ({'; '.join(failures)})")

    @staticmethod
    def _hard_sides(hard_side: np.ndarray, stage: _Stage, side: np.ndarray) -> np.ndarray:
        if stage.hard is None:
            return side[:stage.m_hard].copy()
        out = np.zeros(len(hard_side), dtype=int)
        out[stage.hard] = side[:stage.m_hard]
        return out

    def _onto_bounds(self, x: np.ndarray, x_lower: np.ndarray, x_upper: np.ndarray) -> np.ndarray:
        """``x`` with each component past a bound by round-off only (within the feasibility tolerance,
        as the paths accept their points) put on that bound: the answer then holds its bounds
        exactly. A component farther out (a start kept outside a bound, see :meth:`solve`) stays.
        The compiled :func:`.active_bounds.onto_bounds`, which the active bounds' answers also go
        through (in their :func:`.active_bounds.outcome`)."""
        return _active_bounds_path().onto_bounds(x, x_lower, x_upper, self.feasibility_tolerance)
