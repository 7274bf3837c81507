"""The hierarchical QP on random stacks: strictness, bounds, no failure, and agreement with an
independent lexicographic reference (quadprog) and with the Drake-solver paths."""

import numpy as np
import pytest
import quadprog
from scipy.optimize import lsq_linear

from sotdrake.exceptions import InvalidInput
from sotdrake.hqp import rescue
from sotdrake.hqp.solve import HierarchicalQP, LevelRows
from sotdrake.hqp.tolerances import RANK_THRESHOLD
from tests.hqp_stacks import random_stack


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


def reference_slack_norms(n, levels, x_lower, x_upper, epsilon=1e-12, relaxation=1e-10):
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

        def at_least(coefficients, value, rows=rows, rhs=rhs):
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
        # Every row relaxed (1e-10): nearly dependent rows must not look inconsistent to the solver.
        z = quadprog.solve_qp(G, np.zeros(size), np.array(rows).T, np.array(rhs) - relaxation, 0)[0]
        x_previous = x_previous + N @ z[:r]
        value = level.A @ x_previous
        violation = np.maximum(np.maximum(level.lower - value, value - level.upper), 0)
        norms.append(np.linalg.norm(violation))
        eq = level.equality
        equalities.append(level.A[eq])
        inequalities.append((level.A[~eq], level.lower[~eq] - violation[~eq] - 1e-9, level.upper[~eq] + violation[~eq] + 1e-9))
    return np.array(norms)



def bounds_hold(x, x_lower, x_upper, tolerance=1e-9):
    """Bound rows are unit rows: absolute tolerance (relative above 1, for round-off on big bounds)."""
    with np.errstate(invalid="ignore"):
        return bool(np.all(x >= x_lower - tolerance * np.maximum(1.0, np.abs(x_lower)))
                    and np.all(x <= x_upper + tolerance * np.maximum(1.0, np.abs(x_upper))))


def same_norms(a, b, relative=1e-6, absolute=1e-9, floor=None):
    """|a - b| ≤ relative·max(|a|, |b|) + absolute (+ ``floor``: the round-off of evaluating a level's
    residual, 1e-12·‖A_k‖·‖x‖, per level)."""
    floor = 0.0 if floor is None else floor[: len(a)]
    return bool(np.all(np.abs(a - b) <= relative * np.maximum(np.abs(a), np.abs(b)) + absolute + floor))


def round_off(levels, x):
    return np.array([1e-12 * np.linalg.norm(level.A) * np.linalg.norm(x) for level in levels])


@pytest.fixture(scope="module")
def solvers():
    return {}


BATCH = 100  # 10 batches of 100 stacks: 1000 random stacks


@pytest.mark.parametrize("batch", range(10))
def test_random_stacks_are_strict_bounded_and_never_fail(batch, solvers):
    """The default path on 1000 random stacks (see tests/hqp_stacks.py): every solve succeeds, x is
    finite, the bounds hold exactly (a component past one by round-off is put on it), and the slack
    norms of levels 0..k for the whole stack equal those of the first k+1 levels solved alone (a
    lower level never moves a higher one)."""
    for seed in range(batch * BATCH, (batch + 1) * BATCH):
        n, levels, x_lower, x_upper = random_stack(np.random.default_rng(seed))
        hqp = solvers.setdefault(n, HierarchicalQP(n))
        prefix = solvers.setdefault(-n, HierarchicalQP(n, regularize=False))  # the same slacks, one stage less
        result = hqp.solve(levels, x_lower, x_upper)
        assert np.all(np.isfinite(result.x)), seed
        assert np.all(result.x >= x_lower) and np.all(result.x <= x_upper), seed
        for k in range(len(levels) - 1):
            alone = prefix.solve(levels[: k + 1], x_lower, x_upper)
            floor = np.maximum(round_off(levels, result.x), round_off(levels, alone.x)[: len(levels)])
            assert same_norms(result.slack_norms[: k + 1], alone.slack_norms, floor=floor), \
                (seed, k, result.slack_norms, alone.slack_norms)


@pytest.mark.parametrize("batch", range(2))
def test_random_stacks_agree_with_the_reference(batch, solvers):
    """Unit-scale random stacks (n 5-20, where quadprog's regularised reference is well conditioned)."""
    for seed in range(batch * 50, (batch + 1) * 50):
        n, levels, x_lower, x_upper = random_stack(np.random.default_rng(50_000 + seed), n_range=(5, 20), scaled=False)
        result = solvers.setdefault(n, HierarchicalQP(n)).solve(levels, x_lower, x_upper)
        reference = reference_slack_norms(n, levels, x_lower, x_upper)
        assert same_norms(result.slack_norms, reference, relative=1e-6, absolute=1e-7), (seed, result.slack_norms, reference)


