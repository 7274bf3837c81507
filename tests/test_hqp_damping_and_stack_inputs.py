"""The hierarchical QP's damped last level, the whole-stack paths' arguments and badly scaled levels.

* A damped last level (μ > 0) minimises ``‖w‖² + μ‖x − x_{k−1}‖²``: strictly convex in what the
  levels above leave free, its optimum is one point, and the answer is that point whether or not the
  minimum-norm stage is asked for (it used to move the answer inside the level's null space), and
  whichever path list solves the stack (``DYNAMIC``'s QR sweep used to answer the undamped point).
  Checked against the damped closed form and against scipy's bounded least squares.
* ``solve_stack`` refuses a damping, a start or a ``held`` guess that is not what
  :class:`~sotdrake.hqp.StackProblem` documents, naming it, before any path runs and whatever the
  path list, and leaves the warm start as it was.
* A bounded least-squares level whose rows' norms spread from 0.01 to 2e5 is solved to its optimum
  (scipy's BVLS), cold and warm alike: a bound is not held against a gradient that only the small
  rows decide.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import quadprog
from scipy.linalg import null_space
from scipy.optimize import lsq_linear

from sotdrake.exceptions import InvalidInput
from sotdrake.hqp import BASIC, DYNAMIC, KINEMATIC, HierarchicalQP, LevelRows, StackProblem, WarmStart, solve_stack

PATH_LISTS = {"basic": BASIC, "kinematic": KINEMATIC, "dynamic": DYNAMIC}


def damped_hierarchy(levels: list[tuple[np.ndarray, np.ndarray]], mu: float, start: np.ndarray) -> np.ndarray:
    """The hierarchy of equality levels ``A_k x = b_k`` without bounds, by its definition: each level
    the minimum-norm least-squares step from the point above in what the levels above leave free
    (``x_k = x_{k−1} + Z y``, ``Z`` orthonormal), the last one damped: ``y = (Bᵀ B + μ I)⁻¹ Bᵀ (b −
    A x_{k−1})`` with ``B = A Z`` (the minimiser of ``‖A x − b‖² + μ‖x − x_{k−1}‖²``)."""
    x, Z = start.astype(float).copy(), np.eye(len(start))
    for k, (A, b) in enumerate(levels):
        B, rhs = A @ Z, b - A @ x
        if k == len(levels) - 1:
            y = np.linalg.solve(B.T @ B + mu * np.eye(B.shape[1]), B.T @ rhs)
        else:
            y = np.linalg.pinv(B) @ rhs
        x = x + Z @ y
        Z = Z @ null_space(B) if B.size else Z
    return x


def test_the_minimum_norm_stage_keeps_a_damped_last_levels_optimum():
    """x₃ = 4, then the damped level x₁ + x₃ = 6 (μ = 1) from the start (0, 3, 0): the level above
    leaves (x₁, x₂) free at (0, 3, 4), the damped optimum is (1, 3, 4) (objective 2); the
    minimum-norm stage used to pull x₂ to 0 (objective 11)."""
    n, inf = 3, np.inf
    levels = [(np.array([[0.0, 0.0, 1.0]]), np.array([4.0])), (np.array([[1.0, 0.0, 1.0]]), np.array([6.0]))]
    start = np.array([0.0, 3.0, 0.0])
    expected = damped_hierarchy(levels, 1.0, start)
    np.testing.assert_allclose(expected, [1.0, 3.0, 4.0], atol=1e-12)
    for regularize in (True, False):
        result = HierarchicalQP(n, regularize=regularize).solve([LevelRows(A, b, b) for A, b in levels],
                                                                 np.full(n, -inf), np.full(n, inf), damping=1.0, start=start)
        np.testing.assert_allclose(result.x, expected, atol=1e-10)


@pytest.mark.parametrize("seed", range(6))
def test_a_damped_last_level_is_its_closed_form_whatever_the_solver(seed):
    """Random equality stacks without bounds whose damped last level has fewer rows than the
    directions left to it (the damping decides there): the stages and every path list that takes
    damping answer the closed form."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(6, 12))
    sizes = [int(rng.integers(1, 3)), int(rng.integers(1, 3)), int(rng.integers(1, 3))]
    levels = [(rng.normal(size=(m, n)), rng.normal(size=m)) for m in sizes]
    mu = float(rng.choice([1e-3, 0.1, 1.0]))
    expected = damped_hierarchy(levels, mu, np.zeros(n))
    free = np.full(n, np.inf)
    stages = HierarchicalQP(n).solve([LevelRows(A, b, b) for A, b in levels], -free, free, damping=mu)
    np.testing.assert_allclose(stages.x, expected, atol=1e-9)
    for paths in (KINEMATIC, DYNAMIC):
        result = solve_stack(HierarchicalQP(n), StackProblem([(A, b, b) for A, b in levels], -free, free, mu), paths)
        np.testing.assert_allclose(result.x, expected, atol=1e-9)


