"""The QR path for equality hierarchies against the hierarchical QP it stands in for."""

import numpy as np
import pytest

from sotdrake.hqp.equality_hierarchy import solve_equality_hierarchy
from sotdrake.hqp.solve import HierarchicalQP, LevelRows
from tests.conftest import compiled_only


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


def test_a_bound_in_the_way_is_held_and_a_nan_is_left_to_the_qp():
    """``x0 = 2, x1 = −2`` under ``|x| ≤ 1``: both bounds held, certified by their multipliers (the
    QP's answer, (1, −1, 0, 0)); a non-finite level is never answered."""
    n = 4
    A = np.eye(2, n)
    b = np.array([2.0, -2.0])
    held = solve_equality_hierarchy([(A, b)], np.full(n, -1.0), np.full(n, 1.0))
    np.testing.assert_allclose(held.x, [1.0, -1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_array_equal(held.active_bounds, [0, 1])
    assert solve_equality_hierarchy([(A, b)], np.full(n, -3.0), np.full(n, 3.0)).active_bounds.size == 0
    assert solve_equality_hierarchy([(A, b * np.nan)], np.full(n, -3.0), np.full(n, 3.0)) is None
    assert solve_equality_hierarchy([(A * np.nan, b)], np.full(n, -3.0), np.full(n, 3.0)) is None


def _bounded_problem(rng, n, conflicting):
    """Random levels and bounds that cut the unbounded optimum: a few components in the way."""
    levels = random_levels(rng, n, conflicting)
    free = solve_equality_hierarchy(pairs(levels), np.full(n, -1e9), np.full(n, 1e9))
    reach = np.abs(free.x) if free is not None else np.abs(rng.normal(size=n))
    lower, upper = -np.full(n, np.inf), np.full(n, np.inf)
    cut = rng.choice(n, size=int(rng.integers(1, min(n, 4) + 1)), replace=False)
    scale = rng.uniform(0.3, 0.95, size=len(cut)) * np.maximum(reach[cut], 1e-3)
    lower[cut], upper[cut] = -scale, scale
    return levels, lower, upper


@pytest.mark.parametrize("seed", range(120))
def test_bounds_in_the_way_are_the_hierarchical_qps_answer(seed):
    """Bounds that cut the unbounded optimum are held at equality, each certified by the sign of
    its multiplier at the level that decides it (or at the final minimum-norm stage): where the
    QR path answers, it is the QP's point and slacks, from no guess, the right guess or a wrong one
    (a bound guessed held that the optimum leaves is released)."""
    rng = np.random.default_rng(1000 + seed)
    n = int(rng.integers(3, 30))
    levels, lower, upper = _bounded_problem(rng, n, conflicting=seed % 3 == 0)
    reference = HierarchicalQP(n).solve(levels, lower, upper, start=np.zeros(n))
    scale = max(1.0, float(np.abs(reference.x).max()))
    right_lower = [i for i in reference.active_bounds if reference.x[i] <= lower[i]]
    right_upper = [i for i in reference.active_bounds if reference.x[i] >= upper[i]]
    wrong = [i for i in range(n) if i not in reference.active_bounds and np.isfinite(lower[i])]
    answered = 0
    for guess in (((), ()), (right_lower, right_upper), (wrong, ()), ((), wrong)):
        result = solve_equality_hierarchy(pairs(levels), lower, upper, *guess)
        if result is None:
            continue
        answered += 1
        np.testing.assert_allclose(result.x, reference.x, rtol=0, atol=1e-8 * scale)
        np.testing.assert_allclose(result.slack_norms, reference.slack_norms, rtol=1e-6, atol=1e-8 * scale)
        np.testing.assert_array_equal(result.active_bounds, reference.active_bounds)
        assert np.all(result.x >= lower) and np.all(result.x <= upper)
    if seed % 3:
        assert answered  # no conflicting rows: the bounds alone never stop it


def test_most_bounded_stacks_are_answered():
    """The held bounds are not a rare path: on random stacks without conflicting rows, with bounds
    in the way, the QR path answers at least 9 in 10."""
    rng = np.random.default_rng(7)
    answered = 0
    for _ in range(60):
        n = int(rng.integers(3, 30))
        levels, lower, upper = _bounded_problem(rng, n, conflicting=False)
        answered += solve_equality_hierarchy(pairs(levels), lower, upper) is not None
    assert answered >= 54


@pytest.mark.parametrize("offset", [-1e-13, 0.0, 1e-13])
def test_a_point_on_a_bound_up_to_round_off_is_answered_on_the_bound(offset):
    """The unbounded optimum ``x₀ = 1`` under ``x₀ ≤ 1 + offset``: an offset of round-off (1e-13, far
    below :data:`IN_THE_WAY`) on either side must not decide whether the bound is held, so the answer
    is the same on every CPU: answered, within the bounds exactly, slack round-off."""
    from sotdrake.hqp.equality_hierarchy import IN_THE_WAY

    assert abs(offset) < 1e-3 * IN_THE_WAY
    A = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 1.0]])
    levels = [LevelRows(A, np.array([1.0, 2.0]), np.array([1.0, 2.0]))]
    lower, upper = np.full(3, -5.0), np.array([1.0 + offset, 5.0, 5.0])
    result = solve_equality_hierarchy(pairs(levels), lower, upper)
    assert result is not None
    assert np.all(result.x >= lower) and np.all(result.x <= upper)
    assert result.x[0] == pytest.approx(1.0, abs=2e-13) and result.slack_norms[0] < 2e-13
    np.testing.assert_allclose(result.x[1:], [1.0, 1.0], atol=1e-14)


