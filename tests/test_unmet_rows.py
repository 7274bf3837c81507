"""A collision level's rows kept exact when one of them cannot be met (sotdrake.solvers.unmet_rows).

Pure: the stack is solved by ``HierarchicalQP`` from task levels, no Diagram. The refined answer is
checked against the contract: the levels above keep their optimum, every kept row holds, the moved
rows are met as closely as the kept ones allow, and a level that holds costs no extra solve.
"""

from __future__ import annotations

import numpy as np
import pytest

from sotdrake.hqp import HierarchicalQP, LevelRows
from sotdrake.solvers.unmet_rows import MAX_ROUNDS, keep_met_rows, keyed_inequality, merged, split, unmet
from sotdrake.task import TaskLevel

INF = np.inf


def keyed(J, lower, upper=None) -> TaskLevel:
    J = np.atleast_2d(np.asarray(J, dtype=float))
    lower = np.asarray(lower, dtype=float)
    upper = np.full(len(lower), INF) if upper is None else np.asarray(upper, dtype=float)
    return TaskLevel(J, lower, upper, np.zeros(len(lower)), np.arange(100, 100 + len(lower)))


def stack_solver(x_lower, x_upper, above=(), below=()):
    """``solve(tasks)``: the levels ``above`` (LevelRows), the task levels, then ``below``; counts its calls."""
    calls = []

    def solve(tasks):
        calls.append(len(tasks))
        levels = [*above, *(LevelRows(t.jacobian, t.lower, t.upper) for t in tasks), *below]
        return HierarchicalQP(len(x_lower)).solve(levels, x_lower, x_upper)

    return solve, calls


def violation(task: TaskLevel, x: np.ndarray) -> np.ndarray:
    r = task.jacobian @ x
    return np.maximum(np.maximum(task.lower - r, r - task.upper), 0.0)


def test_one_infeasible_row_no_longer_spreads_its_slack():
    # x in [-1, 1]²; the level: x0 + x1 ≥ 3 (at most 2: infeasible) and x0 ≤ 0.5. In the least-squares
    # sense x0 goes past 0.5 to shave the first row's violation; refined, x0 = 0.5 holds and the
    # first row is met as closely as it allows (x1 = 1, violation 1.5).
    lo, hi = -np.ones(2), np.ones(2)
    task = keyed([[1, 1], [1, 0]], [3, -INF], [INF, 0.5])
    solve, calls = stack_solver(lo, hi)
    plain = solve([task])
    assert plain.slacks[0][1] > 1e-3  # (the spread the refinement is for)
    refined = keep_met_rows(solve, [task], plain, 0)
    assert calls == [1, 2]
    assert refined.slacks[0][1] <= 1e-12
    np.testing.assert_allclose(refined.x, [0.5, 1.0], atol=1e-9)
    np.testing.assert_allclose(refined.slacks[0], violation(task, refined.x), atol=1e-12)
    assert len(refined.slacks) == len(plain.slacks) == 1


def test_a_level_that_holds_costs_no_extra_solve():
    lo, hi = -np.ones(3), np.ones(3)
    task = keyed(np.eye(3), [-0.5, -0.5, -0.5])
    solve, calls = stack_solver(lo, hi, below=[LevelRows(np.eye(3), -2 * np.ones(3), -2 * np.ones(3))])
    plain = solve([task])
    assert keep_met_rows(solve, [task], plain, 0) is plain
    assert calls == [1]