@pytest.mark.parametrize("seed", range(100))
def test_small_stacks_equal_the_reference(seed, solvers):
    rng = np.random.default_rng(1000 + seed)
    n, levels, x_lower, x_upper = random_problem(rng)
    hqp = solvers.setdefault(n, HierarchicalQP(n))
    result = hqp.solve(levels, x_lower, x_upper)
    np.testing.assert_allclose(result.slack_norms, reference_slack_norms(n, levels, x_lower, x_upper), atol=1e-6)
    assert bounds_hold(result.x, x_lower, x_upper)


@pytest.mark.parametrize("batch", range(3))
def test_a_level_of_rows_eight_decades_apart_is_the_bounded_least_squares_optimum(batch, solvers):
    """A nearly flat level: rows of norms 1e-7 to 10, so the smallest rows decide the optimum in
    what the largest leave free and the bounds' multipliers there are about 1e-10 (the residual's
    size times the small rows'). Against scipy's BVLS, an independent bounded least squares: the
    residual within 1e-6 relative (1e-12 of the data's size), on levels whose unit rows have
    every singular value above 1e-5 (no rank decision at τ between the two)."""
    rng = np.random.default_rng(7_000 + batch)
    checked = 0
    while checked < 150:
        n, m = int(rng.integers(2, 9)), int(rng.integers(1, 10))
        A = rng.normal(size=(m, n)) * 10.0 ** rng.integers(-7, 2, size=(m, 1))
        if np.linalg.svd(A / np.linalg.norm(A, axis=1, keepdims=True), compute_uv=False).min() < 1e-5:
            continue
        b = rng.normal(size=m) * 10.0 ** rng.integers(-4, 1, size=m)
        lower, upper = -rng.uniform(0.1, 1.0, n), rng.uniform(0.1, 1.0, n)
        x = solvers.setdefault(n, HierarchicalQP(n)).solve([LevelRows(A, b, b)], lower, upper).x
        reference = lsq_linear(A, b, bounds=(lower, upper), method="bvls", tol=1e-15).x
        residual, best = np.linalg.norm(A @ x - b), np.linalg.norm(A @ reference - b)
        scale = np.linalg.norm(b) + np.linalg.norm(A, 2) * np.linalg.norm(reference)
        assert bounds_hold(x, lower, upper)
        assert residual <= best * (1 + 1e-6) + 1e-12 * scale, (checked, residual, best)
        checked += 1


@pytest.mark.parametrize("solver", ["clarabel", "osqp"])
def test_the_drake_solver_paths_agree_with_the_active_set(solver):
    """Each level as a Drake program, solved by Clarabel or OSQP and polished: the same slack norms
    (the optimum is unique in the slacks) and the same bounds guarantee as the default path."""
    for seed in range(25):
        n, levels, x_lower, x_upper = random_stack(np.random.default_rng(70_000 + seed), n_range=(5, 20))
        hqp = HierarchicalQP(n)
        default = hqp.solve(levels, x_lower, x_upper)
        drake = hqp.solve(levels, x_lower, x_upper, solver=solver)
        assert drake.solver_calls > 0 and default.solver_calls == 0
        assert drake.solver_calls == sum(name.startswith(solver) for name in drake.level_solvers)
        assert same_norms(drake.slack_norms, default.slack_norms), (seed, drake.slack_norms, default.slack_norms)
        assert bounds_hold(drake.x, x_lower, x_upper)


def test_warm_starts_do_not_change_the_answer():
    """The working sets kept from a call are a cache: the same stack from a fresh solver, or after
    solving other stacks, gives the same x (the point is a function of the final working set)."""
    n = 15
    stacks = [random_stack(np.random.default_rng(seed), n_range=(n, n)) for seed in range(20)]
    warm = HierarchicalQP(n)
    for _, levels, x_lower, x_upper in stacks + stacks[::-1]:
        fresh = HierarchicalQP(n).solve(levels, x_lower, x_upper)
        again = warm.solve(levels, x_lower, x_upper)
        np.testing.assert_allclose(again.x, fresh.x, atol=1e-9 * max(1.0, np.abs(fresh.x).max()))


def counterexample(seed: int = 37):
    """The issue's stack: n = 6, level 0 two random equality rows, level 1 a combination of those rows
    with another target plus one inequality row; no bounds."""
    rng = np.random.default_rng(seed)
    A0, b0 = rng.normal(size=(2, 6)), rng.normal(size=2)
    A1 = np.vstack([rng.normal(size=2) @ A0, rng.normal(size=(1, 6))])
    b1 = 3 * rng.normal(size=2)
    return [LevelRows(A0, b0, b0), LevelRows(A1, [b1[0], b1[1] - 1], [b1[0], b1[1] + 1])]


