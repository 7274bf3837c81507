"""Scenes: every collision shape of a URDF or SDF model (a table, a shelf) added as obstacles.

``add_scene(robot, source, X_WS, name)`` parses ``source`` (a ``.urdf``/``.sdf`` file, or the
text of one) with Drake's ``Parser`` on a plant of its own, welds each body no joint holds (the
model's root; in an SDF model that is not static, each link without a joint) to the world where the
file puts it (a URDF's root at the model's own frame ``S``), with ``S`` at ``X_WS`` in the world (a
``RigidTransform`` or a 4×4 matrix, m; identity by default), and adds each collision geometry ``G``
as an obstacle (:func:`~.obstacles.add_obstacle`) at ``X_WG = X_WS · X_SB · X_BG`` (``B`` its body),
named ``<name>/<geometry name>``. A scene is fixed: a joint that moves (revolute, prismatic, …) is
placed at its default position (0 unless the file gives one) clipped into its limits, and a URDF
``floating`` joint, which Drake would drop (its child free, its origin lost), is refused. The
obstacles are then in the robot's collision world, drawn in Meshcat when ``meshcat`` is given, and
in the physics plant built after (:func:`obstacle_geometries`, the ``obstacles`` argument of
:func:`~sotdrake.physics.add_physical_talos`).

Everything is checked before anything is added: a missing file, text Drake cannot parse, a mesh
that does not load, a model without collision geometry, a floating joint, a name already used (or
beginning or ending with whitespace), a ``meshcat`` that is not a ``Meshcat`` raise
:class:`~sotdrake.exceptions.SotError` naming it, and the world is left as it was.

:data:`SHELF` is the shelf shipped with sotdrake (``sotdrake/data/shelf.sdf``): a 0.8 m wide,
0.4 m deep, 1.2 m high bookcase with three compartments (boards 2 cm thick at z = 0.41, 0.81 m
and the top), its back at x = +0.2 m, open towards −x, its frame on the floor at its centre.
"""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat, Role, SceneGraph, Shape
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import BodyIndex, RigidBody

from ..exceptions import InvalidInput, SotError
from ..robots.from_file import is_drake_check
from ..robots.urdf_checks import positive_lengths
from .obstacles import _pose, add_obstacle, check_meshcat, check_name, draw_obstacles, make_shape, name_taken
from .world import CollisionWorld, collision_world

#: The shelf shipped with sotdrake (see the module docstring).
SHELF = Path(__file__).resolve().parent.parent / "data" / "shelf.sdf"
#: The shelf's compartments: the centre (m) of the free space of each, in the shelf's frame.
SHELF_COMPARTMENTS = {"low": (0.0, 0.0, 0.21), "middle": (0.0, 0.0, 0.61), "high": (0.0, 0.0, 1.00)}


def scene_shapes(source: str | Path, X_WS: object = None, name: str = "scene") -> list[tuple[str, Shape, RigidTransform]]:
    """``(obstacle name, shape, X_WG)`` of every collision geometry of ``source`` placed at ``X_WS``
    (see the module docstring: movable joints at their default position clipped into their limits,
    a floating joint refused), each shape checked as :func:`~.obstacles.add_obstacle` does."""
    check_name("add_scene", name)
    try:
        X = RigidTransform() if X_WS is None else _pose(f"scene {name}", X_WS)
    except InvalidInput:
        raise InvalidInput(f"add_scene({name!r}): X_WS must be a finite rigid transform (a RigidTransform or a 4×4 "
                           f"matrix, m), got {X_WS!r:.120}") from None
    plant = MultibodyPlant(0.0)
    scene_graph = SceneGraph()
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    parser = Parser(plant, scene_graph)
    parser.SetAutoRenaming(True)
    _parse(parser, source, name)
    for body in _free_bodies(plant):  # welded where the file puts them (a static SDF model's are already)
        plant.WeldFrames(plant.world_frame(), body.body_frame(), plant.GetDefaultFloatingBaseBodyPose(body))
    plant.Finalize()
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, np.clip(plant.GetPositions(context), plant.GetPositionLowerLimits(),
                                        plant.GetPositionUpperLimits()))
    inspector = scene_graph.model_inspector()
    shapes: list[tuple[str, Shape, RigidTransform]] = []
    for geometry in inspector.GetAllGeometryIds(Role.kProximity):
        body = plant.GetBodyFromFrameId(inspector.GetFrameId(geometry))
        X_SB = plant.EvalBodyPoseInWorld(context, body)
        label = f"{name}/{inspector.GetName(geometry).split('::')[-1]}"
        if any(label == taken for taken, _, _ in shapes):  # unnamed URDF geometries share their shape's name
            label = f"{label}_{len(shapes)}"
        shape = make_shape(inspector.GetShape(geometry).Clone(), label)
        shapes.append((label, shape, X @ X_SB @ inspector.GetPoseInFrame(geometry)))
    if not shapes:
        raise InvalidInput(f"add_scene({name!r}): {str(source)[:200]!r} has no collision geometry (no <collision> element "
                           "Drake loads): nothing to avoid")
    return shapes


