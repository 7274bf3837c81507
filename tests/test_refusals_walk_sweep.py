"""Refusals of the walking planner's functions, the sweep helpers and the public numeric helpers:
a bad argument is an InvalidInput naming it, raised before anything is computed (a NaN time used
to end the process inside Drake), and a corrected retry works."""

from __future__ import annotations

import types

import numpy as np
import pytest
from pydrake.math import RigidTransform

import sotdrake.sweep.cases as cases_module
import sotdrake.walking.plan as plan_module
from sotdrake import friction_ratio, hold_move_hold, limit_joint_velocities, manipulability, tilt_of_quaternions
from sotdrake.dynamics.trajectories import minimum_jerk_moves
from sotdrake.exceptions import InvalidInput
from sotdrake.kinematics import Dynamic
from sotdrake.sweep import grid, random_cases, run_sweep
from sotdrake.sweep.cases import MAX_CASES
from sotdrake.walking import GaitParameters, PatternGenerator, Start, WalkCommand, initial_plan, polygon_margin, replan
from sotdrake.walking.com_planner import plan_com

START = Start({"left": RigidTransform([0.0, 0.1, 0.0]), "right": RigidTransform([0.0, -0.1, 0.0])},
              np.array([0.0, 0.0, 0.87]), RigidTransform([0.0, 0.0, 1.0]))
GAIT = GaitParameters()
NAN = float("nan")
SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])


@pytest.fixture(scope="module")
def standing():
    return initial_plan(START, GAIT)


@pytest.fixture
def no_planning(monkeypatch):
    """Planning reached is a failure (on the old code a NaN time went on into Drake and ended the process)."""

    def reached(*args, **kwargs):
        raise AssertionError("the planner was reached")

    monkeypatch.setattr(plan_module, "new_steps", reached)


# --- walking --------------------------------------------------------------------------------
@pytest.mark.parametrize("t", [NAN, float("inf"), 1e300, -1e300, "0", None, [0.0]])
def test_replan_refuses_a_bad_time_before_drake_is_reached(standing, no_planning, t):
    with pytest.raises(InvalidInput, match="replan: t"):
        replan(standing, WalkCommand(velocity=(0.1, 0.0, 0.0)), t, GAIT)


def test_replan_refuses_a_time_before_the_plan_and_a_corrected_retry_works(standing):
    walking = replan(standing, WalkCommand(velocity=(0.1, 0.0, 0.0)), 1.0, GAIT)
    with pytest.raises(InvalidInput, match="before the plan's time"):
        replan(walking, WalkCommand(), 0.5, GAIT)
    stopped = replan(walking, WalkCommand(), np.float64(1.5), GAIT)
    assert stopped.planned_at == 1.5 and walking.command == WalkCommand(velocity=(0.1, 0.0, 0.0))


@pytest.mark.parametrize(("arguments", "named"), [
    ({"command": None}, "command"),
    ({"command": (0.1, 0.0, 0.0)}, "command"),
    ({"plan": None}, "plan"),
    ({"gait": "fast"}, "gait"),
    ({"gait": None}, "gait"),
    ({"legs": "x"}, "legs"),
    ({"input_cost": -1.0}, "input_cost"),
    ({"input_cost": 1e300}, "input_cost"),
    ({"input_cost": NAN}, "input_cost"),
    ({"input_cost": "1e-6"}, "input_cost"),
])
def test_replan_refuses_arguments_of_the_wrong_kind(standing, no_planning, arguments, named):
    given = {"plan": standing, "command": WalkCommand(velocity=(0.1, 0.0, 0.0)), "t": 0.0, "gait": GAIT, **arguments}
    with pytest.raises(InvalidInput, match=named):
        replan(**given)