@pytest.mark.parametrize("solver", ["active-set", "clarabel", "osqp"])
def test_a_conflicting_lower_level_never_moves_level_0(solver):
    """Regression: with seed 37 the least-squares polish inverted the round-off of the conflicting row
    (projected to ~1e-16) and level 0's slack went from 0 to 0.17 (217 in the issue's instance)."""
    free = np.full(6, np.inf)
    for seed in [37, *range(20)]:
        levels = counterexample(seed)
        result = HierarchicalQP(6).solve(levels, -free, free, solver=solver)
        assert result.slack_norms[0] < 1e-12, (seed, result.slack_norms)
        # Level 1 does its best in what level 0 leaves: the inequality row is met.
        assert result.slacks[1][1] < 1e-9


def test_the_rank_threshold_is_one_setting():
    """A row that differs from a level-0 row by 1e-7 (relative) is a new direction for τ = 1e-8 and a
    copy of it for τ = 1e-6: the solver then leaves it alone instead of taking a 1e7 step."""
    a = np.array([1.0, 0.0, 0.0])
    levels = [LevelRows(a[None], [0.0], [0.0]), LevelRows((a + [0.0, 1e-7, 0.0])[None], [1.0], [1.0])]
    free = np.full(3, np.inf)
    fine = HierarchicalQP(3).solve(levels, -free, free)
    coarse = HierarchicalQP(3, rank_threshold=1e-6).solve(levels, -free, free)
    assert fine.slack_norms[1] < 1e-9 and abs(fine.x[1]) == pytest.approx(1e7)
    assert coarse.slack_norms[1] == pytest.approx(1.0) and np.abs(coarse.x).max() < 1e-9
    assert RANK_THRESHOLD == 1e-8
    with pytest.raises(InvalidInput):
        HierarchicalQP(3, rank_threshold=0.0)


def test_a_level_extended_by_the_user_goes_through_its_program():
    """``LevelRows(..., extend=f)``: f adds a constraint to the level's MathematicalProgram; that level
    is solved by Drake, the constraint holds there, and the levels below keep its optimum."""
    def at_least_half(prog, x, own):
        prog.AddLinearConstraint(x[0] + x[1] >= 0.5)  # kept by the levels below (own or not)
        if own:
            prog.AddQuadraticCost(1e-3 * (x[2] - 1.0) ** 2)  # this level's own preference

    levels = [LevelRows(np.array([[1.0, -1.0, 0.0]]), [0.0], [0.0], extend=at_least_half),
              LevelRows(np.eye(3), np.zeros(3), np.zeros(3))]
    bounds = np.full(3, 10.0)
    result = HierarchicalQP(3).solve(levels, -bounds, bounds)
    assert result.level_solvers[:2] == ["clarabel"] * 2  # the extended level and the one below
    assert result.x[0] + result.x[1] >= 0.5 - 1e-6
    np.testing.assert_allclose(result.x, [0.25, 0.25, 0.0], atol=1e-5)
    alone = HierarchicalQP(3, regularize=False).solve(levels[:1], -bounds, bounds)
    np.testing.assert_allclose(alone.x[2], 1.0, atol=1e-4)  # the level's own cost acted on its own stage


def test_bounds_beat_tasks_and_the_hierarchy_degrades_gracefully():
    hqp = HierarchicalQP(2)
    levels = [LevelRows(np.array([[1.0, 0.0]]), [2.0], [2.0]),  # wants x0 = 2, bound says ≤ 1
              LevelRows(np.array([[1.0, 1.0]]), [0.0], [0.0])]
    result = hqp.solve(levels, np.array([-1.0, -1.0]), np.array([1.0, 1.0]))
    np.testing.assert_allclose(result.x, [1.0, -1.0], atol=1e-12)
    np.testing.assert_allclose(result.slack_norms, [1.0, 0.0], atol=1e-12)
    assert result.solver_calls == 0 and 0 in result.active_bounds


