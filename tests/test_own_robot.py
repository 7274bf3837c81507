"""Your own robot: load a URDF by path, build a stack from ``sotdrake``'s public names only, run it.

The robots are written here: a 3-link planar arm and a 7-DoF arm (alternate z and y axes, a fixed
``hand`` link at the tip). The run asserts behaviour: the hand error falls a lot within ~1 s and
no joint leaves its limits.
"""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from sotdrake import (
    FrameNotFound,
    InvalidInput,
    MetaTaskKine6d,
    MetaTaskKineJointLimits,
    MetaTaskKinePosture,
    PackageNotFound,
    RobotDescriptionError,
    RobotFileNotFound,
    RobotModel,
    RobotNotFound,
    add_sot,
    gotoNd,
    load_robot,
    robot,
)

ROOT = Path(__file__).resolve().parents[1]

_INERTIAL = '<inertial><origin xyz="{c}"/><mass value="1"/><inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>'


def chain_urdf(name: str, axes: list[str], length: float, limits: list[tuple[float, float]], visual: str = "", extra: str = "") -> str:
    """A serial chain: ``base`` then one revolute joint per axis (``joint1``…), links of
    ``length`` m along z (x for a planar arm), a fixed ``hand`` link at the tip."""
    planar = all(a == "0 0 1" for a in axes)
    step = f"{length} 0 0" if planar else f"0 0 {length}"
    half = f"{length / 2} 0 0" if planar else f"0 0 {length / 2}"
    links = [f'<link name="base">{_INERTIAL.format(c="0 0 0")}{visual}</link>']
    joints = []
    for i, (axis, (low, high)) in enumerate(zip(axes, limits, strict=True), start=1):
        parent = "base" if i == 1 else f"link{i - 1}"
        origin = "0 0 0" if i == 1 else step
        links.append(f'<link name="link{i}">{_INERTIAL.format(c=half)}</link>')
        joints.append(
            f'<joint name="joint{i}" type="revolute"><parent link="{parent}"/><child link="link{i}"/>'
            f'<origin xyz="{origin}"/><axis xyz="{axis}"/>'
            f'<limit lower="{low}" upper="{high}" effort="50" velocity="2"/></joint>'
        )
    links.append(f'<link name="hand">{_INERTIAL.format(c="0 0 0")}</link>')
    joints.append(
        f'<joint name="hand_joint" type="fixed"><parent link="link{len(axes)}"/><child link="hand"/><origin xyz="{step}"/></joint>'
    )
    return f'<robot name="{name}">{"".join(links)}{"".join(joints)}{extra}</robot>'


def three_link(path: Path) -> Path:
    path.write_text(chain_urdf("three_link", ["0 0 1"] * 3, 0.3, [(-2.0, 2.0)] * 3))
    return path


def seven_dof(path: Path) -> Path:
    axes = ["0 0 1", "0 1 0"] * 3 + ["0 0 1"]
    limits = [(-2.8, 2.8), (-1.7, 1.7), (-2.8, 2.8), (-2.5, 0.1), (-2.8, 2.8), (-0.1, 2.5), (-2.8, 2.8)]
    path.write_text(chain_urdf("arm7", axes, 0.2, limits))
    return path


def run_reach(model: RobotModel, target: np.ndarray, duration: float = 1.0) -> tuple[float, float, float]:
    """Hand task below the joint limits, on the hierarchical QP; returns the hand's initial and
    final distance to ``target`` and the largest excursion past a joint limit (≤ 0 inside)."""
    builder = DiagramBuilder()
    bot = robot(builder, model)
    sot = add_sot(bot, solver="hqp")
    limits = MetaTaskKineJointLimits(bot)
    hand = MetaTaskKine6d("hand", bot, "hand", "hand")
    gotoNd(hand, target, "111", 6.0)
    sot.push(limits)
    sot.push(hand)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    device = bot.device.GetMyContextFromRoot(context)
    lower, upper = model.plant.GetPositionLowerLimits(), model.plant.GetPositionUpperLimits()

    def hand_distance() -> float:
        q = bot.device.GetOutputPort("state").Eval(device)
        return float(np.linalg.norm(bot.dynamic.pose_at("hand", q).translation() - target))

    start = hand_distance()
    excursion = -np.inf
    for t in np.arange(0.05, duration + 1e-9, 0.05):
        simulator.AdvanceTo(t)
        q = bot.device.GetOutputPort("state").Eval(device)
        excursion = max(excursion, float(np.max(np.concatenate([lower - q, q - upper]))))
    return start, hand_distance(), excursion


