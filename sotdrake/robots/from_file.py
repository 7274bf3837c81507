"""Your own robot: a :class:`~sotdrake.robots.model.RobotModel` from a URDF, SDF or MJCF file.

``load_robot("path/to/arm.urdf", floating_base=False)`` (see :func:`sotdrake.robots.load_robot`)
comes here. The file is read as the catalog's robots are:

* a URDF gets the fix-ups of :func:`~sotdrake.robots.urdf_text.prepare_urdf` (meshes resolved
  through :class:`~sotdrake.robots.packages.PackageResolver`, STL and COLLADA converted to cached
  OBJ files, ``<mimic>`` on fixed joints, transmissions …) and its limits are checked first: a
  revolute or prismatic joint's ``lower`` and ``upper`` must be finite (an unbounded one is
  ``continuous``); a ``velocity="0"`` limit (often written for "not given") is read as no limit;
* an SDF or MJCF file is parsed by Drake with the same package folders;
* what Drake would read otherwise than the file says is refused first
  (:mod:`~sotdrake.robots.model_checks`: a file under the name of another format, a negative mass,
  a ``<mimic>`` cycle, a floating joint between two links, ``world`` as a joint's child, links
  left free besides the one floating base);
* every 1-DOF joint without an actuator gets one (the URDF's effort limit, else unlimited).

Base: ``floating_base=True`` leaves the root link free (Drake's 6-DOF floating base,
``q = (qw, qx, qy, qz, x, y, z, …)``, ``v = (ω_WB, v_WB, …)`` in the world frame) and names it
``root_joint`` for the op points (``'waist'``); ``False`` welds it to the world at the origin. A
file whose root is already welded to ``world`` stays welded.

Operational points: the given ones (op-point name → joint, link or frame of the model; a list of
frame names maps each to itself), else the SRDF's ``<end_effector>`` (name → its ``parent_link``),
every leaf link (a link with no child) under its own name and, for a floating base, ``waist``
(the link ``waist`` itself when the model has one). Any frame, link or joint name is accepted where
an op point is expected; an op point may not be named like another frame of the model (it would
hide it: :class:`~sotdrake.exceptions.InvalidInput`).

Reference posture ``q0``: the given array (nq, Drake's order) or ``{joint: value}``, else an SRDF
``group_state`` (the one named, else ``half_sitting``, ``standing``, ``default``, ``home``,
``ready``, else the first), else every joint at 0; always clipped into the joint limits, a
``<mimic>`` follower set from its leader (``q_f = multiplier q_l + offset``, as the physics holds it). The SRDF
is ``srdf=`` or, when not given, ``<name>.srdf`` beside the file or in a sibling ``srdf/`` folder.
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from os import PathLike
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.geometry import SceneGraph
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JointIndex, ModelInstanceIndex

from ..exceptions import InvalidInput, RobotDescriptionError
from .mimic import mimic_table
from .model import OperationalPoints, RobotModel
from .model_checks import FORMATS, attach_roots, check_is_file, check_user_urdf, description_format
from .model_defaults import operational_points_of, posture_of
from .packages import PackageResolver
from .urdf_checks import check_masses, check_other_limits
from .urdf_text import prepare_urdf

log = logging.getLogger(__name__)

PathArg = str | PathLike[str]


def looks_like_path(name: object) -> bool:
    """Whether :func:`~sotdrake.robots.load_robot` should read ``name`` as a file, not a catalog
    name: a ``PathLike``, or a string with a folder separator or a description suffix."""
    if isinstance(name, PathLike):
        return True
    return isinstance(name, str) and ("/" in name or "\\" in name or Path(name).suffix.lower() in FORMATS)


def is_drake_check(error: BaseException) -> bool:
    """Whether ``error`` is one of Drake's failed checks, which pydrake raises as ``SystemExit``
    (``Failure at …``; an ``except Exception`` does not catch it)."""
    return isinstance(error, SystemExit) and str(error).startswith("Failure at ")


@contextmanager
def drake_refusals(source: object) -> Iterator[None]:
    """Drake's refusals of a description as :class:`RobotDescriptionError` naming ``source``: its
    parser's errors and the checks of its constructors (a box of negative size, joint limits
    ``lower > upper`` or NaN in an SDF or MJCF file …), which pydrake raises as ``SystemExit``."""
    try:
        yield
    except SystemExit as error:
        if not is_drake_check(error):  # (a real exit)
            raise
        raise RobotDescriptionError(f"{source}: Drake refused the description: {error}") from None
    except (RuntimeError, ValueError) as error:
        if isinstance(error, RobotDescriptionError):
            raise
        raise RobotDescriptionError(f"{source}: Drake's parser refused the file: {error}") from None


def _read_text(path: Path) -> str:
    try:
        return path.read_text()
    except UnicodeDecodeError as error:
        raise RobotDescriptionError(f"{path}: not UTF-8 text ({error})") from None


def _root_links(text: str) -> list[str]:
    root = ET.fromstring(text)
    children = {child.get("link") for joint in root.iter("joint") if (child := joint.find("child")) is not None}
    return [link.get("name", "") for link in root.findall("link") if link.get("name") not in children]


def _add_urdf(plant: MultibodyPlant, path: Path, resolver: PackageResolver, meshes: bool, floating_base: bool) -> ModelInstanceIndex:
    from .loader import add_actuators, joint_table

    text = check_user_urdf(_read_text(path), str(path))
    text = prepare_urdf(text, Path(), meshes, True, str(path), resolver.path)
    roots = _root_links(text)
    if len(roots) != 1:
        raise RobotDescriptionError(f"{path}: a URDF has one root link (a link no joint has as child), found {roots}")
    with drake_refusals(path):
        (instance,) = Parser(plant).AddModelsFromString(text, "urdf")
    followers = sorted(joint_table(text)[1])
    if followers:
        log.warning("%s: the joints %s follow another joint (<mimic>): Drake's physics holds them coupled, the SoT's "
                    "kinematic device does not; leave them out of the control (robot.velocity_selection(excluding=%s)) "
                    "or give them a task", path, followers, followers)
    if roots[0] != "world" and not floating_base:
        with drake_refusals(path):
            plant.WeldFrames(plant.world_frame(), plant.GetFrameByName(roots[0], instance))
    add_actuators(plant, instance, text)
    return instance


def _add_other(plant: MultibodyPlant, path: Path, resolver: PackageResolver, floating_base: bool) -> list[ModelInstanceIndex]:
    """An SDF or MJCF file's models, read by Drake's parser with the package folders of ``resolver``
    (those its text names are found as for a URDF: :meth:`PackageResolver.packages_in`), checked
    (limits, masses, unique names, one free body at most) and attached (:func:`attach_roots`)."""
    from .loader import add_actuators

    parser = Parser(plant)
    known = set(parser.package_map().GetPackageNames())
    for name, folder in {**resolver.packages, **resolver.packages_in(_read_text(path), known)}.items():
        if not parser.package_map().Contains(name):
            parser.package_map().Add(name, str(folder))
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, UnicodeDecodeError):
        root = None  # (Drake's parser says what is wrong with it)
    if root is not None and root.tag in ("sdf", "mujoco"):
        check_other_limits(root, str(path))  # (Drake would refuse them without naming the joint)
        check_masses(root, str(path))  # (Drake would take another mass for a negative one)
    with drake_refusals(path):
        instances = parser.AddModels(str(path))
    _check_unique_names(plant, instances, path)
    with drake_refusals(path):
        attach_roots(plant, instances, path, floating_base, _mjcf_free_bodies(root))
    for instance in instances:
        add_actuators(plant, instance, "<robot/>")
    return instances


def _check_unique_names(plant: MultibodyPlant, instances: list[ModelInstanceIndex], path: Path) -> None:
    """:class:`RobotDescriptionError` if two of the file's models have a link or a joint of the same
    name: op points, tasks, postures and collision pairs name them without their model."""
    for kind, indices, get in (("link", plant.GetBodyIndices, plant.get_body), ("joint", plant.GetJointIndices, plant.get_joint)):
        owner: dict[str, ModelInstanceIndex] = {}
        for instance in instances:
            for index in indices(instance):
                name = get(index).name()
                if owner.setdefault(name, instance) != instance:
                    models = sorted({plant.GetModelInstanceName(owner[name]), plant.GetModelInstanceName(instance)})
                    raise RobotDescriptionError(
                        f"{path}: the models {models[0]!r} and {models[1]!r} both have a {kind} named {name!r}; sotdrake names "
                        "links and joints without their model (op points, tasks, postures, collision pairs): rename one")


def _mjcf_free_bodies(root: ET.Element | None) -> set[str]:
    """The bodies an MJCF file (its parsed ``root``) frees itself (a ``<freejoint/>`` or a
    ``<joint type="free"/>``): Drake leaves them floating; they are not welded (none for another
    format, or a file that is not XML)."""
    if root is None or root.tag != "mujoco":
        return set()
    return {body.get("name", "") for body in root.iter("body")
            if body.find("freejoint") is not None or any(j.get("type") == "free" for j in body.findall("joint"))}


def add_robot_file(
    plant: MultibodyPlant,
    path: PathArg,
    *,
    meshes: bool = False,
    floating_base: bool = False,
    package_paths: Mapping[str, PathArg] | None = None,
) -> list[ModelInstanceIndex]:
    """Add the robot described by the file ``path`` to an unfinalized ``plant`` (its geometry only
    with ``meshes`` and a plant registered with a SceneGraph), as :func:`load_robot_file` does, and
    return its model instances (one for a URDF). For a plant of your own, e.g. a physics plant."""
    file = Path(path).expanduser()
    check_is_file(file, path)
    resolver = PackageResolver(file, package_paths)
    if description_format(file) == "urdf":
        return [_add_urdf(plant, file, resolver, meshes, floating_base)]
    return _add_other(plant, file, resolver, floating_base)


def check_time_step(time_step: object) -> float:
    """``time_step`` (s) if it is a finite number ≥ 0 (0: a continuous plant), else :class:`InvalidInput`."""
    if isinstance(time_step, bool) or not isinstance(time_step, (int, float, np.floating, np.integer)) \
            or not (np.isfinite(time_step) and time_step >= 0):
        raise InvalidInput(f"time_step: expected a finite number ≥ 0 (s; 0 for a continuous plant), got {time_step!r:.60}")
    return float(time_step)


#: Drake joints whose ``q̇`` is not ``v`` (roll-pitch-yaw angles): the SoT's device integrates ``q``
#: as ``q̇ = v`` for every joint but the quaternion floating base.
UNSUPPORTED_JOINTS = {"ball_rpy": "a ball joint (Drake's BallRpyJoint)", "rpy_floating": "a roll-pitch-yaw floating joint"}


def check_joint_types(plant: MultibodyPlant, source: object) -> None:
    """:class:`RobotDescriptionError` naming a joint of ``plant`` the SoT cannot integrate
    (:data:`UNSUPPORTED_JOINTS`)."""
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        kind = UNSUPPORTED_JOINTS.get(joint.type_name())
        if kind is not None:
            raise RobotDescriptionError(
                f"{source}: joint {joint.name()!r} is {kind}, whose q̇ is not its velocity v: not supported (the SoT "
                "integrates revolute, prismatic, continuous, planar and universal joints and one free base); "
                "model it as a chain of revolute joints, or as a free base (<freejoint/>)")


def find_srdf(path: Path) -> Path | None:
    """``<stem>.srdf`` beside the description, or in a ``srdf/`` folder beside its folder."""
    for candidate in (path.with_suffix(".srdf"), path.parent.parent / "srdf" / f"{path.stem}.srdf"):
        if candidate.is_file():
            return candidate
    return None


def _movable_dofs(plant: MultibodyPlant) -> int:
    return sum(
        plant.get_joint(JointIndex(i)).num_velocities()
        for i in range(plant.num_joints())
        if not plant.get_joint(JointIndex(i)).type_name().endswith("quaternion_floating")
    )


def load_robot_file(
    path: PathArg,
    meshes: bool = False,
    time_step: float = 0.0,
    *,
    srdf: PathArg | None = None,
    package_paths: Mapping[str, PathArg] | None = None,
    floating_base: bool = False,
    operational_points: Mapping[str, str] | Sequence[str] | None = None,
    reference_posture: Any = None,
) -> RobotModel:
    """A finalized :class:`RobotModel` of the robot described by ``path`` (see the module
    docstring). Errors: :class:`~sotdrake.exceptions.RobotFileNotFound` (no such file, or a folder),
    :class:`~sotdrake.exceptions.RobotDescriptionError` (unreadable file, a non-finite limit, no
    movable joint, see :mod:`~sotdrake.robots.model_checks`), :class:`~sotdrake.exceptions.PackageNotFound`,
    :class:`~sotdrake.exceptions.FrameNotFound` (an op point on a frame the model lacks),
    :class:`~sotdrake.exceptions.InvalidInput` (an op point named like another frame)."""
    file = Path(path).expanduser()
    check_is_file(file, path)
    if not isinstance(floating_base, bool):
        raise InvalidInput(f"floating_base must be True or False, got {floating_base!r}")
    if srdf is not None and not isinstance(srdf, (str, PathLike)):
        raise InvalidInput(f"srdf: expected the path of an SRDF file (a string or a path), got {srdf!r:.60}")
    srdf_path = find_srdf(file) if srdf is None else Path(srdf).expanduser()
    if srdf_path is not None and not srdf_path.is_file():
        raise InvalidInput(f"srdf={str(srdf)!r}: no such file")
    if srdf_path is not None:
        srdf_path = srdf_path.resolve()  # (kept: a later change of directory does not change the file)
    plant = MultibodyPlant(check_time_step(time_step))
    scene_graph = None
    if meshes:
        scene_graph = SceneGraph()
        plant.RegisterAsSourceForSceneGraph(scene_graph)
    add_robot_file(plant, file, meshes=meshes, floating_base=floating_base, package_paths=package_paths)
    with drake_refusals(file):
        plant.Finalize()
    if _movable_dofs(plant) == 0 and not plant.GetFloatingBaseBodies():
        raise RobotDescriptionError(f"{file}: the robot has no movable joint (every joint is fixed): nothing to control "
                                    "(a single flying body: floating_base=True)")
    check_joint_types(plant, file)
    floating = bool(plant.GetFloatingBaseBodies())
    model = RobotModel(
        plant=plant,
        variant="file",
        OperationalPointsMap=OperationalPoints(),
        half_sitting=np.zeros(plant.num_positions()),
        fixed_base=not floating,
        scene_graph=scene_graph,
        srdf_path=srdf_path,
        name=file.stem,
        base="free" if floating else "fixed",
        source_path=file.resolve(),
        load_options={
            "srdf": None if srdf is None else srdf_path,
            "package_paths": None if package_paths is None else {name: Path(folder).expanduser().resolve()
                                                                 for name, folder in package_paths.items()},
            "floating_base": floating_base,
            "operational_points": operational_points,
            "reference_posture": reference_posture,
        },
    )
    model.OperationalPointsMap.update(operational_points_of(model, operational_points))
    if description_format(file) == "urdf":
        model.mimic = mimic_table(_read_text(file))
    model.half_sitting = posture_of(model, reference_posture)
    return model