def test_equality_levels_inside_the_bounds_are_their_least_squares_steps():
    """Equality-only levels whose least-squares steps stay inside the bounds (solved by that step,
    without the active set): the lexicographic minimum-norm solution, computed here by pseudo-inverses
    in the null space of the level above; a bound in the way changes the answer and is respected."""
    rng = np.random.default_rng(5)
    n = 9
    A0, A1 = rng.normal(size=(3, n)), rng.normal(size=(4, n)) * [[1e-3], [1.0], [1e3], [1.0]]
    A1[0] = 2.0 * A0[1] - A0[0]  # a conflicting row: fixed by level 0, its target differs
    b0, b1 = rng.normal(size=3), rng.normal(size=4)
    levels = [LevelRows(A0, b0, b0), LevelRows(A1, b1, b1)]
    x0 = np.linalg.pinv(A0) @ b0
    N = np.linalg.svd(A0)[2][3:].T
    expected = x0 + N @ (np.linalg.pinv(A1 @ N, rcond=1e-10) @ (b1 - A1 @ x0))
    loose = np.full(n, 10.0 * np.abs(expected).max())
    result = HierarchicalQP(n).solve(levels, -loose, loose)
    np.testing.assert_allclose(result.x, expected, atol=1e-9 * max(1.0, np.abs(expected).max()))
    assert result.iterations == [0, 0, 0] and result.fallbacks == [] and len(result.active_bounds) == 0
    tight = np.abs(expected) * 0.5
    bounded = HierarchicalQP(n).solve(levels, -tight, tight)
    assert bounds_hold(bounded.x, -tight, tight) and len(bounded.active_bounds) > 0
    assert bounded.slack_norms[0] > result.slack_norms[0] + 1e-3  # the bounds now beat level 0


def test_inequality_rows_and_their_activity():
    hqp = HierarchicalQP(2)
    levels = [LevelRows(np.array([[0.0, 1.0]]), [-np.inf], [0.5]),  # x1 ≤ 0.5
              LevelRows(np.eye(2), [1.0, 1.0], [1.0, 1.0])]  # wants (1, 1)
    result = hqp.solve(levels, np.full(2, -10.0), np.full(2, 10.0))
    np.testing.assert_allclose(result.x, [1.0, 0.5], atol=1e-12)
    assert list(result.active_rows[0]) == [0]
    np.testing.assert_allclose(result.slacks[1], [0.0, -0.5], atol=1e-12)


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
    dict(A=np.array([[1.0, np.nan, 0.0]]), lower=[0.0], upper=[1.0]),
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
        hqp.solve([], -np.ones(2), np.ones(2), damping=-1.0)
    with pytest.raises(InvalidInput):
        HierarchicalQP(2, solver="quadprog")


def test_a_start_inside_the_bounds_enforces_a_bound_that_excludes_zero():
    """x₀ ≥ 2 with one level asking x₀ = x₁ = 1: from the default start 0 the bound is relaxed to
    0 (a start outside a bound is kept, as a joint already past its limit); from a start inside
    the bounds it holds, and the level's least squares is taken under it."""
    A = np.array([[1.0, 0.0], [0.0, 1.0]])
    b = np.ones(2)
    lower, upper = np.array([2.0, -np.inf]), np.array([np.inf, np.inf])
    hqp = HierarchicalQP(2)
    assert hqp.solve([LevelRows(A, b, b)], lower, upper).x[0] == pytest.approx(1.0)
    held = hqp.solve([LevelRows(A, b, b)], lower, upper, start=np.minimum(np.maximum(0.0, lower), upper)).x
    np.testing.assert_allclose(held, [2.0, 1.0], atol=1e-12)
    with pytest.raises(InvalidInput):
        hqp.solve([LevelRows(A, b, b)], lower, upper, start=np.array([np.nan, 0.0]))


def test_a_degenerate_vertex_is_solved_within_the_bounds():
    """A stack recorded from SolverDyn at a random valid TALOS state (tests/data: 82 unknowns
    (q̈, w, τ), levels dynamics, contacts, hand, CoM, damping): on the last level bounds meet nearly
    dependent at the same value, where with the working set's rank decisions at τ a path can end
    2e-8 beyond a bound. Solved within the bounds to 1e-9 (by the correction onto
    the hard rows, round-off of a large point, or by the retry with a finer working set,
    :data:`~sotdrake.hqp.solve.DEGENERATE_RETRY`), the dynamics and contacts exact, the hand
    level's slack the sequential quadprog reference's. (Below it the problem is too ill-conditioned
    for the reference, whose rows are relaxed by 1e-10, or 1e-8 where quadprog finds them
    inconsistent on a CPU's round-off: its CoM and damping slacks are 1e-3 and 6e-3 above the
    solver's.)"""
    from pathlib import Path

    data = np.load(Path(__file__).parent / "data" / "degenerate_vertex.npz")
    levels = [LevelRows(data[f"A{k}"], data[f"lower{k}"], data[f"upper{k}"]) for k in range(int(data["levels"]))]
    x_lower, x_upper = data["x_lower"], data["x_upper"]
    result = HierarchicalQP(len(x_lower)).solve(levels, x_lower, x_upper, start=data["start"])
    assert np.all(np.isfinite(result.x)) and bounds_hold(result.x, x_lower, x_upper)
    assert np.all(result.slack_norms[:2] <= 1e-9)
    try:
        reference = reference_slack_norms(len(x_lower), levels, x_lower, x_upper)
    except ValueError:  # quadprog: "constraints are inconsistent" at 1e-10 on some CPUs' round-off
        reference = reference_slack_norms(len(x_lower), levels, x_lower, x_upper, relaxation=1e-8)
    assert same_norms(result.slack_norms[2:3], reference[2:3], relative=1e-5), (result.slack_norms, reference)



