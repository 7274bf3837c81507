"""The hierarchical QP's public entry points refuse what is not their input by name, with
`InvalidInput`, before anything is solved or changed, and take numpy scalars and plain (nested)
lists where they document ints, bools and arrays: the answer is then the one of the arrays."""

from __future__ import annotations

import numpy as np
import pytest

from sotdrake.exceptions import InvalidInput
from sotdrake.hqp import KINEMATIC, HierarchicalQP, LevelRows, StackProblem, WarmStart, check_solver, solve_cascade, solve_stack

N = 3
LOWER, UPPER = -np.ones(N), np.ones(N)
ROW = np.eye(N)[:1]
HALF = np.array([0.5])


# --- solver names ---------------------------------------------------------------------------

@pytest.mark.parametrize("name", [["osqp"], ("osqp",), {"osqp": 1}, None, 5, np.array(["osqp"])])
def test_a_solver_name_that_is_not_a_string_is_refused_by_name(name):
    with pytest.raises(InvalidInput, match="solver: unknown QP solver"):
        check_solver(name)
    with pytest.raises(InvalidInput, match="solver: unknown QP solver"):
        HierarchicalQP(N, solver=name)
    if name is not None:  # (None: the solver's default)
        with pytest.raises(InvalidInput, match="solver: unknown QP solver"):
            HierarchicalQP(N).solve([LevelRows(ROW, HALF, HALF)], LOWER, UPPER, solver=name)


@pytest.mark.parametrize("level_solvers", [5, 1.5, object(), [["osqp"]], ["osqp", 5]])
def test_level_solvers_that_are_not_a_list_of_names_are_refused_by_name(level_solvers):
    with pytest.raises(InvalidInput, match="level_solvers"):
        HierarchicalQP(N, level_solvers=level_solvers)
    assert HierarchicalQP(N, level_solvers=np.array(["osqp", "active-set"])).level_solvers == ["osqp", "active-set"]


def test_the_dynamic_solver_refuses_a_list_of_solver_names(talos_model):
    from sotdrake.dynamics.solver_dyn import SolverDyn

    solver = SolverDyn("s", talos_model, 1e-3)
    with pytest.raises(InvalidInput, match="solver: unknown QP solver"):
        solver.setSolver(["osqp"])
    solver.setSolver("osqp")


# --- HierarchicalQP and its solve -----------------------------------------------------------

def test_regularize_takes_numpy_bools_and_refuses_other_values():
    levels = [LevelRows(ROW, HALF, HALF)]
    for flag in (True, False):
        numpy_flag = HierarchicalQP(N, regularize=np.bool_(flag))
        assert numpy_flag.regularize is flag
        expected = HierarchicalQP(N, regularize=flag).solve(levels, LOWER, UPPER, start=np.full(N, 0.25)).x
        np.testing.assert_array_equal(numpy_flag.solve(levels, LOWER, UPPER, start=np.full(N, 0.25)).x, expected)
    for bad in (1, "yes", None, np.array([True])):
        with pytest.raises(InvalidInput, match="regularize"):
            HierarchicalQP(N, regularize=bad)


@pytest.mark.parametrize(("start", "named"), [
    ("abc", "start must be numbers"),
    ({}, "start must be numbers"),
    (np.ones(N) * 1j, "start must be real numbers"),
    ([1.0, 2.0, 3.0j], "start must be real numbers"),
    ([[0.0, 0.0], [0.0]], "start must be numbers"),
])
def test_a_start_that_is_not_real_numbers_is_refused_by_name_and_changes_nothing(start, named):
    qp = HierarchicalQP(N)
    own = qp.warm
    with pytest.raises(InvalidInput, match=named):
        qp.solve([LevelRows(ROW, HALF, HALF)], LOWER, UPPER, start=start, warm=WarmStart(N))
    assert qp.warm is own


def test_solve_equalities_takes_lists_as_its_arrays():
    qp = HierarchicalQP(N)
    from_arrays = qp.solve_equalities([ROW, np.eye(N)[1:]], [HALF, np.array([0.25, 0.0])], LOWER, UPPER)
    from_lists = HierarchicalQP(N).solve_equalities([ROW.tolist(), np.eye(N)[1:].tolist()], [[0.5], [0.25, 0]],
                                                    LOWER.tolist(), UPPER.tolist())
    assert from_arrays is not None and from_lists is not None
    np.testing.assert_array_equal(from_lists.x, from_arrays.x)
    np.testing.assert_allclose(from_lists.x, [0.5, 0.25, 0.0], atol=1e-15)


@pytest.mark.parametrize(("call", "named"), [
    (lambda qp: qp.solve_equalities([ROW], [HALF], "a", "b"), "x_lower must be numbers"),
    (lambda qp: qp.solve_equalities([ROW], [HALF], LOWER, UPPER * 1j), "x_upper must be real numbers"),
    (lambda qp: qp.solve_equalities([[["a", 0, 0]]], [HALF], LOWER, UPPER), r"jacobians\[0\] must be numbers"),
    (lambda qp: qp.solve_equalities([ROW], [[0.5j]], LOWER, UPPER), r"values\[0\] must be real numbers"),
    (lambda qp: qp.solve_equalities(None, [HALF], LOWER, UPPER), "jacobians: a list of arrays"),
    (lambda qp: qp.solve_equalities([ROW], 5, LOWER, UPPER), "values: a list of arrays"),
    (lambda qp: qp.solve_equalities([ROW], [HALF], LOWER, UPPER, damping="abc"), "damping"),
])
def test_solve_equalities_refuses_what_is_not_real_numbers_by_name(call, named):
    with pytest.raises(InvalidInput, match=named):
        call(HierarchicalQP(N))


