"""Drake's ``MathematicalProgram`` path of a stage: the stage written as a program in ``(y, w)`` and
solved by one of Drake's solvers (:data:`~.problem.SOLVERS`); the paths polish its point with the
active set (:class:`~.paths.PolishedDrake`), and a stage whose levels add rows to the program
(:data:`~.problem.Extension`) is solved by it alone (:func:`~.paths.extended_paths`).
"""

from __future__ import annotations

import numpy as np
from pydrake.solvers import MathematicalProgram, SolverOptions

from .problem import SOLVERS


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



class DrakePrograms:
    """The programs of one QP (cached per size: rebuilding one costs more than solving it) and its
    Drake solvers (made once). A cache: the answers do not depend on it."""

    def __init__(self, n: int):
        self.n = n
        self._cache: dict[tuple[int, int, int], _Program] = {}
        self._solvers: dict[str, tuple] = {}

    def _solver(self, name: str):
        if name not in self._solvers:
            self._solvers[name] = (SOLVERS[name](), _options(name))
        return self._solvers[name]


    def solve(self, level, x0, Z, hard, mu, name, carried=None):
        """The stage as a ``MathematicalProgram`` in ``(y, w)`` solved by Drake's ``name``:
        ``(x, "")`` or ``(None, why)``."""
        free, _, held, hard_lower, hard_upper, _ = hard
        hard_A = np.concatenate([np.eye(self.n)[free], held])  # the bound rows (unit rows of x), the held rows
        r = Z.shape[1]
        m = 0 if level is None else level.A.shape[0]
        extended = carried is not None
        offset = hard_A @ x0
        c_lower = np.minimum(hard_lower, offset) - offset
        c_upper = np.maximum(hard_upper, offset) - offset
        C = hard_A @ Z
        rows_A, rows_lower, rows_upper = [np.hstack([C, np.zeros((len(C), m))])], [c_lower], [c_upper]
        if level is not None:
            AZ, Ax0, identity = level.A @ Z, level.A @ x0, np.eye(m)
            rows_A += [np.hstack([AZ, -identity]), np.hstack([AZ, identity])]
            rows_lower += [np.full(m, -np.inf), level.lower - Ax0]
            rows_upper += [level.upper - Ax0, np.full(m, np.inf)]
        A_all = np.vstack(rows_A)
        if level is None:  # ‖x0 + Z y‖² = ‖y‖² + 2 (Zᵀx0)ᵀ y + const
            Q, b = 2.0 * np.eye(r), 2.0 * (Z.T @ x0)
        else:
            Q = np.diag(np.concatenate([np.full(r, 2.0 * mu), np.full(m, 2.0)]))
            b = np.zeros(r + m)
        if extended:
            program = _Program(r, len(A_all), m)
        else:
            cached = self._cache.get((r, len(A_all), m))
            program = cached if cached is not None else _Program(r, len(A_all), m)
            self._cache[(r, len(A_all), m)] = program
        if program.rows is not None:
            program.rows.evaluator().UpdateCoefficients(A_all, np.concatenate(rows_lower), np.concatenate(rows_upper))
        program.cost.evaluator().UpdateCoefficients(Q, b)
        if extended:
            with np.errstate(invalid="ignore"):  # numpy's checks on symbolic (object) arrays
                x_expression = x0 + Z @ program.y
            for extension in carried:
                extension(program.prog, x_expression, False)
            if level is not None and level.extend is not None:
                level.extend(program.prog, x_expression, True)
        drake_solver, options = self._solver(name)
        result = drake_solver.Solve(program.prog, np.zeros(r + m), options)
        x = x0 + Z @ result.GetSolution(program.y)
        if not np.isfinite(x).all():
            return None, str(result.get_solution_result())
        if extended and not result.is_success():
            return None, str(result.get_solution_result())
        return x, ""

