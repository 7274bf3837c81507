"""One loader for the robots of example-robot-data, ``load_robot("romeo")``, ``load_robot("pr2")``…,
and for your own: ``load_robot("path/to/robot.urdf")`` (see :mod:`.from_file`).

``add_robot`` adds a robot of :data:`sotdrake.robots.catalog.ROBOTS` to an unfinalized
``MultibodyPlant``: its URDF text is fixed up by :func:`~sotdrake.robots.urdf_text.prepare_urdf`,
parsed by Drake, its base attached as asked (free, planar or welded), and every 1-DOF joint left
without an actuator by the URDF (and not a mimic follower) gets one, with the URDF effort limit.
``load_robot`` finalizes the plant and returns a :class:`~sotdrake.robots.model.RobotModel` in the
robot's reference posture.

Drake's coordinates: a free base comes first, ``q = (qw, qx, qy, qz, x, y, z, …)``,
``v = (ω_WB, v_WB, …)`` both expressed in the world frame; a planar base is the joint
``root_joint``, ``q = (x, y, θ)`` and ``v = (ẋ, ẏ, θ̇)`` in the world frame.
"""

from __future__ import annotations

import importlib.metadata
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.geometry import SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex, PlanarJoint

from ..exceptions import InvalidInput, RobotNotFound, SotError, VariantNotFound
from .catalog import BASES, ROBOTS, RobotSpec
from .from_file import add_robot_file, check_time_step, drake_refusals, load_robot_file, looks_like_path
from .mimic import follow_mimics, mimic_joints, mimic_table
from .model import RobotModel, posture_from_srdf, register_loader
from .model_defaults import operational_points_of, posture_of
from .srdf import read_group_state
from .urdf_text import prepare_urdf

#: Name of the planar joint that carries a ``planar`` base (sot-talos names the free flyer so too).
PLANAR_BASE_JOINT = "root_joint"


def example_robot_data_dir() -> Path:
    """``share/example-robot-data`` of the installed example-robot-data wheel."""
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        raise SotError(
            "the robot package example-robot-data is not installed: `pip install example-robot-data`"
        ) from None
    path = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data")))
    if not (path / "robots").is_dir():
        raise SotError(f"example-robot-data is installed but has no robots directory at {path}")
    return path


def _names_a_file(name: object) -> bool:
    """Whether ``name`` is the path of a robot's file rather than a catalog name."""
    return looks_like_path(name) or (isinstance(name, str) and name not in ROBOTS and Path(name).is_file())


def available_robots() -> list[str]:
    """The names :func:`load_robot` accepts."""
    return list(ROBOTS)


def robot_spec(name: str) -> RobotSpec:
    """The catalog entry of ``name``; :class:`RobotNotFound` lists the robots that exist."""
    if name not in ROBOTS:
        error = RobotNotFound(name, list(ROBOTS))
        error.args = (f"{error.args[0]}; or give the path of a URDF, SDF or MJCF file",)
        raise error
    return ROBOTS[name]


def _variant(spec: RobotSpec, variant: str | None) -> str:
    variant = spec.default_variant if variant is None else variant
    if variant not in spec.variants:
        raise VariantNotFound(variant, list(spec.variants))
    return variant


def _base(spec: RobotSpec, variant: str, base: str | None) -> str:
    if variant in spec.fixed_base_variants and base is None:
        return "fixed"
    base = spec.base if base is None else base
    if base not in BASES:
        raise InvalidInput(f"base must be one of {BASES}, got {base!r}")
    if base not in spec.bases and variant not in spec.fixed_base_variants:
        raise InvalidInput(f"{spec.name} offers the bases {spec.bases}, not {base!r}")
    return base


def urdf_path(name: str, variant: str | None = None) -> Path:
    """The URDF file of a robot variant (default: the robot's first variant)."""
    spec = robot_spec(name)
    return example_robot_data_dir() / "robots" / spec.package / spec.urdf_dir / spec.variants[_variant(spec, variant)]