def test_a_stage_whose_point_is_hundreds_of_times_its_targets_is_solved_strictly():
    """A stack recorded from SolverDyn at a random valid TALOS state (tests/data: 82 unknowns,
    levels dynamics, contacts, left hand, CoM, right hand held against its limits, damping). The
    damping level's point is of size 449, so the active set's solves, which lose cond·ε of it, can
    land a few 1e-9 off a bound row (on one CPU they did, on another they do not). Whichever path
    answers: bounds to 1e-9, and levels 0–4 keep the slacks of the stack without the damping level
    (strict priority). The correction onto the rows is tested on its own below."""
    from pathlib import Path

    data = np.load(Path(__file__).parent / "data" / "hqp_round_off_stage.npz")
    levels = [LevelRows(data[f"A{k}"], data[f"b{k}"], data[f"b{k}"]) for k in range(6)]
    x_lower, x_upper = data["lower"], data["upper"]
    start = np.minimum(np.maximum(0.0, x_lower), x_upper)
    result = HierarchicalQP(len(x_lower)).solve(levels, x_lower, x_upper, start=start)
    assert np.all(np.isfinite(result.x)) and bounds_hold(result.x, x_lower, x_upper)
    alone = HierarchicalQP(len(x_lower)).solve(levels[:5], x_lower, x_upper, start=start)
    assert same_norms(result.slack_norms[:5], alone.slack_norms, relative=1e-6), (result.slack_norms, alone.slack_norms)
    assert alone.slack_norms[4] > 1.0  # the right hand is held against its limits



def test_inequality_rows_the_levels_above_fix_move_only_their_slacks():
    """A random stack (seed 105151 of tests/hqp_stacks.py: n = 25, rows scaled up to 3e9) whose last
    level's three inequality rows are fixed by the levels above: their projections are 2e-16 to
    7e-16 of their norms, round-off in no meaningful direction. Kept in the stage, they let the
    active set buy smaller slacks with a step of 1e16 along that noise, which every path then
    refused (outside the bounds): a false failure. Constant over the stage (at most τ times their
    norm), only their slacks move: solved, bounds exact, strict."""
    n, levels, x_lower, x_upper = random_stack(np.random.default_rng(105151))
    result = HierarchicalQP(n).solve(levels, x_lower, x_upper)
    assert np.all(np.isfinite(result.x)) and np.all(result.x >= x_lower) and np.all(result.x <= x_upper)
    for k in range(len(levels) - 1):
        alone = HierarchicalQP(n, regularize=False).solve(levels[: k + 1], x_lower, x_upper)
        floor = np.maximum(round_off(levels, result.x), round_off(levels, alone.x)[: len(levels)])
        assert same_norms(result.slack_norms[: k + 1], alone.slack_norms, floor=floor)

def test_a_point_far_outside_is_not_moved():
    """Only round-off is corrected: a point that misses a bound by more than 1e-9 of its size is
    refused (the next path decides), one that misses it by less is put on it."""
    hqp = HierarchicalQP(2)
    stage = hqp._build(None, np.zeros(2), np.eye(2), (slice(None), np.ones(2), np.zeros((0, 2)), np.array([0.0, -1e3]),
                                                       np.array([1.0, 1e3]), np.zeros(2, dtype=int)), 0.0)
    side = np.zeros(len(stage.G), dtype=int)
    assert rescue.onto_hard_rows(hqp, stage, np.array([-3e-9, 0.5]), side) is None  # 3e-9 of a point of size 0.5
    assert rescue.onto_hard_rows(hqp, stage, np.array([-1e-3, 500.0]), side) is None
    moved = rescue.onto_hard_rows(hqp, stage, np.array([-3e-9, 500.0]), side)  # 3e-9 of a point of size 500: round-off
    assert moved is not None and moved[0] >= -1e-15 and abs(moved[1] - 500.0) < 1e-12
    # Nearly dependent rows: a miss of round-off size that only a large move could correct is refused.
    from sotdrake.hqp.solve import _Stage

    y = np.array([0.0, 500.0])
    G = np.array([[1.0, 0.0], [1.0, 1e-6]]) / np.array([[1.0], [np.hypot(1.0, 1e-6)]])
    lower = np.array([0.0, G[1] @ y + 2e-7])
    tight = _Stage(np.eye(2), np.zeros(2), np.ones(2), G, lower, np.full(2, np.inf), np.zeros(2), 2, None, np.zeros(2, dtype=int), 2)
    assert rescue.onto_hard_rows(hqp, tight, y, np.array([-1, 0])) is None


