"""The ``JointLimitator`` (sot-core's rule) and the seed's ``Solver(robot)`` wrapper, on a 2-joint
planar arm written here (and the same arm on a free-flying base)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake import (
    SOT,
    InvalidInput,
    JointLimitator,
    MetaTaskKine6d,
    Solver,
    SolverKine,
    gotoNd,
    limit_joint_velocities,
    load_robot,
    robot,
)

LIMITS = [(-1.0, 0.5), (-0.2, 1.5)]
_INERTIA = '<mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/>'
_INERTIAL = f'<inertial><origin xyz="0.15 0 0"/>{_INERTIA}</inertial>'


def two_joint_urdf() -> str:
    links = [f'<link name="base"><inertial>{_INERTIA}</inertial></link>']
    joints = []
    for i, (low, high) in enumerate(LIMITS, start=1):
        parent = "base" if i == 1 else f"link{i - 1}"
        origin = "0 0 0" if i == 1 else "0.3 0 0"
        links.append(f'<link name="link{i}">{_INERTIAL}</link>')
        joints.append(f'<joint name="joint{i}" type="revolute"><parent link="{parent}"/><child link="link{i}"/>'
                      f'<origin xyz="{origin}"/><axis xyz="0 0 1"/><limit lower="{low}" upper="{high}" effort="50" velocity="3"/></joint>')
    links.append(f'<link name="hand">{_INERTIAL}</link>')
    joints.append('<joint name="hand_joint" type="fixed"><parent link="link2"/><child link="hand"/><origin xyz="0.3 0 0"/></joint>')
    return f'<robot name="two_joint">{"".join(links)}{"".join(joints)}</robot>'


@pytest.fixture(scope="module")
def arm_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("arm") / "two_joint.urdf"
    path.write_text(two_joint_urdf())
    return path


@pytest.fixture(scope="module")
def arm(arm_file):
    return load_robot(arm_file, operational_points={"hand": "hand"}, reference_posture={"joint1": 0.0, "joint2": 0.5})


def sot_core_rule(q, v, lower, upper, step):
    """sot-core's ``JointLimitator::computeControl``, element by element (no free flyer)."""
    out = np.zeros_like(v)
    for i in range(len(v)):
        q_next = q[i] + v[i] * step
        if q_next < upper[i] and q_next > lower[i]:
            out[i] = v[i]
    return out


def test_the_rule_matches_sot_core_on_random_inputs():
    rng = np.random.default_rng(7)
    lower, upper = np.array(LIMITS).T
    for _ in range(200):
        q = rng.uniform(lower - 0.1, upper + 0.1)
        v = rng.normal(scale=20.0, size=2)
        step = rng.uniform(1e-3, 0.05)
        np.testing.assert_array_equal(limit_joint_velocities(q, v, lower, upper, step), sot_core_rule(q, v, lower, upper, step))


def test_a_joint_on_its_limit_gets_exactly_zero_toward_it_and_keeps_its_velocity_away():
    lower, upper = np.array(LIMITS).T
    step = 0.005
    q = upper.copy()  # both joints on their upper limit
    out = limit_joint_velocities(q, np.array([0.3, 0.0]), lower, upper, step)
    assert out[0] == 0.0 and out[1] == 0.0  # toward the limit (and zero) → exactly 0
    out = limit_joint_velocities(q, np.array([-0.3, -2.0]), lower, upper, step)
    np.testing.assert_array_equal(out, [-0.3, -2.0])  # away from it: untouched
    q = lower.copy()
    np.testing.assert_array_equal(limit_joint_velocities(q, np.array([-1e-9, 0.7]), lower, upper, step), [0.0, 0.7])
    # Inside, a step that would land past the limit within one look-ahead is stopped; a smaller one is not.
    q = np.array([0.49, 0.0])
    assert limit_joint_velocities(q, np.array([2.0 + 1e-9, 0.0]), lower, upper, step)[0] == 0.0  # 0.49 + 0.005·2 = 0.5
    assert limit_joint_velocities(q, np.array([1.9, 0.0]), lower, upper, step)[0] == 1.9
    # No limit (±inf) never stops a joint.
    assert limit_joint_velocities(q, np.array([1e6, -1e6]), np.full(2, -np.inf), np.full(2, np.inf), step).tolist() == [1e6, -1e6]