@pytest.mark.parametrize("floating_base", [False, True])
def test_three_link_arm_by_path_reaches(tmp_path, floating_base):
    model = load_robot(three_link(tmp_path / "three_link.urdf"), floating_base=floating_base)
    assert model.nv == 3 + (6 if floating_base else 0)
    assert "hand" in model.OperationalPointsMap
    start, end, excursion = run_reach(model, np.array([0.5, 0.4, 0.0]))
    assert end < 0.05 * start
    assert excursion <= 1e-9


@pytest.mark.parametrize("floating_base", [False, True])
def test_seven_dof_arm_by_path_reaches_within_limits(tmp_path, floating_base):
    model = load_robot(str(seven_dof(tmp_path / "arm7.urdf")), floating_base=floating_base)
    assert model.nv == 7 + (6 if floating_base else 0)
    # joint4 and joint6 start on a bound's side of zero: the reach bends them against it
    start, end, excursion = run_reach(model, np.array([0.35, 0.2, 0.9]))
    assert end < 0.1 * start
    assert excursion <= 1e-9


def erd_robot(relative: str) -> Path:
    import importlib.metadata

    dist = importlib.metadata.distribution("example-robot-data")
    return Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots"))) / relative


def test_example_robot_data_panda_by_path():
    path = erd_robot("panda_description/urdf/panda.urdf")
    model = load_robot(path)  # its SRDF is found in ../srdf/: end effector and 'default' posture
    assert model.OperationalPointsMap["end_effector"] == "panda_hand_tcp"
    catalog = load_robot("panda")
    np.testing.assert_allclose(model.reference_posture, catalog.reference_posture)
    X = MetaTaskKine6d  # noqa: F841  (public name)
    tcp = model.plant.CalcRelativeTransform(model.plant.CreateDefaultContext(), model.plant.world_frame(), model.frame("end_effector"))
    assert np.isfinite(tcp.translation()).all()


def test_example_robot_data_ur5_by_path_with_meshes_reaches():
    path = erd_robot("ur_description/urdf/ur5_robot.urdf")
    model = load_robot(path, meshes=True, operational_points={"hand": "tool0"}, reference_posture=[0.0, -1.0, 1.0, -1.5, -1.5, 0.0])
    assert model.scene_graph is not None  # package://example-robot-data/… resolved, meshes converted
    q0 = model.reference_posture
    X = model.plant.CalcRelativeTransform(_context_at(model, q0), model.plant.world_frame(), model.frame("hand"))
    target = X.translation() + [0.05, 0.1, -0.1]
    start, end, excursion = run_reach(model, target)
    assert end < 0.1 * start
    assert excursion <= 1e-9


def _context_at(model: RobotModel, q: np.ndarray):
    context = model.plant.CreateDefaultContext()
    model.plant.SetPositions(context, q)
    return context


def test_catalog_names_still_load():
    talos = load_robot("talos")
    assert talos.nq == 39 and talos.OperationalPointsMap["right-wrist"] == "arm_right_7_joint"


def test_package_uris_resolved_from_package_xml_and_package_paths(tmp_path):
    package = tmp_path / "src" / "my_arm_description"
    (package / "urdf").mkdir(parents=True)
    (package / "meshes").mkdir()
    (package / "package.xml").write_text("<package><name>my_arm_description</name></package>")
    (package / "meshes" / "box.stl").write_text(_ASCII_STL)
    visual = '<visual><geometry><mesh filename="package://my_arm_description/meshes/box.stl"/></geometry></visual>'
    urdf = package / "urdf" / "arm.urdf"
    urdf.write_text(chain_urdf("arm", ["0 0 1"] * 2, 0.3, [(-1.0, 1.0)] * 2, visual))
    assert load_robot(urdf, meshes=True).scene_graph is not None
    # elsewhere, without a package.xml: package_paths says where the package is
    (package / "package.xml").unlink()
    moved = tmp_path / "elsewhere" / "arm.urdf"
    moved.parent.mkdir()
    moved.write_text(urdf.read_text())
    with pytest.raises(PackageNotFound, match=r"my_arm_description.*package_paths"):
        load_robot(moved, meshes=True)
    assert load_robot(moved, meshes=True, package_paths={"my_arm_description": package}).scene_graph is not None


_ASCII_STL = textwrap.dedent("""\
    solid box
    facet normal 0 0 1
    outer loop
    vertex 0 0 0
    vertex 0.1 0 0
    vertex 0 0.1 0
    endloop
    endfacet
    facet normal 0 0 -1
    outer loop
    vertex 0 0 0
    vertex 0 0.1 0
    vertex 0 0 0.1
    endloop
    endfacet
    endsolid box
    """)


