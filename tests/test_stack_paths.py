"""The whole-stack paths (sotdrake.hqp.stack_paths): each closed form, when it answers, gives the
level-by-level stages' answer (same slack per level, same minimum-norm point, bounds held); each
applies only where it says; the solvers' declared lists always decide."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from sotdrake.exceptions import InvalidInput, SolverError
from sotdrake.hqp import HierarchicalQP
from sotdrake.hqp.active_bounds import SOLVED, solve_held_rows
from sotdrake.hqp.equality_hierarchy import StackedLevels
from sotdrake.hqp.problem import LevelRows, result_of
from sotdrake.hqp.stack_paths import (
    ACTIVE_BOUNDS,
    BASIC,
    CASCADE,
    DYNAMIC,
    HELD_ROWS,
    INACTIVE_ROWS,
    KINEMATIC,
    QR_SWEEP,
    STAGES,
    WARM_QR_SWEEP,
    StackProblem,
    solve_stack,
)
from sotdrake.hqp.tolerances import CERTIFIED_FACTOR, VERIFIED
from sotdrake.hqp.warm import back_off


def equality_stack(rng: np.random.Generator, bounds: str):
    """``(n, levels, lower, upper)``: 1-4 equality levels of 1-6 rows over n in [6, 30] variables,
    some rank deficient or repeating a higher level's rows with other targets (conflicts); bounds
    none, loose (never reached by the answer's scale) or tight."""
    n = int(rng.integers(6, 31))
    levels = []
    for _ in range(int(rng.integers(1, 5))):
        m = int(rng.integers(1, 7))
        rank = int(rng.integers(1, m + 1)) if rng.random() < 0.3 else m
        A = rng.normal(size=(m, rank)) @ rng.normal(size=(rank, n)) / np.sqrt(rank)
        if levels and rng.random() < 0.3:
            A[0] = levels[-1][0][0]
        b = rng.normal(size=m)
        levels.append((A, b, b))
    width = {"none": np.inf, "loose": 1e3, "tight": rng.uniform(0.02, 0.3)}[bounds]
    return n, levels, np.full(n, -width), np.full(n, width)


def assert_same_answer(result, reference, levels, lower, upper):
    scale = 1.0 + np.abs(reference.x).max()
    for k, (A, b, _) in enumerate(levels):  # each level's slack: the stages' (strict hierarchy)
        size = 1.0 + np.abs(b).max(initial=0.0) + np.abs(A).max(initial=0.0) * scale
        assert abs(np.linalg.norm(A @ result.x - b) - reference.slack_norms[k]) <= 1e-7 * size, f"level {k}"
    assert np.all(result.x >= lower - 1e-9 * scale) and np.all(result.x <= upper + 1e-9 * scale)
    assert np.linalg.norm(result.x - reference.x) <= 1e-6 * scale  # the minimum-norm point, unique


@pytest.mark.parametrize("bounds", ["none", "loose", "tight"])
@pytest.mark.parametrize("path", [QR_SWEEP, ACTIVE_BOUNDS, WARM_QR_SWEEP], ids=lambda p: p.name)
def test_the_closed_forms_under_bounds_give_the_stages_answer(path, bounds):
    rng = np.random.default_rng(20261126)
    clear = 0
    for _ in range(60):
        n, levels, lower, upper = equality_stack(rng, bounds)
        problem = StackProblem(levels, lower, upper)
        reference = STAGES.attempt(HierarchicalQP(n), problem)
        result = path.attempt(HierarchicalQP(n), problem)
        if result is not None:
            assert_same_answer(result, reference, levels, lower, upper)
        stacked = np.vstack([A for A, _, _ in levels])
        if bounds != "tight" and np.linalg.matrix_rank(stacked) == len(stacked):
            clear += 1  # every level met exactly, no bound in the way: both paths apply and verify
            assert result is not None
    assert clear >= 20 or bounds == "tight"


def test_the_qr_sweep_takes_levels_already_stacked():
    rng = np.random.default_rng(7)
    n, levels, lower, upper = equality_stack(rng, "loose")
    stacked = StackedLevels.of([(A, b) for A, b, _ in levels])
    reference = STAGES.attempt(HierarchicalQP(n), StackProblem(levels, lower, upper))
    result = QR_SWEEP.attempt(HierarchicalQP(n), StackProblem([], lower, upper, stacked=stacked))
    assert result is not None
    assert_same_answer(result, reference, levels, lower, upper)


def test_the_cascade_without_damping_gives_the_stages_answer_without_bounds():
    rng = np.random.default_rng(11)
    for _ in range(60):
        n, levels, lower, upper = equality_stack(rng, "none")
        problem = StackProblem(levels, lower, upper)
        result = CASCADE.attempt(HierarchicalQP(n), problem)
        assert result is not None and result.level_solvers == ["cascade"] * len(levels)
        assert_same_answer(result, STAGES.attempt(HierarchicalQP(n), problem), levels, lower, upper)


def test_the_cascade_applies_to_equalities_without_bounds_and_the_default_solver_only():
    rng = np.random.default_rng(3)
    n, levels, lower, upper = equality_stack(rng, "none")
    qp = HierarchicalQP(n)
    assert CASCADE.attempt(qp, StackProblem(levels, np.full(n, -1.0), upper)) is None
    A, b, _ = levels[0]
    inequality = [(A, b - 1.0, b + 1.0), *levels[1:]]
    assert CASCADE.attempt(qp, StackProblem(inequality, lower, upper)) is None
    assert QR_SWEEP.attempt(qp, StackProblem(inequality, lower, upper)) is None
    assert ACTIVE_BOUNDS.attempt(qp, StackProblem(inequality, lower, upper)) is None
    assert WARM_QR_SWEEP.attempt(qp, StackProblem(inequality, lower, upper)) is None
    for path in (CASCADE, QR_SWEEP, ACTIVE_BOUNDS, WARM_QR_SWEEP):
        assert path.attempt(qp, StackProblem(levels, lower, upper, solver="clarabel")) is None


def test_the_cascade_with_damping_is_the_damped_inverse():
    """One level ``J v = r`` damped by δ: ``v = Jᵀ (J Jᵀ + δ I)⁻¹ r``, not the exact solution."""
    rng = np.random.default_rng(5)
    J, r = rng.normal(size=(3, 8)), rng.normal(size=3)
    damping = 0.1
    result = CASCADE.attempt(HierarchicalQP(8), StackProblem([(J, r, r)], np.full(8, -np.inf), np.full(8, np.inf), damping))
    assert result is not None
    np.testing.assert_allclose(result.x, J.T @ np.linalg.solve(J @ J.T + damping * np.eye(3), r), rtol=1e-10, atol=1e-12)
    assert result.slack_norms[0] > 1e-3


def test_the_solvers_lists_always_decide():
    assert KINEMATIC[-1] is STAGES and DYNAMIC[-1] is STAGES and BASIC == (CASCADE,)
    rng = np.random.default_rng(2)
    n, levels, lower, upper = equality_stack(rng, "tight")
    A, b, _ = levels[0]
    levels = [(A, b - 0.5, b + 0.5), *levels[1:]]  # an inequality level: the closed forms do not apply
    for paths in (KINEMATIC, DYNAMIC):
        result = solve_stack(HierarchicalQP(n), StackProblem(levels, lower, upper), paths)
        assert np.all(result.x >= lower - 1e-9) and np.all(result.x <= upper + 1e-9)
    with pytest.raises(SolverError, match="no path answered"):
        solve_stack(HierarchicalQP(n), StackProblem(levels, lower, upper), (QR_SWEEP, ACTIVE_BOUNDS))


@pytest.mark.parametrize("path", [QR_SWEEP, ACTIVE_BOUNDS, WARM_QR_SWEEP], ids=lambda p: p.name)
def test_a_level_without_rows_does_not_keep_the_closed_forms_out(path):
    """An inequality level with no row (a collision level with no pair in range) is no inequality."""
    rng = np.random.default_rng(13)
    n, levels, lower, upper = equality_stack(rng, "loose")
    while np.linalg.matrix_rank(np.vstack([A for A, _, _ in levels])) < sum(len(A) for A, _, _ in levels):
        n, levels, lower, upper = equality_stack(rng, "loose")
    empty = (np.zeros((0, n)), np.zeros(0), np.zeros(0))
    levels = [levels[0], empty, *levels[1:]]
    problem = StackProblem(levels, lower, upper)
    result = path.attempt(HierarchicalQP(n), problem)
    assert result is not None
    assert_same_answer(result, STAGES.attempt(HierarchicalQP(n), problem), levels, lower, upper)


def with_posture(rng: np.random.Generator, bounds: str):
    """An equality stack (:func:`equality_stack`, its levels of full row rank together) with a
    posture-like level at the bottom: n rows (a random invertible matrix, random targets), more than
    the levels above leave free."""
    n, levels, lower, upper = equality_stack(rng, bounds)
    while np.linalg.matrix_rank(np.vstack([A for A, _, _ in levels])) < sum(len(A) for A, _, _ in levels):
        n, levels, lower, upper = equality_stack(rng, bounds)
    posture = np.eye(n) + 0.3 * rng.normal(size=(n, n)) / np.sqrt(n)
    target = rng.normal(size=n)
    return n, [*levels, (posture, target, target)], lower, upper


@pytest.mark.parametrize("bounds", ["none", "loose", "tight"])
def test_the_warm_qr_sweep_answers_a_posture_below_the_levels(bounds):
    """A level of more rows than what is left free (a posture task at the bottom): the active bounds
    cannot certify it (their levels must be of full row rank); the warm QR sweep answers with the
    stages' answer, cold (no bound held: it holds the bounds in the way one at a time, a few times)
    and from a warm start (the bounds the last answer holds, here the stages', as its first guess:
    with tight bounds most components end at one, too many to find one at a time)."""
    rng = np.random.default_rng(20261127)
    answered = {"cold": 0, "warm": 0}
    for _ in range(40):
        n, levels, lower, upper = with_posture(rng, bounds)
        problem = StackProblem(levels, lower, upper)
        reference = STAGES.attempt(HierarchicalQP(n), problem)
        assert ACTIVE_BOUNDS.attempt(HierarchicalQP(n), problem) is None
        for start in answered:
            qp = HierarchicalQP(n)
            if start == "warm":
                qp.warm.bound_sides = (reference.x, lower, upper)
            result = WARM_QR_SWEEP.attempt(qp, problem)
            if result is not None:
                assert_same_answer(result, reference, levels, lower, upper)
                assert isinstance(qp.warm.bound_sides, tuple) and qp.warm.bound_sides[0] is result.x
                answered[start] += 1
    assert answered["warm"] >= 30 and (answered["cold"] >= 30 or bounds == "tight")


def test_the_warm_qr_sweep_applies_only_where_it_stands_for_the_default_stages():
    rng = np.random.default_rng(29)
    n, levels, lower, upper = with_posture(rng, "loose")
    assert WARM_QR_SWEEP.attempt(HierarchicalQP(n), StackProblem(levels, lower, upper)) is not None
    assert WARM_QR_SWEEP.attempt(HierarchicalQP(n), StackProblem(levels, lower, upper, damping=0.1)) is None
    assert WARM_QR_SWEEP.attempt(HierarchicalQP(n, rank_threshold=1e-6), StackProblem(levels, lower, upper)) is None
    assert WARM_QR_SWEEP.attempt(HierarchicalQP(n, hold_tolerance=1e-3), StackProblem(levels, lower, upper)) is None
    assert WARM_QR_SWEEP.attempt(HierarchicalQP(n, regularize=False), StackProblem(levels, lower, upper)) is None
    outside = np.full(n, 2e3)  # the stages' start outside the bounds: they relax a bound to it
    assert WARM_QR_SWEEP.attempt(HierarchicalQP(n), StackProblem(levels, lower, upper, start=outside)) is None
    nan = lower.copy()
    nan[0] = np.nan
    assert WARM_QR_SWEEP.attempt(HierarchicalQP(n), StackProblem(levels, nan, upper)) is None
    qp = HierarchicalQP(n)
    assert WARM_QR_SWEEP.attempt(qp, StackProblem([], lower, upper)) is None  # an empty stack: not a failure
    assert qp.warm.sweep_failures == 0


def test_the_warm_qr_sweep_backs_off_after_failures():
    """A stack whose rank is not clear-cut (two rows within 1e-7 of each other: a singular value
    between the negligible and the certified ones) is the stages' to decide: after f failures in a
    row the next 2^(f−1) calls skip the sweep, a success resets the count, and a cloned warm start
    keeps the count."""
    rng = np.random.default_rng(31)
    n = 12
    A = rng.normal(size=(2, n))
    A[1] = A[0] + 1e-7 * rng.normal(size=n)
    b = rng.normal(size=2)
    unclear = StackProblem([(A, b, b)], np.full(n, -1e3), np.full(n, 1e3))
    qp = HierarchicalQP(n)
    tries = 0
    for _ in range(12):
        before = qp.warm.sweep_skips
        assert WARM_QR_SWEEP.attempt(qp, unclear) is None
        if before == 0:
            tries += 1
            assert qp.warm.sweep_failures == tries and qp.warm.sweep_skips == back_off(tries)
        else:
            assert qp.warm.sweep_skips == before - 1
    assert tries == 4  # calls 0, 1, 3 and 7 tried (skips 1, 2, 4 between them)
    assert copy.deepcopy(qp.warm).sweep_failures == tries
    target = b[:1]
    clear = StackProblem([(A[:1], target, target)], np.full(n, -1e3), np.full(n, 1e3))
    for _ in range(qp.warm.sweep_skips):
        assert WARM_QR_SWEEP.attempt(qp, clear) is None
    assert WARM_QR_SWEEP.attempt(qp, clear) is not None and qp.warm.sweep_failures == 0
    qp.forget_warm_starts()
    assert qp.warm.sweep_failures == qp.warm.sweep_skips == 0


def with_inequalities(rng: np.random.Generator, n: int, levels: list, x_eq: np.ndarray, holding: bool) -> list:
    """``levels`` with inequality rows added around ``x_eq`` (the equality stack's answer): a level of
    2-5 inequality rows inserted at a random place and 1-3 rows appended to a random equality level
    (a mixed level); rows scaled over 10²; one side may be infinite. ``holding``: every row holds at
    ``x_eq`` with a margin; otherwise the inserted level's first row cuts ``x_eq`` off."""
    def rows(m: int):
        A = rng.normal(size=(m, n)) * 10.0 ** rng.uniform(-1, 1, size=(m, 1))
        value = A @ x_eq
        margin = rng.uniform(0.05, 1.0, m) * (1.0 + np.abs(value))
        lower, upper = value - margin, value + margin
        lower[rng.random(m) < 0.3] = -np.inf
        upper[np.isfinite(lower) & (rng.random(m) < 0.3)] = np.inf
        return A, lower, upper
    out = list(levels)
    k = int(rng.integers(len(out)))
    A, b, _ = out[k]
    A_in, lower_in, upper_in = rows(int(rng.integers(1, 4)))
    out[k] = (np.vstack([A, A_in]), np.concatenate([b, lower_in]), np.concatenate([b, upper_in]))
    A_in, lower_in, upper_in = rows(int(rng.integers(2, 6)))
    if not holding:  # the first row asks A x ≥ A x_eq + 1: violated at x_eq
        lower_in[0], upper_in[0] = A_in[0] @ x_eq + 1.0, np.inf
    out.insert(int(rng.integers(len(out) + 1)), (A_in, lower_in, upper_in))
    return out


def around_the_equality_answer(rng: np.random.Generator, n: int, levels: list, lower, upper,
                               holding: bool) -> tuple[list, np.ndarray]:
    """``(mixed, x_eq)``: the stages' answer ``x_eq`` of the equality ``levels`` under the bounds, and
    the levels with inequality rows around it (:func:`with_inequalities`)."""
    x_eq = STAGES.attempt(HierarchicalQP(n), StackProblem(levels, lower, upper)).x
    return with_inequalities(rng, n, levels, x_eq, holding), x_eq


def assert_same_mixed_answer(result, reference, levels, lower, upper):
    """Each level's slack (inequality violations included) as the stages', the bounds held, the
    minimum-norm point; the reported slacks are the point's."""
    scale = 1.0 + np.abs(reference.x).max()
    for k, (A, lo, hi) in enumerate(levels):
        slack = LevelRows(A, lo, hi).slack(result.x)
        size = 1.0 + np.abs(A).max() * scale + np.abs(lo[np.isfinite(lo)]).max(initial=0.0)
        assert abs(np.linalg.norm(slack) - reference.slack_norms[k]) <= 1e-7 * size, f"level {k}"
        assert np.allclose(result.slacks[k], slack) and result.slack_norms[k] == pytest.approx(np.linalg.norm(slack))
    assert np.all(result.x >= lower - 1e-9 * scale) and np.all(result.x <= upper + 1e-9 * scale)
    assert np.linalg.norm(result.x - reference.x) <= 1e-6 * scale
    reported = result_of([LevelRows(*level) for level in levels], result.x, lower, upper, lower == upper, [])
    for k in range(len(levels)):  # the rows at a side and the bounds reached, as the stages report them at x
        np.testing.assert_array_equal(result.active_rows[k], reported.active_rows[k])
    np.testing.assert_array_equal(result.active_bounds, reported.active_bounds)


@pytest.mark.parametrize("bounds", ["none", "loose", "tight"])
def test_held_rows_give_the_stages_answer_and_answer_when_the_equality_rows_are_clear(bounds):
    """Inequality rows inserted as a level and appended to an equality level, all holding at the
    equality stack's answer or one of them cutting it off (then it has to be held at its bound).
    Whenever the path answers, it is the stages' answer of the whole stack: each level's slack
    (inequality violations included), the bounds, the minimum-norm point. With every row holding it
    answers when the equality stack is clear (full row rank, no bound in the way), and it answers
    most clear stacks whose row has to be held (the held row independent of the others, the rows it
    moves staying inside their margins)."""
    rng = np.random.default_rng(20261127)
    clear = {True: 0, False: 0}
    answered = {True: 0, False: 0}
    total = 0
    for trial in range(150):
        n, levels, lower, upper = equality_stack(rng, bounds)
        holding = trial % 3 != 0
        mixed, x_eq = around_the_equality_answer(rng, n, levels, lower, upper, holding)
        problem = StackProblem(mixed, lower, upper)
        result = HELD_ROWS.attempt(HierarchicalQP(n), problem)
        reference = STAGES.attempt(HierarchicalQP(n), problem)
        if result is not None:
            assert_same_mixed_answer(result, reference, mixed, lower, upper)
            total += 1
            if not holding:  # the cut row is met at its bound
                A_in, lo_in, _ = next(level for level in mixed if np.isfinite(level[1][0]) and np.isinf(level[2][0])
                                      and level[1][0] - level[0][0] @ x_eq >= 1.0 - 1e-9)
                assert A_in[0] @ result.x == pytest.approx(lo_in[0], abs=1e-9 * (1.0 + abs(lo_in[0])))
        stacked = np.vstack([A for A, _, _ in levels])
        if bounds != "tight" and np.linalg.matrix_rank(stacked) == len(stacked):
            clear[holding] += 1
            answered[holding] += result is not None
    assert total >= 5
    if bounds != "tight":
        assert clear[True] >= 20 and answered[True] == clear[True]
        assert clear[False] >= 10 and answered[False] >= 0.7 * clear[False]


def test_a_guess_of_the_held_rows_changes_the_cost_never_the_answer():
    """Stacks whose answer holds inequality rows: the path warm from its last answer's rows (the same
    stack, then its targets moved) gives the stages' answer; the answer's own held rows as the
    guess are verified at once (one round), and random guesses give the cold answer or none."""
    rng = np.random.default_rng(20261128)
    certified, feasibility = CERTIFIED_FACTOR * 1e-8, VERIFIED
    warm_answers = one_round = wrong_answers = 0
    for _ in range(60):
        n, levels, lower, upper = equality_stack(rng, "loose")
        mixed, _ = around_the_equality_answer(rng, n, levels, lower, upper, False)
        qp = HierarchicalQP(n)
        if HELD_ROWS.attempt(qp, StackProblem(mixed, lower, upper)) is None:
            continue
        assert qp.warm.row_sides is not None and qp.warm.row_sides[1].any()  # (the cut row)
        moved = [(A, np.where(lo != hi, lo + 1e-3 * rng.normal(size=lo.shape), lo), hi) if lo is not hi else (A, lo, hi)
                 for A, lo, hi in mixed]  # (the inequality rows' lower sides)
        for stack in (mixed, moved):
            problem = StackProblem(stack, lower, upper)
            result = HELD_ROWS.attempt(qp, problem)
            if result is not None:
                assert_same_mixed_answer(result, STAGES.attempt(HierarchicalQP(n), problem), stack, lower, upper)
                warm_answers += 1
        A, lo, hi = (np.concatenate([level[i] for level in mixed]) for i in range(3))
        sizes = np.array([len(level[0]) for level in mixed], dtype=np.int64)
        guess = np.zeros(n, dtype=np.int64)
        cold = solve_held_rows(A, lo, hi, sizes, lower, upper, guess, certified, feasibility, 1e-9)
        assert cold[0] == SOLVED
        right = solve_held_rows(A, lo, hi, sizes, lower, upper, guess, certified, feasibility, 1e-9, rounds=1, row_guess=cold[3])
        assert right[0] == SOLVED and np.array_equal(right[3], cold[3])
        one_round += 1
        for _ in range(5):
            wrong = rng.integers(-1, 2, size=cold[3].size)
            answer = solve_held_rows(A, lo, hi, sizes, lower, upper, guess, certified, feasibility, 1e-9, row_guess=wrong)
            if answer[0] == SOLVED:
                assert np.linalg.norm(answer[1] - cold[1]) <= 1e-6 * (1.0 + np.abs(cold[1]).max())
                wrong_answers += 1
    assert one_round >= 20 and warm_answers >= 1.8 * one_round and wrong_answers >= one_round


@pytest.mark.parametrize("defect", ["nan coefficient", "sides out of order", "infinite equality value", "too few columns"])
def test_held_rows_leave_bad_rows_to_the_stages(defect):
    """Rows the stages refuse: the path gives no answer, and the stack's solve raises the stages' error."""
    rng = np.random.default_rng(5)
    n, levels, lower, upper = equality_stack(rng, "loose")
    mixed, _ = around_the_equality_answer(rng, n, levels, lower, upper, True)
    k = next(i for i, (_, lo, hi) in enumerate(mixed) if lo is not hi)
    A, lo, hi = (np.array(part, dtype=float) for part in mixed[k])
    if defect == "nan coefficient":
        A[0, 0] = np.nan
    elif defect == "sides out of order":
        lo[0], hi[0] = 1.0, -1.0
    elif defect == "infinite equality value":
        lo[0] = hi[0] = np.inf
    else:
        A = A[:, :-1]
    mixed[k] = (A, lo, hi)
    problem = StackProblem(mixed, lower, upper)
    assert HELD_ROWS.attempt(HierarchicalQP(n), problem) is None
    with pytest.raises(InvalidInput):
        solve_stack(HierarchicalQP(n), problem, KINEMATIC)


def test_held_rows_back_off_after_failures_and_apply_only_where_they_say():
    rng = np.random.default_rng(17)
    n, levels, lower, upper = equality_stack(rng, "loose")
    while np.linalg.matrix_rank(np.vstack([A for A, _, _ in levels])) < sum(len(A) for A, _, _ in levels):
        n, levels, lower, upper = equality_stack(rng, "loose")  # a clear stack: the equality solve answers
    qp = HierarchicalQP(n)
    assert HELD_ROWS.attempt(qp, StackProblem(levels, lower, upper)) is None  # no inequality row: not its stack
    held, x_eq = around_the_equality_answer(rng, n, levels, lower, upper, False)
    assert HELD_ROWS.attempt(HierarchicalQP(n), StackProblem(held, lower, upper)) is not None  # (its row is held)
    relaxed = HierarchicalQP(n, hold_tolerance=1e-6)  # then the stages let the levels below pass a held row
    assert HELD_ROWS.attempt(relaxed, StackProblem(held, lower, upper)) is None
    # A row above the last level that keeps it from its target: that level cannot be met, the path fails.
    row = levels[-1][0][:1]
    cut = [(row, row @ x_eq + 1.0, np.full(1, np.inf)), *levels]
    assert HELD_ROWS.attempt(qp, StackProblem(cut, lower, upper, solver="clarabel")) is None
    assert HELD_ROWS.attempt(qp, StackProblem(cut, lower, upper, damping=0.1)) is None
    failures = []
    for _ in range(8):  # tried (1 failure), skipped once, tried (2), skipped twice, tried (3), skipped 4 times
        assert HELD_ROWS.attempt(qp, StackProblem(cut, lower, upper)) is None
        failures.append(qp.warm.row_failures)
    assert failures == [1, 1, 2, 2, 2, 3, 3, 3]
    result = solve_stack(qp, StackProblem(cut, lower, upper), KINEMATIC)  # the stages decide
    assert np.all(result.x >= lower - 1e-9) and np.all(result.x <= upper + 1e-9)
    assert result.slack_norms == pytest.approx(STAGES.attempt(HierarchicalQP(n), StackProblem(cut, lower, upper)).slack_norms,
                                               abs=1e-7)


@pytest.mark.parametrize("bounds", ["none", "loose", "tight"])
def test_inactive_rows_give_the_stages_answer_below_a_level_that_cannot_be_met(bounds):
    """Inequality rows around the answer of the equality rows alone, in a stack whose last level
    cannot be met (a posture): when they all hold there, that answer is the stages' answer of the
    whole stack (each level's slack, the bounds, the minimum-norm point, the rows reported at a
    side); when one is cut off, the path leaves the stack to the stages and counts a failure."""
    rng = np.random.default_rng(20261128)
    answered = {True: 0, False: 0}
    for trial in range(60):
        n, levels, lower, upper = with_posture(rng, bounds)
        holding = trial % 3 != 0
        mixed, _ = around_the_equality_answer(rng, n, levels, lower, upper, holding)
        problem = StackProblem(mixed, lower, upper)
        qp = HierarchicalQP(n)
        result = INACTIVE_ROWS.attempt(qp, problem)
        if result is not None:
            assert holding
            assert_same_mixed_answer(result, STAGES.attempt(HierarchicalQP(n), problem), mixed, lower, upper)
        elif not holding:
            assert qp.warm.inactive_failures in (0, 1)  # (1: the rows cut off; 0: the equality rows undecided)
        answered[holding] += result is not None
    assert (answered[True] >= 25 or bounds == "tight") and answered[False] == 0  # (tight: too many bounds to find cold)


def test_inactive_rows_apply_only_where_they_say_and_back_off():
    rng = np.random.default_rng(37)
    n, levels, lower, upper = with_posture(rng, "loose")
    holding, x_eq = around_the_equality_answer(rng, n, levels, lower, upper, True)
    qp = HierarchicalQP(n)
    assert INACTIVE_ROWS.attempt(qp, StackProblem(levels, lower, upper)) is None  # no inequality row: not its stack
    assert INACTIVE_ROWS.attempt(qp, StackProblem(holding, lower, upper, damping=0.1)) is None
    assert INACTIVE_ROWS.attempt(qp, StackProblem(holding, lower, upper, solver="clarabel")) is None
    A, lo, hi = holding[0]
    bad = [(A, lo, np.full_like(hi, np.nan)), *holding[1:]]
    assert INACTIVE_ROWS.attempt(qp, StackProblem(bad, lower, upper)) is None  # (the stages say what is wrong)
    assert INACTIVE_ROWS.attempt(qp, StackProblem(holding, lower, upper)) is not None
    cut = with_inequalities(rng, n, levels, x_eq, holding=False)
    tries = 0
    for _ in range(12):  # tries at calls 0, 2, 5 and 10 (skips 1, 2, 4 between them)
        before = qp.warm.inactive_skips
        assert INACTIVE_ROWS.attempt(qp, StackProblem(cut, lower, upper)) is None
        if before == 0:
            tries += 1
            assert qp.warm.inactive_failures == tries and qp.warm.inactive_skips == back_off(tries)
    assert tries == 4 and copy.deepcopy(qp.warm).inactive_failures == 4
    for _ in range(qp.warm.inactive_skips):
        assert INACTIVE_ROWS.attempt(qp, StackProblem(holding, lower, upper)) is None
    assert INACTIVE_ROWS.attempt(qp, StackProblem(holding, lower, upper)) is not None and qp.warm.inactive_failures == 0
