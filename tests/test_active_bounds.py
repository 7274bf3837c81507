"""The equality hierarchy solved from guessed active bounds (sotdrake/solvers/active_bounds.py): every
point it returns is the hierarchical QP's (the stages' path), whatever the guess."""

import numpy as np
import pytest

from sotdrake.hqp.active_bounds import outcome, sides_at_bounds, solve_with_active_bounds
from sotdrake.hqp.solve import ACTIVE_BOUNDS, ACTIVE_SET, HierarchicalQP, LevelRows
from sotdrake.hqp.tolerances import FEASIBILITY
from sotdrake.hqp.warm import WarmStart
from tests.conftest import compiled_only


def equality_stack(rng, n_range=(8, 30)):
    """Equality levels of full row rank together (random rows, m ≤ n - 2), some rows scaled by
    10^U(-2, 2), bounds tight enough that some are in the way, a few fixed components."""
    n = int(rng.integers(*n_range))
    levels, m = [], 0
    for _ in range(int(rng.integers(1, 5))):
        rows = int(rng.integers(1, 7))
        if m + rows > n - 2:
            break
        A = rng.normal(size=(rows, n)) * 10.0 ** rng.uniform(-2, 2, size=(rows, 1))
        levels.append(LevelRows(A, *(2 * [A @ rng.normal(size=n) * 0.3])))
        m += rows
    size = rng.uniform(0.05, 1.0, n)
    lower, upper = -size * rng.uniform(0.2, 1.0, n), size.copy()
    fixed = rng.random(n) < 0.1
    lower[fixed] = upper[fixed] = rng.uniform(-0.05, 0.05, int(fixed.sum()))
    return n, levels, lower, upper


def by_stages(n, levels, lower, upper):
    """The hierarchical QP's answer through its stages (the active-bounds path switched off)."""
    hqp = HierarchicalQP(n)
    hqp._equalities_only = lambda *args: False  # type: ignore[method-assign]
    return hqp.solve(levels, lower, upper)


def stacked(levels):
    return (np.concatenate([level.A for level in levels]), np.concatenate([level.lower for level in levels]),
            np.concatenate([level.eq_norms for level in levels]), [len(level.A) for level in levels])


def close(x, reference):
    return np.allclose(x, reference, rtol=0.0, atol=1e-9 * max(1.0, np.abs(reference).max()))


def test_any_guess_gives_the_stages_point_or_nothing():
    """On 150 random equality stacks: from the sides of the stages' answer the point comes back
    (in most stacks, where every level is exactly solvable), and from random guesses (three rounds
    of corrections) every returned point is the stages' point, with its bounds held."""
    exact, from_answer, from_random, returned_random = 0, 0, 0, 0
    for seed in range(150):
        rng = np.random.default_rng(90_000 + seed)
        n, levels, lower, upper = equality_stack(rng)
        reference = by_stages(n, levels, lower, upper)
        A, b, norms, sizes = stacked(levels)
        fixed = lower == upper
        with np.errstate(invalid="ignore"):
            at_upper, at_lower = np.abs(reference.x - upper) <= 1e-9, np.abs(reference.x - lower) <= 1e-9
            sides = np.where(~fixed & at_upper, 1, np.where(~fixed & at_lower, -1, 0))
            solvable = float(reference.slack_norms.max()) <= 1e-9 * max(1.0, float(np.abs(b).max()))
            exact += solvable
            solved = solve_with_active_bounds(A, b, norms, sizes, lower, upper, fixed, sides, rounds=1)
            if solved is not None:
                from_answer += 1
                assert close(solved[0], reference.x), seed
            for _ in range(5):
                guess = rng.choice([-1, 0, 0, 0, 1], size=n)
                solved = solve_with_active_bounds(A, b, norms, sizes, lower, upper, fixed, guess)
                from_random += 1
                if solved is not None:
                    returned_random += 1
                    assert close(solved[0], reference.x), seed
                    assert np.all(solved[0] >= lower - 1e-9) and np.all(solved[0] <= upper + 1e-9), seed
                    assert solvable, seed
    assert exact >= 50 and from_answer >= 0.9 * exact, (exact, from_answer)
    assert returned_random >= 0.1 * from_random, (returned_random, from_random)