# --- the cascade ----------------------------------------------------------------------------

def test_the_cascade_takes_lists_and_numpy_integers():
    expected = solve_cascade([(np.array([[1.0, 0.0, 0.0]]), np.array([0.5]))], 3, control_selection=np.ones(3, dtype=bool))
    result = solve_cascade([([[1, 0, 0]], [0.5])], np.int64(3), control_selection=[True, True, True])
    np.testing.assert_array_equal(result.velocity, expected.velocity)
    np.testing.assert_array_equal(result.residuals, expected.residuals)
    np.testing.assert_array_equal(result.ranks, expected.ranks)


@pytest.mark.parametrize("nv", ["3", -1, 2**40, 2.0, True, None, [3]])
def test_the_cascade_refuses_a_bad_number_of_velocities_by_name(nv):
    with pytest.raises(InvalidInput, match="nv"):
        solve_cascade([(ROW, HALF)], nv)
    with pytest.raises(InvalidInput, match="nv"):
        solve_cascade([], nv)


@pytest.mark.parametrize("selection", ["abc", ["a", "b", "c"], [1j, 0, 1], [[1, 0], [1]]])
def test_the_cascade_refuses_a_control_selection_that_is_not_booleans(selection):
    with pytest.raises(InvalidInput, match="control_selection"):
        solve_cascade([(ROW, HALF)], N, control_selection=selection)


@pytest.mark.parametrize(("levels", "named"), [
    ([(ROW + 1j, HALF)], r"levels\[0\]: J must be real numbers"),
    ([(ROW, HALF * 1j)], r"levels\[0\]: ė\* must be real numbers"),
    ([(ROW, HALF), (ROW[0], HALF)], r"levels\[1\]: J must be a matrix"),
    ([(ROW, HALF, HALF)], r"levels\[0\]: a \(J, ė\*\) pair"),
    ([ROW], r"levels\[0\]: a \(J, ė\*\) pair"),
    ([("abc", HALF)], r"levels\[0\]: J must be numbers"),
])
def test_the_cascade_refuses_levels_that_are_not_pairs_of_real_arrays_by_name(levels, named):
    with pytest.raises(InvalidInput, match=named):
        solve_cascade(levels, N)


# --- whole stacks ---------------------------------------------------------------------------

@pytest.mark.parametrize(("make", "named"), [
    (lambda: StackProblem(None, LOWER, UPPER), "levels: a sequence"),
    (lambda: StackProblem(5, LOWER, UPPER), "levels: a sequence"),
    (lambda: StackProblem([(ROW, HALF, HALF)], None, None), "x_lower: expected a vector"),
    (lambda: StackProblem([(ROW, HALF, HALF)], LOWER, 1.0), "x_upper: expected a vector"),
    (lambda: StackProblem([(ROW, HALF, HALF)], LOWER, ["a"] * N), "x_upper must be numbers"),
    (lambda: StackProblem([(ROW, HALF, HALF)], LOWER, UPPER, start="abc"), "start must be numbers"),
    (lambda: StackProblem([(ROW, [0.5j], [0.5j])], LOWER, UPPER), "level 0: lower must be real numbers"),
    (lambda: StackProblem((level for level in [(ROW, HALF, HALF)]), LOWER, UPPER), "levels: a sequence"),
])
def test_a_stack_problem_that_is_not_arrays_is_refused_when_it_is_made(make, named):
    with pytest.raises(InvalidInput, match=named):
        make()


def test_a_stack_of_lists_is_solved_as_the_stack_of_arrays():
    second = np.array([0.25, 0.0])
    arrays = StackProblem([(ROW, HALF, HALF), (np.eye(N)[1:], second, second)], LOWER, UPPER)
    first, second_list = [0.5], [0.25, 0]
    lists = StackProblem([([[1, 0, 0]], first, first), (np.eye(N)[1:].tolist(), second_list, second_list)],
                         LOWER.tolist(), UPPER.tolist(), start=[0, 0, 0])
    assert all(lower is upper for _, lower, upper in lists.levels)  # (still equality levels)
    expected, result = solve_stack(HierarchicalQP(N), arrays, KINEMATIC), solve_stack(HierarchicalQP(N), lists, KINEMATIC)
    np.testing.assert_array_equal(result.x, expected.x)


# --- TaskPD's kept rows ---------------------------------------------------------------------

@pytest.mark.parametrize("max_rows", [2.7, "3", [3], 2**40, True, np.float64(3.0)])
def test_task_pd_refuses_a_max_rows_that_is_not_a_count_by_name(max_rows):
    from sotdrake.task import TaskPD

    with pytest.raises(InvalidInput, match="max_rows"):
        TaskPD("pd", N, 1e-3, max_rows)
    kept = TaskPD("pd", N, 1e-3, np.int64(2)).max_rows
    assert kept == 2 and type(kept) is int
