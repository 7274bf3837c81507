"""TALOS (PAL Robotics) from the example-robot-data wheel, loaded into a Drake ``MultibodyPlant``.

Fix-ups applied to the URDF text before Drake parses it:

* mesh URIs (``package://example-robot-data/…`` and the three-slash ``package:///…`` form) are
  resolved to files; STL meshes are replaced by cached OBJ conversions (:mod:`.mesh_cache`), or
  dropped with their ``<visual>``/``<collision>`` elements when no geometry is wanted (control models);
* ``<mimic>`` on fixed (0-DOF) joints is removed (Drake rejects it; a fixed joint has nothing to mimic);
* the ``friction`` attribute of ``<dynamics>`` is removed (``MultibodyPlant`` has no joint friction);
* transmissions Drake cannot use (differential ones on torso, head, wrists; ones naming joints the
  variant does not have) are removed, and every
  1-DOF joint left without an actuator (and not a mimic follower) gets one, with the URDF effort limit.

Drake's coordinates: the floating base ``base_link`` comes first, ``q = (qw, qx, qy, qz, x, y, z, …)``
and ``v = (ω_WB, v_WB, …)``, both expressed in the world frame.
"""

from __future__ import annotations

import importlib.metadata
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.geometry import SceneGraph
from pydrake.math import RigidTransform
from pydrake.common.eigen_geometry import Quaternion
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, FrameIndex, JointActuatorIndex, ModelInstanceIndex

from ..exceptions import FrameNotFound, RobotNotFound, SotError
from .mesh_cache import obj_for_stl
from .srdf import read_group_state
from .urdf_checks import check_urdf_limits

#: URDF file of each TALOS variant, under ``robots/talos_data/robots/``.
VARIANTS: dict[str, str] = {
    "reduced": "talos_reduced.urdf",
    "full_v2": "talos_full_v2.urdf",
    "left_arm": "talos_left_arm.urdf",
}

#: sot-talos operational points (``robot.OperationalPointsMap``): op-point name → joint name.
#: The operational point is the child frame of the joint (the URDF link frame), as in sot-dynamic.
OPERATIONAL_POINTS: dict[str, str] = {
    "left-wrist": "arm_left_7_joint",
    "right-wrist": "arm_right_7_joint",
    "left-ankle": "leg_left_6_joint",
    "right-ankle": "leg_right_6_joint",
    "gaze": "head_2_joint",
    "waist": "root_joint",
    "chest": "torso_2_joint",
    "left-sole": "left_sole_link",
    "right-sole": "right_sole_link",
}


def example_robot_data_dir() -> Path:
    """``share/example-robot-data`` of the installed example-robot-data wheel."""
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        raise SotError(
            "the robot package example-robot-data is not installed: `pip install example-robot-data`"
        ) from None
    path = Path(dist.locate_file("cmeel.prefix/share/example-robot-data"))
    if not (path / "robots").is_dir():
        raise SotError(f"example-robot-data is installed but has no robots directory at {path}")
    return path


def talos_urdf_path(variant: str) -> Path:
    if variant not in VARIANTS:
        raise RobotNotFound(variant, VARIANTS)
    return example_robot_data_dir() / "robots" / "talos_data" / "robots" / VARIANTS[variant]


def _resolve_mesh(uri: str, share: Path, meshes: bool) -> str:
    relative = re.sub(r"^package:/{2,3}example-robot-data/", "", uri)
    path = share / relative
    if not path.is_file():
        raise SotError(f"mesh {uri} not found at {path}")
    return (obj_for_stl(path) if meshes and path.suffix.lower() == ".stl" else path).as_uri()


