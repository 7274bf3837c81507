"""Your own robot at the edges: names shared by a link and a joint or by two models, a robot with no
mass or no joint, one far from the origin, SRDFs that do not fit, limits Drake would refuse without
naming the joint, markup in single quotes. Each refusal comes when the call is made, names what is
wrong and leaves the builder as it was."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder

from sotdrake import (
    InvalidInput,
    MetaTaskKine6d,
    MetaTaskKineCom,
    MetaTaskKinePosture,
    RobotDescriptionError,
    add_sot,
    load_robot,
    robot,
)

_INERTIAL = '<inertial><mass value="{m}"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
_BOX = '<collision><origin xyz="0 0 {z}"/><geometry><box size="0.05 0.05 {h}"/></geometry></collision>'


def link(name: str, mass: float = 1.0, box: float = 0.0) -> str:
    shape = _BOX.format(z=box / 2, h=box) if box else ""
    return f'<link name="{name}">{_INERTIAL.format(m=mass) if mass else ""}{shape}</link>'


def revolute(name: str, parent: str, child: str, z: float, axis: str = "0 0 1") -> str:
    return (f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/><origin xyz="0 0 {z}"/>'
            f'<axis xyz="{axis}"/><limit lower="-2" upper="2" effort="50" velocity="2"/></joint>')


def arm(name: str = "arm", mass: float = 1.0, scale: float = 1.0) -> str:
    """``base`` (welded), two revolute joints ``j1``, ``j2`` and a fixed ``tool`` at the tip, links of
    ``scale`` × 0.2 m along z with boxes for collision geometry."""
    length = 0.2 * scale
    return (f'<robot name="{name}">{link("base", mass, length)}{link("l1", mass, length)}{link("l2", mass, length)}{link("tool", mass)}'
            f'{revolute("j1", "base", "l1", length)}{revolute("j2", "l1", "l2", length, "0 1 0")}'
            f'<joint name="tool_joint" type="fixed"><parent link="l2"/><child link="tool"/><origin xyz="0 0 {length}"/></joint>'
            "</robot>")


def systems(builder: DiagramBuilder) -> list[str]:
    return sorted(system.get_name() for system in builder.GetSystems())


def test_a_name_of_a_link_and_of_a_joint_is_the_link(tmp_path):
    """Joint ``base`` joins link ``base`` (welded) to ``arm``: the op point ``base`` is the link, so
    holding it constrains nothing."""
    path = tmp_path / "named.urdf"
    path.write_text(f'<robot name="named">{link("base")}{link("arm")}{revolute("base", "base", "arm", 0.1)}</robot>')
    model = load_robot(path, operational_points={"base": "base"})
    assert model.frame("base").body().name() == "base"
    context = model.plant.CreateDefaultContext()
    model.plant.SetPositions(context, [1.0])  # (the joint's child moves; the link base does not)
    X = model.plant.CalcRelativeTransform(context, model.plant.world_frame(), model.frame("base"))
    np.testing.assert_allclose(X.GetAsMatrix4(), np.eye(4), atol=1e-12)
    bot = robot(DiagramBuilder(), model)
    assert np.all(MetaTaskKine6d("b", bot, "b", "base").dyn.pose_at("b", np.array([1.0])).GetAsMatrix4() == np.eye(4))


def test_two_models_with_a_link_of_the_same_name_are_refused(tmp_path):
    def model(name: str, x: float) -> str:
        body = "<inertial><mass>1</mass></inertial>"
        return (f'<model name="{name}"><pose>{x} 0 0 0 0 0</pose><link name="base">{body}</link><link name="tool">{body}</link>'
                '<joint name="j" type="revolute"><parent>base</parent><child>tool</child><axis><xyz>0 0 1</xyz>'
                "<limit><lower>-1</lower><upper>1</upper></limit></axis></joint></model>")

    path = tmp_path / "two.sdf"
    path.write_text(f'<?xml version="1.0"?><sdf version="1.9"><world name="w">{model("a", 0)}{model("b", 1)}</world></sdf>')
    with pytest.raises(RobotDescriptionError, match=r"the models 'a' and 'b' both have a link named 'base'"):
        load_robot(path)


def test_a_robot_of_no_mass_has_no_com_task_and_nothing_is_added(tmp_path):
    path = tmp_path / "massless.urdf"
    path.write_text(arm("massless", mass=0.0))
    bot = robot(builder := DiagramBuilder(), load_robot(path))
    before = systems(builder)
    for _ in range(2):  # (the same name is free on the second try)
        with pytest.raises(InvalidInput, match="total mass of 0 kg: it has no centre of mass"):
            MetaTaskKineCom(bot)
        assert systems(builder) == before
    MetaTaskKine6d("tool", bot, "tool", "tool")  # (a pose task does not need a mass)


def test_an_op_point_beyond_the_references_range_is_refused_before_anything_is_added(tmp_path):
    path = tmp_path / "giant.urdf"
    path.write_text(arm("giant", scale=400.0))  # the tool 240 m up, the CoM 120 m: a robot in mm read as m
    bot = robot(builder := DiagramBuilder(), load_robot(path))
    add_sot(bot)
    before = systems(builder)
    with pytest.raises(InvalidInput, match=r"MetaTaskKine6d\('tool'\): the op point 'tool' starts at \[0.0, 0.0, 240.0\] m"):
        MetaTaskKine6d("tool", bot, "tool", "tool")
    with pytest.raises(InvalidInput, match="the centre of mass starts at"):
        MetaTaskKineCom(bot)
    assert systems(builder) == before
    MetaTaskKine6d("low", bot, "low", "l1")  # (l1 at 80 m: in range)


def test_a_posture_task_on_a_robot_without_joints_is_refused(tmp_path):
    path = tmp_path / "single.urdf"
    path.write_text(f'<robot name="single">{link("body")}</robot>')
    bot = robot(builder := DiagramBuilder(), load_robot(path, floating_base=True))
    before = systems(builder)
    with pytest.raises(InvalidInput, match="has no joint besides its floating base"):
        MetaTaskKinePosture(bot)
    assert systems(builder) == before


def test_srdfs_that_do_not_fit_the_robot_are_told(tmp_path, caplog):
    path = tmp_path / "arm.urdf"
    path.write_text(arm())
    other = tmp_path / "humanoid.srdf"  # (a humanoid's group state lists its free flyer first)
    other.write_text('<robot name="h"><group_state name="half_sitting" group="all"><joint name="root_joint" '
                     'value="0 0 1 0 0 0 1"/><joint name="leg_left_1_joint" value="0.1"/></group_state></robot>')
    with caplog.at_level(logging.WARNING, logger="sotdrake"):
        load_robot(path, srdf=other)
    assert "an SRDF of another robot?" in caplog.text
    mine = tmp_path / "mine.srdf"
    mine.write_text('<robot name="arm"><end_effector name="gripper" parent_link="no_such_link" group="g"/>'
                    '<group_state name="home" group="g"><joint name="j1" value="0.2 0.3"/><joint name="j2" value="0.5"/>'
                    '</group_state><disable_collisions link1="L1" link2="tool" reason="typo"/></robot>')
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="sotdrake"):
        model = load_robot(path, srdf=mine)
    assert "gripper (no_such_link)" in caplog.text and "gripper" not in model.OperationalPointsMap
    assert "joint 'j1' has 1 positions, the SRDF gives 2 values" in caplog.text
    np.testing.assert_array_equal(model.reference_posture, [0.0, 0.5])
    from sotdrake.collision import CollisionWorld

    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="sotdrake"):
        CollisionWorld(model)
    assert "L1 (l1?)" in caplog.text
    with pytest.raises(RobotDescriptionError, match="a URDF, not an SRDF"):
        load_robot(path, srdf=path)


def test_a_mimic_on_a_fixed_joint_in_single_quotes_is_left_out(tmp_path):
    path = tmp_path / "quoted.urdf"
    path.write_text(arm().replace("</robot>", f"{link('finger')}<joint name='fixed_finger' type='fixed'><parent link='tool'/>"
                                              "<child link='finger'/><mimic joint='j1'></mimic></joint></robot>"))
    assert load_robot(path).nq == 2


@pytest.mark.parametrize("name, text, message", [
    ("nan.sdf", '<?xml version="1.0"?><sdf version="1.9"><model name="m"><link name="base"/><link name="l1"/>'
                '<joint name="j1" type="revolute"><parent>base</parent><child>l1</child><axis><xyz>0 0 1</xyz><limit>'
                "<lower>nan</lower><upper>1</upper></limit></axis></joint></model></sdf>",
     r"joint 'j1': <axis><limit> lower = 'nan' is not a number"),
    ("swapped.xml", '<mujoco model="m"><worldbody><body name="base"><geom type="sphere" size="0.05"/><body name="l1">'
                    '<joint name="j1" type="hinge" axis="0 0 1" range="2 -2" limited="true"/><geom type="sphere" size="0.02"/>'
                    "</body></body></worldbody></mujoco>",
     r"joint 'j1': range: lower = 2.0 must be ≤ upper = -2.0"),
])
def test_bad_limits_in_sdf_and_mjcf_name_the_joint(tmp_path, name, text, message):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(RobotDescriptionError, match=message):
        load_robot(path)


def test_a_continuous_joint_turns_the_short_way_to_its_posture(tmp_path):
    """A URDF ``continuous`` joint (Drake: revolute, no position limits): from −3 rad towards +3 rad
    the posture error is the wrapped 2π − 6 = 0.283 rad (not −6 rad), and the joint gets there turning the
    short way (as sot-core's Pinocchio difference does). Bounded joints keep ``q − q*``."""
    path = tmp_path / "wheel.urdf"
    path.write_text(f'<robot name="wheel">{link("base")}{link("wheel")}{link("arm")}<joint name="spin" type="continuous">'
                    '<parent link="base"/><child link="wheel"/><axis xyz="0 0 1"/></joint>'
                    f'{revolute("lift", "wheel", "arm", 0.1, "0 1 0")}</robot>')
    model = load_robot(path, reference_posture={"spin": -3.0, "lift": 1.9})
    bot = robot(builder := DiagramBuilder(), model)
    sot = add_sot(bot)
    posture = MetaTaskKinePosture(bot)
    posture.feature.setPosture(np.array([3.0, 1.8]))
    posture.gain.setConstant(5.0)
    sot.push(posture)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    e = posture.feature.GetOutputPort("error").Eval(posture.feature.GetMyContextFromRoot(context))
    np.testing.assert_allclose(e, [2 * np.pi - 6.0, 0.1], atol=1e-12)  # (spin wrapped, lift not)
    from pydrake.systems.analysis import Simulator

    simulator = Simulator(diagram, context)
    simulator.AdvanceTo(1.5)
    q = bot.device.GetOutputPort("state").Eval(bot.device.GetMyContextFromRoot(context))
    assert -3.0 - 0.3 < q[0] < -3.0  # the short way: down through −π, ≡ +3
    np.testing.assert_allclose(np.cos(q[0]), np.cos(3.0), atol=1e-3)
    np.testing.assert_allclose(q[1], 1.8, atol=1e-3)


def test_the_dynamic_sot_runs_an_arm_with_unlimited_joints_and_fewer_than_six(tmp_path):
    """``SolverDyn`` on a 2-joint arm whose first joint is ``continuous`` and whose second has no
    ``lower``/``upper``: the joint-limit bounds of the unlimited sides are infinite (they were NaN and
    refused at the first tick), and a 6D task on the tool (6 rows over 2 joints) is taken."""
    from pydrake.systems.analysis import Simulator

    from sotdrake import MetaTaskDyn6d, RobotDyn
    from sotdrake.dynamics.terms import joint_acceleration_bounds

    lower, upper = joint_acceleration_bounds(np.zeros(2), np.array([0.5, -0.5]), np.array([-np.inf, -1.0]), np.array([np.inf, 1.0]),
                                             np.full(2, -2.0), np.full(2, 2.0), 0.1, 1e-3, dt=1e-3, braking=np.array([100.0, 100.0]))
    assert np.all(np.isfinite(lower)) and np.all(np.isfinite(upper)) and np.all(lower <= upper)
    path = tmp_path / "free.urdf"
    path.write_text(f'<robot name="free">{link("base")}{link("l1")}{link("l2")}{link("tool")}'
                    '<joint name="j1" type="continuous"><parent link="base"/><child link="l1"/><origin xyz="0 0 0.2"/>'
                    '<axis xyz="0 0 1"/><limit effort="50" velocity="2"/></joint>'
                    '<joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0 0 0.2"/>'
                    '<axis xyz="0 1 0"/><limit effort="50" velocity="2"/></joint>'
                    '<joint name="tool_joint" type="fixed"><parent link="l2"/><child link="tool"/><origin xyz="0 0 0.2"/>'
                    "</joint></robot>")
    model = load_robot(path, reference_posture={"j2": 0.5})
    assert np.isinf(model.joint_limits()["position_upper"]).all()
    bot = RobotDyn(builder := DiagramBuilder(), model, "dynsimu")
    hand = MetaTaskDyn6d("tool", bot, "tool", "tool", kp=50.0)
    target = bot.dynamic.pose_at("tool", np.array([0.3, 0.8])).translation()  # (reachable: j1 0.3, j2 0.8)
    start = np.linalg.norm(hand.initial_pose().translation() - target)
    hand.feature.selec("000111")  # (the position: 3 joints cannot also hold the orientation)
    hand.featureDes.setPosition(RigidTransform(target))
    bot.sot.push(hand.task.name)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(1.0)
    x = bot.state_port.Eval(bot.state_port.get_system().GetMyContextFromRoot(simulator.get_context()))
    assert np.all(np.isfinite(x))
    reached = bot.dynamic.pose_at("tool", x[:model.nq]).translation()
    assert start > 0.05 and np.linalg.norm(reached - target) < 0.1 * start


def test_a_file_named_talos_is_not_the_catalog_s_talos(tmp_path):
    from sotdrake import RobotDyn

    (folder := tmp_path / "mine").mkdir()
    path = folder / "talos.urdf"
    path.write_text(arm("talos").replace("</robot>", f"{link('left-sole')}<joint name='sole_joint' type='fixed'>"
                                                   "<parent link='tool'/><child link='left-sole'/></joint></robot>"))
    model = load_robot(path)
    bot = RobotDyn(builder := DiagramBuilder(), model, "dynsimu")
    before = systems(builder)
    with pytest.raises(InvalidInput, match="no sole rectangle known for talos's 'left-sole'"):
        bot.add_contact("LF", "left-sole")  # (not TALOS' sole box)
    assert systems(builder) == before
    with pytest.raises(InvalidInput, match="device='physics' is TALOS' torque-driven plant"):
        RobotDyn(DiagramBuilder(), model, "physics")


def test_an_op_point_may_not_take_another_frame_s_name(tmp_path):
    path = tmp_path / "arm.urdf"
    path.write_text(arm())
    bot = robot(builder := DiagramBuilder(), load_robot(path))
    before = systems(builder)
    with pytest.raises(InvalidInput, match="'l1' already names another frame"):
        MetaTaskKine6d("hand", bot, "l1", "tool")  # (the op point 'l1' on the tool would hide the link l1)
    assert systems(builder) == before
    MetaTaskKine6d("hand", bot, "tool", "tool")
    MetaTaskKine6d("link", bot, "l1")


def test_a_q0_beyond_the_joint_limits_is_warned(tmp_path, caplog):
    from sotdrake import RobotDyn

    path = tmp_path / "arm.urdf"
    path.write_text(arm())
    model = load_robot(path)
    for make in (lambda: robot(DiagramBuilder(), model, q0=np.array([0.0, 2.5])),
                 lambda: RobotDyn(DiagramBuilder(), model, "dynsimu", q0=np.array([0.0, 2.5]))):
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger="sotdrake"):
            make()
        assert "j2 = 2.5 not in [-2, 2]" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="sotdrake"):
        robot(DiagramBuilder(), model, q0=np.array([0.0, 2.0]))  # (on the limit: fine)
    assert "beyond the joint limits" not in caplog.text