def test_a_conflict_or_a_rank_loss_is_left_to_the_stages():
    """A row copied from a higher level with another target (a level that cannot be met), and a
    level made rank deficient by the held bounds, are not certified: None."""
    rng = np.random.default_rng(3)
    n = 6
    A0 = rng.normal(size=(2, n))
    A1 = np.vstack([A0[0], rng.normal(size=(1, n))])
    A, b = np.vstack([A0, A1]), np.array([0.1, 0.2, 0.3, 0.0])
    wide = np.full(n, 10.0)
    norms = np.linalg.norm(A, axis=1)
    assert solve_with_active_bounds(A, b, norms, [2, 2], -wide, wide, np.zeros(n, bool), np.zeros(n, int)) is None
    # Level 1 moves x_0 only: holding x_0 at a bound leaves it no direction.
    A = np.vstack([np.eye(n)[1:3], np.eye(n)[:1]])
    b = np.array([0.1, 0.1, 5.0])
    guess = np.zeros(n, int)
    guess[0] = 1
    assert solve_with_active_bounds(A, b, np.ones(3), [2, 1], -wide, wide, np.zeros(n, bool), guess) is None
    # Without the guess the level is met (x_0 = 5 inside the bounds).
    x, sides = solve_with_active_bounds(A, b, np.ones(3), [2, 1], -wide, wide, np.zeros(n, bool), np.zeros(n, int))
    assert x[0] == pytest.approx(5.0) and not sides.any()


def test_a_bound_whose_multiplier_has_the_wrong_sign_is_released_and_a_violated_one_held():
    """min ‖x‖ s.t. x_0 + x_1 = 1, x in [-1, 0.8]³: the answer (0.5, 0.5, 0) holds no bound; a guess
    holding x_0 at 0.8 gives (0.8, 0.2, 0) with a wrong-signed multiplier, released in a second
    round. With x_0 + x_1 + x_2 = 1 and x_0 ≤ 0.2, the free answer (1/3, 1/3, 1/3) violates x_0's
    bound, which is then held: (0.2, 0.4, 0.4)."""
    A, b = np.array([[1.0, 1.0, 0.0]]), np.array([1.0])
    lower, upper = np.full(3, -1.0), np.full(3, 0.8)
    guess = np.array([1, 0, 0])
    x, sides = solve_with_active_bounds(A, b, np.array([np.sqrt(2.0)]), [1], lower, upper, np.zeros(3, bool), guess, rounds=2)
    np.testing.assert_allclose(x, [0.5, 0.5, 0.0], atol=1e-12)
    assert not sides.any()
    assert solve_with_active_bounds(A, b, np.array([np.sqrt(2.0)]), [1], lower, upper, np.zeros(3, bool), guess, rounds=1) is None
    A = np.array([[1.0, 1.0, 1.0]])
    upper = np.array([0.2, 1.0, 1.0])
    x, sides = solve_with_active_bounds(A, b, np.array([np.sqrt(3.0)]), [1], lower, upper, np.zeros(3, bool), np.zeros(3, int))
    np.testing.assert_allclose(x, [0.2, 0.4, 0.4], atol=1e-12)
    assert list(sides) == [1, 0, 0]


def test_warm_ticks_take_the_active_bounds_and_match_the_stages():
    """A stack whose targets grow from call to call (a robot's ticks), bounds in the way of more and
    more components: while every level can be met the answer comes from the active bounds, then
    (the last level out of reach) from the stages, and it is always the stages' answer."""
    rng = np.random.default_rng(11)
    n = 20
    A = [rng.normal(size=(6, n)), rng.normal(size=(3, n)), rng.normal(size=(3, n))]
    direction = [rng.normal(size=6), rng.normal(size=3), rng.normal(size=3)]
    lower, upper = np.full(n, -0.4), np.full(n, 0.4)
    lower[:2] = upper[:2] = 0.0
    hqp = HierarchicalQP(n)
    paths, held, met = [], [], []
    for tick in range(40):
        levels = [LevelRows(a, d * (1 + 0.01 * tick), d * (1 + 0.01 * tick)) for a, d in zip(A, direction, strict=True)]
        result = hqp.solve(levels, lower, upper)
        reference = by_stages(n, levels, lower, upper)
        assert close(result.x, reference.x), tick
        assert np.allclose(result.slack_norms, reference.slack_norms, atol=1e-9), tick
        paths.append(result.level_solvers[0])
        held.append(len(result.active_bounds))
        met.append(float(result.slack_norms.max()) < 1e-9)
    assert min(held) >= 1 and max(held) >= 5  # the bounds are in the way on every call, more and more of them
    assert paths == [ACTIVE_BOUNDS if ok else ACTIVE_SET for ok in met]
    assert sum(met) >= 30 and not all(met)