@pytest.mark.parametrize("paths", [KINEMATIC, DYNAMIC], ids=["kinematic", "dynamic"])
@pytest.mark.parametrize("start", [None, "inside"])
def test_a_damped_bounded_level_is_scipys_bounded_least_squares(paths, start):
    """One damped level under bounds: ``min ‖A x − b‖² + μ‖x − x₀‖²`` over the box is the bounded
    least squares of ``[A; √μ I] x ≈ [b; √μ x₀]`` (scipy's BVLS). ``DYNAMIC`` used to answer the
    undamped point by its QR sweep."""
    rng = np.random.default_rng(0)
    n, mu = 6, 0.5
    A, b = rng.normal(size=(3, n)), rng.normal(size=3)
    lower, upper = np.full(n, -0.3), np.full(n, 0.3)
    x0 = np.zeros(n) if start is None else rng.uniform(-0.2, 0.2, n)
    reference = lsq_linear(np.vstack([A, np.sqrt(mu) * np.eye(n)]), np.concatenate([b, np.sqrt(mu) * x0]),
                           bounds=(lower, upper), method="bvls", tol=1e-15, lsq_solver="exact").x
    problem = StackProblem([(A, b, b)], lower, upper, mu, start=None if start is None else x0, warm=WarmStart(n))
    result = solve_stack(HierarchicalQP(n), problem, paths)
    np.testing.assert_allclose(result.x, reference, atol=1e-9)


def test_a_start_outside_the_bounds_is_the_stages_for_the_dynamic_paths():
    """A start outside a bound relaxes that bound (the stages' documented behaviour): ``DYNAMIC``'s QR
    sweep, which always holds the bounds, leaves such a stack to them. Here x = (0.5, 0.5) starts
    past its upper bound 0.3; the level x₁ + x₂ = 2 then stays where the relaxed bounds allow:
    (0.5, 0.5) itself, the level's residual 1 (against 1.4 with the bounds held)."""
    n = 2
    A, b = np.ones((1, n)), np.array([2.0])
    start = np.full(n, 0.5)
    problem = StackProblem([(A, b, b)], np.full(n, -0.3), np.full(n, 0.3), start=start)
    result = solve_stack(HierarchicalQP(n), problem, DYNAMIC)
    np.testing.assert_allclose(result.x, [0.5, 0.5], atol=1e-12)


BAD_ARGUMENTS = [
    (dict(damping=np.nan), "damping"),
    (dict(damping=-1.0), "damping"),
    (dict(damping=np.inf), "damping"),
    (dict(damping="0.1"), "damping"),
    (dict(start=np.full(6, np.nan)), "start"),
    (dict(start=np.array([0.0, 0.0, np.inf, 0.0, 0.0, 0.0])), "start"),
    (dict(start=np.zeros(2)), "start"),
    (dict(start=np.zeros((6, 1))), "start"),
    (dict(held="ab"), "held"),
    (dict(held=((0, 1),)), "held"),
    (dict(held=((0.5,), ())), "held"),
    (dict(held=((True,), ())), "held"),
    (dict(held=((99,), (-7,))), "held"),
    (dict(held=(np.array([0.0]), ())), "held"),
    (dict(held=(3, ())), "held"),
]


