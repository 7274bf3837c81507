"""What Drake would read otherwise than a robot file says is refused at load, naming the file and the
element: a floating joint between two links, ``world`` as a joint's child, links left free besides
the one floating base, a negative mass, a file under the name of another format. What it reads as
the file says is followed: a ``<mimic>`` chain in any order, the package folders of an SDF as of a
URDF. An op point never hides another frame of the model."""

from __future__ import annotations

import itertools
import logging

import pytest

from sotdrake import InvalidInput, RobotDescriptionError, load_robot
from sotdrake.exceptions import PackageNotFound, RobotFileNotFound

_I = '<inertial><mass value="{m}"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'
_SDF_I = ("<inertial><mass>{m}</mass><inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz>"
          "<ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial>")


def link(name: str, mass: float | str = 1.0) -> str:
    return f'<link name="{name}">{_I.format(m=mass)}</link>'


def joint(name: str, parent: str, child: str, kind: str = "revolute", mimic: str = "") -> str:
    limit = '<axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="1" velocity="1"/>' if kind == "revolute" else ""
    return (f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/><origin xyz="0 0 0.1"/>'
            f"{limit}{mimic}</joint>")


def chain(names: list[str], extra: str = "") -> str:
    """A URDF of links ``names`` joined in a chain by revolute joints ``j0``, ``j1`` …"""
    joints = "".join(joint(f"j{i}", parent, child) for i, (parent, child) in enumerate(itertools.pairwise(names)))
    return f'<robot name="r">{"".join(map(link, names))}{joints}{extra}</robot>'


def sdf_link(name: str, mass: float = 1.0, visual: str = "") -> str:
    return f'<link name="{name}">{_SDF_I.format(m=mass)}{visual}</link>'


def sdf_model(links: str, name: str = "m", parent: str = "a", child: str = "b") -> str:
    """An SDF model of ``links`` where a revolute joint ``j_<name>`` attaches ``child`` to ``parent``."""
    return (f'<model name="{name}">{links}<joint name="j_{name}" type="revolute"><parent>{parent}</parent><child>{child}</child>'
            "<axis><xyz>0 0 1</xyz><limit><lower>-1</lower><upper>1</upper></limit></axis></joint></model>")


def write(folder, name: str, text: str):
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(text)
    return path


# --- joints Drake would read otherwise -------------------------------------------------------------

def test_a_floating_joint_between_two_links_is_refused_naming_it(tmp_path):
    text = chain(["base", "arm"], link("tool") + joint("tool_joint", "arm", "tool", "floating"))
    with pytest.raises(RobotDescriptionError, match=r"r\.urdf: joint 'tool_joint' is a floating joint between the links 'arm' and 'tool'"):
        load_robot(write(tmp_path, "r.urdf", text), floating_base=False)


def test_a_floating_joint_from_world_is_the_free_base(tmp_path):
    text = chain(["base", "arm"], '<link name="world"/>' + joint("free", "world", "base", "floating"))
    model = load_robot(write(tmp_path, "r.urdf", text))
    assert model.base == "free" and model.nv == 7


def test_world_as_a_joint_s_child_is_refused_naming_the_file_and_the_joint(tmp_path):
    text = chain(["world", "b"], '<link name="base"/>' + joint("up", "base", "world", "fixed"))
    with pytest.raises(RobotDescriptionError, match=r"r\.urdf: joint 'up' has the link 'world' as its child"):
        load_robot(write(tmp_path, "r.urdf", text))


def test_a_mimic_chain_written_followers_first_starts_coupled(tmp_path):
    """j2 mimics j1 which mimics j0, j2 written first: q0 sets j1 from j0, then j2 from j1."""
    links = "".join(link(f"l{i}") for i in range(4))
    joints = (joint("j2", "l2", "l3", mimic='<mimic joint="j1" multiplier="2"/>')
              + joint("j1", "l1", "l2", mimic='<mimic joint="j0" multiplier="2"/>') + joint("j0", "l0", "l1"))
    model = load_robot(write(tmp_path, "r.urdf", f'<robot name="r">{links}{joints}</robot>'), reference_posture={"j0": 0.1})
    q = {name: model.reference_posture[model.plant.GetJointByName(name).position_start()] for name in ("j0", "j1", "j2")}
    assert q == pytest.approx({"j0": 0.1, "j1": 0.2, "j2": 0.4})