def srdf_path(name: str, variant: str | None = None) -> Path | None:
    """The SRDF file of a robot variant, or None when it has none."""
    spec = robot_spec(name)
    srdf = spec.srdf_file(_variant(spec, variant))
    return None if srdf is None else example_robot_data_dir() / "robots" / spec.package / "srdf" / srdf


def robot_urdf_text(name: str, variant: str | None = None, meshes: bool = False, collision: bool = True) -> str:
    """The URDF text of a robot variant, fixed up for Drake (:func:`prepare_urdf`)."""
    path = urdf_path(name, variant)
    return prepare_urdf(path.read_text(), example_robot_data_dir(), meshes, collision, str(path))


def _root_link(urdf_text: str) -> str:
    root = ET.fromstring(urdf_text)
    children = {child.get("link") for joint in root.findall("joint") if (child := joint.find("child")) is not None}
    (link,) = [element.get("name", "") for element in root.findall("link") if element.get("name") not in children]
    return link


def joint_table(urdf_text: str) -> tuple[dict[str, float], set[str]]:
    """Effort limit of each joint and the set of mimic followers, read from the URDF."""
    root = ET.fromstring(urdf_text)
    effort: dict[str, float] = {}
    for joint in root.iter("joint"):
        name, limit = joint.get("name", ""), joint.find("limit")
        limit_effort = float(limit.get("effort") or 0) if limit is not None else 0.0
        if limit_effort > 0:  # 0: not given (Romeo's fingers)
            effort[name] = limit_effort
    return effort, set(mimic_joints(root))


def add_actuators(plant: MultibodyPlant, instance: ModelInstanceIndex, urdf_text: str) -> None:
    """An actuator (URDF effort limit, else unlimited) on every 1-DOF joint of ``instance`` that the
    URDF's transmissions left without one, mimic followers excepted."""
    effort, followers = joint_table(urdf_text)
    # URDF transmissions may land in another model instance: look at every actuator.
    actuated = {plant.get_joint_actuator(i).joint().name() for i in plant.GetJointActuatorIndices()}
    for index in plant.GetJointIndices(instance):
        joint = plant.get_joint(index)
        if joint.num_velocities() == 1 and joint.name() not in actuated | followers:
            plant.AddJointActuator(f"{joint.name()}_motor", joint, effort.get(joint.name(), float("inf")))


def add_robot(
    plant: MultibodyPlant,
    name: str | PathLike[str],
    variant: str | None = None,
    meshes: bool = False,
    base: str | None = None,
    collision: bool = True,
) -> ModelInstanceIndex:
    """Add robot ``name`` to an unfinalized ``plant`` and return its model instance.

    ``variant``: one of the robot's variants (default: its first). ``meshes``: visual and collision
    geometry (the plant must be registered with a SceneGraph); ``collision=False`` keeps only the
    visuals. ``base``: ``'free'``, ``'planar'`` or ``'fixed'`` (default: the robot's own, see
    :data:`sotdrake.robots.catalog.ROBOTS`). A URDF whose root is already welded to ``world`` stays
    welded. ``name`` may also be the path of your URDF, SDF or MJCF file (see
    :func:`~sotdrake.robots.from_file.add_robot_file`; ``base``: ``'free'`` or ``'fixed'``, the
    default).
    """
    if not isinstance(plant, MultibodyPlant):
        raise InvalidInput(f"add_robot: plant must be a Drake MultibodyPlant, got {type(plant).__name__}")
    if plant.is_finalized():
        raise InvalidInput("add_robot: the plant is finalized; add the robot before plant.Finalize()")
    if _names_a_file(name):
        if variant is not None or base not in (None, "free", "fixed"):
            raise InvalidInput(f"a robot file has no variants and a free or fixed base, got variant={variant!r}, base={base!r}")
        instances = add_robot_file(plant, name, meshes=meshes, floating_base=base == "free")
        return instances[0]
    return _add_catalog_robot(plant, str(name), variant, meshes, base, collision)[0]


