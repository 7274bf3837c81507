"""The hierarchical QP against an independent lexicographic reference on random stacks."""

import numpy as np
import pytest
import quadprog

from sotdrake.exceptions import InvalidInput
from sotdrake.solvers.hqp import HierarchicalQP, LevelRows


def random_problem(rng, with_inequalities=True):
    n = int(rng.integers(3, 9))
    levels = []
    for _ in range(int(rng.integers(1, 5))):
        m = int(rng.integers(1, 6))
        rank = int(rng.integers(1, min(m, n) + 1))
        # Rank-deficient but well conditioned: nonzero singular values in [0.5, 2].
        U = np.linalg.qr(rng.normal(size=(m, m)))[0][:, :rank]
        V = np.linalg.qr(rng.normal(size=(n, n)))[0][:, :rank]
        A = U @ np.diag(rng.uniform(0.5, 2.0, rank)) @ V.T
        b = rng.normal(size=m)
        lower, upper = b.copy(), b.copy()
        if with_inequalities:
            inequality = rng.random(m) < 0.5
            width = rng.uniform(0.0, 1.0, m)
            lower = np.where(inequality, b - width, b)
            upper = np.where(inequality, b + width, b)
            lower[inequality & (rng.random(m) < 0.2)] = -np.inf
            upper[inequality & (rng.random(m) < 0.2)] = np.inf
        levels.append(LevelRows(A, lower, upper))
    x_upper = np.where(rng.random(n) < 0.7, rng.uniform(0.05, 1.5, n), np.inf)
    x_lower = np.where(rng.random(n) < 0.7, -rng.uniform(0.05, 1.5, n), -np.inf)
    fixed = rng.random(n) < 0.1
    x_lower[fixed] = x_upper[fixed] = 0.0
    return n, levels, x_lower, x_upper


def reference_slack_norms(n, levels, x_lower, x_upper, epsilon=1e-12):
    """Sequential QPs written independently of the solver under test, solved by Goldfarb-Idnani's
    dual active-set method (quadprog: exact at convergence, no interior point, no Drake). Each level
    lives in the null space of *all* equality rows held so far (and the fixed bounds), recomputed
    from scratch by one SVD of their stack, with one slack per side of each row:
    min ‖up‖² + ‖down‖² + ε‖y‖² (ε makes the Hessian definite; it moves a slack by ~ε, far below the
    test's tolerance). Inequality rows are held within 1e-9 of their optimal violation."""
    fixed = x_lower == x_upper
    equalities = [np.eye(n)[fixed]]
    x_previous = np.where(fixed, x_lower, 0.0)
    inequalities = []  # (A, lo, hi)
    norms = []
    for level in levels:
        E = np.vstack(equalities)
        _, sigma, Vt = np.linalg.svd(E) if len(E) else (None, np.zeros(0), np.eye(n))
        N = Vt[int(np.sum(sigma > 1e-9)):].T  # x = x_previous + N y
        r, m = N.shape[1], level.A.shape[0]
        size = r + 2 * m  # z = (y, up, down)
        rows, rhs = [], []  # rows · z ≥ rhs

        def at_least(coefficients, value):
            if not np.isfinite(value):
                return
            if np.linalg.norm(coefficients) < 1e-12:  # nothing left to constrain (y = 0 satisfies it)
                assert value <= 1e-9
                return
            rows.append(coefficients)
            rhs.append(value)

        for A, lo, hi in [(np.eye(n)[~fixed], x_lower[~fixed], x_upper[~fixed])] + inequalities:
            at, AN = A @ x_previous, A @ N
            for i in range(len(A)):  # relaxed to contain y = 0, as the previous point satisfies them
                at_least(np.concatenate([AN[i], np.zeros(2 * m)]), min(lo[i], at[i]) - at[i])
                at_least(np.concatenate([-AN[i], np.zeros(2 * m)]), at[i] - max(hi[i], at[i]))
        at, AN, unit = level.A @ x_previous, level.A @ N, np.eye(m)
        for i in range(m):  # lower - down ≤ A x ≤ upper + up,  up, down ≥ 0
            at_least(np.concatenate([-AN[i], unit[i], np.zeros(m)]), at[i] - level.upper[i])
            at_least(np.concatenate([AN[i], np.zeros(m), unit[i]]), level.lower[i] - at[i])
            at_least(np.concatenate([np.zeros(r), unit[i], np.zeros(m)]), 0.0)
            at_least(np.concatenate([np.zeros(r), np.zeros(m), unit[i]]), 0.0)
        G = np.diag(np.concatenate([np.full(r, epsilon), np.full(2 * m, 2.0)]))
        # Every row relaxed by 1e-10: nearly dependent rows must not look inconsistent to the solver.
        z = quadprog.solve_qp(G, np.zeros(size), np.array(rows).T, np.array(rhs) - 1e-10, 0)[0]
        x_previous = x_previous + N @ z[:r]
        value = level.A @ x_previous
        violation = np.maximum(np.maximum(level.lower - value, value - level.upper), 0)
        norms.append(np.linalg.norm(violation))
        eq = level.equality
        equalities.append(level.A[eq])
        inequalities.append((level.A[~eq], level.lower[~eq] - violation[~eq] - 1e-9, level.upper[~eq] + violation[~eq] + 1e-9))
    return np.array(norms)