def test_a_mimic_cycle_is_refused_naming_its_joints(tmp_path):
    links = "".join(link(f"l{i}") for i in range(3))
    joints = joint("j0", "l0", "l1", mimic='<mimic joint="j1"/>') + joint("j1", "l1", "l2", mimic='<mimic joint="j0"/>')
    with pytest.raises(RobotDescriptionError, match=r"r\.urdf: the <mimic> joints 'j0' → 'j1' → 'j0' .*cycle"):
        load_robot(write(tmp_path, "r.urdf", f'<robot name="r">{links}{joints}</robot>'))


# --- bodies left free ------------------------------------------------------------------------------

def test_an_sdf_link_no_joint_attaches_is_refused_naming_it(tmp_path):
    text = f'<sdf version="1.7">{sdf_model(sdf_link("a") + sdf_link("b") + sdf_link("loose"))}</sdf>'
    for floating_base in (False, True):
        with pytest.raises(RobotDescriptionError, match=r"m\.sdf: model 'm' has 2 links no joint attaches, \['a', 'loose'\]"):
            load_robot(write(tmp_path, "m.sdf", text), floating_base=floating_base)


def test_two_free_bodies_are_refused_at_load_naming_them(tmp_path):
    mjcf = ('<mujoco model="m"><worldbody><body name="a"><freejoint/><geom type="sphere" size="0.1"/><body name="b" pos="0 0 0.2">'
            '<joint name="jb" type="hinge" axis="0 1 0"/><geom type="sphere" size="0.1"/></body></body>'
            '<body name="d"><freejoint/><geom type="sphere" size="0.1"/></body></worldbody></mujoco>')
    with pytest.raises(RobotDescriptionError, match=r"m\.xml: 2 bodies would be free, \['a', 'd'\]"):
        load_robot(write(tmp_path, "m.xml", mjcf))
    models = sdf_model(sdf_link("a") + sdf_link("b"), "m1") + sdf_model(sdf_link("a2") + sdf_link("b2"), "m2", "a2", "b2")
    path = write(tmp_path, "two.sdf", f'<sdf version="1.9"><world name="w">{models}</world></sdf>')
    assert load_robot(path, floating_base=False).nv == 2  # (each model's root welded)
    with pytest.raises(RobotDescriptionError, match=r"two\.sdf: 2 bodies would be free, \['a', 'a2'\]"):
        load_robot(path, floating_base=True)


# --- masses ----------------------------------------------------------------------------------------

def test_a_negative_mass_is_refused_naming_the_link_in_every_format(tmp_path):
    with pytest.raises(RobotDescriptionError, match=r"r\.urdf: link 'b': mass -1 must be a finite number ≥ 0"):
        load_robot(write(tmp_path, "r.urdf", chain(["a", "b"]).replace(link("b"), link("b", -1))))
    sdf = f'<sdf version="1.7">{sdf_model(sdf_link("a") + sdf_link("b", -1.0))}</sdf>'
    with pytest.raises(RobotDescriptionError, match=r"m\.sdf: link 'b': mass -1.0 must be a finite number ≥ 0"):
        load_robot(write(tmp_path, "m.sdf", sdf))
    mjcf = ('<mujoco model="m"><worldbody><body name="arm"><joint name="h" type="hinge"/>'
            '<geom type="sphere" size="0.1" mass="-2"/></body></worldbody></mujoco>')
    with pytest.raises(RobotDescriptionError, match=r"m\.xml: body 'arm': mass -2 \(<geom>\) must be a finite number ≥ 0"):
        load_robot(write(tmp_path, "m.xml", mjcf))


def test_a_zero_mass_and_an_inertia_drake_finds_unphysical_load(tmp_path):
    massless = chain(["a", "b", "c"]).replace(_I.format(m=1.0), _I.format(m=0), 2)
    assert load_robot(write(tmp_path, "zero.urdf", massless)).nv == 2
    lopsided = chain(["a", "b"]).replace('ixx="0.01"', 'ixx="1"')  # (breaks the triangle inequality)
    assert load_robot(write(tmp_path, "lopsided.urdf", lopsided)).nv == 1


# --- names and formats -----------------------------------------------------------------------------

def test_a_folder_named_like_a_file_is_said_to_be_a_folder(tmp_path):
    (tmp_path / "robot.urdf").mkdir()
    write(tmp_path / "robot.urdf", "arm.urdf", chain(["a", "b"]))
    with pytest.raises(RobotFileNotFound, match=r"robot\.urdf' is a folder, not a file \(it holds arm\.urdf\)"):
        load_robot(tmp_path / "robot.urdf")


