"""The solver wing as a library: arguments that cannot be solved are an :class:`InvalidInput` at
the call (never a raw Python or numba error, never a NaN answer), and the edge values the
documented ranges include (a threshold of 0, a gain of 0 on a one-sided bound, numpy scalars) work."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake import InvalidInput, MetaTaskKine6d, add_sot, gotoNd, load_robot, robot
from sotdrake.gains import GainAdaptive, GainHyperbolic
from sotdrake.hqp.cascade import cascade_factorization, solve_cascade
from sotdrake.hqp.solve import HierarchicalQP, LevelRows
from sotdrake.task import TaskInequality
from tests.test_own_robot import three_link


@pytest.mark.parametrize("threshold", [0.0, 1e-200])
def test_a_threshold_of_zero_is_no_truncation(threshold):
    rng = np.random.default_rng(3)
    A, B = rng.normal(size=(3, 5)), rng.normal(size=(2, 5))
    a, b = rng.normal(size=3), rng.normal(size=2)
    v = solve_cascade([(A, a), (B, b)], 5, svd_threshold=threshold).velocity
    reference = solve_cascade([(A, a), (B, b)], 5, svd_threshold=1e-12).velocity
    np.testing.assert_allclose(v, reference, atol=1e-10)
    np.testing.assert_allclose(A @ v, a, atol=1e-10)


def test_the_basic_sot_runs_with_a_threshold_of_zero(tmp_path):
    builder = DiagramBuilder()
    bot = robot(builder, load_robot(three_link(tmp_path / "arm.urdf")))
    sot = add_sot(bot)
    sot.setThreshold(0.0)
    hand = MetaTaskKine6d("hand", bot, "hand", "hand")
    gotoNd(hand, hand.current_pose().translation() + [0.0, 0.05, 0.0], "011", 5.0)
    sot.push(hand)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(0.05)
    q = bot.device.GetOutputPort("state").Eval(bot.device.GetMyContextFromRoot(simulator.get_context()))
    assert np.isfinite(q).all() and np.abs(q - bot.device.initial_position).max() > 0


@pytest.mark.parametrize("options", [
    {"svd_threshold": -1.0}, {"svd_threshold": float("nan")}, {"svd_threshold": "1e-4"}, {"damping": -1.0},
    {"damping": float("nan")}, {"damping": True}, {"damping": "x"}, {"control_selection": np.full(3, 2.0)},
])
def test_cascade_options_are_checked(options):
    with pytest.raises(InvalidInput):
        cascade_factorization([(np.eye(3), np.ones(3))], 3, **options)


def test_a_non_finite_level_is_named():
    with pytest.raises(InvalidInput, match=r"levels \[1\]"):
        solve_cascade([(np.eye(3), np.ones(3)), (np.eye(3), np.array([1.0, np.nan, 1.0]))], 3)
    assert solve_cascade([(np.eye(3), np.ones(3))], 3, damping=np.float32(0.1)).velocity == pytest.approx(np.full(3, 1 / 1.1))


@pytest.mark.parametrize("arguments", [
    {"n": -1}, {"n": 1.5}, {"n": "3"}, {"n": None}, {"n": True}, {"n": 2**40},
    {"n": 3, "rank_threshold": "x"}, {"n": 3, "rank_threshold": True}, {"n": 3, "hold_tolerance": -1.0},
    {"n": 3, "feasibility_tolerance": -1.0}, {"n": 3, "feasibility_tolerance": float("nan")}, {"n": 3, "regularize": "no"},
])
def test_hierarchical_qp_arguments(arguments):
    with pytest.raises(InvalidInput):
        HierarchicalQP(**arguments)


def test_hierarchical_qp_solve_arguments():
    hqp = HierarchicalQP(3)
    bounds = (np.full(3, -1.0), np.full(3, 1.0))
    for levels in (None, [np.eye(3)], [(np.eye(3), np.ones(3))], "levels"):
        with pytest.raises(InvalidInput, match="LevelRows"):
            hqp.solve(levels, *bounds)  # type: ignore[arg-type]
    level = LevelRows(np.eye(3), np.full(3, 0.5), np.full(3, 0.5))
    for damping in (True, "x", None, [0.1]):
        with pytest.raises(InvalidInput, match="damping"):
            hqp.solve([level], *bounds, damping=damping)  # type: ignore[arg-type]
    assert hqp.solve([level], *bounds).x == pytest.approx(np.full(3, 0.5))


def test_magnitudes_whose_squares_overflow_are_refused_and_those_below_are_solved():
    """Beyond ±1e150 the squared norms the solver forms overflow (a row of 1e160 was solved as 0).
    (An inequality row's violation is measured in its own units, to 1e-9: scaled far below unit
    norm, it is met to that absolute tolerance, hence its smaller scales not checked here.)"""
    A, b = np.array([[1.0, 2.0], [0.5, -1.0]]), np.array([0.3, 0.1])
    bounds = (np.full(2, -1.0), np.full(2, 1.0))
    band = HierarchicalQP(2).solve([LevelRows(A, b - 0.1, b + 0.1)], *bounds).x
    for scale in (1e-140, 1e-20, 1e60, 1e140):
        assert HierarchicalQP(2).solve([LevelRows(A * scale, b * scale, b * scale)], *bounds).x == pytest.approx([0.25, 0.025])
    for scale in (1e-4, 1e60, 1e140):
        level = LevelRows(A * scale, (b - 0.1) * scale, (b + 0.1) * scale)
        assert HierarchicalQP(2).solve([level], *bounds).x == pytest.approx(band)
    for rows in ((A * 1e160, b, b), (A, b * 1e160, b * 1e160), (A, b - 1e160, b + 1), (A, b - 1, b + 1e160)):
        with pytest.raises(InvalidInput, match="1e"):
            LevelRows(*rows)
    assert LevelRows(A, np.full(2, -np.inf), np.full(2, np.inf)).A_in.shape == (2, 2)
    hqp, level = HierarchicalQP(2), LevelRows(A, b, b)
    for lower, upper, start in ((np.array([-1e160, -1.0]), bounds[1], None), (bounds[0], np.array([1.0, 1e160]), None),
                                (*bounds, np.array([0.0, 1e160]))):
        with pytest.raises(InvalidInput, match="1e"):
            hqp.solve([level], lower, upper, start=start)
    assert hqp.solve([level], np.full(2, -np.inf), np.full(2, np.inf)).x == pytest.approx([0.25, 0.025])


def test_a_one_sided_bound_under_a_gain_of_zero_stays_free():
    task = TaskInequality("limits", 2)
    task.setBounds([-np.inf, -1.0], [0.5, np.inf])
    lower, upper = task._rows(task.CreateDefaultContext(), np.array([0.2, 0.3]), 0.0)
    assert lower.tolist() == [-np.inf, -0.0] and upper.tolist() == [0.0, np.inf]
    for lower_bound, upper_bound in (([np.inf], [np.inf]), ([-np.inf], [-np.inf])):
        with pytest.raises(InvalidInput, match="no error meets"):
            task.setBounds(lower_bound, upper_bound)


def test_gains_take_numpy_numbers():
    gain = GainAdaptive("g", 1e-3)
    gain.set(np.int64(4), np.int64(1), np.int64(5))
    gain.setByPoint(np.float32(4.0), np.float32(1.0), np.float32(0.1), np.float32(0.5))
    GainHyperbolic("h", 1e-3).set(np.float32(4.0), np.float32(1.0), np.float32(5.0), np.float32(0.0))
    with pytest.raises(InvalidInput):
        gain.set(True, 1.0, 5.0)