@pytest.mark.parametrize("paths", PATH_LISTS.values(), ids=PATH_LISTS.keys())
@pytest.mark.parametrize(("arguments", "named"), BAD_ARGUMENTS, ids=[f"{k}-{i}" for i, (_, k) in enumerate(BAD_ARGUMENTS)])
def test_bad_stack_arguments_are_refused_by_name_before_any_path(paths, arguments, named):
    """Whatever the path list, a bad damping, start or ``held`` is an :class:`InvalidInput` naming it
    (not an answer, a bare numpy error or a :class:`SolverError`), and the warm start is untouched."""
    rng = np.random.default_rng(0)
    n = 6
    A, b = rng.normal(size=(3, n)), rng.normal(size=3)
    lower, upper = np.full(n, -0.3), np.full(n, 0.3)
    qp, warm = HierarchicalQP(n), WarmStart(n)
    answer = solve_stack(qp, StackProblem([(A, b, b)], lower, upper, warm=warm), KINEMATIC).x
    before = pickle.dumps(warm)
    with pytest.raises(InvalidInput, match=named):
        solve_stack(qp, StackProblem([(A, b, b)], lower, upper, warm=warm, **arguments), paths)
    assert pickle.dumps(warm) == before
    np.testing.assert_allclose(solve_stack(qp, StackProblem([(A, b, b)], lower, upper, warm=warm), KINEMATIC).x, answer,
                               atol=1e-12)


@pytest.mark.parametrize("held", [((), ()), ((0, 1), (2,)), (np.array([4]), []), ([99], [6, 7])])
def test_a_held_guess_never_changes_the_answer(held):
    """``held`` is a guess (indices past the variables: a larger problem's, not held): the answer is
    the one without it, the hierarchy's (here a level that the bounds keep from its target)."""
    rng = np.random.default_rng(3)
    n = 6
    A, b = rng.normal(size=(3, n)), 5.0 * rng.normal(size=3)
    lower, upper = np.full(n, -0.3), np.full(n, 0.3)
    reference = lsq_linear(A, b, bounds=(lower, upper), method="bvls", tol=1e-15, lsq_solver="exact").x
    result = solve_stack(HierarchicalQP(n), StackProblem([(A, b, b)], lower, upper, held=held), DYNAMIC)
    assert np.linalg.norm(A @ result.x - b) <= np.linalg.norm(A @ reference - b) + 1e-9


# One equality level of rows of norms 0.03, 0.27 and 2e5 over four variables, two of them bounded on
# both sides (a randomized stack's level, reduced).
SCALED_A = np.array([[-1.1580919858366559e-02, 1.6477926757114607e-02, 9.0145088178157032e-03, 2.7950882299276605e-03],
                     [4.3796033037514240e-02, 6.6233066964598297e-02, -2.5039276809566169e-01, 4.5344100020722027e-02],
                     [2.6781720961713756e+04, 5.4484535840280383e+04, -1.2711265692619453e+05, -1.2508491106113963e+05]])
SCALED_B = np.array([1.7560389083017827e-01, -1.4501874739224263e+00, -2.3311739651209661e+06])
SCALED_LOWER = np.array([-3.0324353430272377, 0.04082238915467085, -np.inf, -1.5427693243949305])
SCALED_UPPER = np.array([-0.8365380113965801, 2.095735230778705, np.inf, np.inf])