@pytest.mark.parametrize(("name", "text", "message"), [
    ("r.sdf", chain(["a", "b"]), r"r\.sdf: a URDF file \(root element <robot>\).*rename it .* to 'r\.urdf'"),
    ("m.sdf", '<mujoco model="m"><worldbody/></mujoco>', r"m\.sdf: a MJCF file \(root element <mujoco>\).*to 'm\.xml'"),
    ("r.mjcf", chain(["a", "b"]), r"r\.mjcf: a URDF file \(root element <robot>\).*to 'r\.urdf'"),
    ("s.urdf", '<sdf version="1.7"><model name="m"/></sdf>', r"s\.urdf: a SDF file \(root element <sdf>\).*to 's\.sdf'"),
])
def test_a_file_under_another_format_s_name_is_refused_naming_its_format(tmp_path, name, text, message):
    with pytest.raises(RobotDescriptionError, match=message):
        load_robot(write(tmp_path, name, text))


_OBJ = "v 0 0 0\nv 0.05 0 0\nv 0 0.05 0\nv 0 0 0.05\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def test_an_sdf_in_a_ros_layout_finds_its_package_as_a_urdf_does(tmp_path):
    package = tmp_path / "ws" / "src" / "my_robot_description"
    write(package / "meshes", "box.obj", _OBJ)
    visual = ('<visual name="v"><geometry><mesh><uri>package://my_robot_description/meshes/box.obj</uri></mesh></geometry>'
              "</visual>")
    sdf = write(package / "sdf", "m.sdf", f'<sdf version="1.7">{sdf_model(sdf_link("a") + sdf_link("b", visual=visual))}</sdf>')
    model = load_robot(sdf, meshes=True)
    assert model.scene_graph is not None and model.scene_graph.model_inspector().num_geometries() == 1
    write(package / "sdf", "lost.sdf", sdf.read_text().replace("package://my_robot_description/", "package://no_such_description/"))
    with pytest.raises(PackageNotFound, match=r"unknown package 'no_such_description'.*package_paths"):
        load_robot(package / "sdf" / "lost.sdf", meshes=True)


# --- op points that would hide a frame -------------------------------------------------------------

def test_an_op_point_named_like_another_frame_is_refused_naming_both(tmp_path):
    path = write(tmp_path, "r.urdf", chain(["l0", "l1", "l2", "l3"]))
    with pytest.raises(InvalidInput, match=r"op point 'l1' on 'l3': 'l1' already names another frame of r \('l1'\)"):
        load_robot(path, operational_points={"l1": "l3"})
    with pytest.raises(InvalidInput, match=r"op point 'j0' on 'l3': 'j0' already names another frame"):
        load_robot(path, operational_points={"j0": "l3"})  # (a joint's name is its child frame)
    model = load_robot(path, operational_points={"l3": "l3", "tip": "l3", "j2": "l3"})  # (a name of its own frame: fine)
    assert model.frame("l1").name() == "l1"


def test_a_catalog_robot_s_op_point_may_not_hide_a_frame_either():
    with pytest.raises(InvalidInput, match=r"op point 'wrist_1_link' on 'tool0'"):
        load_robot("ur5", operational_points={"wrist_1_link": "tool0"})


def test_an_srdf_end_effector_named_like_another_frame_is_left_out_with_a_warning(tmp_path, caplog):
    path = write(tmp_path, "r.urdf", chain(["l0", "l1", "l2", "l3"]))
    write(tmp_path, "r.srdf", '<robot name="r"><end_effector name="l1" parent_link="l3" group="g"/>'
          '<end_effector name="hand" parent_link="l3" group="g"/></robot>')
    with caplog.at_level(logging.WARNING, logger="sotdrake.robots.model_defaults"):
        model = load_robot(path)
    assert "l1" not in model.OperationalPointsMap and model.OperationalPointsMap["hand"] == "l3"
    assert model.frame("l1").name() == "l1"
    assert any("l1 (l3, hiding l1)" in record.getMessage() for record in caplog.records)


def test_the_default_waist_of_a_floating_base_is_the_model_s_own_waist_link(tmp_path):
    model = load_robot(write(tmp_path, "w.urdf", chain(["l0", "waist", "l2"])), floating_base=True)
    assert model.frame("waist").name() == "waist"
    plain = load_robot(write(tmp_path, "p.urdf", chain(["l0", "l1", "l2"])), floating_base=True)
    assert plain.OperationalPointsMap["waist"] == "root_joint" and plain.frame("waist").name() == "l0"