def _parse(parser: Parser, source: str | Path, name: str) -> None:
    """Add the models of ``source`` (a path or the text of a URDF/SDF) to ``parser``'s plant, its SDF
    sizes and URDF joints checked first; :class:`InvalidInput` naming what Drake or the checks refuse."""
    try:
        if isinstance(source, Path) or (isinstance(source, str) and "<" not in source):
            path = Path(source)
            if path.suffix.lower() not in (".urdf", ".sdf") or not path.is_file():
                raise InvalidInput(f"add_scene({name!r}): source {str(source)!r:.200} is not an existing .urdf or .sdf file "
                                   "(or the text of one)")
            _check_text(path.read_text(encoding="utf-8", errors="replace"), path.suffix.lower()[1:], name)
            parser.AddModels(str(path))
        elif isinstance(source, str):
            kind = "sdf" if "<sdf" in source else "urdf"
            _check_text(source, kind, name)
            parser.AddModelsFromString(source, kind)
        else:
            raise InvalidInput(f"add_scene({name!r}): source must be a path or the text of a URDF/SDF, got {type(source).__name__}")
    except (RuntimeError, ValueError, SystemExit) as error:  # (SystemExit: one of Drake's checks, a box of size 0 …)
        if isinstance(error, InvalidInput) or (isinstance(error, SystemExit) and not is_drake_check(error)):
            raise
        raise InvalidInput(f"add_scene({name!r}): Drake could not parse {str(source)[:200]!r}: {str(error)[:400]}") from None


def _check_text(text: str, kind: str, name: str) -> None:
    """What Drake would read otherwise: an SDF shape size that is not a positive finite number, a
    URDF ``floating`` joint (Drake drops it: its child link would be left free, the joint's origin
    lost). :class:`InvalidInput` naming it; text that is not XML is left to Drake's parser."""
    try:
        root = ElementTree.fromstring(text)
    except ElementTree.ParseError:
        return  # (Drake's parser says what is wrong with it)
    if kind == "sdf":
        _check_sdf_sizes(root, name)
        return
    for joint in root.iter("joint"):
        if joint.get("type") == "floating":
            child = joint.find("child")
            raise InvalidInput(f"add_scene({name!r}): joint {joint.get('name')!r} is floating: Drake would leave its child "
                               f"link {child.get('link') if child is not None else None!r} free (a scene is fixed): "
                               "make it a fixed joint")


#: The sizes of SDFormat's shapes (m): each a positive finite number (SDFormat replaces a wrong one by its
#: default, 1 m, with a warning only).
_SDF_SIZES = {"box": ("size",), "sphere": ("radius",), "cylinder": ("radius", "length"), "capsule": ("radius", "length"),
              "ellipsoid": ("radii",)}


def _check_sdf_sizes(root: ElementTree.Element, name: str) -> None:
    """:class:`InvalidInput` naming the first SDF shape size that is not a positive finite number."""
    for shape, fields in _SDF_SIZES.items():
        for element in root.iter(shape):
            for field in fields:
                value = element.find(field)
                if value is not None and not positive_lengths(value.text):
                    raise InvalidInput(f"add_scene({name!r}): an SDF {shape}'s {field} must be positive finite numbers "
                                       f"(m), got {value.text!r:.80}")


def _free_bodies(plant: MultibodyPlant) -> list[RigidBody]:
    """The bodies of ``plant`` that no joint holds (each model's root; an SDF link without a joint),
    which Drake would leave free: the scene welds them."""
    children = {plant.get_joint(j).child_body().index() for j in plant.GetJointIndices()}
    bodies = (plant.get_body(BodyIndex(i)) for i in range(plant.num_bodies()))
    return [b for b in bodies if b.index() not in children and b.index() != plant.world_body().index()]


def add_scene(robot, source: str | Path, X_WS: object = None, name: str = "scene",
              meshcat: Meshcat | None = None) -> list[str]:
    """Add every collision geometry of the URDF/SDF ``source`` as an obstacle of ``robot`` (a
    :class:`~sotdrake.robot.Robot` or a :class:`~.world.CollisionWorld`), the model at ``X_WS``;
    returns the obstacles' names (see the module docstring: a joint that moves is placed at its
    default position clipped into its limits, a floating joint is refused). ``meshcat``: None or a
    ``Meshcat``. Nothing is added unless all can be."""
    check_meshcat("add_scene", meshcat)
    world = robot if isinstance(robot, CollisionWorld) else collision_world(robot)
    shapes = scene_shapes(source, X_WS, name)
    taken = [label for label, _, _ in shapes if name_taken(world, label)]
    if taken or len({label for label, _, _ in shapes}) != len(shapes):
        raise InvalidInput(f"add_scene({name!r}): obstacle names {taken or [s[0] for s in shapes]} are taken already "
                           "(or repeated): give the scene another name")
    if world.contexts_made:
        raise SotError(f"add_scene({name!r}): the collision world is in use already (a context of the diagram exists): "
                       "add scenes before building the diagram and creating its context")
    for label, shape, pose in shapes:
        add_obstacle(world, shape, pose, label)
    if meshcat is not None:
        draw_obstacles(meshcat, world, [label for label, _, _ in shapes])
    return [label for label, _, _ in shapes]


def obstacle_geometries(robot) -> list[tuple[str, Shape, RigidTransform]]:
    """``(name, shape, X_WO)`` of every obstacle of ``robot``'s collision world (or of a
    ``CollisionWorld``): the ``obstacles`` argument of :func:`~sotdrake.physics.add_physical_talos`,
    so that the simulated robot touches what the controller avoids."""
    world = robot if isinstance(robot, CollisionWorld) else collision_world(robot)
    out = []
    for name, (shape, pose) in world.obstacle_shapes.items():
        assert isinstance(shape, Shape) and isinstance(pose, RigidTransform)
        out.append((name, shape, pose))
    return out


def scene_point(X_WS: RigidTransform | np.ndarray, p_S: tuple[float, float, float]) -> np.ndarray:
    """A point given in the scene's frame (m), in the world."""
    X = X_WS if isinstance(X_WS, RigidTransform) else RigidTransform(np.asarray(X_WS))
    return X @ np.asarray(p_S, dtype=float)
