"""A robot file, an SRDF or a load option Drake would refuse (or abort on) is refused by
``load_robot`` with a :class:`SotError` naming the file or the option, never a raw exception or a
process exit; and what Drake reads differently from the SoT (a ball joint, an MJCF free joint, a
``<mimic>``) is refused, followed or reported."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from sotdrake import InvalidInput, RobotDescriptionError, SotError, load_robot
from tests.test_own_robot import SDF, chain_urdf, three_link

_SPHERE_INERTIA = ("<inertial><mass>1</mass><inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz>"
                   "<ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial>")


def _write(tmp_path, name: str, text: str, encoding: str = "utf-8"):
    path = tmp_path / name
    path.write_text(text, encoding=encoding)
    return path


@pytest.mark.parametrize("origin", ["0 0 nan", "0 0", "a b c"])
def test_bad_numbers_in_a_urdf_are_a_description_error(tmp_path, origin):
    text = chain_urdf("bad", ["0 0 1", "0 1 0"], 0.3, [(-1, 1), (-1, 1)]).replace('<origin xyz="0 0 0.3"/>', f'<origin xyz="{origin}"/>', 1)
    with pytest.raises(RobotDescriptionError, match=r"bad\.urdf"):
        load_robot(_write(tmp_path, "bad.urdf", text))


def test_drake_checks_become_description_errors(tmp_path):
    """A URDF box of negative size (refused by the loader's own check) and SDF/MJCF joint limits Drake
    asserts on: pydrake raises these as SystemExit, which a script's ``except Exception`` would not catch."""
    box = chain_urdf("box", ["0 0 1"], 0.3, [(-1, 1)], visual='<collision><geometry><box size="-1 0.1 0.1"/></geometry></collision>')
    with pytest.raises(RobotDescriptionError, match=r"box\.urdf: link .base.: a box.s size must be positive"):
        load_robot(_write(tmp_path, "box.urdf", box), meshes=True)
    sdf = SDF.replace("<lower>-1</lower>", "<lower>nan</lower>", 1)
    with pytest.raises(RobotDescriptionError, match=r"arm\.sdf"):
        load_robot(_write(tmp_path, "arm.sdf", sdf))
    mjcf = ('<mujoco model="m"><worldbody><body name="b1"><joint name="h1" type="hinge" axis="0 1 0" range="1 -1" '
            'limited="true"/><geom type="sphere" size="0.05"/></body></worldbody></mujoco>')
    with pytest.raises(RobotDescriptionError, match=r"m\.xml"):
        load_robot(_write(tmp_path, "m.xml", mjcf))


def test_a_file_that_is_not_utf8_or_a_corrupt_mesh(tmp_path):
    text = chain_urdf("latin", ["0 0 1"], 0.3, [(-1, 1)]).replace('name="base"', 'name="basé"').replace('link="base"', 'link="basé"')
    with pytest.raises(RobotDescriptionError, match="not UTF-8"):
        load_robot(_write(tmp_path, "latin.urdf", text, encoding="latin-1"))
    (tmp_path / "bad.dae").write_text("this is not COLLADA")
    mesh = '<visual><geometry><mesh filename="bad.dae"/></geometry></visual>'
    with pytest.raises(RobotDescriptionError, match=r"bad.dae.*does not load"):
        load_robot(_write(tmp_path, "mesh.urdf", chain_urdf("mesh", ["0 0 1"], 0.3, [(-1, 1)], visual=mesh)), meshes=True)


@pytest.mark.parametrize("content", [b"", b"solid x\nnot a facet\nendsolid x\n", b"\0" * 80 + (1000).to_bytes(4, "little") + b"\1" * 100],
                         ids=["empty", "ascii-garbage", "truncated-binary"])
def test_an_stl_without_triangles_is_refused(tmp_path, content):
    (tmp_path / "part.stl").write_bytes(content)
    mesh = '<visual><geometry><mesh filename="part.stl"/></geometry></visual>'
    with pytest.raises(RobotDescriptionError, match=r"part\.stl.*no triangle"):
        load_robot(_write(tmp_path, "stl.urdf", chain_urdf("stl", ["0 0 1"], 0.3, [(-1, 1)], visual=mesh)), meshes=True)


@pytest.mark.parametrize(("value", "message"), [
    ("abc", "not a list of numbers"), ("nan", "not finite"),
])
def test_srdf_values_are_checked(tmp_path, value, message):
    arm = three_link(tmp_path / "arm.urdf")
    srdf = _write(tmp_path, "arm.srdf", f'<robot name="arm"><group_state name="home" group="all"><joint name="joint1" value="{value}"/>'
                  "</group_state></robot>")
    with pytest.raises(RobotDescriptionError, match=rf"arm.srdf.*'home'.*'joint1'.*{message}"):
        load_robot(arm, srdf=srdf)


def test_srdf_that_is_not_xml_and_a_bad_base_pose(tmp_path):
    arm = three_link(tmp_path / "arm.urdf")
    with pytest.raises(RobotDescriptionError, match=r"arm.srdf.*not well-formed"):
        load_robot(arm, srdf=_write(tmp_path, "arm.srdf", "<robot"))
    for pose in ("0 0 1", "0 0 1 0 0 0 0"):
        srdf = _write(tmp_path, "base.srdf", f'<robot name="arm"><group_state name="home" group="all"><joint name="root_joint" '
                      f'value="{pose}"/></group_state></robot>')
        with pytest.raises(RobotDescriptionError, match="seven numbers"):
            load_robot(arm, srdf=srdf, floating_base=True)


@pytest.mark.parametrize("options", [
    {"time_step": -1.0}, {"time_step": float("nan")}, {"time_step": "a"}, {"time_step": True},
    {"srdf": 5}, {"srdf": b"x.srdf"}, {"package_paths": {"p": None}}, {"package_paths": {"p": 5}},
    {"base": "fixed", "floating_base": True}, {"reference_posture": [0.0] * 10},
])
def test_load_options_are_checked(tmp_path, options):
    arm = three_link(tmp_path / "arm.urdf")
    if "reference_posture" in options:  # a free base with a zero quaternion
        options = {**options, "floating_base": True}
    with pytest.raises(InvalidInput):
        load_robot(arm, **options)


def test_catalog_time_step_is_checked():
    with pytest.raises(InvalidInput, match="time_step"):
        load_robot("ur5", time_step=-1e-3)


def test_reference_posture_quaternion_is_normalized(tmp_path):
    arm = three_link(tmp_path / "arm.urdf")
    q = np.array([2.0, 0, 0, 0, 0, 0, 0.5, 0.1, 0.2, 0.3])
    model = load_robot(arm, floating_base=True, reference_posture=q)
    assert model.half_sitting[:4] == pytest.approx([1.0, 0, 0, 0])
    assert model.half_sitting[4:] == pytest.approx(q[4:])


def test_ball_joints_are_refused(tmp_path):
    """Drake's BallRpyJoint has q̇ = N(q) v, which the SoT's device does not integrate."""
    sdf = (f'<sdf version="1.7"><model name="b"><link name="base">{_SPHERE_INERTIA}</link><link name="l1">{_SPHERE_INERTIA}</link>'
           '<joint name="j1" type="ball"><parent>base</parent><child>l1</child></joint></model></sdf>')
    with pytest.raises(RobotDescriptionError, match=r"joint 'j1' is a ball joint"):
        load_robot(_write(tmp_path, "ball.sdf", sdf))


def test_an_mjcf_free_joint_is_a_free_base(tmp_path):
    mjcf = ('<mujoco model="m"><worldbody><body name="b1" pos="0 0 1"><freejoint/><geom type="sphere" size="0.05"/>'
            '<body name="b2" pos="0 0 0.3"><joint name="h2" type="hinge" axis="0 1 0" range="-2 2" limited="true"/>'
            '<geom type="sphere" size="0.05"/></body></body></worldbody></mujoco>')
    model = load_robot(_write(tmp_path, "free.xml", mjcf))
    assert (model.nq, model.nv, model.base) == (8, 7, "free")
    welded = load_robot(_write(tmp_path, "welded.xml", mjcf.replace("<freejoint/>", "")))
    assert (welded.nq, welded.base) == (1, "fixed")


def test_mimic_followers_are_reported(tmp_path, caplog):
    text = chain_urdf("mimic", ["0 0 1", "0 1 0"], 0.3, [(-1, 1), (-1, 1)])
    text = text.replace('name="joint2" type="revolute">', 'name="joint2" type="revolute"><mimic joint="joint1" multiplier="-1"/>')
    with caplog.at_level(logging.WARNING, logger="sotdrake.robots.from_file"):
        load_robot(_write(tmp_path, "mimic.urdf", text))
    assert any("joint2" in r.getMessage() and "velocity_selection" in r.getMessage() for r in caplog.records)


@pytest.mark.parametrize(("multiplier", "offset"), [("-1", None), ("0.5", "0.1"), ("3", None)])
def test_mimic_followers_follow_their_leader_in_the_reference_posture(tmp_path, multiplier, offset):
    """q0 is a posture the physics holds: q_f = m q_l + offset (clipped into the follower's limits)."""
    text = chain_urdf("mimic", ["0 0 1", "0 1 0"], 0.3, [(-1, 1), (-1, 1)])
    mimic = f'<mimic joint="joint1" multiplier="{multiplier}"' + (f' offset="{offset}"' if offset else "") + "/>"
    text = text.replace('name="joint2" type="revolute">', f'name="joint2" type="revolute">{mimic}')
    path = _write(tmp_path, "mimic.urdf", text)
    for given in ({"joint1": 0.4}, [0.4, 0.0], {"joint1": 0.4, "joint2": -0.9}):
        model = load_robot(path, reference_posture=given)
        expected = np.clip(float(multiplier) * 0.4 + float(offset or 0.0), -1, 1)
        assert model.mimic == {"joint2": ("joint1", float(multiplier), float(offset or 0.0))}
        assert model.half_sitting.tolist() == pytest.approx([0.4, expected], abs=1e-15)


def test_a_catalog_robot_s_mimic_fingers_start_coupled():
    model = load_robot("panda")
    q = {name: model.half_sitting[model.plant.GetJointByName(name).position_start()]
         for name in ("panda_finger_joint1", "panda_finger_joint2")}
    assert model.mimic == {"panda_finger_joint2": ("panda_finger_joint1", 1.0, 0.0)}
    assert q["panda_finger_joint2"] == q["panda_finger_joint1"] != 0.0


def test_refusals_are_sot_errors(tmp_path):
    """Every refusal above is also a SotError (one ``except`` for a user's script)."""
    with pytest.raises(SotError):
        load_robot(three_link(tmp_path / "arm.urdf"), time_step=float("inf"))
