"""Hierarchical QP (soth / sot-dyninv ``SolverKine``), level by level with Drake's
``MathematicalProgram``, as on the seed's slides.

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
``w``. Last, unless ``regularize=False``, the minimum-norm ``x`` of the whole optimal set is taken.

How it is solved, exactly where it can be:

* held equality rows and fixed bounds (``x_min = x_max``) are eliminated: ``x = x_{k-1} + Z y`` with
  ``Z`` an orthonormal basis of their null space (SVD, rank threshold ``rank_threshold``), so they
  hold exactly and no program ever sees a degenerate equality;
* an equality-only level first takes its closed-form (damped) least-squares step
  ``y = (A Z)^♯ (b - A x_{k-1})``; if that point satisfies the bounds and the held inequalities it is
  the level's optimum and no program is solved. The same holds for the minimum-norm stage
  (``x - Z Zᵀ x``). With no active bound and no inequality row, the HQP is the strict cascade;
* otherwise the level is a ``MathematicalProgram`` in ``(y, w)``, built once per structure (sizes)
  and updated in place, solved by the level's Drake solver (Clarabel by default, tight tolerances).
  An interior-point answer is only accurate to about the square root of its gap tolerance in ``w``
  (the objective is ``‖w‖²``), so it is then *polished* as on the seed's slides ("the LSI optimum is
  the LSE optimum for the good active set"): the active set read off the solver's answer gives an
  equality-constrained least-squares problem, solved exactly, and kept only if it is feasible and
  no worse than the solver's answer.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from pydrake.solvers import (
    ClarabelSolver,
    MathematicalProgram,
    OsqpSolver,
    SnoptSolver,
    SolverOptions,
)

from ..exceptions import InvalidInput, SolverError

SOLVERS = {"clarabel": ClarabelSolver, "osqp": OsqpSolver, "snopt": SnoptSolver}


def check_solver(name: str) -> str:
    """``name`` if it is one of :data:`SOLVERS`, else :class:`InvalidInput` listing them."""
    if name not in SOLVERS:
        raise InvalidInput(f"unknown QP solver {name!r}; available: {sorted(SOLVERS)}")
    return name


def _options(name: str) -> SolverOptions:
    options = SolverOptions()
    settings = {
        "clarabel": {"tol_gap_abs": 1e-11, "tol_gap_rel": 1e-11, "tol_feas": 1e-11, "max_iter": 500},
        "osqp": {"eps_abs": 1e-9, "eps_rel": 1e-9, "polishing": 1, "max_iter": 50000},
        "snopt": {"Major optimality tolerance": 1e-10, "Major feasibility tolerance": 1e-10},
    }[name]
    solver_id = SOLVERS[name]().solver_id()
    for key, value in settings.items():
        options.SetOption(solver_id, key, value)
    return options


class LevelRows:
    """Rows ``lower ≤ A x ≤ upper`` of one level (``lower[i] == upper[i]``: an equality row)."""

    def __init__(self, A: np.ndarray, lower: np.ndarray, upper: np.ndarray):
        A, lower, upper = (np.asarray(a, dtype=float) for a in (A, lower, upper))
        if A.ndim != 2 or lower.shape != (A.shape[0],) or upper.shape != (A.shape[0],):
            raise InvalidInput(f"level rows: A {A.shape}, lower {lower.shape}, upper {upper.shape} do not fit")
        if not np.all(np.isfinite(A)) or np.any(np.isnan(lower)) or np.any(np.isnan(upper)):
            raise InvalidInput("level rows: NaN or infinite coefficients")
        if np.any(lower > upper):
            raise InvalidInput(f"level rows: lower bound above upper bound in rows {np.flatnonzero(lower > upper)}")
        self.A, self.lower, self.upper = A, lower, upper
        self.equality = lower == upper
        if np.any(~np.isfinite(lower[self.equality])):
            raise InvalidInput("level rows: an equality row needs a finite value")

    def slack(self, x: np.ndarray) -> np.ndarray:
        """Signed residual ``A x - b`` on equality rows, violation ``≥ 0`` on inequality rows."""
        r = self.A @ x
        violation = np.maximum(np.maximum(self.lower - r, r - self.upper), 0.0)
        return np.where(self.equality, r - self.lower, violation)


@dataclass
class HqpResult:
    x: np.ndarray
    slacks: list[np.ndarray]  # per level, see LevelRows.slack
    slack_norms: np.ndarray
    active_rows: list[np.ndarray]  # per level, inequality rows at one of their bounds
    active_bounds: np.ndarray  # components of x at one of their bounds (not the fixed ones)
    solve_time_s: float = 0.0
    level_solvers: list[str] = field(default_factory=list)  # "closed-form" or the Drake solver, per stage

    @property
    def solver_calls(self) -> int:
        return sum(name != "closed-form" for name in self.level_solvers)


class _Program:
    """One cached program in (y, w): min ‖w‖² + μ‖y‖² (or ‖x0 + Z y‖²) s.t. the stacked rows
    ``lower ≤ [C, D] (y, w) ≤ upper`` (bounds, held inequalities and the level's rows)."""

    def __init__(self, r: int, m_constraints: int, m: int):
        self.prog = prog = MathematicalProgram()
        self.y = prog.NewContinuousVariables(r, "y")
        self.w = prog.NewContinuousVariables(m, "w")
        variables = np.concatenate([self.y, self.w])
        self.rows = prog.AddLinearConstraint(
            np.zeros((m_constraints, r + m)), np.zeros(m_constraints), np.zeros(m_constraints), variables
        ) if m_constraints else None
        self.cost = prog.AddQuadraticCost(np.eye(r + m), np.zeros(r + m), variables, is_convex=True)


def _null_space(M: np.ndarray, threshold: float) -> np.ndarray:
    """Orthonormal basis of ``{y : M y = 0}`` (singular values ≤ threshold count as zero)."""
    if M.shape[0] == 0:
        return np.eye(M.shape[1])
    _, sigma, Vt = np.linalg.svd(M, full_matrices=True)
    return Vt[int(np.count_nonzero(sigma > threshold)):].T


class HierarchicalQP:
    """Solve stacks of :class:`LevelRows` in strict priority (see the module docstring)."""

    def __init__(
        self,
        n: int,
        solver: str = "clarabel",
        level_solvers: Sequence[str] | None = None,
        hold_tolerance: float = 1e-9,
        rank_threshold: float = 1e-9,
        regularize: bool = True,
        closed_form: bool = True,
    ):
        for name in [solver, *(level_solvers or [])]:
            check_solver(name)
        self.n, self.solver, self.level_solvers = n, solver, list(level_solvers or [])
        self.hold_tolerance, self.rank_threshold, self.regularize = hold_tolerance, rank_threshold, regularize
        self.closed_form = closed_form  # False: every stage is a program (to test and measure them)
        self._programs: dict[tuple[int, int, int], _Program] = {}  # a cache: results never depend on it
        self._solvers = {name: (SOLVERS[name](), _options(name)) for name in SOLVERS}

    def solve(
        self,
        levels: Sequence[LevelRows],
        x_lower: np.ndarray,
        x_upper: np.ndarray,
        damping: float = 0.0,
        solver: str | None = None,
    ) -> HqpResult:
        """Solve in strict priority; ``damping`` μ applies to the last level; ``solver`` overrides
        the default Drake solver for this call. Raises :class:`SolverError` naming the level when a
        program cannot be solved."""
        solver = self.solver if solver is None else check_solver(solver)
        n = self.n
        x_lower, x_upper = np.asarray(x_lower, dtype=float), np.asarray(x_upper, dtype=float)
        if x_lower.shape != (n,) or x_upper.shape != (n,) or np.any(np.isnan(x_lower)) or np.any(np.isnan(x_upper)):
            raise InvalidInput(f"bounds must be {n} numbers without NaN")
        if np.any(x_lower > x_upper):
            raise InvalidInput(f"lower bound above upper bound at {np.flatnonzero(x_lower > x_upper)}")
        if not np.all(np.isfinite(x_lower[x_lower == x_upper])):
            raise InvalidInput("a fixed component (lower == upper) needs a finite value")
        for level in levels:
            if level.A.shape[1] != n:
                raise InvalidInput(f"a level has {level.A.shape[1]} columns, expected {n}")
        start = time.perf_counter()
        fixed = x_lower == x_upper
        x = np.where(fixed, x_lower, 0.0)
        Z = np.eye(n)[:, ~fixed]
        free = ~fixed & (np.isfinite(x_lower) | np.isfinite(x_upper))  # bound rows that can bind
        bound_rows = (np.eye(n)[free], x_lower[free], x_upper[free])
        held = (np.zeros((0, n)), np.zeros(0), np.zeros(0))  # held inequality rows
        used = []
        stages = list(levels) + ([None] if self.regularize else [])
        for k, level in enumerate(stages):
            mu = damping if k == len(levels) - 1 else 0.0
            x, how = self._stage(k, level, x, Z, bound_rows, held, mu, solver)
            used.append(how)
            if level is None:
                break
            eq = level.equality
            Z = Z @ _null_space(level.A[eq] @ Z, self.rank_threshold) if eq.any() else Z
            if (~eq).any():
                slack = level.slack(x)[~eq]
                band = self.hold_tolerance
                held = (np.vstack([held[0], level.A[~eq]]),
                        np.concatenate([held[1], level.lower[~eq] - slack - band]),
                        np.concatenate([held[2], level.upper[~eq] + slack + band]))
        result = self._result(levels, x, x_lower, x_upper, fixed, used)
        result.solve_time_s = time.perf_counter() - start
        return result

    def _stage(self, k, level, x0, Z, bound_rows, held, mu, solver: str) -> tuple[np.ndarray, str]:
        """One level (or the minimum-norm stage when ``level`` is None): returns x and how."""
        r = Z.shape[1]
        if r == 0:
            return x0, "closed-form"
        constraint_A = np.vstack([bound_rows[0], held[0]])
        offset = constraint_A @ x0
        # Never ask more than the previous point achieves: a round-off violation left by a solver
        # (≈ its tolerance) may not grow, and cannot make this stage infeasible (y = 0 stays feasible).
        constraint_lower = np.minimum(np.concatenate([bound_rows[1], held[1]]), offset)
        constraint_upper = np.maximum(np.concatenate([bound_rows[2], held[2]]), offset)

        def feasible(x):
            value = constraint_A @ x
            slack = 1e-10 * np.maximum(1.0, np.abs(value))
            return np.all(value >= constraint_lower - slack) and np.all(value <= constraint_upper + slack)

        # Closed form: the (damped) least-squares step, or the projection for the minimum norm.
        if self.closed_form and level is None:
            x = x0 - Z @ (Z.T @ x0)
            if feasible(x):
                return x, "closed-form"
        elif self.closed_form and level.equality.all():
            U, sigma, Vt = np.linalg.svd(level.A @ Z, full_matrices=False)
            keep = sigma > self.rank_threshold
            s = sigma[keep]
            inverse = 1.0 / s if mu == 0.0 else s / (s * s + mu)
            y = Vt[keep].T @ (inverse * (U[:, keep].T @ (level.lower - level.A @ x0)))
            x = x0 + Z @ y
            if feasible(x):
                return x, "closed-form"

        # The program in (y, w).
        m = 0 if level is None else level.A.shape[0]
        C = constraint_A @ Z
        with np.errstate(invalid="ignore"):
            rows_A = [np.hstack([C, np.zeros((len(C), m))])]
            rows_lower, rows_upper = [constraint_lower - offset], [constraint_upper - offset]
        if level is not None:
            AZ, Ax0, identity = level.A @ Z, level.A @ x0, np.eye(m)
            rows_A += [np.hstack([AZ, -identity]), np.hstack([AZ, identity])]
            rows_lower += [np.full(m, -np.inf), level.lower - Ax0]
            rows_upper += [level.upper - Ax0, np.full(m, np.inf)]
        A_all = np.vstack(rows_A)
        program = self._programs.get((r, len(A_all), m))
        if program is None:
            program = self._programs[(r, len(A_all), m)] = _Program(r, len(A_all), m)
        if program.rows is not None:
            program.rows.evaluator().UpdateCoefficients(A_all, np.concatenate(rows_lower), np.concatenate(rows_upper))
        if level is None:  # ‖x0 + Z y‖² = ‖y‖² + 2 (Zᵀx0)ᵀ y + const
            Q, b = 2.0 * np.eye(r), 2.0 * (Z.T @ x0)
        else:
            Q = np.diag(np.concatenate([np.full(r, 2.0 * mu), np.full(m, 2.0)]))
            b = np.zeros(r + m)
        program.cost.evaluator().UpdateCoefficients(Q, b)
        name = self.level_solvers[k] if k < len(self.level_solvers) else solver
        what = "the minimum-norm stage" if level is None else f"level {k}"
        failures = []
        # A solver that stops short (e.g. "insufficient progress") usually leaves a point from which
        # the active-set polish finds the exact optimum; OSQP is the fallback for the rest.
        for attempt in dict.fromkeys([name, "osqp"]):
            drake_solver, options = self._solvers[attempt]
            result = drake_solver.Solve(program.prog, np.zeros(r + m), options)
            x = x0 + Z @ result.GetSolution(program.y)
            if not np.all(np.isfinite(x)):
                failures.append(f"{attempt}: {result.get_solution_result()}")
                continue
            polished = self._polish(level, x, x0, Z, constraint_A, constraint_lower, constraint_upper, mu)
            if polished is not None:
                return polished, attempt + "+polish"
            if result.is_success():
                return x, attempt
            failures.append(f"{attempt}: {result.get_solution_result()}")
        raise SolverError(f"hierarchical QP: no solution on {what} ({'; '.join(failures)})")

    @staticmethod
    def _stage_cost(level, x, x0, Z, mu) -> float:
        if level is None:
            return float(x @ x)
        step = Z.T @ (x - x0)
        return float(np.sum(level.slack(x) ** 2) + mu * step @ step)

    def _polish(self, level, x, x0, Z, C_A, C_lower, C_upper, mu) -> np.ndarray | None:
        """Exact LSI by a primal active set started from ``x`` (see the module docstring), or None.

        Working set: constraint rows held at one of their bounds, and the level's inequality rows
        in the objective at one of their bounds. Each iteration solves the equality-constrained
        least squares of the working set, then adds the most violated constraint or row, or drops
        a row now satisfied or a constraint whose multiplier has the wrong sign.
        """
        r = Z.shape[1]
        C = C_A @ Z
        c_lower, c_upper = C_lower - C_A @ x0, C_upper - C_A @ x0
        if level is None:
            A, lo, hi, eq = Z, -x0, -x0, np.ones(self.n, dtype=bool)
        else:
            A, lo, hi, eq = level.A @ Z, level.lower - level.A @ x0, level.upper - level.A @ x0, level.equality
        y = Z.T @ (x - x0)

        def side(value, lower, upper, threshold):  # -1: at lower, +1: at upper, 0: free
            scale = threshold * np.maximum(1.0, np.abs(value))
            return np.where(value <= lower + scale, -1, np.where(value >= upper - scale, 1, 0))

        held = side(C @ y, c_lower, c_upper, 1e-5)
        rows = np.where(eq, 0, side(A @ y, lo, hi, 1e-5))
        seen = set()
        for _ in range(4 * (len(C) + len(A)) + 10):
            working = (held.tobytes(), rows.tobytes())
            if working in seen:  # cycling (degenerate constraints): give up, keep the solver's point
                return None
            seen.add(working)
            in_objective = eq | (rows != 0)
            M = A[in_objective]
            t = np.where(eq, lo, np.where(rows > 0, hi, lo))[in_objective]
            if mu > 0.0:
                M, t = np.vstack([M, np.sqrt(mu) * np.eye(r)]), np.concatenate([t, np.zeros(r)])
            E, e = C[held != 0], np.where(held > 0, c_upper, c_lower)[held != 0]
            y = np.linalg.lstsq(E, e, rcond=None)[0] if len(E) else np.zeros(r)
            N = _null_space(E, self.rank_threshold) if len(E) else np.eye(r)
            if N.shape[1]:
                y = y + N @ np.linalg.lstsq(M @ N, t - M @ y, rcond=None)[0]
            value, row_value = C @ y, A @ y
            tol = 1e-10 * np.maximum(1.0, np.abs(value))
            violation = np.maximum(c_lower - tol - value, value - c_upper - tol) * (held == 0)
            if np.any(violation > 0):
                i = int(np.argmax(violation))
                held[i] = 1 if value[i] > c_upper[i] else -1
                continue
            row_tol = 1e-10 * np.maximum(1.0, np.abs(row_value))
            outside = np.maximum(lo - row_tol - row_value, row_value - hi - row_tol) * (~eq & (rows == 0))
            if np.any(outside > 0):
                i = int(np.argmax(outside))
                rows[i] = 1 if row_value[i] > hi[i] else -1
                continue
            # Rows pulled back inside their bounds leave the objective.
            inside = ~eq & (((rows > 0) & (row_value < hi - row_tol)) | ((rows < 0) & (row_value > lo + row_tol)))
            if inside.any():
                rows[np.flatnonzero(inside)[0]] = 0
                continue
            if len(E):  # multipliers: Mᵀ(M y - t) + Eᵀ λ = 0; λ ≥ 0 at upper, ≤ 0 at lower
                lam = -np.linalg.lstsq(E.T, M.T @ (M @ y - t), rcond=None)[0]
                wrong = np.where(held[held != 0] > 0, -lam, lam)
                if np.any(wrong > 1e-9):
                    held[np.flatnonzero(held)[int(np.argmax(wrong))]] = 0
                    continue
            if np.any(value < c_lower - tol) or np.any(value > c_upper + tol):
                return None  # an inconsistent working set: least squares could not hold it
            # KKT holds (feasible, rows on the right side, multipliers of the right sign): this is the
            # optimum of the convex stage. The cost comparison only guards against a bug.
            candidate = x0 + Z @ y
            cost, solver_cost = self._stage_cost(level, candidate, x0, Z, mu), self._stage_cost(level, x, x0, Z, mu)
            return candidate if cost <= solver_cost * (1 + 1e-6) + 1e-12 else None
        return None

    def _result(self, levels, x, x_lower, x_upper, fixed, used) -> HqpResult:
        slacks = [level.slack(x) for level in levels]
        active = []
        for level in levels:
            r = level.A @ x
            scale = 1e-7 * np.maximum(1.0, np.abs(r))
            at_bound = (np.abs(r - level.lower) <= scale) | (np.abs(r - level.upper) <= scale)
            active.append(np.flatnonzero(at_bound & ~level.equality))
        scale = 1e-7 * np.maximum(1.0, np.abs(x))
        bounds = np.flatnonzero(~fixed & ((np.abs(x - x_lower) <= scale) | (np.abs(x - x_upper) <= scale)))
        return HqpResult(
            x=x,
            slacks=slacks,
            slack_norms=np.array([np.linalg.norm(s) for s in slacks]),
            active_rows=active,
            active_bounds=bounds,
            level_solvers=used,
        )
