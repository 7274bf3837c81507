"""The QR path for equality hierarchies against the hierarchical QP it stands in for."""

import numpy as np
import pytest

from sotdrake.solvers.equality_hierarchy import solve_equality_hierarchy
from sotdrake.solvers.hqp import HierarchicalQP, LevelRows


def pairs(levels):
    return [(level.A, level.b_eq) for level in levels]


def random_levels(rng, n, conflicting=False):
    levels, rows = [], []
    for _ in range(int(rng.integers(1, 6))):
        m = int(rng.integers(1, n + 3))
        A = rng.normal(size=(m, n)) * 10.0 ** rng.uniform(-2, 2, size=(m, 1))
        if conflicting and rows and rng.random() < 0.5:
            A[0] = rows[0]  # a row a higher level already fixes, another target
        rows.extend(A)
        b = rng.normal(size=m)
        levels.append(LevelRows(A, b, b))
    return levels


@pytest.mark.parametrize("seed", range(150))
def test_qr_path_is_the_hierarchical_qp(seed):
    """Where it answers, the QR path gives the QP's point and slacks; with no conflict and loose
    bounds it always answers."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(3, 45))
    conflicting = seed % 3 == 0
    levels = random_levels(rng, n, conflicting)
    lower, upper = np.full(n, -1e6), np.full(n, 1e6)
    fixed = rng.random(n) < 0.15
    lower[fixed] = upper[fixed] = rng.normal(size=fixed.sum())
    result = solve_equality_hierarchy(pairs(levels), lower, upper)
    if not conflicting:
        assert result is not None
    if result is None:
        return
    reference = HierarchicalQP(n).solve(levels, lower, upper)
    scale = max(1.0, float(np.abs(reference.x).max()))
    np.testing.assert_allclose(result.x, reference.x, rtol=0, atol=1e-8 * scale)
    np.testing.assert_allclose(result.slack_norms, reference.slack_norms, rtol=1e-6, atol=1e-8 * scale)
    assert np.all(result.x[fixed] == lower[fixed])


@pytest.mark.parametrize("seed", range(20))
def test_conflicts_and_rank_losses_are_the_qps_answer(seed):
    """A level that repeats a row of a higher one (its projection is round-off), or has dependent
    rows, goes through the rank-revealing path: same point and slacks as the QP."""
    rng = np.random.default_rng(seed)
    n = 12
    top = rng.normal(size=(3, n))
    below = np.vstack([top[1], rng.normal(size=(2, n))])
    dependent = rng.normal(size=(2, n))
    dependent = np.vstack([dependent, dependent.sum(axis=0)])
    last = rng.normal(size=(4, n))
    for levels in ([LevelRows(top, np.zeros(3), np.zeros(3)), LevelRows(below, np.ones(3), np.ones(3)),
                    LevelRows(last, np.ones(4), np.ones(4))],
                   [LevelRows(dependent, np.array([1.0, 2.0, 0.0]), np.array([1.0, 2.0, 0.0])),
                    LevelRows(last, np.ones(4), np.ones(4))]):
        bounds = np.full(n, -10.0), np.full(n, 10.0)
        result = solve_equality_hierarchy(pairs(levels), *bounds)
        reference = HierarchicalQP(n).solve(levels, *bounds)
        assert result is not None
        np.testing.assert_allclose(result.x, reference.x, atol=1e-9)
        np.testing.assert_allclose(result.slack_norms, reference.slack_norms, atol=1e-9)


def test_a_rank_decision_near_the_threshold_is_left_to_the_qp():
    """A row whose projection is between clearly zero and clearly not: no answer."""
    n = 6
    A = np.eye(2, n)
    near = np.array([[1.0, 0.0, 1e-9, 0.0, 0.0, 0.0]])  # projects to 1e-9 (unit-norm row)
    levels = [LevelRows(A, np.zeros(2), np.zeros(2)), LevelRows(near, np.ones(1), np.ones(1))]
    assert solve_equality_hierarchy(pairs(levels), np.full(n, -1e12), np.full(n, 1e12)) is None


def test_a_bound_in_the_way_or_a_nan_is_left_to_the_qp():
    n = 4
    A = np.eye(2, n)
    b = np.array([2.0, -2.0])
    assert solve_equality_hierarchy([(A, b)], np.full(n, -1.0), np.full(n, 1.0)) is None
    assert solve_equality_hierarchy([(A, b)], np.full(n, -3.0), np.full(n, 3.0)) is not None
    assert solve_equality_hierarchy([(A, b * np.nan)], np.full(n, -3.0), np.full(n, 3.0)) is None
    assert solve_equality_hierarchy([(A * np.nan, b)], np.full(n, -3.0), np.full(n, 3.0)) is None


def test_minimum_norm_of_what_is_left_and_fixed_components():
    """One row x0 + x1 = 2 with x2 fixed at 5: the minimum-norm point is (1, 1, 5, 0)."""
    A = np.array([[1.0, 1.0, 1.0, 0.0]])
    lower, upper = np.array([-9.0, -9.0, 5.0, -9.0]), np.array([9.0, 9.0, 5.0, 9.0])
    result = solve_equality_hierarchy([(A, np.array([7.0]))], lower, upper)
    np.testing.assert_allclose(result.x, [1.0, 1.0, 5.0, 0.0], atol=1e-14)
    assert result.slack_norms[0] == pytest.approx(0.0, abs=1e-14)
