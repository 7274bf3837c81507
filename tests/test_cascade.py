"""The cascade against an independent lexicographic reference on random stacks."""

import numpy as np
import pytest

from sotdrake.solvers import solve_cascade


def random_stack(rng, nv):
    levels = []
    for _ in range(rng.integers(1, 6)):
        m = int(rng.integers(1, 8))
        rank = int(rng.integers(1, min(m, nv) + 1))
        J = rng.normal(size=(m, rank)) @ rng.normal(size=(rank, nv))  # rank-deficient rows
        if rng.random() < 0.3 and levels:  # a level in conflict with a higher one
            J[0] = levels[0][0][0]
        levels.append((J, rng.normal(size=m)))
    return levels


def lexicographic_reference(levels, nv):
    """Each level: min ‖J_i v - r_i‖ s.t. every higher level keeps its optimal value (KKT,
    least-squares); last, the minimum-norm v. Shares no code with the cascade."""
    A_fix, b_fix = np.zeros((0, nv)), np.zeros(0)
    v = np.zeros(nv)
    for J, r in [*levels, (np.eye(nv), np.zeros(nv))]:
        m = len(A_fix)
        K = np.block([[J.T @ J, A_fix.T], [A_fix, np.zeros((m, m))]])
        sol = np.linalg.lstsq(K, np.concatenate([J.T @ r, b_fix]), rcond=1e-10)[0]
        v = sol[:nv]
        A_fix, b_fix = np.vstack([A_fix, J]), np.concatenate([b_fix, J @ v])
    return v


@pytest.mark.parametrize("seed", range(200))
def test_cascade_equals_lexicographic_optimum(seed):
    rng = np.random.default_rng(seed)
    nv = int(rng.integers(3, 15))
    levels = random_stack(rng, nv)
    result = solve_cascade(levels, nv, svd_threshold=1e-8)
    reference = lexicographic_reference(levels, nv)
    np.testing.assert_allclose(result.velocity, reference, atol=1e-7)
    for i in range(len(levels)):  # strictness: adding lower levels never changes level i
        alone = solve_cascade(levels[: i + 1], nv, svd_threshold=1e-8)
        assert result.residuals[i] == pytest.approx(alone.residuals[i], abs=1e-8)


@pytest.mark.parametrize("seed", range(20))
def test_damping_keeps_priorities_and_bounds_velocity(seed):
    rng = np.random.default_rng(seed)
    nv = 8
    levels = random_stack(rng, nv)
    damped = solve_cascade(levels, nv, damping=1e-2)
    plain = solve_cascade(levels, nv)
    assert np.linalg.norm(damped.velocity) <= np.linalg.norm(plain.velocity) + 1e-12
    for i in range(len(levels)):
        alone = solve_cascade(levels[: i + 1], nv, damping=1e-2)
        assert damped.residuals[i] == pytest.approx(alone.residuals[i], abs=1e-9)


def test_control_selection_leaves_unselected_velocities_at_zero(rng):
    nv = 6
    levels = [(rng.normal(size=(2, nv)), rng.normal(size=2))]
    selection = np.array([True, False, True, True, False, True])
    result = solve_cascade(levels, nv, control_selection=selection)
    assert np.all(result.velocity[~selection] == 0)
    assert result.residuals[0] < 1e-10  # 4 free velocities still solve 2 rows


def test_singular_level_is_truncated_not_amplified():
    J = np.array([[1.0, 0.0], [0.0, 1e-6]])
    result = solve_cascade([(J, np.array([1.0, 1.0]))], 2, svd_threshold=1e-4)
    np.testing.assert_allclose(result.velocity, [1.0, 0.0])
    assert result.ranks[0] == 1