@pytest.mark.parametrize(("command", "named"), [
    ({"velocity": (NAN, 0.0, 0.0)}, "velocity"),
    ({"velocity": (10.0, 0.0, 0.0)}, r"x = 10\.0 m/s is out of range"),
    ({"velocity": (0.0, -0.21, 0.0)}, "y = "),
    ({"velocity": (0.0, 0.0, 1.0)}, "theta = "),
    ({"velocity": (0.1, 0.0)}, "velocity"),
    ({"velocity": "fast"}, "velocity"),
    ({"velocity": None}, "velocity"),
    ({"steps": ((NAN, 0.0, 0.0),)}, "steps"),
    ({"steps": ((0.1, 0.0),)}, "steps"),
    ({"steps": ((0.1, 0.0, 1.0),)}, "dθ"),
    ({"steps": ((0.1, 0.0, 0.0),) * 10_001}, "steps"),
    ({"velocity": (0.1, 0.0, 0.0), "steps": ((0.1, 0.0, 0.0),)}, "not both"),
])
def test_a_walk_command_out_of_the_pattern_generators_range_is_refused_when_made(command, named):
    with pytest.raises(InvalidInput, match=named):
        WalkCommand(**command)


def test_a_walk_command_takes_lists_and_numpy_numbers_as_plain_tuples():
    command = WalkCommand(velocity=[np.float64(0.1), 0, np.int64(0)])
    assert command == WalkCommand(velocity=(0.1, 0.0, 0.0)) and type(command.velocity[1]) is float
    assert hash(command) == hash(WalkCommand(velocity=(0.1, 0.0, 0.0)))
    assert WalkCommand(steps=np.array([[0.2, 0.0, 0.0]])).steps == ((0.2, 0.0, 0.0),)
    assert WalkCommand(steps=[]) == WalkCommand()


def test_replan_refuses_steps_longer_than_the_gait_allows_and_a_retry_works(standing):
    with pytest.raises(InvalidInput, match=r"command\.steps: accepted \|dx\|, \|dy\| ≤ 0\.32 m"):
        replan(standing, WalkCommand(steps=((1e6, 0.0, 0.0),)), 0.0, GAIT)
    plan = replan(standing, WalkCommand(steps=((0.2, 0.0, 0.0),)), 0.0, GAIT)
    assert plan.steps[0].x == pytest.approx(0.2)


@pytest.mark.parametrize(("arguments", "named"), [
    ({"start": None}, "start"),
    ({"start": {"left": RigidTransform()}}, "start"),
    ({"gait": "fast"}, "gait"),
    ({"input_cost": -1}, "input_cost"),
    ({"input_cost": 0.0}, "input_cost"),
    ({"input_cost": 1e300}, "input_cost"),
    ({"legs": 3}, "legs"),
])
def test_initial_plan_refuses_bad_arguments(arguments, named):
    with pytest.raises(InvalidInput, match=named):
        initial_plan(**{"start": START, "gait": GAIT, **arguments})


def test_the_com_planner_names_input_cost_when_drake_finds_no_plan(standing):
    with pytest.raises(InvalidInput, match="input_cost"):
        plan_com(standing.zmp, np.zeros(2), np.zeros(2), 1000.0, 1e-12)


@pytest.mark.parametrize(("arguments", "named"), [
    ({"gait": "fast"}, "gait"),
    ({"legs": "x"}, "legs"),
    ({"input_cost": 1e300}, "input_cost"),
    ({"input_cost": 1e-300}, "input_cost"),
])
def test_the_pattern_generator_refuses_a_bad_gait_model_or_cost_and_a_retry_works(arguments, named):
    with pytest.raises(InvalidInput, match=named):
        PatternGenerator(START, 0.01, **arguments)
    pg = PatternGenerator(START, 0.01, gait=GAIT, input_cost=np.float64(1e-6))
    assert pg.input_cost == 1e-6 and pg.gait is GAIT


# --- sweeps ---------------------------------------------------------------------------------
def test_run_sweep_takes_a_numpy_integer_for_num_cpus():
    result = run_sweep(lambda case: {"y": case["a"]}, grid({"a": [1]}), num_cpus=np.int64(1), progress=False)
    assert result.rows[0]["y"] == 1
    for bad in (0, True, 1.5, "2"):
        with pytest.raises(InvalidInput, match="num_cpus"):
            run_sweep(lambda case: {}, grid({"a": [1]}), num_cpus=bad, progress=False)


