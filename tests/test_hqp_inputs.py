"""The hierarchical QP's whole-stack paths take only what its stages take: a NaN, an infinite or a
huge coefficient or target, NaN or crossed bounds, given to `solve_stack` under any path list, is
refused with `InvalidInput` (the QR sweep, warmed by an earlier answer, used to answer them), and
inputs that are not real numbers are refused by name."""

from __future__ import annotations

import numpy as np
import pytest

from sotdrake.exceptions import InvalidInput
from sotdrake.hqp import BASIC, DYNAMIC, KINEMATIC, HierarchicalQP, LevelRows, StackProblem, solve_stack

N = 4
LOWER, UPPER = -np.ones(N), np.ones(N)
A = np.eye(2, N)
GOOD = np.array([1.0, 2.0])  # beyond the upper bound of x1: held there


def _warm() -> HierarchicalQP:
    qp = HierarchicalQP(N)
    solve_stack(qp, StackProblem([(A, GOOD, GOOD)], LOWER, UPPER), KINEMATIC)
    return qp


@pytest.mark.parametrize("paths", [KINEMATIC, DYNAMIC], ids=["kinematic", "dynamic"])
@pytest.mark.parametrize(("coefficients", "target"), [
    (np.array([[np.nan, 0, 0, 0], [0, 1, 0, 0]]), GOOD),
    (np.array([[np.inf, 0, 0, 0], [0, 1, 0, 0]]), GOOD),
    (np.array([[1e200, 0, 0, 0], [0, 1, 0, 0]]), GOOD),
    (A, np.array([np.nan, 2.0])),
    (A, np.array([np.inf, 2.0])),
    (A, np.array([1e300, 2.0])),
])
def test_a_level_the_stages_refuse_is_refused_whatever_path_is_tried(paths, coefficients, target):
    with pytest.raises(InvalidInput):
        solve_stack(_warm(), StackProblem([(coefficients, target, target)], LOWER, UPPER, held=([], [0, 1])), paths)


@pytest.mark.parametrize("paths", [KINEMATIC, DYNAMIC], ids=["kinematic", "dynamic"])
@pytest.mark.parametrize(("lower", "upper"), [
    (np.array([-1.0, -1.0, -1.0, -1.0]), np.array([1.0, np.nan, 1.0, 1.0])),
    (np.array([np.nan, -1.0, -1.0, -1.0]), UPPER),
    (np.array([2.0, -1.0, -1.0, -1.0]), UPPER),
])
def test_nan_or_crossed_bounds_are_refused_whatever_path_is_tried(paths, lower, upper):
    with pytest.raises(InvalidInput, match="bound"):
        solve_stack(_warm(), StackProblem([(A, GOOD, GOOD)], lower, upper), paths)


def test_the_cascade_names_a_nan_coefficient_instead_of_failing():
    b = np.ones(1)
    free = np.full(N, np.inf)
    with pytest.raises(InvalidInput, match="level 0: level rows: NaN, infinite or beyond"):
        solve_stack(HierarchicalQP(N), StackProblem([(np.array([[np.nan, 0.0, 0.0, 0.0]]), b, b)], -free, free), BASIC)


@pytest.mark.parametrize(("call", "named"), [
    (lambda: LevelRows("abc", [0.0], [0.0]), "A must be numbers"),
    (lambda: LevelRows([[1.0, 2.0], [1.0]], [0.0, 0.0], [0.0, 0.0]), "A must be numbers"),
    (lambda: LevelRows(np.eye(1, N), ["a"], ["b"]), "lower must be numbers"),
    (lambda: LevelRows(np.eye(1, N) * (1 + 5j), [1.0], [1.0]), "real numbers"),
    (lambda: LevelRows(np.eye(1, N), [0.0], [0.0], extend=5), "extend must be a callable"),
    (lambda: HierarchicalQP(N).solve([], ["a"] * N, UPPER), "bounds must be numbers"),
    (lambda: solve_stack(HierarchicalQP(N), StackProblem([(np.eye(1, N), np.ones(1))], LOWER, UPPER), KINEMATIC), "triples"),
    (lambda: HierarchicalQP(N, level_solvers="osqp"), "give \\['osqp'\\]"),
])
def test_inputs_that_are_not_real_numbers_are_refused_by_name(call, named):
    with pytest.raises(InvalidInput, match=named):
        call()


def test_the_solver_answers_after_a_refusal():
    qp = _warm()
    with pytest.raises(InvalidInput):
        solve_stack(qp, StackProblem([(A, np.array([np.nan, 2.0]), np.array([np.nan, 2.0]))], LOWER, UPPER), DYNAMIC)
    result = solve_stack(qp, StackProblem([(A, GOOD, GOOD)], LOWER, UPPER), DYNAMIC)
    np.testing.assert_allclose(result.x, [1.0, 1.0, 0.0, 0.0], atol=1e-12)