def test_load_errors_are_clear(tmp_path):
    with pytest.raises(RobotFileNotFound, match=r"my_robot\.urdf.*not found.*'talos'"):
        load_robot("my_robot.urdf")
    with pytest.raises(RobotNotFound, match=r"unknown robot 'my_robot'.*path of a URDF"):
        load_robot("my_robot")
    fixed = tmp_path / "fixed.urdf"
    fixed.write_text(
        '<robot name="f"><link name="a"/><link name="b"/><joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint></robot>'
    )
    with pytest.raises(RobotDescriptionError, match="no movable joint"):
        load_robot(fixed)
    unbounded = tmp_path / "unbounded.urdf"
    unbounded.write_text(chain_urdf("u", ["0 0 1"], 0.3, [(-1.0, float("inf"))]))
    with pytest.raises(RobotDescriptionError, match=r"joint 'joint1'.*upper='inf'.*continuous"):
        load_robot(unbounded)
    arm = three_link(tmp_path / "arm.urdf")
    with pytest.raises(FrameNotFound, match=r"'palm'.*'hand'"):
        load_robot(arm, operational_points={"tool": "palm"})
    with pytest.raises(InvalidInput, match="no SRDF"):
        load_robot(arm, reference_posture="home")
    with pytest.raises(InvalidInput, match=r"reference_posture.*shape \(3,\)"):
        load_robot(arm, reference_posture=[0.0, 0.1])


def test_reference_posture_clipped_and_named_op_points(tmp_path):
    arm = three_link(tmp_path / "arm.urdf")
    model = load_robot(arm, reference_posture={"joint2": 3.0}, operational_points=["link2", "hand"])
    np.testing.assert_allclose(model.reference_posture, [0.0, 2.0, 0.0])  # clipped into [-2, 2]
    assert dict(model.OperationalPointsMap) == {"link2": "link2", "hand": "hand"}
    builder = DiagramBuilder()
    bot = robot(builder, model)
    MetaTaskKinePosture(bot)  # a posture task towards q0
    with pytest.raises(KeyError, match=r"'palm'.*available: 'link2', 'hand'"):
        bot.OperationalPointsMap["palm"]