def test_solve_equalities_is_solve_without_level_rows():
    """``HierarchicalQP.solve_equalities`` (the robot's equality stacks, no LevelRows) gives solve's
    answer, and None where that path does not apply or its values are not finite."""
    rng = np.random.default_rng(9)
    n = 12
    A = [rng.normal(size=(4, n)), rng.normal(size=(3, n))]
    x_true = rng.normal(size=n) * 0.2
    b = [A[0] @ x_true, A[1] @ x_true]
    lower, upper = np.full(n, -0.3), np.full(n, 0.3)
    reference = by_stages(n, [LevelRows(a, v, v) for a, v in zip(A, b, strict=True)], lower, upper)
    assert len(reference.active_bounds) and reference.slack_norms.max() < 1e-9  # bounds in the way, every level met
    hqp = HierarchicalQP(n)
    levels = [LevelRows(a, v, v) for a, v in zip(A, b, strict=True)]
    result = None
    for _ in range(4):  # (the first calls may need the stages' answer as their guess)
        result = hqp.solve_equalities(A, b, lower, upper) or hqp.solve(levels, lower, upper)
    assert result is not None and result.level_solvers[0] == ACTIVE_BOUNDS
    assert close(result.x, reference.x) and np.allclose(result.slack_norms, reference.slack_norms, atol=1e-12)
    assert hqp.solve_equalities(A, b, lower, upper, damping=1e-3) is None
    assert HierarchicalQP(n, regularize=False).solve_equalities(A, b, lower, upper) is None
    assert hqp.solve_equalities(A, [b[0], np.full(3, np.nan)], lower, upper) is None
    assert hqp.solve_equalities([A[0] * np.inf, A[1]], b, lower, upper) is None
    assert hqp.solve_equalities(A, b, upper, lower) is None  # lower above upper
    assert hqp.solve_equalities(A, b, np.full(n, np.nan), upper) is None
    assert hqp.solve_equalities(A, b, lower + 0.5, upper + 1.0) is None  # 0 outside the bounds: the stages relax them
    assert hqp.solve_equalities([A[0][:, :-1], A[1]], b, lower, upper) is None


