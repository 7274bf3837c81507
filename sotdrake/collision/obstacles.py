"""Obstacles: fixed shapes in the world that the robot's collision task keeps away from.

``add_obstacle(robot, shape, X_WO, name)`` adds the shape, at pose ``X_WO`` (its frame ``O`` in
the world, a ``RigidTransform`` or a 4×4 matrix, m), to the robot's collision world
(:func:`~.world.collision_world`) as anchored geometry, and draws it in Meshcat when one is given.
``shape`` is one of

* ``("box", (x, y, z))`` (full sizes, m, centred on ``O``), ``("sphere", r)``,
  ``("cylinder", r, length)`` (along ``O``'s z), ``("mesh", path)`` or ``("mesh", path, scale)``
  (an OBJ file; Drake uses its convex hull for distances);
* or the Drake shape itself (``Box``, ``Sphere``, ``Cylinder``, ``Capsule``, ``Ellipsoid``,
  ``Mesh``, ``Convex``).

Every value is checked before anything is added: a size that is not a finite number in
[1 µm, 100 m], a non-finite pose, a mesh that does not load (or has no volume; an OBJ file without
faces or with a face index out of range), a name that is empty, begins or ends with whitespace
(Drake would strip it, and ``"table "`` would be ``"table"``) or is already used by a link, a frame,
a joint, an op point or an obstacle, a ``meshcat`` that is neither None nor a ``Meshcat``, an
obstacle added after the collision world's first context was made.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from pydrake.geometry import (
    Box,
    Capsule,
    Convex,
    Cylinder,
    Ellipsoid,
    GeometryId,
    GeometryInstance,
    Mesh,
    Meshcat,
    ProximityProperties,
    Rgba,
    Shape,
    Sphere,
)
from pydrake.math import RigidTransform

from ..exceptions import InvalidInput, NotFound, SotError, check_finite
from ..lie import check_rotation
from .world import CollisionWorld, collision_world

#: The colour obstacles are drawn in (RGBA).
OBSTACLE_COLOR = Rgba(0.85, 0.45, 0.2, 0.6)
#: Smallest and largest size accepted for an obstacle (m).
MIN_SIZE, MAX_SIZE = 1e-6, 100.0


def _size(name: str, what: str, value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)) \
            or not (math.isfinite(value) and MIN_SIZE <= value <= MAX_SIZE):
        raise InvalidInput(f"add_obstacle({name!r}): shape {what} must be a finite number in [{MIN_SIZE:g}, {MAX_SIZE:g}] m, "
                           f"got {value!r:.80}")
    return float(value)


def make_shape(shape: object, name: str = "obstacle") -> Shape:
    """A Drake shape from a description (see the module docstring), every size checked."""
    if isinstance(shape, Shape):
        return _checked_drake_shape(shape, name)
    if not isinstance(shape, (tuple, list)) or not shape or not isinstance(shape[0], str):
        raise InvalidInput(f"add_obstacle({name!r}): shape must be ('box', (x, y, z)), ('sphere', r), ('cylinder', r, length), "
                           f"('mesh', path[, scale]) or a Drake shape, got {shape!r:.100}")
    kind, args = shape[0], tuple(shape[1:])
    if kind == "box" and len(args) == 1 and isinstance(args[0], (tuple, list, np.ndarray)) and len(args[0]) == 3:
        return Box(*(_size(name, f"box size {axis}", v) for axis, v in zip("xyz", args[0], strict=True)))
    if kind == "sphere" and len(args) == 1:
        return Sphere(_size(name, "sphere radius", args[0]))
    if kind == "cylinder" and len(args) == 2:
        return Cylinder(_size(name, "cylinder radius", args[0]), _size(name, "cylinder length", args[1]))
    if kind == "mesh" and len(args) in (1, 2):
        scale = _size(name, "mesh scale", args[1]) if len(args) == 2 else 1.0
        return _checked_drake_shape(Mesh(str(_mesh_path(name, args[0])), scale), name)
    raise InvalidInput(f"add_obstacle({name!r}): unknown shape {shape!r:.100}: ('box', (x, y, z)), ('sphere', r), "
                       "('cylinder', r, length) or ('mesh', path[, scale])")


def _mesh_path(name: str, path: object) -> Path:
    if not isinstance(path, (str, Path)) or not Path(path).is_file():
        raise InvalidInput(f"add_obstacle({name!r}): mesh file {path!r:.200} does not exist")
    if Path(path).suffix.lower() == ".obj":
        _check_obj(name, Path(path))
    return Path(path)


def _check_obj(name: str, path: Path) -> None:
    """An OBJ file's vertices (three finite numbers each: the convex hull leaves a NaN vertex out)
    and faces (at least one of three vertices or more, every index one of the vertices given so far,
    from 1, or from -1 backwards): Drake registers a mesh without faces, or with an index out of
    range, only halfway or stops the process, after the convex hull, which ignores faces, was taken."""
    vertices = faces = 0
    with open(path, encoding="utf-8", errors="replace") as file:
        for line_number, line in enumerate(file, 1):
            words = line.split()
            where = f"add_obstacle({name!r}): mesh {str(path)!r} line {line_number}"
            if words[:1] == ["v"]:
                if not (len(words) >= 4 and all(math.isfinite(number(word)) for word in words[1:4])):
                    raise InvalidInput(f"{where}: a vertex that is not three finite numbers: {line.strip()!r:.80}")
                vertices += 1
            elif words[:1] == ["f"]:
                indices = [number(word.split("/")[0]) for word in words[1:]]
                if len(indices) < 3 or not all(math.isfinite(i) and i == int(i) and (1 <= i <= vertices or -vertices <= i <= -1)
                                               for i in indices):
                    raise InvalidInput(f"{where}: a face needs three vertex indices or more, each from 1 to the {vertices} "
                                       f"vertices given before it (or -1 to -{vertices}): {line.strip()!r:.80}")
                faces += 1
    if faces == 0:
        raise InvalidInput(f"add_obstacle({name!r}): mesh {str(path)!r} has no face (an 'f' line): a surface is needed")


def number(word: str) -> float:
    """``word`` as a float, NaN if it is not a number (a mesh's or a scene's text)."""
    try:
        return float(word)
    except ValueError:
        return math.nan


def _checked_drake_shape(shape: Shape, name: str) -> Shape:
    if isinstance(shape, (Mesh, Convex)):
        _mesh_path(name, shape.filename() if hasattr(shape, "filename") else shape.source().path())
        try:
            hull = shape.GetConvexHull()
        except RuntimeError as error:
            if "coplanar" in str(error) or "volume" in str(error):
                raise InvalidInput(f"add_obstacle({name!r}): the mesh is flat (its convex hull has no volume)") from None
            raise InvalidInput(f"add_obstacle({name!r}): the mesh does not load: {error}") from None
        vertices = np.array([hull.vertex(i) for i in range(hull.num_vertices())])
        if vertices.size == 0 or not np.ptp(vertices, axis=0).min() > 0:  # (NaN too)
            raise InvalidInput(f"add_obstacle({name!r}): the mesh is flat, empty or has a non-finite vertex (its convex "
                               "hull has no volume)")
        extent = float(np.ptp(vertices, axis=0).max())  # (the hull's vertices are scaled)
        if not extent <= 2 * MAX_SIZE:
            raise InvalidInput(f"add_obstacle({name!r}): the mesh spans {extent:.6g} m (scaled): at most {2 * MAX_SIZE:g} m")
        if hasattr(shape, "scale3"):  # (a mirrored or huge mesh, as a described one)
            for axis, value in zip("xyz", shape.scale3(), strict=True):
                _size(name, f"mesh scale {axis}", float(value))
        else:
            _size(name, "mesh scale", float(shape.scale()))
    elif not isinstance(shape, (Box, Sphere, Cylinder, Capsule, Ellipsoid)):
        raise InvalidInput(f"add_obstacle({name!r}): {type(shape).__name__} is not a shape an obstacle can have")
    else:  # the sizes a described shape has checked (Drake accepts any positive one)
        for what, value in _DRAKE_SIZES[type(shape)](shape):
            _size(name, f"{type(shape).__name__.lower()} {what}", float(value))
    return shape


#: The sizes (m) of each Drake shape an obstacle can be, for :func:`_size`.
_DRAKE_SIZES = {
    Box: lambda s: (("size x", s.width()), ("size y", s.depth()), ("size z", s.height())),
    Sphere: lambda s: (("radius", s.radius()),),
    Cylinder: lambda s: (("radius", s.radius()), ("length", s.length())),
    Capsule: lambda s: (("radius", s.radius()), ("length", s.length())),
    Ellipsoid: lambda s: (("a", s.a()), ("b", s.b()), ("c", s.c())),
}


def _pose(name: str, X_WO: object) -> RigidTransform:
    if isinstance(X_WO, RigidTransform):
        matrix = X_WO.GetAsMatrix4()
    else:
        matrix = check_finite(f"add_obstacle({name!r}): X_WO (a RigidTransform or a 4×4 matrix)", X_WO, (4, 4))
    matrix = check_finite(f"add_obstacle({name!r}): X_WO", matrix, (4, 4), bound=1e3)
    if not np.allclose(matrix[3], [0, 0, 0, 1]):
        raise InvalidInput(f"add_obstacle({name!r}): X_WO is not a rigid transform (its last row is not (0, 0, 0, 1))")
    check_rotation(f"add_obstacle({name!r}): X_WO is not a rigid transform: its rotation", matrix[:3, :3])
    return RigidTransform(matrix) if not isinstance(X_WO, RigidTransform) else X_WO


def check_name(what: str, name: object) -> str:
    """``name`` if it is a non-empty string that neither begins nor ends with whitespace (Drake
    strips it from a geometry's name: ``"table "`` would be registered as ``"table"``), else
    :class:`InvalidInput` naming ``what``."""
    if not isinstance(name, str) or not name.strip():
        raise InvalidInput(f"{what}: name must be a non-empty string, got {name!r:.80}")
    if name != name.strip():
        raise InvalidInput(f"{what}: name {name!r:.80} begins or ends with whitespace, which Drake strips from a "
                           f"geometry's name: give {name.strip()!r:.80}")
    return name


def check_meshcat(what: str, meshcat: object) -> Meshcat | None:
    """``meshcat`` if it is None or a pydrake ``Meshcat`` (:func:`~sotdrake.start_meshcat`), else
    :class:`InvalidInput` naming ``what``: checked before anything is added."""
    if meshcat is not None and not isinstance(meshcat, Meshcat):
        raise InvalidInput(f"{what}: meshcat must be None or a pydrake Meshcat (start_meshcat()), got {type(meshcat).__name__}")
    return meshcat


def name_taken(world: CollisionWorld, name: str) -> str | None:
    """What already has ``name`` in ``world`` (an obstacle, a link, or a frame, joint or op point of
    the robot: a pair naming it would then mean the obstacle), or None."""
    if name in world.obstacles:
        return "an obstacle"
    if name in world.links or world.plant.HasBodyNamed(name):
        return "a link"
    if world.model.find_frame(name) is not None:  # (frames, op points, and joints by their child frame)
        return f"a frame, joint or op point of {world.model.name}"
    return None


def add_obstacle(robot, shape: object, X_WO: object, name: str, meshcat: Meshcat | None = None) -> GeometryId:
    """Add an obstacle to the collision world of ``robot`` (a :class:`~sotdrake.robot.Robot`, or a
    :class:`~.world.CollisionWorld`) and return its geometry id; see the module docstring. With
    ``meshcat`` (None or a ``Meshcat``) it is drawn there too, under ``obstacles/<name>``. Every
    argument is checked first (:class:`InvalidInput` naming it): nothing is added on a refusal."""
    check_meshcat("add_obstacle", meshcat)
    world = robot if isinstance(robot, CollisionWorld) else collision_world(robot)
    check_name("add_obstacle", name)
    taken = name_taken(world, name)
    if taken:
        raise InvalidInput(f"add_obstacle: {name!r} is already the name of {taken}: take another name")
    drake_shape = make_shape(shape, name)
    pose = _pose(name, X_WO)
    if world.contexts_made:
        raise SotError(f"add_obstacle({name!r}): the collision world is in use already (a context of the diagram exists): "
                       "add obstacles before building the diagram and creating its context")
    instance = GeometryInstance(pose, drake_shape, name)
    instance.set_proximity_properties(ProximityProperties())
    geometry = world.scene_graph.RegisterAnchoredGeometry(world.source_id, instance)
    world.obstacles[name] = geometry
    world.obstacle_shapes[name] = (drake_shape, pose)
    if meshcat is not None:
        draw_obstacles(meshcat, world, [name])
    return geometry


def draw_obstacles(meshcat: Meshcat, robot, names: list[str] | None = None) -> None:
    """Draw the obstacles of ``robot``'s collision world (or of a ``CollisionWorld``) in Meshcat,
    under ``obstacles/<name>`` (all of them, or ``names``, a list of obstacle names). A ``meshcat``
    that is not a ``Meshcat`` or ``names`` that is not a list of strings: :class:`InvalidInput`; a
    name that is not an obstacle's: :class:`~sotdrake.exceptions.NotFound` listing them; nothing is
    drawn then."""
    if not isinstance(meshcat, Meshcat):
        raise InvalidInput(f"draw_obstacles: meshcat must be a pydrake Meshcat (start_meshcat()), got {type(meshcat).__name__}")
    world = robot if isinstance(robot, CollisionWorld) else collision_world(robot)
    if names is None:
        names = list(world.obstacle_shapes)
    if isinstance(names, str) or not isinstance(names, (list, tuple)) or not all(isinstance(n, str) for n in names):
        raise InvalidInput(f"draw_obstacles: names must be None or a list of obstacle names, got {names!r:.80}")
    for name in names:
        if name not in world.obstacle_shapes:
            raise NotFound(name, list(world.obstacle_shapes)).but("draw_obstacles: names: not an obstacle")
    for name in names:
        shape, pose = world.obstacle_shapes[name]
        meshcat.SetObject(f"obstacles/{name}", shape, OBSTACLE_COLOR)
        meshcat.SetTransform(f"obstacles/{name}", pose)
