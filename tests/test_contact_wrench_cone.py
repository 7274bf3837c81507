"""A sole contact's wrench rows are exactly its contact wrench cone: the wrenches (about the sole
frame's origin) that four forces at the rectangle's corners, each in the friction pyramid
``|f_x|, |f_y| ≤ μ/√2 · f_z``, produce. Checked both ways against an independent linear program
over the corner forces, on rectangles off the frame's origin and with a CoP margin."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import linprog

from sotdrake.dynamics.contact import wrench_constraints

CASES = [(0.3, (-0.1, 0.1, -0.05, 0.05), 0.0), (0.8, (-0.08, 0.12, -0.06, 0.07), 0.01), (0.5, (0.02, 0.2, -0.03, 0.09), 0.005)]


def _corners(rectangle, margin):
    x_min, x_max, y_min, y_max = rectangle
    return [np.array([x, y, 0.0]) for x in (x_min + margin, x_max - margin) for y in (y_min + margin, y_max - margin)]


def _wrench(corners, forces) -> np.ndarray:
    """``(n, f)`` about the origin of forces applied at ``corners``."""
    return np.concatenate([sum(np.cross(p, f) for p, f in zip(corners, forces, strict=True)), forces.sum(axis=0)])


def _generated(corners, k: float, w: np.ndarray) -> bool:
    """Whether corner forces in the pyramids of slope ``k`` produce ``w`` (a feasibility LP)."""
    A_eq = np.zeros((6, 12))
    for i, p in enumerate(corners):
        for j, e in enumerate(np.eye(3)):
            A_eq[:3, 3 * i + j], A_eq[3:, 3 * i + j] = np.cross(p, e), e
    A_ub = []
    for i in range(4):
        for j in (0, 1):
            for sign in (1.0, -1.0):
                row = np.zeros(12)
                row[3 * i + j], row[3 * i + 2] = sign, -k
                A_ub.append(row)
    result = linprog(np.zeros(12), A_ub=np.array(A_ub), b_ub=np.zeros(len(A_ub)), A_eq=A_eq, b_eq=w, bounds=(None, None))
    assert result.status in (0, 2), result.message
    return result.status == 0


@pytest.mark.parametrize(("mu", "rectangle", "margin"), CASES)
def test_corner_forces_meet_the_rows(mu, rectangle, margin):
    A, corners, k = wrench_constraints(mu, rectangle, margin), _corners(rectangle, margin), mu / math.sqrt(2)
    rng = np.random.default_rng(1)
    for _ in range(1000):
        fz = rng.uniform(0.0, 200.0, 4) * (rng.random(4) < 0.8)  # some corners unloaded
        shear = rng.uniform(-1.0, 1.0, (4, 2))
        if rng.random() < 0.5:
            shear = np.sign(shear)  # on the pyramids' edges
        w = _wrench(corners, np.column_stack([shear * k * fz[:, None], fz]))
        assert (A @ w).max() <= 1e-12 * max(1.0, fz.sum())


@pytest.mark.parametrize(("mu", "rectangle", "margin"), CASES)
def test_the_rows_hold_only_what_corner_forces_make(mu, rectangle, margin):
    """Wrenches inside the rows are generated; wrenches just outside are not (so the yaw torque
    allowed shrinks as the CoP nears an edge and as the shear grows)."""
    A, corners, k = wrench_constraints(mu, rectangle, margin), _corners(rectangle, margin), mu / math.sqrt(2)
    rng = np.random.default_rng(2)
    inside = outside = 0
    while inside < 100 or outside < 100:
        w = rng.normal(size=6) * np.array([4.0, 4.0, 4.0, 20.0, 20.0, 0.0]) + np.array([0, 0, 0, 0, 0, 100.0])
        worst = (A @ w).max()
        if worst <= 0 and inside < 100:
            inside += 1
            assert _generated(corners, k, w)
        elif 1e-6 < worst < 0.5 and outside < 100:
            outside += 1
            assert not _generated(corners, k, w)


def test_yaw_torque_shrinks_towards_an_edge():
    """At the centre without shear the sole resists ``k(X+Y) f_z`` of yaw torque; with the CoP on an
    edge, ``k·Y f_z`` (the edge's own half-length): what a sole pivoting on its toe can hold."""
    x_min, x_max, y_min, y_max = rectangle = (-0.1, 0.1, -0.05, 0.05)
    mu, fz = 0.4, 100.0
    A, k = wrench_constraints(mu, rectangle, 0.0), mu / math.sqrt(2)

    def largest_yaw(cop_x: float) -> float:
        w = np.array([0.0, -cop_x * fz, 0.0, 0.0, 0.0, fz])  # n_y = −x·f_z puts the CoP at x
        rows = A[:, 2] > 0
        return float(np.min(-(A[rows] @ w) / A[rows, 2]))

    assert largest_yaw(0.0) == pytest.approx(k * (0.1 + 0.05) * fz)
    assert largest_yaw(x_max) == pytest.approx(k * 0.05 * fz)
