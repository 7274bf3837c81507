"""The walking helpers check their inputs: a bad one is a ``SotError`` naming the argument, raised
when the call is made, with nothing changed; none reaches Drake, which aborts the process on some
(a CoM height of 0 in ``ZmpPlanner``, a wrong-sized ``q``), nor leaves a NaN plan behind (a ZMP
reference segment too long for ``ZmpPlanner``'s exponentials)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.trajectories import PiecewisePolynomial

from sotdrake import attime
from sotdrake.exceptions import FrameNotFound, InvalidInput, SotError
from sotdrake.walking import (
    ComStabilizer,
    GaitParameters,
    GravityFeedforward,
    MeasuredCom,
    PatternGenerator,
    Start,
    WalkCommand,
    footprint,
    initial_plan,
    leg_masses,
    motion_zmp,
    plan_com,
    plan_steps,
    replan,
    sole_centre,
    support_polygon,
    zmp_from_momentum,
)
from sotdrake.walking.com_planner import GRAVITY
from sotdrake.walking.plan import MAX_TIME

FEET = {"left": RigidTransform([0.0, 0.085, 0.0]), "right": RigidTransform([0.0, -0.085, 0.0])}
WAIST = RigidTransform([0.0, 0.0, 1.0])


def start(height: float = 0.87) -> Start:
    return Start(FEET, np.array([-0.0054, 0.0, height]), WAIST)


def reference(times, x) -> PiecewisePolynomial:
    """A ZMP reference moving along x only (first-order hold)."""
    return PiecewisePolynomial.FirstOrderHold(times, np.array([x, np.zeros(len(x))]))


def finite_plan(plan) -> bool:
    times = np.linspace(plan.planned_at, plan.end, 201)
    return all(np.all(np.isfinite(np.concatenate(plan.com.state(t)))) for t in times)


# --- long durations: ZmpPlanner's exponentials overflow ----------------------------------------
@pytest.mark.parametrize("options", [{"step_duration": 100.0, "single_support": 99.0}, {"start_duration": 200.0},
                                     {"stop_duration": 100.0}, {"step_duration": 1000.0, "single_support": 0.7}])
def test_a_gait_too_long_for_the_com_planner_is_refused_when_made(options):
    """Durations up to 1000 s were accepted; from about 100 s the CoM plan was NaN from t = 0."""
    name = next(iter(options))
    with pytest.raises(InvalidInput, match=f"GaitParameters.{name} must be a number in \\(0, 20\\] s"):
        GaitParameters(**options)


def test_the_longest_gait_plans_a_finite_com_that_follows_its_reference():
    from sotdrake.walking.gait import MAX_DURATION

    gait = GaitParameters(step_duration=MAX_DURATION, single_support=MAX_DURATION - 0.1, start_duration=MAX_DURATION,
                          stop_duration=MAX_DURATION)
    plan = replan(initial_plan(start(), gait), WalkCommand(steps=((0.1, 0.0, 0.0),)), 0.0, gait)
    assert finite_plan(plan)
    # Standing still through the start's long hold: the realised ZMP is on its reference.
    assert np.abs(plan.com.zmp(5.0) - plan.zmp_reference(5.0)).max() < 1e-4


def test_plan_com_refuses_a_plan_that_is_not_finite():
    """A 60 s segment at 0.87 m (ω·T ≈ 200): the plan was NaN everywhere, and returned."""
    with pytest.raises(InvalidInput, match="plan_com: ZmpPlanner's CoM plan is not finite: zmp_d's longest segment, 60 s"):
        plan_com(reference([0.0, 60.0, 61.0, 62.0], [0.0, 0.0, 0.1, 0.1]), (0.0, 0.0), (0.0, 0.0), 0.87)
    plan = plan_com(reference([0.0, 20.0, 21.0, 22.0], [0.0, 0.0, 0.1, 0.1]), (0.0, 0.0), (0.0, 0.0), 0.87)
    assert np.all(np.isfinite(plan.state(0.0)[0]))


def test_a_gait_too_long_for_a_low_com_is_refused_before_anything_is_planned():
    """At a CoM height of 5 cm a 20 s segment overflows (ω·T ≈ 280): the pattern generator planned NaN."""
    from sotdrake.walking.plan import check_segments

    gait = GaitParameters(stop_duration=20.0)
    with pytest.raises(InvalidInput, match="stop_duration makes ZMP reference segments of 20 s"):
        PatternGenerator(start(0.05), 0.01, gait)
    plan = initial_plan(start(0.1), GaitParameters())
    long_steps = GaitParameters(step_duration=20.0, single_support=19.0)
    with pytest.raises(InvalidInput, match="replan: GaitParameters' single_support"):
        replan(plan, WalkCommand(steps=((0.1, 0.0, 0.0),)), 0.0, long_steps)
    check_segments("a gait", long_steps, 0.87)  # (TALOS' height: every gait fits)


# --- plan_com ---------------------------------------------------------------------------------
@pytest.mark.parametrize(("position", "velocity", "height", "named"), [
    ((0.0, 0.0), (0.0, 0.0), 0.0, "height"),
    ((0.0, 0.0), (0.0, 0.0), -0.8, "height"),
    ((0.0, 0.0), (0.0, 0.0), float("nan"), "height"),
    ((0.0, 0.0), (0.0, 0.0), "0.8", "height"),
    ((np.nan, 0.0), (0.0, 0.0), 0.8, "position"),
    ((0.0, 0.0, 0.0), (0.0, 0.0), 0.8, "position"),
    ((0.0, 0.0), (np.inf, 0.0), 0.8, "velocity"),
])
def test_plan_com_refuses_what_drake_would_abort_on_or_plan_nan_from(position, velocity, height, named):
    """A height ≤ 0 or NaN ended the process (a failed DRAKE_DEMAND); a NaN position planned NaN."""
    with pytest.raises(InvalidInput, match=f"plan_com: {named}"):
        plan_com(reference([0.0, 1.0, 2.0], [0.0, 0.1, 0.1]), position, velocity, height)


@pytest.mark.parametrize(("zmp_d", "named"), [
    (PiecewisePolynomial.FirstOrderHold([0.0, 1.0], np.zeros((3, 2))), "2 rows"),
    (reference([0.0, 1.0, 2.0], [0.0, np.nan, 0.1]), "zmp_d"),
    ("a reference", "zmp_d"),
])
def test_plan_com_refuses_a_reference_it_cannot_plan(zmp_d, named):
    with pytest.raises(InvalidInput, match=named):
        plan_com(zmp_d, (0.0, 0.0), (0.0, 0.0), 0.87)


# --- the other helpers --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def talos_robot():
    from sotdrake import talos

    return talos(DiagramBuilder())


def test_leg_masses_and_motion_zmp_check_q_before_drake_sees_it(talos_robot):
    model, q0 = talos_robot.model, talos_robot.device.initial_position
    nan = q0.copy()
    nan[10] = np.nan
    no_rotation = q0.copy()
    no_rotation[:4] = 0.0
    for q in (q0[:5], nan, no_rotation):
        with pytest.raises(InvalidInput, match="leg_masses: q0"):
            leg_masses(model, q)
    with pytest.raises(FrameNotFound, match="leg_masses: soles: unknown frame or operational point 'nope'"):
        leg_masses(model, q0, soles=("nope", "right_sole_link"))
    with pytest.raises(InvalidInput, match="leg_masses: soles"):
        leg_masses(model, q0, soles=("left_sole_link", "left_sole_link"))
    plant = model.plant
    with pytest.raises(InvalidInput, match="motion_zmp: positions must be k×nq"):
        motion_zmp(plant, [0.0, 1.0, 2.0], np.zeros((3, 5)))
    with pytest.raises(InvalidInput, match="motion_zmp: times"):
        motion_zmp(plant, [0.0, 0.0, 0.0], np.tile(q0, (3, 1)))  # (a NaN ZMP, from a division by zero)
    with pytest.raises(InvalidInput, match="motion_zmp: positions: the floating base's quaternion"):
        motion_zmp(plant, [0.0, 1.0, 2.0], np.tile(no_rotation, (3, 1)))
    zmp, com = motion_zmp(plant, [0.0, 0.01, 0.02], np.tile(q0, (3, 1)))
    assert np.allclose(zmp, com[:, :2])  # (standing still: the ZMP under the CoM)


@pytest.mark.parametrize(("arguments", "named"), [
    (([0.87], 1e-3), "height"),
    ((0.87, None), "dt"),
    ((0.0, 1e-3), "height"),
    ((0.87, 1e-3, "5"), "com_gain"),
    ((0.87, 1e-3, 5.0, None), "zmp_gain"),
    ((0.87, 1e-3, 5.0, 0.0, [0.05]), "max_offset"),
])
def test_the_stabilizer_refuses_arguments_that_are_not_numbers(arguments, named):
    with pytest.raises(InvalidInput, match=f"stabilizer: {named} must be a number"):
        ComStabilizer(*arguments)


def test_start_of_refuses_the_same_sole_twice(talos_robot):
    with pytest.raises(InvalidInput, match="start_of: feet"):
        start_of_robot(talos_robot, ("left-sole", "left-sole"))


def start_of_robot(robot, feet):
    from sotdrake.walking import start_of

    return start_of(robot.dynamic, robot.device.initial_position, feet)


def test_the_feed_forward_and_the_measured_com_check_their_arguments(talos_robot):
    model = talos_robot.model
    with pytest.raises(InvalidInput, match="sole_centre"):
        GravityFeedforward(model, np.arange(6, 10), sole_centre=(np.nan, 0.0))
    with pytest.raises(InvalidInput, match="actuated_v"):
        GravityFeedforward(model, [np.nan])
    with pytest.raises(InvalidInput, match="soles"):
        GravityFeedforward(model, np.arange(6, 10), soles=("left-sole",))
    with pytest.raises(InvalidInput, match="model"):
        MeasuredCom(None)


@pytest.mark.parametrize(("call", "named"), [
    (lambda gait: support_polygon([(np.nan, 0.0, 0.0)], gait), "support_polygon: poses"),
    (lambda gait: support_polygon([(0.0, 0.0, 0.0)] * 3, gait), "support_polygon: poses"),
    (lambda gait: sole_centre((np.nan, 0.0, 0.0), gait), "sole_centre: pose"),
    (lambda gait: footprint((0.0, 0.0), gait), "footprint: pose"),
    (lambda gait: sole_centre((0.0, 0.0, 0.0), None), "sole_centre: gait"),
    (lambda gait: plan_steps((np.nan, 0.0, 0.0), "left", 0.0, [(0.1, 0.0, 0.0)], gait), "plan_steps: body"),
    (lambda gait: plan_steps((0.0, 0.0, 0.0), "up", 0.0, [(0.1, 0.0, 0.0)], gait), "plan_steps: side"),
    (lambda gait: zmp_from_momentum((0.0, 0.0, 1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0), "zmp_from_momentum: mass"),
    (lambda gait: zmp_from_momentum((0.0, 0.0, 1.0), (0.0, 0.0, -GRAVITY), (0.0, 0.0, 0.0), 1.0), "free fall"),
    (lambda gait: zmp_from_momentum((0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 1.0), "one shape"),
])
def test_the_support_and_momentum_helpers_refuse_what_would_give_nan(call, named):
    with pytest.raises(InvalidInput, match=named):
        call(GaitParameters())


def test_the_helpers_still_compute():
    gait = GaitParameters()
    assert np.allclose(sole_centre((0.0, 0.0, 0.0), gait), gait.sole_centre)
    assert support_polygon([(0.0, 0.1, 0.0), (0.0, -0.1, 0.0)], gait).shape == (4, 2)
    assert np.allclose(zmp_from_momentum((0.0, 0.0, 1.0), (0.1, 0.0, 0.0), (0.0, 0.0, 0.0), 2.0), [-0.1 / GRAVITY, 0.0])
    assert [s.side for s in plan_steps((0.0, 0.0, 0.0), "left", 0.0, [(0.1, 0.0, 0.0)] * 2, gait)] == ["left", "right"]


# --- the pattern generator past the plans' end ---------------------------------------------------
def pattern_generator():
    builder = DiagramBuilder()
    pg = builder.AddSystem(PatternGenerator(start(), 0.01))
    return pg, builder.Build()


def test_a_command_given_past_the_plans_end_is_refused_when_made():
    """At t = 1.2e6 s the command was taken, then the update's replan raised inside the simulation."""
    pg, diagram = pattern_generator()
    context = diagram.CreateDefaultContext()
    context.SetTime(1.2e6)
    with pytest.raises(InvalidInput, match=r"pg.setVelocity: the context's time 1200000 s is past .* \(1e\+06 s\)"):
        pg.setVelocity(0.1, 0.0, 0.0, context=context)
    with pytest.raises(InvalidInput, match=r"pg\.setSteps: the context's time"):
        pg.setSteps([(0.1, 0.0, 0.0)], context=context)
    assert pg.settings(context).command == WalkCommand()
    context.SetTime(MAX_TIME - 1.0)
    pg.setVelocity(0.1, 0.0, 0.0, context=context)  # (before the end: taken)
    assert pg.settings(context).command == WalkCommand(velocity=(0.1, 0.0, 0.0))


