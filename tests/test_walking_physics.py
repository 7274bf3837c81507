"""The walk's physics helpers (servo feed-forward, stabiliser, measured CoM) and the walk's robots."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.tree import JacobianWrtVariable, MultibodyForces
from pydrake.systems.analysis import Simulator

from sotdrake.exceptions import InvalidInput
from sotdrake.walking.gravity_feedforward import GravityFeedforward, left_share, support_wrench
from tests.conftest import random_configuration


@pytest.mark.parametrize("forces, zmp", [((400.0, 0.0), (0.0, 0.0)), ((0.0, 400.0), (0.0, 0.0)), ((400.0, 400.0), (0.0, 0.03)),
                                         ((400.0, 400.0), (0.0, -0.5)), ((0.0, 0.0), (0.0, 0.02))])
def test_static_torques_balance_gravity_by_drakes_inverse_dynamics(talos_model, rng, forces, zmp):
    """Drake's inverse dynamics at rest, with the soles' wrenches applied as external forces, needs
    no force on the floating base and the feed-forward's torques on the joints; a sole measured in
    the air carries nothing."""
    plant = talos_model.plant
    actuated = np.arange(6, plant.num_velocities())
    ff = GravityFeedforward(talos_model, actuated)
    context = ff.CreateDefaultContext()
    q = random_configuration(talos_model, rng, spread=0.2)
    ff.GetInputPort("position").FixValue(context, q)
    ff.GetInputPort("normal_forces").FixValue(context, forces)
    ff.GetInputPort("zmp_reference").FixValue(context, zmp)
    torque = ff.GetOutputPort("torque").Eval(context)
    # The soles' wrenches the feed-forward assumes, rebuilt from its pure functions.
    pc = plant.CreateDefaultContext()
    plant.SetPositions(pc, q)
    world = plant.world_frame()
    g = plant.CalcGravityGeneralizedForces(pc)
    frames = {side: talos_model.frame(f"{side}-sole") for side in ("left", "right")}
    J = {s: plant.CalcJacobianSpatialVelocity(pc, JacobianWrtVariable.kV, f, np.zeros(3), world, world) for s, f in frames.items()}
    centres = {s: plant.CalcPointsPositions(pc, f, np.zeros(3), world).ravel()[:2] for s, f in frames.items()}
    loaded = [f > 20.0 for f in forces]
    alpha = float(loaded[0]) if loaded[0] != loaded[1] else left_share(np.array(zmp), centres["left"], centres["right"])
    forces = MultibodyForces(plant)
    plant.CalcForceElementsContribution(pc, forces)  # gravity
    for side, share in (("left", alpha), ("right", 1 - alpha)):
        w = share * support_wrench(g[:6], J[side][:, :6])
        frame = frames[side]
        body = frame.body()
        p_BS_W = body.EvalPoseInWorld(pc).rotation() @ frame.GetFixedPoseInBodyFrame().translation()
        body.AddInForce(pc, p_BS_W, SpatialForce(w[:3], w[3:]), world, forces)
    required = plant.CalcInverseDynamics(pc, np.zeros(plant.num_velocities()), forces)
    assert np.abs(required[:6]).max() < 1e-6 * np.abs(g).max()  # the base is balanced by the soles
    assert np.allclose(required[6:], torque, atol=1e-6 * np.abs(g).max())
    assert np.abs(torque).max() > 10.0  # TALOS' legs really carry torque


def test_the_measured_contact_only_switches_a_share_off():
    from sotdrake.walking.gravity_feedforward import gated_share

    assert gated_share(0.3, 500.0, 400.0) == 0.3  # both on the ground: the plan's share
    assert gated_share(0.3, 500.0, 5.0) == 1.0  # the right sole in the air
    assert gated_share(0.3, 0.0, 800.0) == 0.0
    assert gated_share(0.3, 0.0, 0.0) == 0.3


def test_left_share_is_the_zmp_along_the_feet():
    left, right = np.array([0.0, 0.1]), np.array([0.0, -0.1])
    assert left_share(np.array([0.05, 0.0]), left, right) == pytest.approx(0.5)
    assert left_share(np.array([0.0, 0.05]), left, right) == pytest.approx(0.75)
    assert left_share(np.array([0.0, 0.3]), left, right) == 1.0
    assert left_share(np.array([0.0, -0.3]), left, right) == 0.0


# --- the walk's robots ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def walk_script():
    from sotdrake.scenarios import walk

    return walk


@pytest.mark.slow
def test_romeo_walks_kinematically(walk_script):
    """``--robot romeo``: the first step of a walk at 0.1 m/s under ``SolverKine`` (joint position and
    velocity limits hard), feet and CoM on their references."""
    walk = walk_script.build_diagram("romeo", velocity=(0.1, 0.0, 0.0), dt=2e-3)
    simulator = Simulator(walk.diagram)
    simulator.AdvanceTo(1.6)  # the right foot lands at 1.5 s
    summary, trace = walk_script.summarize(walk, simulator, 1.6, 1.0)
    assert summary["robot"] == "romeo" and summary["steps"] == 1 and not summary["fell"]
    assert summary["max_foot_tracking_error_m"] < 1e-3
    assert summary["max_com_tracking_error_m"] < 3e-3  # 2.1 mm at the touch-down (TALOS: < 1 mm)
    assert summary["min_zmp_margin_m"] >= 0.02
    assert summary["max_slip_per_step_m"] < 1e-4
    assert trace["pg_feet"][-1, 4] - trace["pg_feet"][0, 4] == pytest.approx(0.08)  # v·T
    # Romeo's own feet: 0.192 m apart at the start (TALOS': 0.17 m)
    assert trace["pg_feet"][0, 1] - trace["pg_feet"][0, 5] == pytest.approx(0.192, abs=1e-3)


def test_romeo_has_no_physical_model(walk_script):
    with pytest.raises(InvalidInput, match=r"no physical model for 'romeo'.*kinematic"):
        walk_script.build_diagram("romeo", mode="physics")


# --- the CoM stabiliser ---------------------------------------------------------------------
def test_feedback_rate_signs_and_a_missing_cop():
    """A CoM behind its reference is pushed forward; a ZMP behind its reference slows the CoM
    command (the deceleration moves the ZMP forward); no CoP (NaN): the CoM term alone."""
    from sotdrake.walking.stabilizer import feedback_rate

    zero = np.zeros(2)
    assert np.allclose(feedback_rate(zero, [-0.01, 0.0], zero, zero, 5.0, 1.0), [0.05, 0.0])
    assert np.allclose(feedback_rate(zero, zero, zero, [-0.02, 0.01], 5.0, 1.0), [-0.02, 0.01])
    assert np.allclose(feedback_rate(zero, [0.0, 0.01], zero, [np.nan, np.nan], 5.0, 1.0), [0.0, -0.05])


def test_stabilizer_cancels_a_steady_com_offset_and_leaves_exact_tracking_alone():
    """The robot's CoM follows the command with a constant error ``e`` (a servo sag): the
    stabiliser's offset converges to ``−e`` and the measured CoM to the plan; without an error the
    plan is passed through unchanged."""
    from sotdrake.walking import ComStabilizer

    dt = 1e-3
    stabilizer = ComStabilizer(0.877, dt, com_gain=8.0)
    context = stabilizer.CreateDefaultContext()
    plan = np.array([0.1, -0.05, 0.877])
    for port, value in (("com_reference", plan), ("com_velocity_reference", np.zeros(3)),
                        ("com_acceleration_reference", np.zeros(3)), ("measured_cop", [np.nan, np.nan])):
        stabilizer.GetInputPort(port).FixValue(context, value)
    sag = np.array([0.012, -0.004, 0.0])
    for _ in range(2000):  # 2 s of ticks
        command = stabilizer.GetOutputPort("com").Eval(context)
        stabilizer.GetInputPort("measured_com").FixValue(context, command + sag)
        context.SetDiscreteState(stabilizer.EvalUniquePeriodicDiscreteUpdate(context).get_vector().get_value())
    assert np.allclose(stabilizer.GetOutputPort("offset").Eval(context), -sag[:2], atol=1e-6)
    assert np.allclose(stabilizer.GetOutputPort("com").Eval(context) + sag, plan, atol=1e-6)
    # Exact tracking: nothing to correct.
    context.SetDiscreteState(np.zeros(2))
    stabilizer.GetInputPort("measured_com").FixValue(context, plan)
    assert not stabilizer.EvalUniquePeriodicDiscreteUpdate(context).get_vector().get_value().any()


@pytest.mark.parametrize("kwargs", [{"com_gain": 3.0}, {"zmp_gain": 3.4}, {"zmp_gain": -1.0}, {"max_offset": 0.0}])
def test_stabilizer_gains_outside_the_stable_range_are_refused(kwargs):
    from sotdrake.walking import ComStabilizer

    with pytest.raises(InvalidInput, match=r"must be"):
        ComStabilizer(0.877, 1e-3, **kwargs)


# --- landing below the ground (position servos) ---------------------------------------------
def test_landing_depth_presses_the_sole_then_returns_to_the_ground():
    from sotdrake.walking import GaitParameters, Start, WalkCommand, initial_plan, replan
    from tests.test_walking import START

    depth = 0.01
    plans = {d: replan(initial_plan(START, g := GaitParameters(landing_depth=d)), WalkCommand(steps=((0.2, 0.0, 0.0),) * 2), 0.0, g)
             for d in (0.0, depth)}
    step = plans[depth].steps[0]
    gait = GaitParameters()
    z = {d: (lambda t, p=p: p.references(t).feet[step.side][2]) for d, p in plans.items()}
    assert z[depth](step.touchdown) == pytest.approx(-depth, abs=1e-9)
    assert z[depth](step.touchdown + gait.double_support) == pytest.approx(0.0, abs=1e-9)
    assert z[0.0](step.touchdown) == pytest.approx(0.0, abs=1e-12)
    # Before the touch-down the two swings rise alike to the apex; the planned CoM and ZMP are the same.
    mid = 0.5 * (step.liftoff + step.touchdown)
    assert z[depth](mid) == pytest.approx(gait.swing_height) == pytest.approx(z[0.0](mid))
    assert plans[depth].com.state(1.3)[0] == pytest.approx(plans[0.0].com.state(1.3)[0])
    assert isinstance(START, Start)
    with pytest.raises(InvalidInput, match="landing_depth"):
        GaitParameters(landing_depth=0.05)


# --- the swing's profile (dynamic walk) ----------------------------------------------------
def test_quintic_swing_starts_and_lands_with_zero_acceleration_and_is_c2():
    """The cubic swing's acceleration jumps to 6 Δ/T² at the lift-off; the quintic's is zero at the
    lift-off, apex and touch-down, continuous everywhere (central differences of its velocity), and
    both reach the same footstep with zero velocity through the same apex."""
    from sotdrake.walking import GaitParameters, WalkCommand, initial_plan, replan
    from tests.test_walking import START

    plans = {profile: replan(initial_plan(START, g := GaitParameters(swing_profile=profile)),
                             WalkCommand(steps=((0.2, 0.0, 0.0),) * 3), 0.0, g)
             for profile in ("cubic", "quintic")}
    step = plans["cubic"].steps[1]  # the left foot's 0.4 m swing
    T, side = step.touchdown - step.liftoff, step.side
    travel = step.x - START.feet[side].translation()[0]  # the sole's forward travel (0.4 m)
    refs = {p: (lambda t, plan=plan: plan.references(t)) for p, plan in plans.items()}
    after = step.liftoff + 1e-6
    assert refs["cubic"](after).feet_acceleration[side][0] == pytest.approx(6 * travel / T**2, rel=1e-3)
    for t in (step.liftoff - 1e-6, after, step.liftoff + T / 2, step.touchdown - 1e-6, step.touchdown + 1e-6):
        assert np.abs(refs["quintic"](t).feet_acceleration[side]).max() < 1e-3, t
    times = np.arange(step.liftoff - 0.05, step.touchdown + 0.05, 1e-3)
    h = 1e-6
    for t in times:
        r = refs["quintic"](t)
        finite = (refs["quintic"](t + h).feet_velocity[side] - refs["quintic"](t - h).feet_velocity[side]) / (2 * h)
        assert np.allclose(finite, r.feet_acceleration[side], atol=1e-4), t
    peak = max(abs(refs["quintic"](t).feet_acceleration[side][0]) for t in times)
    assert peak == pytest.approx(10 / np.sqrt(3) * travel / T**2, rel=1e-2)  # 5.77 Δ/T², at 0.21 T
    for t in (step.liftoff + T / 2, step.touchdown):
        assert np.allclose(refs["quintic"](t).feet[side], refs["cubic"](t).feet[side], atol=1e-12)
    assert np.allclose(refs["quintic"](step.touchdown).feet_velocity[side], 0.0, atol=1e-12)
    with pytest.raises(InvalidInput, match="swing_profile"):
        GaitParameters(swing_profile="linear")


# --- the dynamic walk -----------------------------------------------------------------------
@pytest.mark.slow
def test_dynamic_walk_switches_the_contacts_and_steps(walk_script):
    """``--mode dynamic``: SolverDyn on the torque-driven plant; the right sole's contact is released
    before its lift-off and added back at its touch-down; the first step of 0.2 m lands where planned
    with the CoM on its plan, no slip and the CoP well inside the soles. At the left foot's lift-off
    (a 0.4 m swing, quintic: zero acceleration at the lift-off) the right sole stays put: it turns by
    < 1 mrad and moves by < 0.1 mm (measured: 0.15 mrad, 0.01 mm; the cubic swing: the next test)."""
    gait = dataclasses.replace(walk_script.ROBOTS["talos"].gait, start_duration=0.4, swing_profile=walk_script.DYNAMIC_SWING_PROFILE)
    walk = walk_script.build_diagram(mode="dynamic", steps=(2, 0.2), gait=gait)
    assert [c.description for c in walk.commands[:2]] == ["rmContact contactRF", "addContact contactRF"]
    simulator = Simulator(walk.diagram)
    simulator.AdvanceTo(0.7)  # the right foot in the air: its contact released
    assert walk.sot.held_contacts(simulator.get_context()) == ["contactLF"]
    simulator.AdvanceTo(1.15)  # it landed at 1.1 s; the left one is being released for its lift-off at 1.2 s
    assert sorted(walk.sot.held_contacts(simulator.get_context())) == ["contactLF", "contactRF"]
    simulator.AdvanceTo(1.2)
    assert walk.sot.held_contacts(simulator.get_context()) == ["contactRF"]
    simulator.AdvanceTo(1.3)
    summary, trace = walk_script.summarize(walk, simulator, 1.3, 1.0)
    assert summary["steps"] == 1 and not summary["fell"]
    assert summary["max_com_tracking_error_m"] < 2e-3
    assert summary["max_foot_tracking_error_m"] < 5e-3
    assert summary["max_slip_per_step_m"] < 3e-4
    assert summary["min_cop_margin_m"] > 0.02
    standing, spin, drift = _stance_spin(walk, trace, 1.2)
    assert standing < 1e-3 and spin < 1e-3 and drift < 1e-4
    right = walk.robot.dynamic.pose_at("right-sole", trace["x_plant"][-1, : walk.robot.model.nq]).translation()
    assert right[0] - trace["pg_feet"][0, 4] == pytest.approx(0.2, abs=5e-3)


def _stance_spin(walk, trace, liftoff: float, side: str = "right") -> tuple[float, float, float]:
    """The stance sole's yaw change over the 50 ms before ``liftoff`` (the other foot's), and its
    largest yaw change (rad) and origin displacement (m) after it."""
    t, nq = trace["time"], walk.robot.model.nq
    sole = walk.robot.dynamic.trajectory([f"{side}-sole"], trace["x_plant"][:, :nq])[f"{side}-sole"]
    yaw = np.arctan2(sole[:, 1, 0], sole[:, 0, 0])
    before, after = np.searchsorted(t, liftoff - 0.05), np.searchsorted(t, liftoff)
    return (abs(yaw[after] - yaw[before]), np.abs(yaw[after:] - yaw[after]).max(),
            np.linalg.norm(sole[after:, :2, 3] - sole[after, :2, 3], axis=1).max())


@pytest.mark.slow
def test_dynamic_walk_stance_sole_holds_at_a_cubic_swings_lift_off(walk_script):
    """With the cubic swing, at the lift-off of a 0.4 m swing (the second step) the swing foot's
    acceleration jumps to 4.9 m/s²; the stance sole takes the swing leg's yaw torque and its CoP
    jumps 5 cm forward in one tick, onto the toe. The contact's yaw torque is bounded by its contact
    wrench cone, which shrinks the torsion allowed as the CoP nears the toe: the sole turns by about
    2 mrad and its origin moves about 0.15 mm (the quintic swing: 0.15 mrad, 0.01 mm). With a yaw
    bound blind to the CoP (``μ r f_z``), the toe's small patch could not hold the torque asked and
    the sole spun 14 mrad, 1 mm, within 70 ms."""
    gait = dataclasses.replace(walk_script.ROBOTS["talos"].gait, start_duration=0.4, swing_profile="cubic")
    walk = walk_script.build_diagram(mode="dynamic", steps=(2, 0.2), gait=gait)
    liftoff = gait.start_duration + gait.step_duration  # the left foot's (1.2 s), the right one standing
    simulator = Simulator(walk.diagram)
    simulator.AdvanceTo(liftoff + 0.1)
    summary, trace = walk_script.summarize(walk, simulator, liftoff + 0.1, 1.0)
    assert not summary["fell"]
    standing, spin, drift = _stance_spin(walk, trace, liftoff)
    assert standing < 1e-3  # on both soles: no spin
    assert spin < 4e-3 and drift < 4e-4 and summary["max_slip_per_step_m"] < 4e-4


def test_dynamic_walk_needs_a_list_of_steps(walk_script):
    with pytest.raises(InvalidInput, match="--steps"):
        walk_script.build_diagram(mode="dynamic", velocity=(0.1, 0.0, 0.0))


def test_physics_walk_closed_loop_reads_the_plants_q(walk_script):
    walk = walk_script.build_diagram(mode="physics", steps=(2, 0.2), solver="cascade",
                                     servos=walk_script.Servos(closed_loop=True, feedforward=True))
    simulator = Simulator(walk.diagram)
    simulator.AdvanceTo(0.05)
    context = simulator.get_context()
    dynamic = walk.robot.dynamic
    q_read = dynamic.GetInputPort("position").Eval(dynamic.GetMyContextFromRoot(context))
    plant = walk.physical.plant
    q_plant = plant.GetPositions(plant.GetMyContextFromRoot(context))
    assert np.array_equal(q_read, q_plant)
    device = walk.robot.device
    assert not np.array_equal(q_plant, device.GetOutputPort("state").Eval(device.GetMyContextFromRoot(context)))
    ff = walk.diagram.GetSubsystemByName("feedforward_torque")
    assert np.abs(ff.get_output_port().Eval(ff.GetMyContextFromRoot(context))).max() > 10.0  # the legs' static torques


def test_physics_walk_servos_get_the_velocity_the_device_integrated(walk_script):
    """The servos' desired state is consistent: the velocity they are given is the one that moved the
    device's joints over the last tick, ``q_des(t) − q_des(t − dt) = dt · v_des(t)``, while the walk
    steps (the plan changing at every tick)."""
    walk = walk_script.build_diagram(mode="physics", steps=(2, 0.2), solver="cascade")
    simulator = Simulator(walk.diagram)
    context = simulator.get_context()
    desired = walk.diagram.GetSubsystemByName("desired_state")
    desired_context = desired.GetMyContextFromRoot(context)
    dt = walk.robot.dt
    simulator.AdvanceTo(0.6)
    previous = desired.get_output_port().Eval(desired_context).copy()
    moved = 0.0
    for k in range(1, 21):
        simulator.AdvanceTo(0.6 + k * dt)
        state = desired.get_output_port().Eval(desired_context).copy()
        half = len(state) // 2
        np.testing.assert_allclose(state[:half] - previous[:half], dt * state[half:], rtol=0, atol=1e-12)
        moved = max(moved, np.abs(state[half:]).max())
        previous = state
    assert moved > 0.05  # (the joints are moving: rad/s)