def test_the_correction_onto_hard_rows_cuts_at_tau():
    """The least-norm correction's rank decision is the QP's τ, not a library default cutoff: a
    singular value of 1e-9 (below τ = 1e-8) is dropped, one of 1e-7 is kept, and the result is
    ``V_k Σ_k⁻¹ U_kᵀ b`` over the kept values (numpy's default cutoff, ``ε · max(m, n) · σ_max``,
    would invert 1e-9 and move the point by 1e9 times the residual)."""
    from sotdrake.hqp.solve import least_norm

    rng = np.random.default_rng(7)
    U, _ = np.linalg.qr(rng.standard_normal((5, 5)))
    V, _ = np.linalg.qr(rng.standard_normal((8, 8)))
    sigma = np.array([1.0, 0.5, 1e-3, 1e-7, 1e-9])
    A = U @ np.diag(sigma) @ V[:, :5].T
    b = rng.standard_normal(5)
    x = least_norm(A, b, RANK_THRESHOLD)
    kept = slice(0, 4)
    expected = V[:, kept] @ ((U[:, kept].T @ b) / sigma[kept])
    assert np.allclose(x, expected, rtol=1e-6, atol=0.0)
    assert np.linalg.norm(x) < 1e8 < np.linalg.norm(np.linalg.lstsq(A, b, rcond=None)[0])
    assert np.allclose(least_norm(A, b, 1e-6), V[:, :3] @ ((U[:, :3].T @ b) / sigma[:3]))  # τ settable
    assert least_norm(np.zeros((2, 3)), np.ones(2), RANK_THRESHOLD).tolist() == [0.0, 0.0, 0.0]


def reference_stage(level, x0, Z, free, held, reference, hard_lower, hard_upper, hard_side, mu, tau=RANK_THRESHOLD):
    """A stage as the :mod:`sotdrake.hqp.kernels.stage` docstring defines it, written with numpy:
    ``(M, t, m_scale, G, lower, upper, z0, kept, guess)``."""
    C = np.vstack([Z[free], held @ Z])
    offset = np.concatenate([x0[free], held @ x0])
    norms = np.linalg.norm(C, axis=1)
    kept = np.flatnonzero(norms > tau * reference)
    C, offset, norms = C[kept], offset[kept], norms[kept]
    G = C / norms[:, None]
    lower = (np.minimum(hard_lower[kept], offset) - offset) / norms
    upper = (np.maximum(hard_upper[kept], offset) - offset) / norms
    r = Z.shape[1]
    if level is None:
        return np.eye(r), -Z.T @ x0, np.ones(r), G, lower, upper, np.zeros(r), kept, hard_side[kept]
    eq = level.lower == level.upper
    A_eq, A_in = level.A[eq], level.A[~eq]
    m_in = len(A_in)
    raw = np.linalg.norm(A_in, axis=1)
    sigma = np.where(raw > 0, raw, 1.0)  # each slack is w = ‖a‖ v: its violation on the unit row, times ‖a‖
    M = np.block([[A_eq @ Z, np.zeros((len(A_eq), m_in))], [np.zeros((m_in, r)), np.diag(sigma)]])
    t = np.concatenate([level.lower[eq] - A_eq @ x0, np.zeros(m_in)])
    m_scale = np.concatenate([np.linalg.norm(A_eq, axis=1), sigma])
    if mu > 0:
        M = np.vstack([M, np.hstack([np.sqrt(mu) * np.eye(r), np.zeros((r, m_in))])])
        t, m_scale = np.concatenate([t, np.zeros(r)]), np.concatenate([m_scale, np.full(r, np.sqrt(mu))])
    value = A_in @ x0
    AZ = A_in @ Z
    AZ[np.linalg.norm(AZ, axis=1) <= tau * sigma] = 0.0  # constant rows: only their slack moves
    soft = np.sqrt(np.linalg.norm(AZ, axis=1) ** 2 + sigma**2)
    G = np.block([[G, np.zeros((len(G), m_in))], [AZ / soft[:, None], -np.diag(sigma / soft)]])
    lower = np.concatenate([lower, (level.lower[~eq] - value) / soft])
    upper = np.concatenate([upper, (level.upper[~eq] - value) / soft])
    violation = np.maximum(level.lower[~eq] - value, 0.0) - np.maximum(value - level.upper[~eq], 0.0)
    z0 = np.concatenate([np.zeros(r), -violation / sigma])  # v = (a·x0 minus its nearest side) / ‖a‖
    return M, t, m_scale, G, lower, upper, z0, kept, np.concatenate([hard_side[kept], np.zeros(m_in, int)])