def test_a_timed_command_past_the_plans_end_is_refused_at_its_time():
    pg, diagram = pattern_generator()
    attime(MAX_TIME + 0.005, lambda: pg.setVelocity(0.1, 0.0, 0.0))
    simulator = Simulator(diagram)
    simulator.get_mutable_context().SetTime(MAX_TIME - 0.02)
    simulator.Initialize()
    simulator.AdvanceTo(MAX_TIME + 0.03)  # (an update replanning for it would raise: t past the end)
    context = simulator.get_context()
    assert pg.settings(context).command == WalkCommand()
    assert [message for _, message in pg.refused_commands] == [
        "pg: a command at t = 1000000.005 s is past the latest time a walk is planned for (1e+06 s)"]


# --- the walk scenario ---------------------------------------------------------------------------
def test_the_walk_refuses_a_velocity_with_steps_and_a_change_past_the_plans_end():
    from sotdrake.walking.controller import build_diagram

    with pytest.raises(InvalidInput, match="build_diagram: velocity and steps: give one or the other"):
        build_diagram(steps=(2, 0.2), velocity=(0.1, 0.0, 0.0))
    with pytest.raises(InvalidInput, match="then's T must be in \\[0, 1e\\+06\\] s"):
        build_diagram(then=(2e6, 0.1, 0.0, 0.0))


def test_the_walk_script_refuses_a_run_shorter_than_a_tick(tmp_path):
    from sotdrake.scenarios import walk

    with pytest.raises(SystemExit, match=r"--duration must be at least one tick \(0\.001 s\), got 0\.0005"):
        walk.main(["--duration", "0.0005", "--no-meshcat", "--quiet", "--out", str(tmp_path / "short")])


def test_the_walk_summary_refuses_a_run_without_a_tick():
    from sotdrake.scenarios import walk

    run = walk.build_diagram(steps=(1, 0.1), solver="cascade", dt=2e-3)
    simulator = Simulator(run.diagram)
    simulator.Initialize()
    with pytest.raises(SotError, match="summarize: the run must last at least one tick"):
        walk.summarize(run, simulator, 0.0, 1.0)