def test_on_talos_with_active_limits_the_answer_is_the_stages(talos_model, monkeypatch):
    """bench/run.py's active-limits scenario (feet, CoM, the hand behind the back): every tick that
    SolverKine solves by the active bounds, with limits in the way, gives the stages' answer."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom, gotoNd
    from sotdrake.robot import Robot, add_sot
    from sotdrake.robots import TALOS_GRIPPERS

    builder = DiagramBuilder()
    robot = Robot(builder, talos_model, 1e-3)
    sot = add_sot(robot, solver="hqp")
    sot.setControlSelection(robot.velocity_selection(TALOS_GRIPPERS))
    tasks = [MetaTaskKine6d("contactRF", robot, "RF", "right-ankle"), MetaTaskKine6d("contactLF", robot, "LF", "left-ankle"),
             MetaTaskKineCom(robot), MetaTaskKine6d("rh", robot, "rh", "right-wrist")]
    for task in tasks[:3]:
        task.gain.setConstant(10.0)
    tasks[3].opmodif = np.array([[1, 0, 0, 0.1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    gotoNd(tasks[3], np.array([-0.45, -0.35, 1.0]), "111", 4.9)
    for task in tasks:
        sot.push(task.task.name)
    diagram = builder.Build()
    checked = []
    solve_equalities = HierarchicalQP.solve_equalities

    def checking(self, jacobians, values, x_lower, x_upper, damping=0.0, warm=None):
        result = solve_equalities(self, jacobians, values, x_lower, x_upper, damping, warm=warm)
        if result is not None:
            levels = [LevelRows(J, v, v) for J, v in zip(jacobians, values, strict=True)]
            reference = by_stages(self.n, levels, x_lower, x_upper)
            assert close(result.x, reference.x), len(checked)
            assert np.allclose(result.slack_norms, reference.slack_norms, atol=1e-12)
            assert np.all(result.x >= x_lower) and np.all(result.x <= x_upper)
            checked.append(len(result.active_bounds))
        return result

    monkeypatch.setattr(HierarchicalQP, "solve_equalities", checking)
    simulator = Simulator(diagram)
    simulator.AdvanceTo(0.3)
    assert len(checked) >= 290 and sum(count > 0 for count in checked) >= 120, (len(checked), checked[-5:])


@compiled_only
def test_any_array_layout_gives_the_same_answer_without_another_compilation():
    """The compiled path takes C-ordered, writeable arrays of one dtype each: read-only,
    Fortran-ordered, strided, integer or boolean-as-integer inputs and a list of sizes are converted
    (the same bits) rather than compiled for again."""
    from sotdrake.hqp import active_bounds

    rng = np.random.default_rng(11)
    n, levels, lower, upper = equality_stack(rng)
    A, b, norms, sizes = stacked(levels)
    fixed = lower == upper
    guess = np.zeros(n, dtype=np.int64)
    plain = solve_with_active_bounds(A, b, norms, np.array(sizes), lower, upper, fixed, guess)
    assert plain is not None
    signatures = len(active_bounds._solve.signatures)
    frozen = [a.copy() for a in (A, b, lower, upper)]
    for a in frozen:
        a.flags.writeable = False
    wide = np.zeros((len(A), 2 * n))
    wide[:, ::2] = A
    for arguments in (
        (frozen[0], frozen[1], norms, sizes, frozen[2], frozen[3], fixed, guess),
        (np.asfortranarray(A), b, norms, tuple(sizes), lower, upper, fixed.astype(np.int8) == 1, guess.astype(np.int32)),
        (wide[:, ::2], b, norms, sizes, np.repeat(lower, 2)[::2], upper, list(fixed), guess.tolist()),
    ):
        x, sides = solve_with_active_bounds(*arguments)
        np.testing.assert_array_equal(x, plain[0])
        np.testing.assert_array_equal(sides, plain[1])
    assert len(active_bounds._solve.signatures) == signatures


def test_outcome_puts_the_answer_on_the_bounds_it_passes_by_round_off():
    """A component past its bound by round-off (1e-9 relative above 1) is put on it, one farther out
    stays (a start kept outside), the others are left as they are; the residuals follow."""
    x_lower, x_upper = np.array([-1.0, -1.0, -1.0, -1.0, -1e3]), np.array([1.0, 1.0, 1.0, 2.0, 1e3])
    x = np.array([1.0 + 5e-10, -1.0 - 3e-10, 0.5, 2.0 + 1e-6, 1e3 + 5e-7])
    A, b = np.eye(5), np.zeros(5)
    moved, residual, norms, active = outcome(A, b, np.array([5]), x.copy(), x_lower, x_upper, np.zeros(5, dtype=bool), 1e-9)
    np.testing.assert_array_equal(moved, [1.0, -1.0, 0.5, 2.0 + 1e-6, 1e3])
    np.testing.assert_array_equal(residual, moved)
    assert norms[0] == np.linalg.norm(moved)
    np.testing.assert_array_equal(active, [0, 1, 3, 4])


def test_solve_stack_is_the_active_bounds_and_their_outcome_in_one_call():
    """``solve_stack`` (the robot's path): the point and sides of ``solve_with_active_bounds`` with
    ``outcome``'s residuals; NOT_APPLICABLE when 0 is outside a free component's bounds (or a bound
    is NaN), NOT_VERIFIED when no guess passes; only the latter counts for the back-off."""
    from sotdrake.hqp import active_bounds as path

    rng = np.random.default_rng(20)  # two levels, two fixed components, two bounds held at the answer
    n, levels, lower, upper = equality_stack(rng)
    A, b, _, sizes = stacked(levels)
    fixed = lower == upper
    guess = np.zeros(n, dtype=np.int64)
    sizes = np.array(sizes, dtype=np.int64)
    status, x, sides, residual, slack_norms, active = path.solve_stack(A, b, sizes, lower, upper, guess, 1e-5, 1e-10, 1e-9)
    expected = solve_with_active_bounds(A, b, path.row_norms(A), sizes, lower, upper, fixed, guess)
    assert status == path.SOLVED and expected is not None
    np.testing.assert_array_equal(sides, expected[1])
    want = outcome(A, b, sizes, expected[0].copy(), lower, upper, fixed, 1e-9)
    for got, wanted in zip((x, residual, slack_norms, active), want, strict=True):
        np.testing.assert_array_equal(got, wanted)
    shifted = lower.copy()
    shifted[~fixed] = np.maximum(shifted[~fixed], 1e-3)  # 0 below every free component's bounds
    assert path.solve_stack(A, b, sizes, shifted, upper + 1.0, guess, 1e-5, 1e-10, 1e-9)[0] == path.NOT_APPLICABLE
    nan = lower.copy()
    nan[np.flatnonzero(~fixed)[0]] = np.nan
    assert path.solve_stack(A, b, sizes, nan, upper, guess, 1e-5, 1e-10, 1e-9)[0] == path.NOT_APPLICABLE
    conflict = np.vstack([A, A[:1]]), np.concatenate([b, b[:1] + 1.0])  # a level that contradicts the first
    status = path.solve_stack(*conflict, np.append(sizes, 1), lower, upper, guess, 1e-5, 1e-10, 1e-9)[0]
    assert status == path.NOT_VERIFIED
    hqp, warm = HierarchicalQP(n), WarmStart(n)
    assert hqp.solve_equalities([A, A[:1]], [b, b[:1] + 1.0], lower, upper, warm=warm) is None
    assert warm.failures == 1 and warm.skips == 1
    assert hqp.solve_equalities([A], [b], shifted, upper + 1.0, warm=warm) is None  # not applicable: no skip used
    assert warm.skips == 1
    assert hqp.solve_equalities([A], [b], lower, upper, warm=warm) is None  # skipped
    assert warm.skips == 0
    assert hqp.solve_equalities([A], [b], lower, upper, warm=warm) is not None and warm.failures == 0


def test_the_sides_of_the_bounds_an_answer_holds():
    """Each component's side against a plain reference: at a finite upper bound (to the feasibility
    tolerance, relative above 1) +1, at a finite lower bound -1, else 0, and 0 on a fixed component;
    infinite bounds and NaN are never at a side."""
    rng = np.random.default_rng(11)
    for _ in range(50):
        n = 40
        lower, upper = -10.0 ** rng.uniform(-3, 3, n), 10.0 ** rng.uniform(-3, 3, n)
        x = rng.uniform(lower, upper)
        pick = rng.random(n)
        x[pick < 0.2] = upper[pick < 0.2] * (1 - rng.uniform(-2, 2, n)[pick < 0.2] * FEASIBILITY)
        x[pick > 0.8] = lower[pick > 0.8] * (1 - rng.uniform(-2, 2, n)[pick > 0.8] * FEASIBILITY)
        lower[rng.random(n) < 0.1], upper[rng.random(n) < 0.1] = -np.inf, np.inf
        x[rng.random(n) < 0.05] = np.nan
        fixed = rng.random(n) < 0.1
        with np.errstate(invalid="ignore"):  # (inf - inf)
            at_upper = ~fixed & np.isfinite(upper) & (x >= upper - FEASIBILITY * np.maximum(1.0, np.abs(upper)))
            at_lower = ~fixed & ~at_upper & np.isfinite(lower) & (x <= lower + FEASIBILITY * np.maximum(1.0, np.abs(lower)))
        expected = at_upper.astype(int) - at_lower.astype(int)
        assert np.array_equal(sides_at_bounds(x, lower, upper, fixed), expected)
        assert 0 < np.count_nonzero(expected)