def _add_catalog_robot(plant: MultibodyPlant, name: str, variant: str | None, meshes: bool, base: str | None,
                       collision: bool = True) -> tuple[ModelInstanceIndex, str]:
    """:func:`add_robot` for a catalog robot: its model instance and the URDF text it was read from."""
    spec = robot_spec(name)
    variant = _variant(spec, variant)
    base = _base(spec, variant, base)
    text = robot_urdf_text(name, variant, meshes, collision)
    with drake_refusals(f"robot {name!r}"):  # (e.g. a second copy in one plant: its model name is taken)
        (instance,) = Parser(plant).AddModelsFromString(text, "urdf")
    root = _root_link(text)
    if root != "world":
        root_frame = plant.GetFrameByName(root, instance)
        if base == "fixed":
            plant.WeldFrames(plant.world_frame(), root_frame)
        elif base == "planar":
            plant.AddJoint(PlanarJoint(PLANAR_BASE_JOINT, plant.world_frame(), root_frame, np.zeros(3)))
    add_actuators(plant, instance, text)
    return instance, text


def _put_on_ground(plant: MultibodyPlant, q: np.ndarray, soles: list) -> np.ndarray:
    """``q`` with the floating base raised or lowered so that the lowest sole frame is at z = 0."""
    (body,) = plant.GetFloatingBaseBodies()
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, q)
    z = min(plant.CalcRelativeTransform(context, plant.world_frame(), f).translation()[2] for f in soles)
    X_WB = plant.EvalBodyPoseInWorld(context, plant.get_body(body))
    plant.SetFreeBodyPose(context, plant.get_body(body), RigidTransform(X_WB.rotation(), X_WB.translation() - [0, 0, z]))
    return plant.GetPositions(context)


def reference_posture(plant: MultibodyPlant, spec: RobotSpec, srdf: Path | None, soles: list) -> np.ndarray:
    """The robot's reference posture: its SRDF ``group_state``s over the default positions (0
    clipped into the joint limits); a floating base the SRDF does not place is put with its lowest
    sole frame (``soles``) at z = 0."""
    q = np.clip(plant.GetDefaultPositions(), plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits())
    places_base = False
    if srdf is not None and spec.posture:
        q = posture_from_srdf(plant, srdf, spec.posture, q)
        places_base = any("root_joint" in read_group_state(srdf, group) for group in spec.posture)
    if plant.GetFloatingBaseBodies() and not places_base and soles:
        q = _put_on_ground(plant, q, soles)
    return q


def _has_target(plant: MultibodyPlant, target: str) -> bool:
    """Whether an op point's joint or frame is in this model (a variant may lack some)."""
    floating = target == "root_joint" and bool(plant.GetFloatingBaseBodies())
    return floating or plant.HasJointNamed(target) or plant.HasFrameNamed(target)


