"""The collision world of a robot: its collision geometry on a SceneGraph, and the obstacles.

The control model (:class:`~sotdrake.robots.RobotModel`) has no geometry: the kinematics need none.
:class:`CollisionWorld` loads the same robot once more with its collision geometry (Drake treats a
mesh as its convex hull for distance queries), on a plant of its own registered with a SceneGraph,
checks that this plant has the control model's coordinates (``q``, ``v`` in the same order), and
keeps the obstacles (anchored geometry, :func:`~sotdrake.collision.add_obstacle`).

Pairs (:mod:`.pairs`): by default every pair of the robot's bodies that its SRDF and its kinematic
tree leave (filtered out of the SceneGraph, so its broad phase skips them) and every pair of a
link and an obstacle (the SceneGraph's collision candidates); with explicit ``pairs`` only those.
The collision task queries them one ``ComputeSignedDistancePairClosestPoints`` each, only those
that may be in range (:mod:`.schedule`). Obstacles are added before the first context of the diagram is made (the task's cache
entry then holds its own copy of this world's context).
"""

from __future__ import annotations

import logging
import weakref
from collections.abc import Sequence

from pydrake.geometry import CollisionFilterDeclaration, GeometryId, GeometrySet, Role
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import BodyIndex, RigidBody
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, LeafContext

from ..exceptions import InvalidInput, SotError, check_flag, check_type
from ..robots import RobotModel
from .pairs import Pair, adjacent_pairs, check_pairs, srdf_disabled_pairs

log = logging.getLogger(__name__)


class NoCollisionGeometry(SotError):
    """The robot has no collision geometry to compute distances with."""


class CollisionWorld:
    """The robot's collision geometry and the obstacles (see the module docstring).

    ``model``: the control model (loaded again with its collision geometry); ``use_srdf``: leave out
    the pairs its SRDF disables (the adjacent pairs are always left out). A ``model`` that is not a
    :class:`~sotdrake.robots.RobotModel` (a robot: :func:`collision_world`) or a ``use_srdf`` that is
    not a bool: :class:`InvalidInput`; :class:`NoCollisionGeometry` for a robot whose description
    has no collision geometry."""

    def __init__(self, model: RobotModel, use_srdf: bool = True):
        hint = ", or collision_world(robot) for a robot" if hasattr(model, "model") else ""
        check_type("CollisionWorld: model", model, RobotModel, f"a RobotModel (robot.model){hint}")
        check_flag("CollisionWorld: use_srdf", use_srdf)
        loaded = model.with_meshes()
        plant, scene_graph = loaded.plant, loaded.scene_graph
        if scene_graph is None:
            raise NoCollisionGeometry(f"{model.name}: loading it with its meshes gave no SceneGraph")
        _check_same_coordinates(model.plant, plant, model.name)
        self.model, self.plant, self.scene_graph = model, plant, scene_graph
        inspector = scene_graph.model_inspector()
        self._geometries: dict[str, list[GeometryId]] = {}
        for geometry in inspector.GetAllGeometryIds(Role.kProximity):
            body = plant.GetBodyFromFrameId(inspector.GetFrameId(geometry))
            if body is not None:
                self._geometries.setdefault(body.name(), []).append(geometry)
        if not self._geometries:
            raise NoCollisionGeometry(
                f"{model.name} has no collision geometry: its description gives no <collision> element (or none Drake "
                "loads); add collision shapes to its URDF/SDF to compute distances")
        self.adjacent = adjacent_pairs(plant)
        self.disabled: set[Pair] = srdf_disabled_pairs(model.srdf_path) if use_srdf else set()
        _warn_case_typos(self.disabled, plant, model)
        self._filter_self_pairs(self.disabled | self.adjacent)
        self.obstacles: dict[str, GeometryId] = {}
        self._info: dict[GeometryId, tuple[str, RigidBody, RigidTransform]] = {}
        self.obstacle_shapes: dict[str, tuple[object, object]] = {}  # name -> (shape, X_WO), for drawing
        self.source_id = scene_graph.RegisterSource("obstacles")
        builder = DiagramBuilder()
        builder.AddSystem(plant)
        builder.AddSystem(scene_graph)
        builder.Connect(plant.get_geometry_pose_output_port(), scene_graph.get_source_pose_port(plant.get_source_id()))
        builder.Connect(scene_graph.get_query_output_port(), plant.get_geometry_query_input_port())
        self.diagram: Diagram = builder.Build()
        self.contexts_made = False
        #: Where each free body's quaternion starts in ``q`` (the floating base's: ``(qw, qx, qy, qz)``).
        self.quaternion_starts = [plant.get_body(b).floating_positions_start() for b in plant.GetFloatingBaseBodies()]
        self._proximity: frozenset[GeometryId] | None = None

    @property
    def links(self) -> list[str]:
        """The bodies that carry collision geometry."""
        return list(self._geometries)

    def geometries(self, name: str) -> list[GeometryId]:
        """The proximity geometries of a body or an obstacle."""
        return [self.obstacles[name]] if name in self.obstacles else self._geometries[name]

    def self_pairs(self) -> list[tuple[str, str]]:
        """Every pair of bodies checked by default (neither SRDF-disabled nor adjacent)."""
        links = self.links
        excluded = self.disabled | self.adjacent
        return [(a, b) for i, a in enumerate(links) for b in links[i + 1 :] if frozenset((a, b)) not in excluded]

    def check_pairs(self, pairs: object) -> list[tuple[str, str]]:
        """``pairs`` checked against this world's links and obstacles (:func:`.pairs.check_pairs`)."""
        return check_pairs(pairs, self.links, self.obstacles, self.adjacent)

    def geometry_pairs(self, pairs: Sequence[tuple[str, str]]) -> list[tuple[GeometryId, GeometryId]]:
        """The geometry pairs of body/obstacle pairs (the robot's side first)."""
        out = []
        for a, b in pairs:
            if a in self.obstacles:
                a, b = b, a
            out += [(ga, gb) for ga in self.geometries(a) for gb in self.geometries(b)]
        return out

    def new_context(self) -> Context:
        """A context of the collision diagram (after which obstacles can no longer be added)."""
        self.contexts_made = True
        return self.diagram.CreateDefaultContext()

    def plant_context(self, context: Context) -> Context:
        """The plant's context in the collision diagram ``context`` (:meth:`new_context`); any other
        value (None, a leaf context, another diagram's context): :class:`InvalidInput`."""
        return self._own_context(self.plant, context)

    def query(self, context: Context):
        """The SceneGraph's query object in the collision diagram ``context`` (:meth:`new_context`);
        any other value: :class:`InvalidInput`."""
        return self.scene_graph.get_query_output_port().Eval(self._own_context(self.scene_graph, context))

    def _own_context(self, system, context: Context) -> Context:
        try:  # (the check costs nothing when the context is right: this runs at every tick)
            return system.GetMyContextFromRoot(context)
        except (TypeError, RuntimeError):  # (None and other types: TypeError; a leaf or foreign context: RuntimeError)
            got = "a leaf context" if isinstance(context, LeafContext) else \
                "another diagram's context" if isinstance(context, Context) else f"{context!r:.60}"
            raise InvalidInput(f"collision world of {self.model.name}: context must be a context of its collision diagram "
                               f"(world.new_context()), got {got}") from None

    @property
    def obstacle_ids(self) -> set[GeometryId]:
        return set(self.obstacles.values())

    def proximity_geometries(self) -> frozenset[GeometryId]:
        """Every geometry a distance query takes (the robot's collision geometry and the obstacles),
        kept once a context is made (no obstacle can be added then)."""
        if self._proximity is not None:
            return self._proximity
        ids = frozenset(self.scene_graph.model_inspector().GetAllGeometryIds(Role.kProximity))
        if self.contexts_made:
            self._proximity = ids
        return ids

    def geometry_info(self, geometry: GeometryId) -> tuple[str, RigidBody, RigidTransform]:
        """``(name, body, X_BG)`` of a geometry: its body's (or obstacle's) name, the body it is
        attached to (the world body for an obstacle) and its pose in that body's frame."""
        info = self._info.get(geometry)
        if info is None:
            inspector = self.scene_graph.model_inspector()
            body = self.plant.GetBodyFromFrameId(inspector.GetFrameId(geometry))
            names = [name for name, obstacle in self.obstacles.items() if obstacle == geometry]
            info = self._info[geometry] = (names[0] if names else body.name(), body, inspector.GetPoseInFrame(geometry))
        return info

    def _filter_self_pairs(self, excluded: set[Pair]) -> None:
        declaration = CollisionFilterDeclaration()
        for pair in excluded:
            a, b = tuple(pair)
            if a in self._geometries and b in self._geometries:
                declaration.ExcludeBetween(GeometrySet(self._geometries[a]), GeometrySet(self._geometries[b]))
        self.scene_graph.collision_filter_manager().Apply(declaration)