def test_a_bound_that_the_optimum_leaves_is_released():
    """``x0 = 0.5`` under ``|x0| ≤ 1`` with the lower bound guessed held: its multiplier is
    negative at the level, the bound is released, and the point is the unbounded one."""
    A = np.array([[1.0, 0.0, 0.0]])
    result = solve_equality_hierarchy([(A, np.array([0.5]))], np.full(3, -1.0), np.full(3, 1.0), at_lower=[0], at_upper=[2])
    np.testing.assert_allclose(result.x, [0.5, 0.0, 0.0], atol=1e-15)
    assert result.active_bounds.size == 0


def test_minimum_norm_of_what_is_left_and_fixed_components():
    """One row x0 + x1 = 2 with x2 fixed at 5: the minimum-norm point is (1, 1, 5, 0)."""
    A = np.array([[1.0, 1.0, 1.0, 0.0]])
    lower, upper = np.array([-9.0, -9.0, 5.0, -9.0]), np.array([9.0, 9.0, 5.0, 9.0])
    result = solve_equality_hierarchy([(A, np.array([7.0]))], lower, upper)
    np.testing.assert_allclose(result.x, [1.0, 1.0, 5.0, 0.0], atol=1e-14)
    assert result.slack_norms[0] == pytest.approx(0.0, abs=1e-14)


@compiled_only
def test_any_array_layout_gives_the_same_answer_without_another_compilation():
    """The compiled sweep takes C-ordered, writeable float arrays: read-only, Fortran-ordered, strided
    and integer inputs are converted (the same answer, bit for bit) rather than compiled for again."""
    import sotdrake.hqp.equality_hierarchy as equality_hierarchy

    rng = np.random.default_rng(3)
    n = 9
    A1, A2 = rng.normal(size=(3, n)), rng.integers(-3, 4, size=(4, n))
    b1, b2 = rng.normal(size=3), rng.integers(-2, 3, size=4)
    lower, upper = np.full(n, -0.4), np.full(n, 0.4)
    upper[2] = lower[2]  # a fixed component
    plain = solve_equality_hierarchy([(A1, b1), (A2.astype(float), b2.astype(float))], lower, upper)
    assert plain is not None and plain.active_bounds.size  # a bound in the way: the held-bound path too
    signatures = len(equality_hierarchy._compiled_sweep.signatures)
    frozen = [a.copy() for a in (A1, b1, lower, upper)]
    for a in frozen:
        a.flags.writeable = False
    wide = np.zeros((3, 2 * n))
    wide[:, ::2] = A1
    for levels, bounds in (
        ([(frozen[0], frozen[1]), (A2, b2)], (frozen[2], frozen[3])),
        ([(np.asfortranarray(A1), b1), (np.asfortranarray(A2), b2)], (lower, upper)),
        ([(wide[:, ::2], b1), (A2, b2)], (np.repeat(lower, 2)[::2], upper)),
    ):
        result = solve_equality_hierarchy(levels, *bounds)
        np.testing.assert_array_equal(result.x, plain.x)
        np.testing.assert_array_equal(result.slack_norms, plain.slack_norms)
    assert len(equality_hierarchy._compiled_sweep.signatures) == signatures


@pytest.mark.parametrize("bad", ["inf_row", "inf_target", "nan_target", "wider", "one_dimensional"])
def test_a_level_that_is_not_numbers_or_does_not_fit_is_left_to_the_qp(bad):
    """Infinite or NaN entries and levels of another width are never answered (the hierarchical QP
    then names what is wrong); nothing raises from the compiled code."""
    n = 5
    A, b = np.eye(2, n), np.array([0.1, 0.2])
    levels = {
        "inf_row": [(A, b), (np.array([[np.inf, 1.0, 0.0, 0.0, 0.0]]), np.ones(1))],
        "inf_target": [(A, np.array([np.inf, 0.0]))],
        "nan_target": [(A, b), (np.ones((1, n)), np.array([np.nan]))],
        "wider": [(A, b), (np.ones((1, n + 1)), np.ones(1))],
        "one_dimensional": [(np.ones(n), np.ones(1))],
    }[bad]
    assert solve_equality_hierarchy(levels, np.full(n, -1.0), np.full(n, 1.0)) is None