def test_levels_above_keep_their_optimum_and_levels_below_see_the_rest():
    # Above: x2 = 0.3 exactly. The keyed level: x0 + x1 + x2 ≥ 3.5 (infeasible), x1 ≤ 0.2, x0 ≤ 0.4.
    # Below: x as close to (1, 1, 1) as what is left allows.
    lo, hi = -np.ones(3), np.ones(3)
    above = [LevelRows(np.array([[0.0, 0, 1]]), np.array([0.3]), np.array([0.3]))]
    below = [LevelRows(np.eye(3), np.ones(3), np.ones(3))]
    task = keyed([[1, 1, 1], [0, 1, 0], [1, 0, 0]], [3.5, -INF, -INF], [INF, 0.2, 0.4])
    solve, _ = stack_solver(lo, hi, above, below)
    plain = solve([task])
    assert unmet(task, plain.slacks[1])[1:].any()
    refined = keep_met_rows(solve, [task], plain, 1)
    assert abs(refined.x[2] - 0.3) <= 1e-12 and refined.slacks[0][0] <= 1e-12
    assert np.all(refined.slacks[1][1:] <= 1e-12)
    np.testing.assert_allclose(refined.x, [0.4, 0.2, 0.3], atol=1e-9)
    assert len(refined.slacks) == 3 and refined.slacks[1].shape == (3,)


def test_merged_puts_slacks_and_active_rows_back_in_the_level_order():
    task = keyed(np.eye(4), [0, 0, 0, 0])
    moved = np.array([False, True, False, True])
    kept, rest = split(task, moved)
    np.testing.assert_array_equal(kept.row_keys, [100, 102])
    np.testing.assert_array_equal(rest.row_keys, [101, 103])
    solve, _ = stack_solver(-np.ones(4), np.ones(4))
    answer = solve([kept, rest])
    answer.slacks[0][:] = [1.0, 3.0]
    answer.slacks[1][:] = [2.0, 4.0]
    answer.active_rows[0] = np.array([1])
    answer.active_rows[1] = np.array([0])
    back = merged(answer, 0, moved)
    np.testing.assert_array_equal(back.slacks[0], [1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(back.active_rows[0], [1, 2])
    assert back.slack_norms[0] == pytest.approx(np.sqrt(30.0))


def test_only_keyed_inequality_levels_are_refined():
    equality = TaskLevel(np.eye(2), np.zeros(2), np.zeros(2), np.zeros(2), np.arange(2))
    unkeyed = TaskLevel(np.eye(2), np.zeros(2), np.full(2, INF), np.zeros(2))
    assert not keyed_inequality(equality) and not keyed_inequality(unkeyed)
    assert keyed_inequality(keyed(np.eye(2), [0, 0]))
    assert not keyed_inequality(keyed(np.zeros((0, 2)), []))


@pytest.mark.parametrize("seed", range(40))
def test_random_levels_keep_every_row_that_can_hold(seed):
    """A random level of feasible rows (they all hold at a point inside the bounds) plus one row no
    point within the bounds meets, under a random equality level above and a posture below: the
    refined answer keeps the level above exact and holds every feasible row exactly, with at most
    MAX_ROUNDS rows moved."""
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(4, 9)), int(rng.integers(3, 8))
    lo, hi = -np.ones(n), np.ones(n)
    A_above = rng.normal(size=(1, n))
    x_in = rng.uniform(-0.5, 0.5, n)
    above = [LevelRows(A_above, A_above @ x_in, A_above @ x_in)]
    J = rng.normal(size=(m, n))
    lower = J @ x_in - rng.uniform(0.0, 0.3, m)
    far = rng.normal(size=n)
    J = np.vstack([J, far])
    lower = np.append(lower, np.abs(far).sum() + 1.0)  # (beyond what the box allows)
    task = keyed(J, lower)
    below = [LevelRows(np.eye(n), np.ones(n), np.ones(n))]
    solve, calls = stack_solver(lo, hi, above, below)
    plain = solve([task])
    refined = keep_met_rows(solve, [task], plain, 1)
    assert refined.slacks[0][0] <= 1e-9 * max(1.0, abs(above[0].lower[0]))
    assert np.all((refined.x >= lo - 1e-12) & (refined.x <= hi + 1e-12))
    np.testing.assert_allclose(refined.slacks[1], violation(task, refined.x), atol=1e-9)
    assert refined is not plain  # (in this family the one infeasible row has the largest slack)
    met = ~unmet(task, refined.slacks[1])
    assert met[:m].all(), "a row that can hold was given up"
    assert np.count_nonzero(~met) <= MAX_ROUNDS and len(calls) <= 1 + MAX_ROUNDS
