"""A row the levels above already fix is constant: its round-off must not steer the level.

Level 1 repeats level 0's row (twice, with another target: the two conflict) beside rows that, with
level 0, fix ``x`` exactly, one of them of norm 1e-8. In exact arithmetic the repeated row projects
to zero and its residual is constant; in doubles it projects to round-off, and a least-squares step
weighted back by the rows' norms followed that round-off along the small row's direction (``x`` of
1e12 to 1e14, level 0 no longer met). The answer is the square system's solution, by every path."""

import numpy as np
import pytest

from sotdrake.hqp.equality_hierarchy import solve_equality_hierarchy
from sotdrake.hqp.solve import HierarchicalQP, LevelRows


def _stack(n: int, big: float, small: float, seed: int):
    rng = np.random.default_rng(seed)
    a = rng.standard_normal(n) * big
    B, t = rng.standard_normal((n - 2, n)) * big, rng.standard_normal(n - 2) * big
    tiny = rng.standard_normal(n) * small
    A1 = np.vstack([B, tiny, 2 * a])
    b1 = np.concatenate([t, [0.3 * small], [5.0 * big]])  # 2a·x = 5 big against a·x = 0.7 big
    square = np.vstack([a, B, tiny])  # level 0 and the level's other rows: x is fixed
    expected = np.linalg.solve(square / np.linalg.norm(square, axis=1)[:, None],
                               np.concatenate([[0.7 * big], t, [0.3 * small]]) / np.linalg.norm(square, axis=1))
    return [(a[None, :], np.array([0.7 * big])), (A1, b1)], expected


@pytest.mark.parametrize("n", [3, 4, 6])
@pytest.mark.parametrize("big, small", [(1.0, 1e-8), (1e6, 1e-8), (1.0, 1e-4), (1e3, 1.0)])
def test_a_row_the_levels_above_fix_does_not_steer_the_level(n, big, small):
    levels, expected = _stack(n, big, small, seed=n)
    inf = np.full(n, np.inf)
    answers = {
        "HierarchicalQP": HierarchicalQP(n).solve([LevelRows(A, b, b) for A, b in levels], -inf, inf).x,
        "QR sweep": solve_equality_hierarchy(levels, -inf, inf).x,
        "QR sweep, bounded": solve_equality_hierarchy(levels, np.full(n, -1e3), np.full(n, 1e3)).x,
    }
    for path, x in answers.items():
        np.testing.assert_allclose(x, expected, rtol=1e-6, atol=1e-9, err_msg=path)
        assert abs(levels[0][0] @ x - levels[0][1])[0] <= 1e-9 * big * np.linalg.norm(x), path


@pytest.mark.parametrize("n", [4, 6])
@pytest.mark.parametrize("big", [1.0, 1e6])
def test_under_binding_bounds_the_fixed_row_changes_nothing(n, big):
    """With bounds that bind (the level is solved by its stage, not its least-squares step), the
    answer is the one of the same stack without the repeated row: that row is constant."""
    levels, expected = _stack(n, big, 1e-8, seed=10 + n)
    bound = 0.5 * np.abs(expected).max()  # the square system's solution is cut off
    x_lower, x_upper = np.full(n, -bound), np.full(n, bound)
    with_row = HierarchicalQP(n).solve([LevelRows(A, b, b) for A, b in levels], x_lower, x_upper).x
    (A0, b0), (A1, b1) = levels
    without = HierarchicalQP(n).solve([LevelRows(A0, b0, b0), LevelRows(A1[:-1], b1[:-1], b1[:-1])], x_lower, x_upper).x
    np.testing.assert_allclose(with_row, without, rtol=1e-6, atol=1e-9 * max(1.0, bound))
    assert np.all(with_row >= x_lower) and np.all(with_row <= x_upper)