def fixed_urdf_text(variant: str, meshes: bool, collision: bool = True) -> str:
    """The URDF of ``variant`` with the fix-ups listed in the module docstring applied; without
    ``collision`` the ``<collision>`` elements are dropped (the physics model adds its own soles)."""
    text = talos_urdf_path(variant).read_text()
    check_urdf_limits(text, str(talos_urdf_path(variant)))  # before any parser sees it
    share = example_robot_data_dir()

    def fix_joint(match: re.Match) -> str:
        joint = match.group(0)
        if re.search(r'type\s*=\s*"fixed"', joint):
            joint = re.sub(r"<mimic\b[^>]*/>", "", joint)
        return joint

    text = re.sub(r"<joint\b[^>]*>.*?</joint>", fix_joint, text, flags=re.S)
    text = re.sub(r'\sfriction="[^"]*"', "", text)
    joints = {j.get("name") for j in ET.fromstring(text).findall("joint")}  # not the ones in <transmission>

    def keep_transmission(match: re.Match) -> str:
        block = match.group(0)
        names = re.findall(r'<joint\b[^>]*\bname="([^"]+)"', block)
        simple = "SimpleTransmission" in block and all(n in joints for n in names)
        return block if simple else ""

    text = re.sub(r"<transmission\b.*?</transmission>", keep_transmission, text, flags=re.S)
    if not collision:
        text = re.sub(r"<collision\b.*?</collision>", "", text, flags=re.S)
    if meshes:
        text = re.sub(
            r'filename="(package:/{2,3}example-robot-data/[^"]+)"',
            lambda m: f'filename="{_resolve_mesh(m.group(1), share, True)}"',
            text,
        )
    else:
        text = re.sub(r"<(visual|collision)\b.*?</\1>", "", text, flags=re.S)
    return text


def _joint_table(urdf_text: str) -> tuple[dict[str, float], set[str]]:
    """Effort limit of each joint and the set of mimic followers, read from the URDF."""
    root = ET.fromstring(urdf_text)
    effort, followers = {}, set()
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        if limit is not None and limit.get("effort") is not None:
            effort[joint.get("name")] = float(limit.get("effort"))
        if joint.find("mimic") is not None and joint.get("type") != "fixed":
            followers.add(joint.get("name"))
    return effort, followers


def add_talos(
    plant: MultibodyPlant,
    variant: str = "reduced",
    meshes: bool = False,
    fixed_base: bool | None = None,
    collision: bool = True,
) -> ModelInstanceIndex:
    """Add TALOS to an unfinalized ``plant`` (geometry only if ``meshes`` and the plant has a
    SceneGraph); returns its model instance. Actuators are added for every actuable joint.

    ``fixed_base`` welds the URDF root link to the world at the origin; by default only the
    ``left_arm`` variant is welded, the others have a floating base.
    """
    text = fixed_urdf_text(variant, meshes, collision)
    (instance,) = Parser(plant).AddModelsFromString(text, "urdf")
    if fixed_base if fixed_base is not None else variant == "left_arm":
        root = ET.fromstring(text)
        children = {j.find("child").get("link") for j in root.findall("joint")}
        (root_link,) = [l.get("name") for l in root.findall("link") if l.get("name") not in children]
        plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(root_link, instance))
    effort, followers = _joint_table(text)
    # URDF transmissions may land in another model instance: look at every actuator.
    actuated = {plant.get_joint_actuator(i).joint().name() for i in plant.GetJointActuatorIndices()}
    for index in plant.GetJointIndices(instance):
        joint = plant.get_joint(index)
        if joint.num_velocities() == 1 and joint.name() not in actuated | followers:
            plant.AddJointActuator(
                f"{joint.name()}_motor", joint, effort.get(joint.name(), float("inf"))
            )
    return instance


