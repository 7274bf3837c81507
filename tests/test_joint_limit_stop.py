"""The dynamic SoT's joint limits stop a joint at its limit: the acceleration bounds
(:func:`sotdrake.dynamics.terms.acceleration_bounds`) keep every joint that starts within its limits
and able to stop (``v² ≤ 2 A room``, ``A = v_max/T``) within them at every tick, whatever the
accelerations asked, when the device integrates them as ``RobotDynSimu`` does; and ``SolverDyn``
on TALOS stops an elbow thrown at its limit."""

import numpy as np
import pytest

from sotdrake.dynamics.terms import joint_acceleration_bounds, stopping_speed

TICKS = 1500


@pytest.mark.parametrize("torque_braking", [False, True])
@pytest.mark.parametrize("dt", [1e-3, 5e-3, 1e-2])
def test_a_joint_never_crosses_its_limits_whatever_is_asked(rng, dt, torque_braking):
    """Also with a torque braking below ``v_max/T`` for some joints (their horizon stretched)."""
    joints = 200
    lower = rng.uniform(-2.0, 0.0, joints)
    upper = lower + rng.uniform(0.05, 3.0, joints)
    v_max = rng.uniform(0.5, 6.0, joints)
    horizon, margin = rng.uniform(max(dt, 0.01), 0.2), rng.uniform(0.0, 2e-3)
    braking = rng.uniform(0.05, 2.0, joints) * v_max / horizon if torque_braking else None
    brake = v_max / horizon if braking is None else np.minimum(v_max / horizon, braking)
    q = rng.uniform(lower, upper)
    v = rng.uniform(-v_max, v_max)
    room_up, room_down = upper - q, q - lower  # (start able to stop on both sides)
    v = np.clip(v, -np.sqrt(2 * brake * room_down), np.sqrt(2 * brake * room_up))
    worst = -np.inf
    for _ in range(TICKS):
        lo, up = joint_acceleration_bounds(q, v, lower, upper, -v_max, v_max, horizon, margin, dt=dt, braking=braking)
        asked = rng.choice([-1e5, 1e5], joints) * rng.random(joints)  # (anything: the bounds decide)
        a = np.clip(asked, lo, up)
        v = v + a * dt
        q = q + v * dt
        worst = max(worst, float(np.max(q - upper)), float(np.max(lower - q)))
    assert worst <= 1e-12 * (1 + np.abs(upper).max())


def test_the_stopping_speed_stops_by_the_limit_at_the_braking():
    """From ``v' = stopping_speed``, one tick at ``v'`` then braking at ``A`` (clamped at rest)
    ends within ``room``, and a speed 1 % higher does not."""
    dt, room, brake = 1e-3, np.array([0.1, 1e-3, 0.5]), np.array([60.0, 200.0, 5.0])
    speed = stopping_speed(room, brake, dt)
    for factor, inside in ((1.0, True), (1.01, False)):
        v, travelled = speed * factor, np.zeros(3)
        travelled += v * dt
        while np.any(v > 0):
            v = np.maximum(v - brake * dt, 0.0)
            travelled += v * dt
        assert np.all(travelled <= room * (1 + 1e-9)) == inside
    assert np.all(stopping_speed(np.array([0.0, -0.1, 0.1]), np.array([60.0, 60.0, 0.0]), dt) == 0.0)
    np.testing.assert_allclose(stopping_speed(np.array([0.02]), np.array([np.inf]), dt), 0.02 / dt)


@pytest.mark.slow
def test_solver_dyn_stops_an_elbow_thrown_at_its_limit(talos_model):
    """The right elbow 0.1 rad from its upper limit, moving towards it at 3 rad/s, under the soles,
    the CoM and the posture: it stops within its limit (it went 0.010 rad past it before)."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder

    from sotdrake.dynamics.meta_tasks_dyn import MetaTaskDynCom, MetaTaskDynPosture
    from sotdrake.dynamics.robot_dyn import RobotDyn

    builder = DiagramBuilder()
    robot = RobotDyn(builder, talos_model, "dynsimu", 1e-3)
    for name, op in (("contactLF", "left-sole"), ("contactRF", "right-sole")):
        robot.sot.addContact(robot.add_contact(name, op))
    robot.sot.push(MetaTaskDynCom(robot).task.name)
    robot.sot.push(MetaTaskDynPosture(robot, kp=25.0).task.name)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    device = robot.device.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    joint = talos_model.plant.GetJointByName("arm_right_4_joint")
    iq, iv = joint.position_start(), joint.velocity_start()
    q0, v0 = talos_model.half_sitting.copy(), np.zeros(talos_model.nv)
    upper = talos_model.plant.GetPositionUpperLimits()[iq]
    q0[iq], v0[iv] = upper - 0.1, 3.0
    device.SetDiscreteState(np.concatenate([q0, v0]))
    simulator.Initialize()
    excursion = -np.inf
    for k in range(1, 301):
        simulator.AdvanceTo(k * 1e-3)
        excursion = max(excursion, robot.device.GetOutputPort("state").Eval(device)[iq] - upper)
    assert excursion <= 1e-9


def test_torque_braking_is_what_half_a_joints_effort_gives_its_own_inertia(talos_model):
    from pydrake.systems.framework import DiagramBuilder

    from sotdrake import InvalidInput
    from sotdrake.dynamics.robot_dyn import RobotDyn

    sot = RobotDyn(DiagramBuilder(), talos_model).sot
    plant = talos_model.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, talos_model.half_sitting)
    M = plant.CalcMassMatrix(context)
    effort = talos_model.joint_limits()["effort"]
    for name in ("torso_1_joint", "arm_right_4_joint", "leg_left_4_joint"):
        joint = plant.GetJointByName(name)
        j = joint.velocity_start()
        actuator = next(a for a in plant.GetJointActuatorIndices() if plant.get_joint_actuator(a).joint().index() == joint.index())
        assert sot.braking[j] == pytest.approx(0.5 * effort[int(actuator)] / M[j, j], rel=1e-12)
    assert np.isinf(sot.braking[:6]).all()  # (the floating base: no actuator)
    assert not sot.settings().torque_braking
    with pytest.raises(InvalidInput, match="setTorqueBraking"):
        sot.setTorqueBraking("yes")  # type: ignore[arg-type]
    sot.setTorqueBraking(True)
    assert sot.settings().torque_braking