MJCF = """\
<mujoco model="arm">
  <compiler angle="radian"/>
  <worldbody>
    <body name="link1" pos="0 0 0.1">
      <joint name="j1" type="hinge" axis="0 0 1" range="-2 2" limited="true"/>
      <geom type="capsule" size="0.02" fromto="0 0 0 0.3 0 0" mass="1"/>
      <body name="link2" pos="0.3 0 0">
        <joint name="j2" type="hinge" axis="0 0 1" range="-2 2" limited="true"/>
        <geom type="capsule" size="0.02" fromto="0 0 0 0.3 0 0" mass="1"/>
        <body name="hand" pos="0.3 0 0">
          <geom type="sphere" size="0.02" mass="0.2"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

SDF = """\
<sdf version="1.7"><model name="arm">
<link name="base"><inertial><mass>1</mass><inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz>
<ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial></link>
<link name="l1"><pose>0 0 0.1 0 0 0</pose><inertial><mass>1</mass><inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz>
<ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial></link>
<link name="hand"><pose>0.3 0 0.1 0 0 0</pose><inertial><mass>1</mass><inertia><ixx>0.01</ixx><iyy>0.01</iyy><izz>0.01</izz>
<ixy>0</ixy><ixz>0</ixz><iyz>0</iyz></inertia></inertial></link>
<joint name="j1" type="revolute"><parent>base</parent><child>l1</child>
<axis><xyz>0 0 1</xyz><limit><lower>-1</lower><upper>1</upper></limit></axis></joint>
<joint name="j2" type="revolute"><pose relative_to="l1">0 0 0 0 0 0</pose><parent>l1</parent><child>hand</child>
<axis><xyz>0 1 0</xyz><limit><lower>-1</lower><upper>1</upper></limit></axis></joint>
</model></sdf>
"""


@pytest.mark.parametrize(("file_name", "text"), [("arm.xml", MJCF), ("arm.sdf", SDF)])
def test_sdf_and_mjcf_by_path(tmp_path, file_name, text):
    path = tmp_path / file_name
    path.write_text(text)
    model = load_robot(path)
    assert model.nv == 2 and model.plant.num_actuators() == 2
    assert model.OperationalPointsMap["hand"] == "hand"
    # a target the arm reaches at q = (0.3, 0.3): j1 turns about z, j2 about y
    X = model.plant.CalcRelativeTransform(_context_at(model, np.array([0.3, 0.3])), model.plant.world_frame(), model.frame("hand"))
    start, end, excursion = run_reach(model, X.translation())
    assert end < 0.1 * start
    assert excursion <= 1e-9


def guide_blocks() -> list[str]:
    text = (ROOT / "docs" / "guide" / "your_robot.md").read_text()
    return re.findall(r"```python\n(.*?)```", text, flags=re.S)


def test_guide_examples_run(tmp_path, monkeypatch):
    blocks = guide_blocks()
    assert blocks
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "guide"}
    for block in blocks:
        exec(compile(block, "your_robot.md", "exec"), namespace)


def test_add_robot_puts_your_file_in_a_plant_of_your_own(tmp_path):
    from pydrake.multibody.plant import MultibodyPlant

    from sotdrake.robots import add_robot

    plant = MultibodyPlant(1e-3)
    add_robot(plant, seven_dof(tmp_path / "arm7.urdf"), base="free")
    plant.Finalize()
    assert (plant.num_positions(), plant.num_velocities(), plant.num_actuators()) == (14, 13, 7)


def test_the_signals_of_a_fixed_base_robot_are_listed_with_those_it_has_not():
    """A fixed-base arm has no centroidal momentum: the report says so on that port and lists the
    others (the live ``displaySignals(dynamic)`` and ``displayAll`` use it)."""
    from sotdrake.introspection import signals_report

    builder = DiagramBuilder()
    arm = robot(builder, load_robot("panda"))
    context = builder.Build().CreateDefaultContext()
    report = signals_report(arm.dynamic, context)
    assert "momentum_matrix          (cannot evaluate: the centroidal momentum needs a floating base" in report
    assert re.search(r"out com\s+\[", report)


@pytest.mark.parametrize("folder", ["with space", "pct%20dir", "nön_ascii_中", "hash#dir"])
def test_meshes_in_any_folder_and_markup_of_any_style_load(tmp_path, folder, monkeypatch):
    """Mesh paths with spaces, %-escapes or non-ASCII characters (Drake does not decode a URI), in
    single or double quotes; a self-closing ``<gazebo/>`` and tags named in comments leave every
    link and joint; ``velocity='0'`` in any spelling is no limit."""
    monkeypatch.setenv("SOTDRAKE_CACHE", str(tmp_path / folder / "cache"))
    root = tmp_path / folder
    (root / "meshes").mkdir(parents=True)
    (root / "meshes" / "box.stl").write_text(_ASCII_STL)
    (root / "meshes" / "box.obj").write_text("v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n")
    visual = ("<visual><geometry><mesh filename='meshes/box.stl'/></geometry></visual>"
              '<collision><geometry><mesh filename = "meshes/box.obj"/></geometry></collision>')
    text = chain_urdf("quirky", ["0 0 1"] * 3, 0.3, [(-2.0, 2.0)] * 3, visual=visual)
    text = text.replace('<link name="link3">', '<gazebo reference="link3"/><!-- no <visual> or <gazebo> here --><link name="link3">')
    text = text.replace('velocity="2"/></joint>', """velocity='0e0'/></joint>""", 1)
    path = root / "quirky.urdf"
    path.write_text(text.replace("</robot>", '<gazebo reference="link3"><material>x</material></gazebo></robot>'))
    model = load_robot(path, meshes=True)
    assert model.nv == 3 and model.plant.HasJointNamed("joint3")  # nothing cut away
    assert model.scene_graph is not None and model.scene_graph.model_inspector().num_geometries() >= 2
    assert np.isinf(model.plant.get_joint(model.plant.GetJointByName("joint1").index()).velocity_upper_limits()[0])


def test_a_description_under_a_name_drakes_parser_reads_otherwise_is_refused_with_the_name_to_give(tmp_path):
    mjcf = tmp_path / "arm.mjcf"
    mjcf.write_text('<mujoco model="m"><worldbody><body name="b"><joint name="j" type="hinge"/>'
                    '<geom type="sphere" size="0.1"/></body></worldbody></mujoco>')
    with pytest.raises(RobotDescriptionError, match=r"a MJCF file.*'arm\.xml'"):
        load_robot(mjcf)
    sdf = tmp_path / "arm_sdf.xml"
    sdf.write_text('<sdf version="1.7"><model name="m"><link name="a"/></model></sdf>')
    with pytest.raises(RobotDescriptionError, match=r"a SDF file.*'arm_sdf\.sdf'"):
        load_robot(sdf)
    renamed = tmp_path / "arm.xml"
    renamed.write_text(mjcf.read_text())
    assert load_robot(renamed).nv == 1


def test_a_posture_by_joint_name_gets_a_unit_base_quaternion_or_is_refused():
    """The floating base's joint given by name (Drake's 7 numbers): normalized as an array posture
    is, refused when zero."""
    base = [2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    model = load_robot("talos", reference_posture={"base_link": base})
    np.testing.assert_allclose(model.reference_posture[:4], [1.0, 0.0, 0.0, 0.0])
    with pytest.raises(InvalidInput, match=r"quaternion .* is zero"):
        load_robot("talos", reference_posture={"base_link": [0.0] * 6 + [1.0]})


def test_an_unusable_mesh_cache_is_named(tmp_path, monkeypatch):
    blocker = tmp_path / "not_a_folder"
    blocker.write_text("")
    monkeypatch.setenv("SOTDRAKE_CACHE", str(blocker))
    (tmp_path / "box.stl").write_text(_ASCII_STL)
    from sotdrake.robots.mesh_cache import obj_for_mesh

    with pytest.raises(InvalidInput, match=r"the mesh cache .*not_a_folder.*set SOTDRAKE_CACHE"):
        obj_for_mesh(tmp_path / "box.stl")


def test_an_srdf_of_another_robot_is_warned(caplog):
    import logging

    with caplog.at_level(logging.WARNING, logger="sotdrake.robots.model"):
        model = load_robot(erd_robot("ur_description/urdf/ur5_robot.urdf"), srdf=erd_robot("panda_description/srdf/panda.srdf"))
    assert not model.reference_posture.any()
    assert any("none of its 8 joints is one of the model's" in r.getMessage() for r in caplog.records)
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="sotdrake.robots.model"):
        load_robot("talos")  # (its SRDF names joints of the full model too: not warned)
    assert not caplog.records


def test_a_free_flying_body_without_joints_is_a_robot_its_base_driven():
    """A quadrotor's single body with ``floating_base=True``: the floating base is all there is to
    control (a fixed one would leave nothing, and is refused)."""
    from sotdrake import robot as make_robot

    path = erd_robot("hector_description/robots/quadrotor_base.urdf")
    with pytest.raises(RobotDescriptionError, match="no movable joint"):
        load_robot(path)
    model = load_robot(path, floating_base=True)
    builder = DiagramBuilder()
    flyer = make_robot(builder, model)
    sot = add_sot(flyer, solver="hqp")
    body = MetaTaskKine6d("body", flyer, "body", "base_link")
    target = body.current_pose().translation() + [0.3, 0.1, 0.2]
    gotoNd(body, target, "111", 5.0)
    sot.push(body.task.name)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(2.0)
    assert np.linalg.norm(body.current_pose(simulator.get_context()).translation() - target) < 1e-3


def test_loader_arguments_of_the_wrong_kind_are_named():
    from sotdrake.exceptions import NotFound

    with pytest.raises(InvalidInput, match="meshes must be True or False, got 'yes'"):
        load_robot("ur5", meshes="yes")
    with pytest.raises(NotFound, match=r"reference_posture: a joint's name: unknown name 'elbow_jont' \(did you mean 'elbow_joint'"):
        load_robot("ur5", reference_posture={"elbow_jont": 0.5})
    builder = DiagramBuilder()
    arm = robot(builder, load_robot("ur5"))
    with pytest.raises(InvalidInput, match=r"excluding is a list of joint names, got the string 'elbow_joint'"):
        arm.velocity_selection(excluding="elbow_joint")
    with pytest.raises(NotFound, match="velocity_selection: excluding: unknown name 'elbow'"):
        arm.velocity_selection(excluding=["elbow"])
    assert arm.velocity_selection(excluding=["elbow_joint"]).sum() == arm.dimension - 1


@pytest.mark.parametrize("shape", ['<sphere radius="0"/>', '<box size="0.1 0 0.1"/>', '<cylinder radius="0.1" length="-1"/>',
                                   '<cylinder radius="0.1"/>', '<sphere radius="nan"/>'])
def test_a_shape_of_no_size_is_refused_naming_its_link(tmp_path, shape):
    visual = f"<visual><geometry>{shape}</geometry></visual>"
    path = tmp_path / "arm.urdf"
    path.write_text(chain_urdf("arm", ["0 0 1"] * 2, 0.3, [(-2.0, 2.0)] * 2, visual=visual))
    with pytest.raises(RobotDescriptionError, match=r"link 'base': a \w+'s \w+ must be positive finite numbers"):
        load_robot(path, meshes=True)
