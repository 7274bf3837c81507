"""The multibody ZMP: the formula against two point masses and against Drake's inverse dynamics,
the legs' mass model against Drake's kinematics, and the corrected CoM plan."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.multibody.tree import MultibodyForces
from pydrake.systems.analysis import Simulator

from sotdrake.walking import GaitParameters, WalkCommand, initial_plan, leg_masses, motion_zmp, replan, zmp_from_momentum
from sotdrake.walking.com_planner import GRAVITY
from sotdrake.walking.multibody_zmp import point_masses_zmp
from tests.test_walking import START


@pytest.fixture(scope="module")
def walk_script():
    from sotdrake.scenarios import walk

    return walk


@pytest.fixture(scope="module")
def legs(talos_model):
    return leg_masses(talos_model, talos_model.half_sitting)


@pytest.fixture(scope="module")
def talos_model():
    from sotdrake import load_talos

    return load_talos("reduced")


def test_zmp_from_momentum_is_the_point_masses_zmp(rng):
    # Two point masses: their CoM, its acceleration and the angular momentum's rate about it give the same ZMP.
    for _ in range(5):
        m = rng.uniform(1.0, 50.0, 2)
        x = rng.normal(size=(2, 3)) + [0.0, 0.0, 1.0]
        a = rng.normal(size=(2, 3))
        c = m @ x / m.sum()
        dL = sum(mi * np.cross(xi - c, ai) for mi, xi, ai in zip(m, x, a, strict=True))  # d/dt Σ m (x − c) × ẋ
        expected = point_masses_zmp(m, x, a)
        assert np.allclose(zmp_from_momentum(c, m @ a / m.sum(), dL, m.sum()), expected, atol=1e-12)
    # One mass at rest: under it; accelerating forward at height z: z a / g behind it.
    assert np.allclose(zmp_from_momentum([0.1, 0.2, 0.8], [1.0, 0.0, 0.0], np.zeros(3), 10.0), [0.1 - 0.8 / GRAVITY, 0.2])


def test_motion_zmp_matches_drakes_inverse_dynamics(talos_model):
    # A known motion: the base translating and every leg joint swinging (sinusoids). The momentum's
    # finite differences against the ground wrench that Drake's inverse dynamics needs at the base.
    plant = talos_model.plant
    q0 = talos_model.half_sitting
    nv = plant.num_velocities()
    legs = [j for j in (plant.get_joint(i) for i in plant.GetJointIndices()) if j.name().startswith("leg_") and j.num_positions() == 1]
    amplitude, frequency = 0.3, 2.0

    def motion(t):
        q, v, vdot = q0.copy(), np.zeros(nv), np.zeros(nv)
        q[4:7] += [0.05 * t**2, -0.02 * t**2, 0.0]  # base translation (world): quaternion first, then p
        v[3:6], vdot[3:6] = [0.1 * t, -0.04 * t, 0.0], [0.1, -0.04, 0.0]
        for k, joint in enumerate(legs):
            phase = frequency * t + k
            q[joint.position_start()] += amplitude * np.sin(phase)
            v[joint.velocity_start()] = amplitude * frequency * np.cos(phase)
            vdot[joint.velocity_start()] = -amplitude * frequency**2 * np.sin(phase)
        return q, v, vdot

    h, context = 1e-4, plant.CreateDefaultContext()
    for t in (0.3, 0.7):
        times = t + h * np.arange(-2, 3)
        zmp, _ = motion_zmp(plant, times, np.array([motion(s)[0] for s in times]))
        q, v, vdot = motion(t)
        plant.SetPositions(context, q)
        plant.SetVelocities(context, v)
        gravity = MultibodyForces(plant)
        plant.CalcForceElementsContribution(context, gravity)
        tau = plant.CalcInverseDynamics(context, vdot, gravity)
        n, f = tau[:3], tau[3:6]  # the base's wrench about its origin (world): what the ground must give
        base = q[4:7]
        expected = [base[0] - (n[1] + base[2] * f[0]) / f[2], base[1] + (n[0] - base[2] * f[1]) / f[2]]
        assert np.allclose(zmp[2], expected, atol=2e-4), (t, zmp[2], expected)
        assert abs(zmp[2][0] - plant.CalcCenterOfMassPositionInWorld(context)[0]) > 0.005  # the legs swing: not the CoM


def test_leg_share_is_the_legs_com_motion_for_a_sole_motion(talos_model, legs):
    # K_l against Drake: move the left sole by (1, 0, 0.5) cm with the leg's joints alone (Drake's
    # inverse kinematics, sole orientation kept), the leg's CoM moves by K_l times that, to first order.
    from pydrake.math import RotationMatrix
    from pydrake.multibody.inverse_kinematics import InverseKinematics
    from pydrake.multibody.tree import ModelInstanceIndex
    from pydrake.solvers import Solve

    plant = talos_model.plant
    q0 = talos_model.half_sitting
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, q0)
    sole = plant.GetFrameByName("left_sole_link")
    X = sole.CalcPoseInWorld(context)
    delta = np.array([0.01, 0.0, 0.005])
    ik = InverseKinematics(plant)
    q = ik.q()
    target = X.translation() + delta
    ik.AddPositionConstraint(sole, np.zeros(3), plant.world_frame(), target - 1e-7, target + 1e-7)
    ik.AddOrientationConstraint(sole, RotationMatrix(), plant.world_frame(), X.rotation(), 1e-7)
    for joint in (plant.get_joint(i) for i in plant.GetJointIndices()):
        if not joint.name().startswith("leg_left_"):
            start, size = joint.position_start(), joint.num_positions()
            ik.prog().AddBoundingBoxConstraint(q0[start:start + size], q0[start:start + size], q[start:start + size])
    ik.prog().SetInitialGuess(q, q0)
    result = Solve(ik.prog())
    assert result.is_success()
    bodies = [plant.get_body(b) for i in range(plant.num_model_instances()) for b in plant.GetBodyIndices(ModelInstanceIndex(i))
              if plant.get_body(b).name().startswith("leg_left_")]

    def leg_com(positions):
        plant.SetPositions(context, positions)
        moments = [b.get_mass(context) * b.EvalPoseInWorld(context).multiply(b.CalcCenterOfMassInBodyFrame(context)) for b in bodies]
        return sum(moments) / sum(b.get_mass(context) for b in bodies)

    moved = leg_com(result.GetSolution(q)) - leg_com(q0)
    assert np.linalg.norm(moved) > 0.003
    assert np.allclose(moved, legs.share["left"] @ delta, atol=3e-4)
    assert legs.leg_mass == pytest.approx(17.56, abs=0.01)
    assert 0.3 < legs.share["left"][0, 0] < 0.5  # the leg's CoM follows 40 % of the sole's forward motion


def test_corrected_plan_puts_the_legs_zmp_on_the_reference(legs):
    gait = GaitParameters()
    command = WalkCommand(steps=((0.2, 0.0, 0.0),) * 4)
    errors = {}
    for name, model in (("lipm", None), ("corrected", legs)):
        plan = replan(initial_plan(START, gait, legs=model), command, 0.0, gait, legs=model)
        t = np.arange(gait.start_duration + 0.0037, plan.end - 0.5, 0.01)  # walking (after the start's ZMP jump), off the knots
        reference = np.array([plan.zmp_reference(s) for s in t])
        lipm = np.array([plan.com.zmp(s) for s in t])
        model_zmp = lipm + legs.zmp_error(t, plan.com, plan.feet, plan.feet_acceleration)
        errors[name] = np.abs(model_zmp - reference).max()
        if model is None:
            assert np.abs(lipm - reference).max() < 0.003  # the pendulum's ZMP is on the reference
        else:
            assert plan.lipm_zmp is not None
    assert errors["lipm"] > 0.03  # the legs' swing moves the whole body's ZMP by centimetres
    assert errors["corrected"] < 0.003


def test_the_sots_motion_has_its_multibody_zmp_closer_to_the_reference_with_the_correction(walk_script):
    # A short kinematic walk (one step of 0.2 m), planned by the pendulum alone then with the legs:
    # the ZMP of the whole body's motion the SoT realises (Drake's momentum), along the walking
    # direction, against the reference over the swing.
    errors = {}
    for corrected in (False, True):
        walk = walk_script.build_diagram(steps=(1, 0.2), solver="cascade", dt=2e-3, gait=GaitParameters(start_duration=0.4),
                                         multibody_zmp=corrected)
        assert (walk.pg.legs is not None) == corrected
        simulator = Simulator(walk.diagram)
        simulator.AdvanceTo(1.2)  # the step lifts off at 0.4 s and lands at 1.1 s
        summary, trace = walk_script.summarize(walk, simulator, 1.2, 1.0)
        assert summary["max_foot_tracking_error_m"] < 1e-3 and summary["max_com_tracking_error_m"] < 1e-3
        swing = np.flatnonzero((trace["time"] >= 0.4) & (trace["time"] <= 1.1))[::5]
        zmp, _ = motion_zmp(walk.robot.model.plant, trace["time"][swing], trace["q_device"][swing])
        errors[corrected] = np.abs(zmp - trace["pg_zmp_reference"][swing])[2:-2, 0].max()
    assert errors[False] > 0.01, errors
    assert errors[True] < 0.4 * errors[False], errors


def test_the_physics_walk_plans_with_the_legs_by_default(walk_script):
    assert walk_script.build_diagram(mode="physics", steps=(1, 0.2), solver="cascade").pg.legs is not None
    assert walk_script.build_diagram(mode="physics", steps=(1, 0.2), solver="cascade", multibody_zmp=False).pg.legs is None
    assert walk_script.build_diagram(steps=(1, 0.2), solver="cascade").pg.legs is None  # kinematic: the pendulum's plan


@pytest.mark.slow
def test_first_physics_step_of_0_2_m_on_position_servos(walk_script):
    # CI's physics walk: the first step (0.2 m, lift-off at 0.4 s, touch-down at 1.1 s), the walk's
    # default servos and the corrected plan, then 0.3 s on both feet.
    walk = walk_script.build_diagram(mode="physics", steps=(1, 0.2), solver="cascade", gait=GaitParameters(start_duration=0.4))
    simulator = Simulator(walk.diagram)
    simulator.AdvanceTo(1.4)
    summary, trace = walk_script.summarize(walk, simulator, 1.4, 1.0)
    assert summary["steps"] == 1 and not summary["fell"]
    assert summary["max_slip_per_step_m"] < 5e-3
    assert summary["min_cop_margin_m"] > 0.0
    right = trace["contact"][:, 5]  # the right sole's normal force: in the air, then carrying weight again
    swing = (trace["time"] > 0.6) & (trace["time"] < 0.9)
    assert right[swing].max() < 1.0 and right[-1] > 100.0


def test_stabilizer_takes_the_zmp_reference_when_it_is_given():
    # A multibody plan's pendulum ZMP is off the reference: connected, the reference is what the CoP is compared with.
    from sotdrake.walking import ComStabilizer

    stabilizer = ComStabilizer(0.877, 1e-3, com_gain=8.0, zmp_gain=2.0)
    context = stabilizer.CreateDefaultContext()
    plan = np.array([0.1, -0.05, 0.877])
    for port, value in (("com_reference", plan), ("com_velocity_reference", np.zeros(3)), ("measured_com", plan),
                        ("com_acceleration_reference", [0.3, 0.0, 0.0]), ("measured_cop", [0.07, -0.05])):
        stabilizer.GetInputPort(port).FixValue(context, value)

    def rate():
        return (stabilizer.EvalUniquePeriodicDiscreteUpdate(context).get_vector().get_value()) / 1e-3

    pendulum_zmp = plan[:2] - np.array([0.3, 0.0]) * 0.877 / GRAVITY
    assert np.allclose(rate(), -2.0 * (pendulum_zmp - [0.07, -0.05]))
    stabilizer.GetInputPort("zmp_reference").FixValue(context, [0.1, -0.05])
    assert np.allclose(rate(), -2.0 * (np.array([0.1, -0.05]) - [0.07, -0.05]))