def test_the_system_filters_joints_and_passes_the_free_flyer(arm_file):
    floating = load_robot(arm_file, floating_base=True, reference_posture={"joint1": 0.0, "joint2": 0.5})
    plant = floating.plant
    limitator = JointLimitator(plant, 0.005)
    context = limitator.CreateDefaultContext()
    q = plant.GetDefaultPositions().copy()
    layout = limitator.layout
    q[layout.joints_q] = [LIMITS[0][1], 0.0]  # joint1 on its upper limit
    v = np.zeros(plant.num_velocities())
    v[layout.base_v : layout.base_v + 6] = [1e3, -2.0, 3.0, 4.0, -5.0, 1e4]  # no limit on the base
    v[layout.joints_v] = [0.4, 0.1]
    limitator.GetInputPort("position").FixValue(context, q)
    limitator.GetInputPort("control_in").FixValue(context, v)
    out = limitator.GetOutputPort("control").Eval(context)
    np.testing.assert_array_equal(out[layout.base_v : layout.base_v + 6], v[layout.base_v : layout.base_v + 6])
    np.testing.assert_array_equal(out[layout.joints_v], [0.0, 0.1])
    # A run-time limit (in the Context) moves the rule with it.
    limitator.setLimits([-1.0, -0.2], [1.0, 0.0], context)  # joint1 inside, joint2 on its new limit
    out = limitator.GetOutputPort("control").Eval(context)
    np.testing.assert_array_equal(out[layout.joints_v], [0.4, 0.0])


def reach(model, make_solver, duration=1.5):
    """The hand sent where joint1 would have to pass its upper limit (0.5 rad)."""
    builder = DiagramBuilder()
    bot = robot(builder, model, dt=0.005)
    solver = make_solver(bot)
    task = MetaTaskKine6d("hand", bot, "hand", "hand")
    gotoNd(task, (0.0, 0.55, 0.0), "011", 5.0)
    solver.push(task)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    qs = []
    device = bot.device
    for k in range(1, round(duration / 0.005) + 1):
        simulator.AdvanceTo(k * 0.005)
        qs.append(device.position(simulator.get_context()))
    return np.array(qs)


def test_solver_keeps_the_arm_within_its_limits_where_the_bare_sot_leaves_them(arm):
    lower, upper = np.array(LIMITS).T
    bare = reach(arm, lambda bot: bot.add_solver(SOT("sot", bot.dimension, dt=bot.dt)))
    assert bare[:, 0].max() > upper[0] + 0.05  # the target pulls joint1 well past its limit
    wrapped = reach(arm, lambda bot: Solver(bot))
    assert np.all(wrapped >= lower) and np.all(wrapped <= upper)
    # joint1 is stopped on the last tick that keeps it inside: within one tick's move of its limit.
    assert upper[0] - wrapped[:, 0].max() < 0.005 * 3.0


def test_solver_is_the_seeds_wrapper(arm):
    builder = DiagramBuilder()
    bot = robot(builder, arm, dt=0.005)
    solver = Solver(bot)
    assert isinstance(solver.sot, SOT) and solver.sot.name == "solver"
    assert solver.settings().svd_threshold == 1e-6 and solver.settings().damping == 0.0  # sot-core's "damping" signal
    assert bot.limitator is solver.jointLimitator
    diagram = builder.Build()
    names = {s.get_name() for s in diagram.GetSystems()}
    assert {"solver", "joint_limitator", "device"} <= names
    hqp = Solver(robot(DiagramBuilder(), arm, dt=0.005), solver="hqp")
    assert isinstance(hqp.sot, SolverKine) and hqp.sot.settings().damping == 1e-6


def test_bad_inputs_are_refused_and_change_nothing(arm):
    with pytest.raises(InvalidInput, match="dt"):
        JointLimitator(arm.plant, 0.0)
    with pytest.raises(InvalidInput, match="dt"):
        JointLimitator(arm.plant, float("nan"))
    limitator = JointLimitator(arm.plant, 0.005)
    for bad in (0.0, -1.0, float("nan"), float("inf"), "0.1", True):
        with pytest.raises(InvalidInput, match="step"):
            limitator.setStep(bad)
    assert limitator.settings().step == 0.005
    limitator.setStep(np.int64(1))  # a numpy integer is a number
    assert limitator.settings().step == 1.0
    limitator.setStep(0.005)
    before = limitator.limits()
    for lower, upper, word in (([0.0], [1.0, 1.0], "lower"), ([0.0, 0.0], [1.0, float("nan")], "NaN"),
                               ([0.0, 2.0], [1.0, 1.0], "lower must be"), (["a", 0.0], [1.0, 1.0], "lower"),
                               ([float("inf"), 0.0], [float("inf"), 1.0], "lower must not be inf"),
                               ([0.0, 0.0], [1.0, -float("inf")], "upper must not be -inf"),
                               ([True, 0.0], [1.0, 1.0], "lower")):
        with pytest.raises(InvalidInput, match=word):
            limitator.setLimits(lower, upper)
    for a, b in zip(limitator.limits(), before, strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(InvalidInput, match="solver"):
        Solver(robot(DiagramBuilder(), arm, dt=0.005), solver="qp")
    with pytest.raises(InvalidInput, match="Robot"):
        Solver(arm)