@pytest.fixture(scope="module")
def solvers():
    return {}


@pytest.mark.parametrize("seed", range(200))
def test_slack_norms_equal_the_reference(seed, solvers):
    rng = np.random.default_rng(1000 + seed)
    n, levels, x_lower, x_upper = random_problem(rng)
    hqp = solvers.setdefault(n, HierarchicalQP(n))
    result = hqp.solve(levels, x_lower, x_upper)
    np.testing.assert_allclose(result.slack_norms, reference_slack_norms(n, levels, x_lower, x_upper), atol=1e-6)
    # Bounds hold exactly after the active-set polish, and to the solver's feasibility tolerance
    # on the stages it could not polish.
    assert np.all(result.x >= x_lower - 1e-8) and np.all(result.x <= x_upper + 1e-8)
    for k in range(len(levels)):  # a lower level never increases a higher level's slack
        above = hqp.solve(levels[: k + 1], x_lower, x_upper)
        assert result.slack_norms[k] <= above.slack_norms[k] + 1e-7


@pytest.mark.parametrize("seed", range(30))
def test_exact_shortcut_agrees_with_the_programs(seed):
    rng = np.random.default_rng(seed)
    n, levels, _, _ = random_problem(rng, with_inequalities=False)
    hqp = HierarchicalQP(n)
    free = np.full(n, np.inf)
    shortcut = hqp.solve(levels, -free, free)
    assert shortcut.solver_calls == 0 and set(shortcut.level_solvers) == {"closed-form"}
    programs = HierarchicalQP(n, closed_form=False).solve(levels, -free, free)
    assert programs.solver_calls > 0
    np.testing.assert_allclose(shortcut.slack_norms, programs.slack_norms, atol=1e-7)
    np.testing.assert_allclose(shortcut.x, programs.x, atol=1e-6)  # both the minimum-norm optimum


def test_bounds_beat_tasks_and_the_hierarchy_degrades_gracefully():
    hqp = HierarchicalQP(2)
    levels = [LevelRows(np.array([[1.0, 0.0]]), [2.0], [2.0]),  # wants x0 = 2, bound says ≤ 1
              LevelRows(np.array([[1.0, 1.0]]), [0.0], [0.0])]
    result = hqp.solve(levels, np.array([-1.0, -1.0]), np.array([1.0, 1.0]))
    np.testing.assert_allclose(result.x, [1.0, -1.0], atol=1e-7)
    np.testing.assert_allclose(result.slack_norms, [1.0, 0.0], atol=1e-7)
    assert result.solver_calls > 0 and 0 in result.active_bounds


def test_inequality_rows_and_their_activity():
    hqp = HierarchicalQP(2)
    levels = [LevelRows(np.array([[0.0, 1.0]]), [-np.inf], [0.5]),  # x1 ≤ 0.5
              LevelRows(np.eye(2), [1.0, 1.0], [1.0, 1.0])]  # wants (1, 1)
    result = hqp.solve(levels, np.full(2, -10.0), np.full(2, 10.0))
    np.testing.assert_allclose(result.x, [1.0, 0.5], atol=1e-7)
    assert list(result.active_rows[0]) == [0]
    np.testing.assert_allclose(result.slacks[1], [0.0, -0.5], atol=1e-7)


def test_damping_on_the_last_level_shrinks_it_only():
    hqp = HierarchicalQP(3)
    levels = [LevelRows(np.array([[1.0, 0.0, 0.0]]), [1.0], [1.0]),
              LevelRows(np.array([[0.0, 1e-3, 0.0]]), [1.0], [1.0])]  # near-singular
    bounds = np.full(3, 1e9)
    plain = hqp.solve(levels, -bounds, bounds)
    damped = hqp.solve(levels, -bounds, bounds, damping=1e-4)
    assert abs(plain.x[1]) == pytest.approx(1000.0)
    assert abs(damped.x[1]) < 10.0 and damped.x[0] == pytest.approx(1.0)


@pytest.mark.parametrize("bad", [
    dict(A=np.ones((2, 3)), lower=np.zeros(2), upper=np.zeros(3)),
    dict(A=np.ones((1, 3)), lower=[np.nan], upper=[1.0]),
    dict(A=np.ones((1, 3)), lower=[2.0], upper=[1.0]),
    dict(A=np.full((1, 3), np.inf), lower=[0.0], upper=[1.0]),
    dict(A=np.ones((1, 3)), lower=[np.inf], upper=[np.inf]),
])
def test_bad_rows_are_rejected(bad):
    with pytest.raises(InvalidInput):
        LevelRows(**bad)


def test_bad_bounds_and_solver_names_are_rejected():
    hqp = HierarchicalQP(2)
    with pytest.raises(InvalidInput):
        hqp.solve([], np.array([1.0, 0.0]), np.array([0.0, 0.0]))
    with pytest.raises(InvalidInput):
        hqp.solve([], np.array([np.nan, 0.0]), np.zeros(2))
    with pytest.raises(InvalidInput):
        hqp.solve([LevelRows(np.ones((1, 3)), [0.0], [0.0])], -np.ones(2), np.ones(2))
    with pytest.raises(InvalidInput):
        HierarchicalQP(2, solver="quadprog")