def _check_same_coordinates(control: MultibodyPlant, collision: MultibodyPlant, name: str) -> None:
    """The collision plant must have the control plant's ``q`` and ``v``, joint by joint."""
    def layout(plant: MultibodyPlant) -> list[tuple[str, int, int, int, int]]:
        joints = (plant.get_joint(i) for i in plant.GetJointIndices())
        return sorted((j.name(), j.position_start(), j.num_positions(), j.velocity_start(), j.num_velocities()) for j in joints)

    if (control.num_positions(), control.num_velocities()) != (collision.num_positions(), collision.num_velocities()) \
            or layout(control) != layout(collision):
        raise NoCollisionGeometry(f"{name}: the model loaded with its collision geometry does not have the control "
                                  "model's coordinates; load the robot with meshes=True and pass that model")


#: The collision world of each robot (a ``sotdrake.Robot``), made on first use.
_WORLDS: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def collision_world(robot) -> CollisionWorld:
    """The collision world of ``robot`` (a :class:`~sotdrake.robot.Robot`), made on first use and
    shared by its collision tasks and obstacles."""
    if not hasattr(robot, "model") or not hasattr(robot, "builder"):
        raise InvalidInput(f"expected the robot (a Robot, or a RobotDyn), got {robot!r:.60}")
    world = _WORLDS.get(robot)
    if world is None:
        world = _WORLDS[robot] = CollisionWorld(robot.model)
    return world


def _warn_case_typos(pairs: set[Pair], plant: MultibodyPlant, model: RobotModel) -> None:
    """A warning for the SRDF's link names the model has only with other cases (``L3`` for ``l3``):
    those pairs stay checked. Other unknown names are left alone (a sub-model, e.g. one arm, leaves
    out links its robot's SRDF names)."""
    names = {plant.get_body(BodyIndex(index)).name() for index in range(plant.num_bodies())}
    lower = {name.lower(): name for name in names}
    typos = sorted({f"{n} ({lower[n.lower()]}?)" for pair in pairs for n in pair if n not in names and n.lower() in lower})
    if typos:
        log.warning("%s: <disable_collisions> names %s, which the model spells otherwise: those pairs stay checked",
                    model.srdf_path, ", ".join(typos))

