"""A stage whose primal paths all end past a row (a sliver of the feasible set) is answered by the dual
method's own point, which holds every row and is optimal.

The two stacks are ``SolverDyn``'s, captured on randomized collision reaches
(``bench/collision_runs.py --dynamic``, torso targets, t = 7 ms): on the damping level, six of the
contacts' wrench rows pass through the start, one implied by five others to within 7.8e-10 (under the
rank threshold τ), and the objective pulls along the direction they leave free. The active set, its
degenerate retries, Clarabel and OSQP all ended 5.3e-8 past that row (or cycled) on the machine where
they were captured (which path answers elsewhere depends on the round-off: the tests assert the contract)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import nnls

from sotdrake.hqp import HierarchicalQP, LevelRows
from sotdrake.hqp.guesses import dual_point
from sotdrake.hqp.paths import DualPoint, stage_paths

DATA = np.load(Path(__file__).parent / "data" / "sliver_damping_level.npz")
LEVELS = 7


def problem(k: int) -> tuple[list[LevelRows], np.ndarray, np.ndarray, np.ndarray]:
    levels = [LevelRows(DATA[f"p{k}_A{j}"], DATA[f"p{k}_lo{j}"], DATA[f"p{k}_up{j}"]) for j in range(LEVELS)]
    return levels, DATA[f"p{k}_x_lower"], DATA[f"p{k}_x_upper"], DATA[f"p{k}_start"]


@pytest.mark.parametrize("k", [0, 1])
def test_the_stack_is_solved_with_every_level_above_untouched(k):
    levels, lower, upper, start = problem(k)
    n = len(lower)
    result = HierarchicalQP(n).solve(levels, lower, upper, start=start)
    above = HierarchicalQP(n).solve(levels[:-1], lower, upper, start=start)
    scale = 1.0 + np.abs(result.x).max()
    assert np.all(result.x >= lower - 1e-9 * scale) and np.all(result.x <= upper + 1e-9 * scale)
    # Strictness: the levels above keep the optimum they have without the damping level, to the
    # solver's feasibility tolerance on rows of that size (1e-9 relative to the point: the rows'
    # check below; an absolute 1e-9 failed under OpenBLAS' Sandybridge kernels, 3.8e-8 at |x| = 540).
    np.testing.assert_allclose(result.slack_norms[:-1], above.slack_norms, rtol=1e-9, atol=1e-9 * scale)
    for level in levels:  # every inequality row of every level above holds (their slack is zero)
        value = level.A @ result.x
        inequality = ~level.equality
        if inequality.any() and level is not levels[-1]:
            assert np.all(value[inequality] <= level.upper[inequality] + 1e-9 * scale)
            assert np.all(value[inequality] >= level.lower[inequality] - 1e-9 * scale)


@pytest.mark.parametrize("k", [0, 1])
def test_the_dual_point_is_feasible_and_satisfies_the_kkt_conditions(k):
    """Checked independently of the solver: every row within 1e-10, and the objective's gradient
    ``Mᵀ(M z − t)`` is, to 1e-6 of its size, a combination with multipliers of the right signs of
    the rows held at their sides (a non-negative least-squares fit, scipy's ``nnls``)."""
    M, t, G, lower, upper = (DATA[f"s{k}_{key}"] for key in ("M", "t", "G", "lower", "upper"))
    found = dual_point(M, t, G, lower, upper)
    assert found is not None
    z, side = found
    value = G @ z
    assert np.all(value >= lower - 1e-10) and np.all(value <= upper + 1e-10)
    np.testing.assert_allclose(value[side > 0], upper[side > 0], atol=1e-10)
    np.testing.assert_allclose(value[side < 0], lower[side < 0], atol=1e-10)
    gradient = M.T @ (M @ z - t)
    # Optimality: -gradient = Σ_{upper} λ_i g_i - Σ_{lower} λ_i g_i with λ ≥ 0.
    directions = np.vstack([G[side > 0], -G[side < 0]]).T
    multipliers, residual = nnls(directions, -gradient)
    assert residual <= 1e-6 * np.linalg.norm(gradient)


def test_the_dual_point_is_a_rescue_not_a_path_and_needs_a_strictly_convex_objective():
    """Only when every path failed (and the round-off rescue did not apply) is the dual point tried;
    a stage whose ``MᵀM`` is singular gets none (a regularised optimum can be far from the level's)."""
    for solver, warm in (("active-set", True), ("active-set", False), ("clarabel", False)):
        assert not any(isinstance(path, DualPoint) for path in stage_paths(solver, warm))
    M = np.array([[1.0, 1.0, 0.0]])  # rank 1 in three variables
    assert dual_point(M, np.ones(1), np.eye(3), -np.ones(3), np.ones(3)) is None


def test_a_dual_point_of_inconsistent_rows_is_none():
    G = np.array([[1.0, 0.0], [1.0, 0.0]])
    assert dual_point(np.eye(2), np.ones(2), G, np.array([1.0, -np.inf]), np.array([np.inf, 0.0])) is None
