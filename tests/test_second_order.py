"""The tick-curvature correction (:mod:`sotdrake.solvers.second_order`) on a planar two-link arm,
whose hand position and Jacobian are known in closed form."""

from __future__ import annotations

import numpy as np
import pytest

from sotdrake.solvers.second_order import corrected_bounds, curvature_correction, keyed_curvature_correction
from tests.oracles import curvature_correction as python_curvature_correction

L1, L2 = 0.7, 0.5


def hand(q: np.ndarray) -> np.ndarray:
    return np.array([L1 * np.cos(q[0]) + L2 * np.cos(q[0] + q[1]), L1 * np.sin(q[0]) + L2 * np.sin(q[0] + q[1])])


def jacobian(q: np.ndarray) -> np.ndarray:
    s1, c1, s12, c12 = np.sin(q[0]), np.cos(q[0]), np.sin(q[0] + q[1]), np.cos(q[0] + q[1])
    return np.array([[-L1 * s1 - L2 * s12, -L2 * s12], [L1 * c1 + L2 * c12, L2 * c12]])


def one_tick_errors(dt: float, rng: np.random.Generator) -> tuple[float, float]:
    """The hand's motion over a tick against ``J_k v dt`` (first order) and ``(J_k v + c_k) dt``
    (corrected), ``v`` held over the last tick and this one, as the device holds it."""
    q_before = rng.uniform(-2.0, 2.0, 2)
    v = rng.uniform(-2.0, 2.0, 2)
    q = q_before + v * dt
    J = jacobian(q)
    moved = hand(q + v * dt) - hand(q)
    correction = curvature_correction(J, v, jacobian(q_before) @ v)
    assert correction is not None
    return float(np.linalg.norm(moved - J @ v * dt)), float(np.linalg.norm(moved - (J @ v + correction) * dt))


def test_the_correction_leaves_a_third_order_residual():
    rng = np.random.default_rng(3)
    for _ in range(20):
        state = rng.bit_generator.state
        first, corrected = one_tick_errors(1e-3, rng)
        rng.bit_generator.state = state
        first_half, corrected_half = one_tick_errors(5e-4, rng)
        assert corrected < 0.05 * first  # a sign error would double the residual instead
        assert 3.5 < first / first_half < 4.5  # second order without the correction
        assert corrected / corrected_half > 7.0  # third order with it


def test_the_correction_is_skipped_on_a_jump_a_resize_and_the_first_tick():
    rng = np.random.default_rng(4)
    q, v = rng.uniform(-2.0, 2.0, 2), rng.uniform(-2.0, 2.0, 2)
    J = jacobian(q)
    assert curvature_correction(J, None, None) is None  # the first tick
    assert curvature_correction(J, v, np.zeros(3)) is None  # the level changed size
    assert curvature_correction(J, v, -(J @ v)) is None  # the Jacobian jumped (a new frame)
    assert curvature_correction(J, np.zeros(2), np.zeros(2)) is not None  # at rest: zero, not skipped
    np.testing.assert_array_equal(curvature_correction(J, np.zeros(2), np.zeros(2)), np.zeros(2))


def test_rows_that_come_and_go_are_corrected_each_from_its_own_row_of_the_last_tick():
    """Keyed rows (the collision pairs in range): the hand's two coordinates as rows 7 and 3, the
    last tick had them in the other order with a row 5 that has left; a new row 9 and a row whose
    Jacobian jumped get no correction."""
    rng = np.random.default_rng(6)
    q_before, v = rng.uniform(-2.0, 2.0, 2), rng.uniform(-1.0, 1.0, 2)
    dt = 1e-3
    J_before, J = jacobian(q_before), jacobian(q_before + v * dt)
    expected = curvature_correction(J, v, J_before @ v)
    assert expected is not None and np.abs(expected).min() > 0
    y = np.array([(J_before @ v)[1], 123.0, (J_before @ v)[0]])
    previous = (y, np.array([3.0, 5.0, 7.0]))  # (as the solver keeps them: floats)
    rows = np.vstack([J[0], J[1], J[0] * 2.0])
    correction = keyed_curvature_correction(rows, np.array([7, 3, 9]), v, previous)
    np.testing.assert_allclose(correction, [expected[0], expected[1], 0.0], rtol=1e-12, atol=0)
    jumped = keyed_curvature_correction(np.vstack([-J[0], J[1]]), np.array([7, 3]), v, previous)
    np.testing.assert_allclose(jumped, [0.0, expected[1]], rtol=1e-12, atol=0)
    assert keyed_curvature_correction(rows, np.array([7, 3, 9]), None, previous) is None
    assert keyed_curvature_correction(rows, np.array([7, 3, 9]), v, None) is None
    np.testing.assert_array_equal(keyed_curvature_correction(np.zeros((0, 2)), np.zeros(0, dtype=int), v, previous), [])
    np.testing.assert_array_equal(keyed_curvature_correction(rows, np.array([7, 3, 9]), v, (np.zeros(0), np.zeros(0))),
                                  np.zeros(3))


def test_a_correction_shifts_an_equality_and_only_tightens_an_inequality():
    c = np.array([0.1, -0.2, 0.3, 0.4])
    reference = np.array([1.0, 2.0, 3.0, 4.0])
    lower, upper = corrected_bounds(reference, reference, c)
    assert lower is upper
    np.testing.assert_array_equal(lower, reference - c)
    lower, upper = corrected_bounds(np.array([0.0, 0.0, 1.0, -np.inf]), np.array([np.inf, 1.0, 1.0, 0.0]), c)
    np.testing.assert_array_equal(lower, [0.0, 0.2, 0.7, -np.inf])  # (row 2: an equality inside an inequality level)
    np.testing.assert_array_equal(upper, [np.inf, 1.0, 0.7, -0.4])
    assert (lower <= upper).all()


def test_the_compiled_correction_is_its_python_reference():
    """Random Jacobians of any layout (C, Fortran, strided, read-only), motions small and large
    around the skip threshold, a NaN: the same correction or the same skip."""
    rng = np.random.default_rng(5)
    for trial in range(2000):
        m, n = int(rng.integers(1, 7)), int(rng.integers(1, 45))
        J = rng.normal(size=(m, n)) * 10.0 ** rng.uniform(-3, 3)
        if trial % 4 == 1:
            J = np.asfortranarray(J)
        elif trial % 4 == 2:
            J = rng.normal(size=(m, 2 * n))[:, ::2]
        elif trial % 4 == 3:
            J.flags.writeable = False
        v = rng.normal(size=n)
        jump = 10.0 ** rng.uniform(-4, 1) * rng.normal(size=m) * np.linalg.norm(J) * np.linalg.norm(v)
        y = J @ v + jump
        if trial % 97 == 0:
            y[0] = np.nan
        compiled, reference = curvature_correction(J, v, y), python_curvature_correction(J, v, y)
        assert (compiled is None) == (reference is None)
        if reference is not None:
            np.testing.assert_allclose(compiled, reference, rtol=1e-12, atol=1e-12 * np.abs(J).max() * np.abs(v).max())
    with pytest.raises(ValueError, match="curvature correction"):
        curvature_correction(np.zeros((2, 3)), np.zeros(2), np.zeros(2))