@pytest.mark.parametrize("start", [None, "inside"])
def test_a_badly_scaled_bounded_level_reaches_its_optimum_cold_and_warm(start):
    """The level's optimum (scipy's BVLS) has x₂ at its upper bound and a residual of 0.00495; the
    active set used to stop with x₂ at its lower bound (a residual of 0.045, nine times more), its
    multiplier's wrong sign (−8.3e-4) inside a tolerance relative to the largest row. Cold, then
    warm (the same solver again, from its working sets), the answer is the optimum."""
    x0 = None if start is None else np.clip(0.0, SCALED_LOWER, SCALED_UPPER)
    reference = lsq_linear(SCALED_A, SCALED_B, bounds=(SCALED_LOWER, SCALED_UPPER), method="bvls", tol=1e-15,
                           lsq_solver="exact").x
    optimum = np.linalg.norm(SCALED_A @ reference - SCALED_B)
    qp = HierarchicalQP(4)
    for _ in range(2):  # cold, then warm
        result = qp.solve([LevelRows(SCALED_A, SCALED_B, SCALED_B)], SCALED_LOWER, SCALED_UPPER, start=x0)
        assert np.linalg.norm(SCALED_A @ result.x - SCALED_B) <= optimum * (1 + 1e-6)
        assert np.all(result.x >= SCALED_LOWER) and np.all(result.x <= SCALED_UPPER)
        np.testing.assert_allclose(result.x, reference, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("scale", [1e-8, 1.0, 1e4, 1e8, 3e8, 1e12, 1e50, 1e100])
def test_conflicting_inequality_rows_of_any_norm_reach_their_optimum(scale):
    """``s x ≥ s`` and ``s x ≤ −s`` (one variable): the least violation is at x = 0 (each row violated
    by s), whatever s. (Each slack used to enter its stage row with the coefficient ``1/‖(s, −1)‖``,
    lost in the rank decisions from s ≈ 1/τ: x = 1 from s = 3e8.)"""
    A = np.array([[scale], [scale]])
    level = LevelRows(A, np.array([scale, -np.inf]), np.array([np.inf, -scale]))
    result = HierarchicalQP(1).solve([level], np.array([-np.inf]), np.array([np.inf]))
    assert abs(result.x[0]) <= 1e-9
    np.testing.assert_allclose(np.linalg.norm(result.slacks[0]), scale * np.sqrt(2.0), rtol=1e-12)


def _slack_reference(top, A, lower, upper, x_lower, x_upper):
    """The level's least-violation point under the equality row ``top``, in box bounds: ``x = x_p +
    N y`` over the row's null space, one signed slack ``w`` per row (``lower ≤ A x − w ≤ upper``),
    ``min ‖w‖²`` (and 1e-12 ‖y‖² to make it strictly convex), one quadprog QP."""
    x_p = np.linalg.lstsq(top.A, top.lower, rcond=None)[0]
    N = null_space(top.A)
    r, m = N.shape[1], len(A)
    AN, base = A @ N, A @ x_p
    rows, sides = [np.hstack([AN, -np.eye(m)])], [lower - base]
    finite = np.isfinite(upper)
    rows.append(-np.hstack([AN, -np.eye(m)])[finite])
    sides.append(-(upper - base)[finite])
    rows += [np.hstack([N, np.zeros((len(N), m))]), -np.hstack([N, np.zeros((len(N), m))])]
    sides += [x_lower - x_p, x_p - x_upper]
    G = np.diag(np.concatenate([np.full(r, 1e-12), np.ones(m)]))
    z = quadprog.solve_qp(G, np.zeros(r + m), np.vstack(rows).T, np.concatenate(sides), 0)[0]
    return x_p + N @ z[:r]


def _violation(A, lower, upper, x):
    value = A @ x
    return np.linalg.norm(np.maximum(lower - value, 0.0) + np.maximum(value - upper, 0.0))


@pytest.mark.parametrize("paths", [None, KINEMATIC, DYNAMIC], ids=["stages", "kinematic", "dynamic"])
@pytest.mark.parametrize("seed", range(12))
def test_scaling_a_levels_rows_together_leaves_its_optimum(seed, paths):
    """Multiplying every row of an inequality level and its sides by one constant s multiplies its
    violation by s and leaves its optimal set: below an equality level, in box bounds, with two
    rows that cannot both hold, the scaled level's least violation is the unscaled one's times s, for
    s from 1e-6 to 1e60, by the stages and by the solvers' paths (the unscaled answer is checked
    against an independent quadprog QP over the equality row's null space, one slack per row)."""
    rng = np.random.default_rng(seed)
    n, m = int(rng.integers(2, 8)), int(rng.integers(2, 7))
    top = LevelRows(rng.normal(size=(1, n)), *(2 * [rng.normal(size=1)]))
    A, lower = rng.normal(size=(m, n)), rng.normal(size=m) + 1.0
    upper = lower + rng.uniform(0.0, 0.3, m)
    A[0], lower[:2], upper[:2] = -A[1], 1.0, np.inf  # a·x ≥ 1 and −a·x ≥ 1: never both
    x_lower, x_upper = np.full(n, -2.0), np.full(n, 2.0)
    optimum = _violation(A, lower, upper, _slack_reference(top, A, lower, upper, x_lower, x_upper))
    for s in (1.0, 1e-6, 1e9, 1e60):
        if paths is None:
            result = HierarchicalQP(n).solve([top, LevelRows(s * A, s * lower, s * upper)], x_lower, x_upper)
        else:  # the solvers' own paths (SolverKine's, SolverDyn's)
            levels = [(top.A, top.lower, top.lower), (s * A, s * lower, s * upper)]
            result = solve_stack(HierarchicalQP(n), StackProblem(levels, x_lower, x_upper), paths)
        np.testing.assert_allclose(top.A @ result.x, top.lower, atol=1e-9)
        assert np.all(result.x >= x_lower) and np.all(result.x <= x_upper)
        assert _violation(A, lower, upper, result.x) <= optimum * (1 + 1e-7) + 1e-9, s
