"""The whole-stack paths (sotdrake.hqp.stack_paths): each closed form, when it answers, gives the
level-by-level stages' answer (same slack per level, same minimum-norm point, bounds held); each
applies only where it says; the solvers' declared lists always decide."""

from __future__ import annotations

import numpy as np
import pytest

from sotdrake.exceptions import SolverError
from sotdrake.hqp import HierarchicalQP
from sotdrake.hqp.equality_hierarchy import StackedLevels
from sotdrake.hqp.stack_paths import (
    ACTIVE_BOUNDS,
    BASIC,
    CASCADE,
    DYNAMIC,
    KINEMATIC,
    QR_SWEEP,
    STAGES,
    StackProblem,
    solve_stack,
)


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
@pytest.mark.parametrize("path", [QR_SWEEP, ACTIVE_BOUNDS], ids=lambda p: p.name)
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
    for path in (CASCADE, QR_SWEEP, ACTIVE_BOUNDS):
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


@pytest.mark.parametrize("path", [QR_SWEEP, ACTIVE_BOUNDS], ids=lambda p: p.name)
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