@pytest.mark.parametrize("seed", range(12))
def test_a_stage_is_assembled_as_its_definition(seed):
    """The compiled assembly of a stage (bound rows of the free components, held rows, a held row and
    an inequality row that the levels above made constant, sides relaxed where x0 is outside them,
    infinite sides, damping, equality and inequality rows, the minimum-norm stage) against its
    definition."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(4, 14))
    r = int(rng.integers(1, n + 1))
    Z = np.linalg.qr(rng.normal(size=(n, r)))[0]
    x0 = rng.normal(size=n)
    free = np.sort(rng.choice(n, int(rng.integers(1, n + 1)), replace=False))
    held = rng.normal(size=(int(rng.integers(0, 4)), n))
    if len(held) and r < n:  # constant over the stage relative to its norm (1e9): left out
        held[0] -= Z @ (Z.T @ held[0])
        held[0] *= 1e9 / np.linalg.norm(held[0])
        held[0] += 1e-7 * Z[:, 0]
    reference = np.concatenate([np.ones(len(free)), np.linalg.norm(held, axis=1)])
    offset = np.concatenate([x0[free], held @ x0])
    hard_lower = offset - rng.uniform(-0.5, 1.0, len(offset))  # some above x0's value: relaxed to it
    hard_upper = offset + rng.uniform(-0.5, 1.0, len(offset))
    hard_lower[rng.random(len(offset)) < 0.2] = -np.inf
    hard_upper[rng.random(len(offset)) < 0.2] = np.inf
    hard_side = rng.integers(-1, 2, len(offset))
    A = rng.normal(size=(int(rng.integers(1, 8)), n))
    lower, upper = rng.normal(size=len(A)), rng.normal(size=len(A))
    lower, upper = np.minimum(lower, upper), np.maximum(lower, upper)
    equality = rng.random(len(A)) < 0.5
    upper[equality] = lower[equality]
    upper[~equality & (rng.random(len(A)) < 0.3)] = np.inf
    if r < n and not equality.all():  # an inequality row the levels above made constant: only its slack moves
        i = int(np.flatnonzero(~equality)[0])
        A[i] -= Z @ (Z.T @ A[i])
        A[i] *= 1e9 / np.linalg.norm(A[i])
        A[i] += 1e-7 * Z[:, 0]
    hqp = HierarchicalQP(n)
    hard = (free, reference, held, hard_lower, hard_upper, hard_side)
    for level in (None, LevelRows(A[equality], lower[equality], lower[equality]), LevelRows(A, lower, upper)):
        for mu in (0.0, 1e-2):
            stage = hqp._build(level, x0, Z, hard, mu)
            M, t, m_scale, G, lo, hi, z0, kept, guess = reference_stage(level, x0, Z, free, held, reference, hard_lower,
                                                                        hard_upper, hard_side, 0.0 if level is None else mu)
            for got, expected in ((stage.M, M), (stage.t, t), (stage.m_scale, m_scale), (stage.G, G),
                                  (stage.lower, lo), (stage.upper, hi), (stage.z0, z0)):
                np.testing.assert_allclose(got, expected, rtol=1e-13, atol=1e-13)
            np.testing.assert_array_equal(np.arange(len(offset)) if stage.hard is None else stage.hard, kept)
            np.testing.assert_array_equal(stage.guess, guess)
            assert (stage.r, stage.m_hard) == (r, len(kept))
            assert stage.kind == (level is None, level is None or (len(m_scale) > 0 and bool(np.all(m_scale == m_scale[0]))))
    full = hqp._build(None, x0, Z, (slice(None), np.ones(n), np.zeros((0, n)), x0 - 1, x0 + 1, np.zeros(n, int)), 0.0)
    np.testing.assert_allclose(full.G, Z / np.linalg.norm(Z, axis=1)[:, None], rtol=1e-13)  # every component bounded


def test_a_level_of_rows_far_apart_in_norm_meets_the_contract():
    """A random stack (seed 126455 of tests/hqp_stacks.py: n = 28, five levels) whose level 3 holds
    inequality rows of norm up to 4e7, their projections 1e-7 to 1e-4 of their norms (with each
    slack entering its stage row at ``1/‖(a Z, −1)‖``, unscaled by the row's norm, the answer was
    1e14). Whatever path answers: no failure, finite, of the size of the truncated stacks' answers
    (≤ 1), within the bounds, every level as strict as the truncated stacks."""
    n, levels, x_lower, x_upper = random_stack(np.random.default_rng(126455))
    result = HierarchicalQP(n).solve(levels, x_lower, x_upper)
    assert np.all(np.isfinite(result.x)) and np.abs(result.x).max() <= 1.0
    assert np.all(result.x >= x_lower) and np.all(result.x <= x_upper)
    for k in range(len(levels) - 1):
        alone = HierarchicalQP(n, regularize=False).solve(levels[: k + 1], x_lower, x_upper)
        floor = np.maximum(round_off(levels, result.x), round_off(levels, alone.x)[: len(levels)])
        assert same_norms(result.slack_norms[: k + 1], alone.slack_norms, floor=floor), k


def test_the_last_resort_holds_rows_to_the_tolerance_relative_to_their_terms():
    """The last resort's measure: a hard row's miss as a fraction of ``tol · Σ|g_j||y_j|`` (tol = 1e-9).
    On the held row ``(y₀ + y₁)/√2 ≥ 0``: at size 1e14 a miss of 0.022 (two ulps) or of 11 is far
    inside (1e-4 of it), one of 1.4e6 is outside; the same 0.022 miss at size 1 is 1e7 times the
    tolerance; a unit bound row (an exact product, its terms one component) is held to 1e-9 of that
    component, whatever the size of the others. Each case is at least a factor 7 from the limit."""
    hqp = HierarchicalQP(2)
    held = np.array([[1.0, 1.0]]) / np.sqrt(2.0)
    stage = hqp._build(None, np.zeros(2), np.eye(2), (np.zeros(0, dtype=int), np.ones(1), held, np.zeros(1),
                                                       np.ones(1), np.zeros(1, dtype=int)), 0.0)
    assert rescue.relative_miss(hqp, stage, np.array([1e14, -1e14])) <= 1e-6  # on the row, but g·y computes to -0.007
    assert 0.0 < rescue.relative_miss(hqp, stage, np.array([1e14, -1e14 - 0.03125])) <= 1e-6
    assert rescue.relative_miss(hqp, stage, np.array([1e14, -1e14 - 16.0])) <= 1e-3
    assert rescue.relative_miss(hqp, stage, np.array([1e14, -1e14 - 2e6])) > 7.0
    assert rescue.relative_miss(hqp, stage, np.array([1.0, -1.03125])) > 1e6
    bound = hqp._build(None, np.zeros(2), np.eye(2), (slice(None), np.ones(2), np.zeros((0, 2)), np.array([0.0, -1e15]),
                                                       np.array([1.0, 1e15]), np.zeros(2, dtype=int)), 0.0)
    assert rescue.relative_miss(hqp, bound, np.array([-1e-3, 1e14])) > 1e6
    assert rescue.relative_miss(hqp, bound, np.array([-1e-9, 1e14])) == 0.0  # within the tolerance itself


def test_the_minimum_norm_stage_keeps_the_last_levels_point_when_no_path_solves_it():
    """A random stack (seed 113554 of tests/hqp_stacks.py: n = 16, no bounds, targets up to 1e9)
    whose last level's exact optimum is 4e14 in size (two of its projected rows dependent to 1e-16,
    the others 6e-7 of their norms from it): every path of the minimum-norm stage misses its held
    rows by the round-off of a point that size (on some CPUs, one degenerate retry gets through),
    which used to fail the whole stack. The last level's point is in the optimal set, so it is then
    kept: the stack is answered, finite, and every level stays as strict as the truncated stacks."""
    n, levels, x_lower, x_upper = random_stack(np.random.default_rng(113554))
    result = HierarchicalQP(n).solve(levels, x_lower, x_upper)
    assert np.all(np.isfinite(result.x))
    for k in range(len(levels)):
        alone = HierarchicalQP(n, regularize=False).solve(levels[: k + 1], x_lower, x_upper)
        floor = np.maximum(round_off(levels, result.x), round_off(levels, alone.x)[: len(levels)])
        assert same_norms(result.slack_norms[: k + 1], alone.slack_norms, floor=floor)