def load_robot(
    name: str | PathLike[str],
    variant: str | None = None,
    meshes: bool = False,
    time_step: float = 0.0,
    base: str | None = None,
    *,
    srdf: str | PathLike[str] | None = None,
    package_paths: Mapping[str, str | PathLike[str]] | None = None,
    floating_base: bool | None = None,
    operational_points: Mapping[str, str] | Sequence[str] | None = None,
    reference_posture: Any = None,
) -> RobotModel:
    """A finalized ``RobotModel``: of robot ``name`` of the catalog (see :func:`available_robots`),
    or of the URDF, SDF or MJCF file at the path ``name`` (see :mod:`.from_file`: ``srdf``,
    ``package_paths`` name → folder for ``package://`` URIs, ``floating_base`` (default False for
    a file), ``operational_points`` name → joint/link/frame, ``reference_posture`` an array, a
    ``{joint: value}`` dict or an SRDF group-state name).

    With ``meshes`` the plant is registered with a SceneGraph (OBJ visual and collision meshes)
    that the model holds. An unknown name raises :class:`RobotNotFound` listing the robots that
    exist, a missing file :class:`~sotdrake.exceptions.RobotFileNotFound`; an unknown variant,
    :class:`VariantNotFound` listing the robot's variants. For a catalog robot, ``floating_base``
    chooses the base (free or fixed), ``operational_points`` are added to its own and
    ``reference_posture`` replaces its own."""
    if floating_base is not None and not isinstance(floating_base, bool):
        raise InvalidInput(f"floating_base must be True or False, got {floating_base!r}")
    time_step = check_time_step(time_step)
    if not isinstance(meshes, (bool, np.bool_)):
        raise InvalidInput(f"meshes must be True or False, got {meshes!r:.60}")
    if _names_a_file(name):
        if variant is not None:
            raise InvalidInput(f"variant={variant!r}: a robot loaded from a file has no variants")
        if base is not None:
            if base not in ("free", "fixed"):
                raise InvalidInput(f"a robot loaded from a file has a free or fixed base, not {base!r}")
            if floating_base is not None and floating_base != (base == "free"):
                raise InvalidInput(f"base={base!r} and floating_base={floating_base} disagree")
            floating_base = base == "free"
        return load_robot_file(name, meshes, time_step, srdf=srdf, package_paths=package_paths,
                               floating_base=bool(floating_base), operational_points=operational_points,
                               reference_posture=reference_posture)
    if srdf is not None or package_paths is not None:
        raise InvalidInput(f"srdf and package_paths are for a robot loaded from a file; {name!r} is a robot of the catalog")
    if floating_base is not None:
        if base is not None and base != ("free" if floating_base else "fixed"):
            raise InvalidInput(f"base={base!r} and floating_base={floating_base} disagree")
        base = "free" if floating_base else "fixed"
    model = _load_catalog_robot(str(name), variant, meshes, time_step, base)
    if operational_points is not None:
        model.OperationalPointsMap.update(operational_points_of(model, operational_points))
        model.load_options["operational_points"] = operational_points
    if reference_posture is not None:
        model.half_sitting = _catalog_posture(model, str(name), reference_posture)
        model.load_options["reference_posture"] = reference_posture
    return model


def _catalog_posture(model: RobotModel, name: str, given: Any) -> np.ndarray:
    """A catalog robot's ``reference_posture``: a ``{joint: value}`` changes its own reference
    posture; a floating base that the posture does not place (an SRDF group state without
    ``root_joint``, a mapping without the base's joint) is put with its lowest sole at z = 0, as
    the robot's own posture is. An array is taken as it is."""
    plant = model.plant
    q = posture_of(model, given, start=model.half_sitting)
    base_joints = {plant.get_joint(j).name() for j in plant.GetJointIndices() if plant.get_joint(j).num_positions() >= 6}
    srdf = model.srdf_path
    places_base = (isinstance(given, Mapping) and bool(base_joints & set(given))) or (
        isinstance(given, str) and srdf is not None and "root_joint" in read_group_state(srdf, given))
    soles = [model.frame(sole) for sole in robot_spec(name).soles]
    if plant.GetFloatingBaseBodies() and soles and not places_base and isinstance(given, (str, Mapping)):
        q = _put_on_ground(plant, q, soles)
    return q


register_loader(load_robot)


def _load_catalog_robot(name: str, variant: str | None, meshes: bool, time_step: float, base: str | None) -> RobotModel:
    spec = robot_spec(name)
    variant = _variant(spec, variant)
    scene_graph = None
    plant = MultibodyPlant(time_step)
    if meshes:
        scene_graph = SceneGraph()
        plant.RegisterAsSourceForSceneGraph(scene_graph)
    _, text = _add_catalog_robot(plant, name, variant, meshes, base)
    plant.Finalize()
    model = RobotModel(
        plant=plant,
        variant=variant,
        OperationalPointsMap={},
        half_sitting=np.zeros(plant.num_positions()),
        fixed_base=not plant.GetFloatingBaseBodies() and not plant.HasJointNamed(PLANAR_BASE_JOINT),
        scene_graph=scene_graph,
        srdf_path=srdf_path(name, variant),
        name=name,
        base=_base(spec, variant, base),
        sole_rectangles=dict(spec.sole_rectangles),
    )
    model.OperationalPointsMap.update(
        {op: target for op, target in spec.op_points.items() if _has_target(plant, target)}
    )
    soles = [model.frame(s) for s in spec.soles]
    model.mimic = mimic_table(text)
    model.half_sitting = follow_mimics(plant, model.mimic, reference_posture(plant, spec, model.srdf_path, soles))
    return model