@pytest.mark.parametrize("count", [2**63, 10**12, MAX_CASES + 1])
def test_random_cases_bounds_the_count(count):
    with pytest.raises(InvalidInput, match="count"):
        random_cases(count, {"a": (0.0, 1.0)}, 0)
    assert len(random_cases(np.int64(3), {"a": (0.0, 1.0)}, 0)) == 3


@pytest.mark.parametrize("axes", [{"a": range(10**6), "b": range(10**6)}, {"a": range(1001), "b": range(1000)}])
def test_grid_bounds_the_number_of_cases_before_building_them(monkeypatch, axes):
    def built(*args):
        raise AssertionError("the cases were built")  # (10¹² of them used to exhaust the memory)

    monkeypatch.setattr(cases_module, "itertools", types.SimpleNamespace(product=built))
    with pytest.raises(InvalidInput, match=f"at most {MAX_CASES}"):
        grid(axes)


@pytest.mark.parametrize("value", [None, {}, object(), [1, 2], np.zeros(2), 1j, b"x"])
def test_grid_refuses_values_that_are_not_plain(value):
    with pytest.raises(InvalidInput, match="axis 'a'"):
        grid({"a": [1.0, value]})
    assert grid({"a": [1.0, np.float32(2.5), "x", True]}) == [{"a": 1.0}, {"a": 2.5}, {"a": "x"}, {"a": True}]


# --- numeric helpers ------------------------------------------------------------------------
@pytest.mark.parametrize(("point", "polygon", "named"), [
    ([NAN, 0.0], SQUARE, "point"),
    ([0.0], SQUARE, "point"),
    ([0.0, 0.0], np.zeros((0, 2)), "polygon"),
    ([0.0, 0.0], SQUARE[:2], "polygon"),
    ([0.0, 0.0], SQUARE[::-1], "counter-clockwise"),
    ([0.0, 0.0], np.vstack([SQUARE, SQUARE[:1]]), "each vertex given once"),
    ([0.0, 0.0], [[0.0, 0.0], [1.0, 0.0], [0.2, 0.2], [0.0, 1.0]], "convex"),
    ([0.0, 0.0], [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]], "polygon"),
    ([0.0, 0.0], np.where(SQUARE == 1.0, np.inf, SQUARE), "polygon"),
])
def test_polygon_margin_refuses_a_bad_point_or_polygon(point, polygon, named):
    with pytest.raises(InvalidInput, match=named):
        polygon_margin(point, polygon)
    assert polygon_margin([0.5, 0.25], SQUARE.tolist()) == pytest.approx(0.25)


@pytest.mark.parametrize(("force", "normal", "mu", "named"), [
    ([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], 0, "mu"),
    ([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], -1, "mu"),
    ([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], NAN, "mu"),
    ([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], "0.7", "mu"),
    ([NAN, 0.0, 1.0], [0.0, 0.0, 1.0], 0.7, "force_world"),
    ([0.0, 0.0, 1.0], [0.0, 0.0, 2.0], 0.7, "normal"),
    ([0.0, 0.0, 1.0], [0.0, 0.0, 0.0], 0.7, "normal"),
    ([0.0, 1.0], [0.0, 0.0, 1.0], 0.7, "force_world"),
])
def test_friction_ratio_refuses_a_bad_force_normal_or_coefficient(force, normal, mu, named):
    with pytest.raises(InvalidInput, match=named):
        friction_ratio(force, normal, mu)
    assert friction_ratio([0.5, 0.0, 1.0], [0.0, 0.0, 1.0], np.float64(0.5)) == pytest.approx(1.0)