@dataclass
class RobotModel:
    """A finalized plant of the robot with what the SoT needs to know about it."""

    plant: MultibodyPlant
    variant: str
    OperationalPointsMap: dict[str, str]
    half_sitting: np.ndarray
    fixed_base: bool = False
    scene_graph: SceneGraph | None = None
    srdf_path: Path | None = None
    _frames: dict[str, Frame] = field(default_factory=dict, repr=False)

    @property
    def nq(self) -> int:
        return self.plant.num_positions()

    @property
    def nv(self) -> int:
        return self.plant.num_velocities()

    def frame(self, name: str) -> Frame:
        """Frame of an operational point (``'right-wrist'``), a joint (its child frame) or a frame.

        Raises :class:`FrameNotFound` listing operational points and frame names.
        """
        if name in self._frames:
            return self._frames[name]
        plant, target = self.plant, self.OperationalPointsMap.get(name, name)
        bases = list(plant.GetFloatingBaseBodies())
        if target == "root_joint" and not plant.HasJointNamed(target) and bases:
            frame = plant.get_body(bases[0]).body_frame()  # sot-talos' name of the free flyer
        elif plant.HasJointNamed(target):
            frame = plant.GetJointByName(target).frame_on_child()
        elif plant.HasFrameNamed(target):
            frame = plant.GetFrameByName(target)
        else:
            frames = {plant.get_frame(FrameIndex(i)).name() for i in range(plant.num_frames())}
            raise FrameNotFound(name, [*self.OperationalPointsMap, *sorted(frames)])
        self._frames[name] = frame
        return frame

    def with_meshes(self) -> "RobotModel":
        """The same robot with visual and collision meshes, on its own plant and SceneGraph."""
        return load_talos(self.variant, meshes=True, fixed_base=self.fixed_base)

    def joint_limits(self) -> dict[str, np.ndarray]:
        """``position_lower/upper`` (nq, ±inf on the floating base), ``velocity_lower/upper`` (nv),
        ``effort`` (one per actuator, in actuator order)."""
        plant = self.plant
        return {
            "position_lower": plant.GetPositionLowerLimits(),
            "position_upper": plant.GetPositionUpperLimits(),
            "velocity_lower": plant.GetVelocityLowerLimits(),
            "velocity_upper": plant.GetVelocityUpperLimits(),
            "effort": np.array(
                [plant.get_joint_actuator(JointActuatorIndex(i)).effort_limit()
                 for i in range(plant.num_actuators())]
            ),
        }


def posture_from_srdf(plant: MultibodyPlant, srdf_path: Path, name: str) -> np.ndarray:
    """Drake ``q`` of an SRDF reference posture (joints not listed stay at zero)."""
    values = read_group_state(srdf_path, name)
    context = plant.CreateDefaultContext()
    for joint_name, value in values.items():
        if joint_name == "root_joint":
            x, y, z, qx, qy, qz, qw = value
            body = next(iter(plant.GetFloatingBaseBodies()), None)
            if body is None:  # welded base: the SRDF base pose does not apply
                continue
            pose = RigidTransform(Quaternion(qw, qx, qy, qz), [x, y, z])
            plant.SetFreeBodyPose(context, plant.get_body(body), pose)
        elif plant.HasJointNamed(joint_name):
            joint = plant.GetJointByName(joint_name)
            q = plant.GetPositions(context)
            q[joint.position_start() : joint.position_start() + joint.num_positions()] = value
            plant.SetPositions(context, q)
    return plant.GetPositions(context)


def load_talos(
    variant: str = "reduced",
    meshes: bool = False,
    time_step: float = 0.0,
    fixed_base: bool | None = None,
) -> RobotModel:
    """A finalized TALOS ``RobotModel``; with ``meshes`` the plant is registered with a SceneGraph
    (OBJ visual and collision meshes) and the model holds that SceneGraph."""
    scene_graph = None
    if meshes:
        scene_graph = SceneGraph()
        plant = MultibodyPlant(time_step)
        plant.RegisterAsSourceForSceneGraph(scene_graph)
    else:
        plant = MultibodyPlant(time_step)
    add_talos(plant, variant, meshes, fixed_base)
    plant.Finalize()
    srdf = example_robot_data_dir() / "robots" / "talos_data" / "srdf" / "talos.srdf"
    return RobotModel(
        plant=plant,
        variant=variant,
        fixed_base=not plant.GetFloatingBaseBodies(),
        OperationalPointsMap=dict(OPERATIONAL_POINTS),
        half_sitting=posture_from_srdf(plant, srdf, "half_sitting"),
        scene_graph=scene_graph,
        srdf_path=srdf,
    )
