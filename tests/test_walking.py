"""The walking wing: footsteps, ZMP reference, CoM (LIPM), replanning, the PatternGenerator
entity, and a short kinematic walk of TALOS."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake.exceptions import InvalidInput, SotError
from sotdrake.features import Feature6dDesired
from sotdrake.sequencer import attime
from sotdrake.walking import (
    GRAVITY,
    GaitParameters,
    PatternGenerator,
    Start,
    WalkCommand,
    initial_plan,
    polygon_margin,
    replan,
    sole_centre,
    support_polygon,
)
from sotdrake.walking.com_planner import plan_com

GAIT = GaitParameters()
# TALOS in half-sitting: soles 0.17 m apart, CoM 0.877 m high.
START = Start({"left": RigidTransform([-0.0088, 0.0848, 0.0]), "right": RigidTransform([-0.0088, -0.0852, 0.0])},
              np.array([-0.0032, 0.0012, 0.8767]), RigidTransform([0.0, 0.0, 1.0193]))


def walk_plan(command: WalkCommand, input_cost: float | None = None):
    kwargs = {} if input_cost is None else {"input_cost": input_cost}
    return replan(initial_plan(START, GAIT, **kwargs), command, 0.0, GAIT, **kwargs)


def times(plan, step=0.005):
    return np.arange(0.0, plan.end, step)


# --- footsteps ------------------------------------------------------------------------------
def test_forward_footsteps_alternate_advance_and_keep_the_feet_apart():
    plan = walk_plan(WalkCommand(velocity=(0.1, 0.0, 0.0)))
    steps = plan.steps
    assert len(steps) == GAIT.horizon_steps
    assert [s.side for s in steps[:4]] == ["right", "left", "right", "left"]
    for a, b in pairwise(steps):
        assert b.liftoff - a.liftoff == pytest.approx(GAIT.step_duration)
        assert a.touchdown - a.liftoff == pytest.approx(GAIT.single_support)
        assert b.body[0] - a.body[0] == pytest.approx(0.1 * GAIT.step_duration)  # v·T per step
        assert abs(b.y - a.y) == pytest.approx(GAIT.feet_distance)  # rest places, d apart
        assert b.yaw == a.yaw == 0.0
    assert steps[0].liftoff == pytest.approx(GAIT.start_duration)


def test_lateral_steps_lead_with_the_foot_on_that_side_and_never_close_the_feet():
    plan = walk_plan(WalkCommand(velocity=(0.0, -0.15, 0.0)))
    steps = plan.steps
    assert steps[0].side == "right"
    left_y, right_y = START.foot("left")[1], START.foot("right")[1]
    for s in steps:
        left_y, right_y = (s.y, right_y) if s.side == "left" else (left_y, s.y)
        assert left_y - right_y >= GAIT.feet_distance - 1e-12
    # The mean lateral velocity is the command's: two steps move the walking frame by 2·vy·T.
    assert steps[3].body[1] - steps[1].body[1] == pytest.approx(-0.15 * 2 * GAIT.step_duration)


def test_turning_steps_turn_the_walking_frame_by_omega_T():
    plan = walk_plan(WalkCommand(velocity=(0.1, 0.0, 0.2)))
    assert plan.steps[0].side == "left"
    yaws = [s.body[2] for s in plan.steps]
    assert np.allclose(np.diff(yaws), 0.2 * GAIT.step_duration)
    for s in plan.steps:  # each foot lands at its rest place, turned with the frame
        assert s.yaw == pytest.approx(s.body[2])


def test_a_list_of_steps_ends_with_the_feet_side_by_side():
    plan = walk_plan(WalkCommand(steps=((0.2, 0.0, 0.0),) * 3))
    last = plan.steps[-1]
    feet = plan.feet_at(last.touchdown)
    assert feet["left"][0] == pytest.approx(feet["right"][0]) == pytest.approx(START.body[0] + 0.6)
    assert feet["left"][1] - feet["right"][1] == pytest.approx(GAIT.feet_distance)
    assert not plan.needs_replan(plan.command, last.touchdown + 5.0, GAIT)


# --- ZMP and CoM ----------------------------------------------------------------------------
@pytest.mark.parametrize("velocity", [(0.1, 0.0, 0.0), (0.2, 0.1, 0.0), (0.1, 0.0, 0.1), (-0.1, -0.2, -0.3)])
def test_zmp_reference_and_planned_zmp_stay_2cm_inside_the_support_polygon(velocity):
    plan = walk_plan(WalkCommand(velocity=velocity))
    for t in times(plan):
        polygon = plan.support_polygon(t, GAIT)
        assert polygon_margin(plan.zmp_reference(t), polygon) >= 0.02
        assert polygon_margin(plan.com.zmp(t), polygon) >= 0.02, t


def test_drake_default_input_cost_lets_the_zmp_stray_the_tuned_one_does_not():
    default = walk_plan(WalkCommand(velocity=(0.1, 0.0, 0.0)), input_cost=0.1)
    tuned = walk_plan(WalkCommand(velocity=(0.1, 0.0, 0.0)))
    late = [t for t in times(tuned) if t > GAIT.start_duration]  # after the start from rest

    def stray(plan):
        return max(np.linalg.norm(plan.com.zmp(t) - plan.zmp_reference(t)) for t in late)

    assert stray(default) > 0.05
    assert stray(tuned) < 0.005


def test_planned_com_obeys_the_lipm_around_the_zmp_reference():
    """``ẍ = g/z (x − p_ref)``, ``ẍ`` by finite differences of the CoM position, within the
    acceleration of a 5 mm ZMP error, after the start from rest."""
    plan = walk_plan(WalkCommand(velocity=(0.1, 0.05, 0.1)))
    h, z = 1e-4, plan.com.height
    for t in np.arange(GAIT.start_duration, plan.end - 0.1, 0.01):
        x = [plan.com.state(t + k * h)[0] for k in (-1, 0, 1)]
        acceleration = (x[0] - 2 * x[1] + x[2]) / h**2
        lipm = GRAVITY / z * (x[1] - plan.zmp_reference(t))
        assert np.abs(acceleration - lipm).max() < GRAVITY / z * 0.005, t


def test_plan_com_starts_from_the_given_state():
    plan = walk_plan(WalkCommand(velocity=(0.1, 0.0, 0.0)))
    com = plan_com(plan.zmp, [0.01, -0.02], [0.05, 0.01], 0.8)
    x, v, _ = com.state(0.0)
    assert np.allclose(x, [0.01, -0.02]) and np.allclose(v, [0.05, 0.01], atol=1e-9)


def test_support_polygon_margin_is_a_signed_distance():
    square = support_polygon([(0.0, 0.0, 0.0)], GaitParameters(sole_length=0.2, sole_width=0.1, sole_centre=(0.0, 0.0)))
    assert polygon_margin([0.0, 0.0], square) == pytest.approx(0.05)
    assert polygon_margin([0.09, 0.0], square) == pytest.approx(0.01)
    assert polygon_margin([0.0, 0.08], square) == pytest.approx(-0.03)


# --- replanning -----------------------------------------------------------------------------
def test_replanning_mid_swing_keeps_the_swing_and_the_com_continuous():
    plan = walk_plan(WalkCommand(velocity=(0.1, 0.0, 0.0)))
    t = plan.steps[1].liftoff + 0.3  # the left foot in the air
    new = replan(plan, WalkCommand(velocity=(0.0, 0.1, 0.2)), t, GAIT)
    assert new.steps[:2] == plan.steps[:2]
    for a, b in zip(plan.com.state(t)[:2], new.com.state(t)[:2], strict=False):
        assert np.allclose(a, b, atol=1e-9)
    assert np.allclose(plan.references(t).feet["left"], new.references(t).feet["left"])
    assert new.steps[2].body[2] == pytest.approx(0.2 * GAIT.step_duration)  # the new command from the next step
    for k in np.arange(t, new.end, 0.01):
        assert polygon_margin(new.com.zmp(k), new.support_polygon(k, GAIT)) >= 0.02


def test_stopping_closes_the_feet_and_holds_the_com_between_them():
    plan = walk_plan(WalkCommand(velocity=(0.1, 0.0, 0.0)))
    t = plan.steps[2].liftoff + 0.1
    stop = replan(plan, WalkCommand(), t, GAIT)
    feet = stop.feet_at(stop.end)
    assert feet["left"][0] == pytest.approx(feet["right"][0])
    middle = 0.5 * (sole_centre(feet["left"], GAIT) + sole_centre(feet["right"], GAIT))
    x, v, _ = stop.com.state(stop.end + 1.0)
    assert np.linalg.norm(x - middle) < 2e-3 and not v.any()


# --- the entity -----------------------------------------------------------------------------
def pattern_generator_diagram():
    builder = DiagramBuilder()
    pg = builder.AddSystem(PatternGenerator(START, 1e-3))
    return builder, pg


def test_set_velocity_out_of_range_is_refused_and_changes_nothing():
    _, pg = pattern_generator_diagram()
    pg.setVelocity(0.1, 0.0, 0.0)
    for bad in [(0.25, 0.0, 0.0), (0.0, -0.21, 0.0), (0.0, 0.0, 1.0), (np.nan, 0.0, 0.0)]:
        with pytest.raises(SotError, match=r"out of range|NaN"):
            pg.setVelocity(*bad)
    with pytest.raises(InvalidInput, match=r"x = 0.25 m/s is out of range; accepted: -0.2 ≤ x ≤ 0.2"):
        pg.setVelocity(0.25, 0, 0)
    for steps in ([], [(0.1, 0.0, 0.0)] * 10_001, [(0.1, 0.0)]):
        with pytest.raises(InvalidInput, match="1 to 10000"):
            pg.setSteps(steps)
    assert pg.settings().command.velocity == (0.1, 0.0, 0.0)


def test_commands_from_context_and_attime_replan():
    builder, pg = pattern_generator_diagram()
    attime(2.0, lambda: pg.setVelocity(0.0, 0.0, 0.0), "stop")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    simulator.Initialize()
    assert pg.plan(context).steps == ()  # standing: the default command
    pg.setVelocity(0.1, 0.0, 0.0, context)
    simulator.AdvanceTo(0.01)
    plan = pg.plan(context)
    assert plan.command.velocity == (0.1, 0.0, 0.0) and plan.steps[0].liftoff == pytest.approx(0.8)
    simulator.AdvanceTo(2.01)
    # Applied at the command's tick: the timed change comes just before the tick's own updates.
    assert pg.plan(context).command == WalkCommand() and pg.plan(context).planned_at == pytest.approx(2.0)
    assert pg.settings().command == WalkCommand()  # the defaults untouched by the context's commands


def test_outputs_velocities_are_the_derivatives_of_the_positions():
    builder, pg = pattern_generator_diagram()
    pg.setVelocity(0.1, 0.05, 0.2)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    own = pg.GetMyContextFromRoot(context)
    h = 1e-3
    simulator.AdvanceTo(1.2)  # the first foot in the air
    samples = []
    for _ in range(3):
        values = {port: pg.GetOutputPort(port).Eval(own) for port in
                  ("com", "com_velocity", "left_foot_pose", "left_foot_velocity", "left_foot_acceleration", "waist_pose",
                   "waist_velocity")}
        samples.append({k: RigidTransform(v) if isinstance(v, RigidTransform) else np.array(v) for k, v in values.items()})
        simulator.AdvanceTo(context.get_time() + h)
    middle = samples[1]
    assert np.allclose((samples[2]["com"] - samples[0]["com"]) / (2 * h), middle["com_velocity"], atol=1e-4)
    for pose, velocity in (("left_foot_pose", "left_foot_velocity"), ("waist_pose", "waist_velocity")):
        p = [s[pose].translation() for s in samples]
        yaw = [RollPitchYaw(s[pose].rotation()).yaw_angle() for s in samples]
        V = middle[velocity]
        assert np.allclose((p[2] - p[0]) / (2 * h), V[3:], atol=1e-3), pose
        assert (yaw[2] - yaw[0]) / (2 * h) == pytest.approx(V[2], abs=1e-3)
    assert np.linalg.norm(middle["left_foot_velocity"][3:]) > 0.05  # really swinging
    # The foot's acceleration (ω̇, p̈) is the derivative of its velocity.
    rate = (samples[2]["left_foot_velocity"] - samples[0]["left_foot_velocity"]) / (2 * h)
    assert np.allclose(rate, middle["left_foot_acceleration"], atol=1e-2)
    assert np.linalg.norm(middle["left_foot_acceleration"][3:]) > 0.1


def test_feature6d_desired_pose_input_overrides_the_setting():
    builder = DiagramBuilder()
    des = builder.AddSystem(Feature6dDesired("des"))
    context = des.CreateDefaultContext()
    X = RigidTransform(RollPitchYaw(0.1, 0.2, 0.3), [1.0, 2.0, 3.0])
    des.pose_in.FixValue(context, X)
    des.spatial_velocity_in.FixValue(context, np.arange(6.0))
    assert des.GetOutputPort("position").Eval(context).IsExactlyEqualTo(X)
    assert np.array_equal(des.GetOutputPort("velocity").Eval(context), np.arange(6.0))
    des.translation_in.FixValue(context, [4.0, 5.0, 6.0])
    assert np.array_equal(des.GetOutputPort("position").Eval(context).translation(), [4.0, 5.0, 6.0])


# --- a short kinematic walk -----------------------------------------------------------------
def test_short_kinematic_walk_tracks_feet_and_com_below_1mm():
    from sotdrake.scenarios import walk as walk_script

    # A quick start (0.4 s) and a 2 ms tick keep it short; the basic SOT (no inequality task).
    walk = walk_script.build_diagram(velocity=(0.1, 0.0, 0.0), solver="cascade", dt=2e-3,
                                     gait=GaitParameters(start_duration=0.4))
    simulator = Simulator(walk.diagram)
    simulator.AdvanceTo(1.2)  # the first step (right foot) lands at 1.1 s
    summary, trace = walk_script.summarize(walk, simulator, 1.2, 1.0)
    assert summary["steps"] == 1 and not summary["fell"]
    assert summary["max_foot_tracking_error_m"] < 1e-3
    assert summary["max_com_tracking_error_m"] < 1e-3
    assert summary["min_zmp_margin_m"] >= 0.02
    # The right sole really moved forward by its step, the left one stayed.
    right = trace["pg_feet"][-1, 4:7]
    assert right[0] - trace["pg_feet"][0, 4] == pytest.approx(0.08 + 0.0, abs=1e-9)
    assert summary["max_slip_per_step_m"] < 1e-3


def test_short_kinematic_walk_with_walkromeos_arm_posture_holds_the_arms():
    """``arms='posture'``: walkromeo's taskPosition, the arm joints held at half-sitting by a posture
    task at the bottom of the stack; the walk tracks as well, the arms do not move."""
    from sotdrake.scenarios import walk as walk_script
    from sotdrake.walking.controller import ARM_JOINTS

    walk = walk_script.build_diagram(velocity=(0.1, 0.0, 0.0), solver="cascade", dt=2e-3,
                                     gait=GaitParameters(start_duration=0.4), arms="posture")
    assert walk.sot.stack()[-1] == "taskArms"
    simulator = Simulator(walk.diagram)
    simulator.AdvanceTo(1.2)
    summary, trace = walk_script.summarize(walk, simulator, 1.2, 1.0)
    assert summary["steps"] == 1 and not summary["fell"]
    assert summary["max_foot_tracking_error_m"] < 1e-3 and summary["max_com_tracking_error_m"] < 1e-3
    plant = walk.robot.model.plant
    arms = [plant.get_joint(j).position_start() for j in plant.GetJointIndices()
            if plant.get_joint(j).num_velocities() == 1 and ARM_JOINTS.search(plant.get_joint(j).name())]
    assert len(arms) == 14
    q0 = walk.robot.device.initial_position
    assert np.abs(trace["q_device"][:, arms] - q0[arms]).max() < 1e-4
    with pytest.raises(InvalidInput, match="arms"):
        walk_script.build_diagram(arms="swing")


@pytest.mark.parametrize("options, named", [
    (["--stiffness", "100"], "--stiffness: options of --mode physics"),
    (["--closed-loop", "--com-gain", "4"], "--com-gain, --closed-loop: options of --mode physics"),
    (["--step-duration", "-1"], "--step-duration -1.0"),
    (["--single-support", "5"], "--single-support 5.0"),
])
def test_the_walk_script_names_the_option_it_refuses(options, named, tmp_path, capsys):
    """A physics option outside --mode physics was ignored; a gait option was named by its field."""
    from sotdrake.scenarios import walk as walk_script

    with pytest.raises(SystemExit) as stopped:
        walk_script.main([*options, "--out", str(tmp_path / "run"), "--no-meshcat", "--quiet"])
    assert stopped.value.code == 2 and named in capsys.readouterr().err
    assert not (tmp_path / "run").exists()