def test_tilt_of_quaternions_refuses_a_zero_quaternion_and_marks_a_diverged_row():
    with pytest.raises(InvalidInput, match="row 0 has norm 0"):
        tilt_of_quaternions(np.zeros((2, 4)))
    with pytest.raises(InvalidInput, match="row 1"):
        tilt_of_quaternions([[1.0, 0.0, 0.0, 0.0], [1e-9, 0.0, 0.0, 0.0]])
    tilts = tilt_of_quaternions([[2.0, 0.0, 0.0, 0.0], [NAN, 0.0, 0.0, 0.0], [np.inf, 0.0, 0.0, 0.0]])
    assert tilts[0] == 0.0 and np.isnan(tilts[1:]).all()  # (fall_report reads NaN as a non-finite fall)


def test_manipulability_takes_lists_and_refuses_non_finite_jacobians():
    assert manipulability([[1.0, 0, 0], [0, 1.0, 0]]) == 1.0
    for J in (np.full((3, 6), np.nan), [[1.0, np.inf, 0.0]], [["a", 0.0]]):
        with pytest.raises(InvalidInput, match="manipulability: J"):
            manipulability(J)


@pytest.mark.parametrize(("arguments", "named"), [
    ({"q": np.full(3, np.nan)}, "q"),
    ({"q": np.zeros((3, 1))}, "q"),
    ({"v": np.ones(2)}, "v"),
    ({"v": [np.inf, 0.0, 0.0]}, "v"),
    ({"lower": np.ones(3), "upper": -np.ones(3)}, "lower must be ≤ upper"),
    ({"lower": [np.nan, -1.0, -1.0]}, "lower"),
    ({"lower": np.full(3, np.inf)}, "lower"),
    ({"upper": np.ones(2)}, "upper"),
    ({"step": 0}, "step"),
    ({"step": NAN}, "step"),
    ({"step": 1e3}, "step"),
])
def test_limit_joint_velocities_refuses_bad_positions_limits_or_step(arguments, named):
    given = {"q": np.zeros(3), "v": np.ones(3), "lower": -np.ones(3), "upper": np.ones(3), "step": 1e-3, **arguments}
    with pytest.raises(InvalidInput, match=named):
        limit_joint_velocities(**given)
    assert limit_joint_velocities([0.0, 0.999], [1.0, 1.0], [-1, -1], [1, np.inf], np.float64(0.01)).tolist() == [1.0, 1.0]


@pytest.mark.parametrize(("call", "named"), [
    (lambda: hold_move_hold(0, 1, [], []), "start"),
    (lambda: hold_move_hold(0, 1, [[0.0]], [[1.0]]), "start"),
    (lambda: minimum_jerk_moves([0.0], [(0.0, 1.0)]), "move"),
    (lambda: minimum_jerk_moves([0.0], 3), "moves"),
    (lambda: minimum_jerk_moves([0.0], [(0.0, 1.0, [1.0])], end=NAN), "end"),
])
def test_minimum_jerk_moves_refuse_an_empty_vector_or_a_malformed_move(call, named):
    with pytest.raises(InvalidInput, match=named):
        call()
    assert hold_move_hold(0, 1, [0.0], [1.0]).value(2.0)[0, 0] == pytest.approx(1.0)


@pytest.fixture(scope="module")
def talos_dynamic(talos_model):
    return Dynamic(talos_model)


def test_pose_at_refuses_a_zero_base_quaternion(talos_dynamic, talos_model):
    q = talos_model.half_sitting.copy()
    q[:4] = 0.0
    with pytest.raises(InvalidInput, match=r"q: the floating base's quaternion q\[0:4\]"):
        talos_dynamic.pose_at("leg_left_6_link", q)
    with pytest.raises(InvalidInput, match="quaternion"):
        talos_dynamic.com_at(q)
    q[0] = 2.0  # (not unit: Drake normalises it)
    expected = talos_dynamic.pose_at("leg_left_6_link", talos_model.half_sitting).translation()
    np.testing.assert_allclose(talos_dynamic.pose_at("leg_left_6_link", q).translation(), expected, atol=1e-12)
