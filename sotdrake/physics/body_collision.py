"""Whole-body collision geometry for the physics model: one box per link, fitted to its collision meshes.

For each body of the robot, the vertices of its URDF collision geometry (the convex hull of each
mesh, computed by Drake, with the URDF scale; the corners of boxes and of the boxes around
cylinders and spheres), expressed in the body frame ``B`` through each geometry's pose ``X_BG``,
give the axis-aligned box (in ``B``) that bounds them: ``fit_link_boxes`` returns its size and
centre ``p_BoBc`` (m). A box bounds the mesh, so a fallen robot rests on the ground at most a few
centimetres higher than on its meshes; feet keep their sole boxes (:mod:`.plant`), so the foot links
get no box.

The boxes collide with the ground only: every pair of the robot's own geometries is filtered
(adjacent links overlap at their joints, and in half-sitting the arm boxes touch the torso box), so a
standing or reaching robot never collides with itself and the standing numbers are those of the
soles alone. They use point contact (``μ`` of the soles, Drake's default point stiffness) against the
rigid-hydroelastic ground.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from pydrake.geometry import (
    Box,
    Capsule,
    Convex,
    Cylinder,
    Ellipsoid,
    GeometrySet,
    Mesh,
    Role,
    SceneGraph,
    Sphere,
)
from pydrake.multibody.plant import MultibodyPlant

from ..exceptions import SotError
from ..robots.talos import add_talos


def shape_vertices(shape) -> np.ndarray:
    """Points (n × 3, geometry frame G) whose convex hull bounds ``shape``."""
    if isinstance(shape, (Mesh, Convex)):
        return _hull_vertices(shape)
    if isinstance(shape, Box):
        half = np.array([shape.width(), shape.depth(), shape.height()]) / 2
    elif isinstance(shape, Cylinder):
        half = np.array([shape.radius(), shape.radius(), shape.length() / 2])
    elif isinstance(shape, Capsule):
        half = np.array([shape.radius(), shape.radius(), shape.length() / 2 + shape.radius()])
    elif isinstance(shape, Sphere):
        half = np.full(3, shape.radius())
    elif isinstance(shape, Ellipsoid):
        half = np.array([shape.a(), shape.b(), shape.c()])
    else:
        raise SotError(f"no bounding box for a collision shape of type {type(shape).__name__}")
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return signs * half


def _hull_vertices(shape) -> np.ndarray:
    hull = shape.GetConvexHull()
    return np.array([hull.vertex(i) for i in range(hull.num_vertices())])


@lru_cache(maxsize=4)
def fit_link_boxes(variant: str = "reduced") -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Body name → ``(size, centre)`` of the box bounding its collision geometry, in the body frame
    (m). A pure cache: the boxes depend on the URDF only."""
    scene_graph = SceneGraph()
    plant = MultibodyPlant(0.0)
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    add_talos(plant, variant, meshes=True, collision=True)
    plant.Finalize()
    inspector = scene_graph.model_inspector()
    points: dict[str, list[np.ndarray]] = {}
    for geometry in inspector.GetGeometryIds(GeometrySet(inspector.GetAllGeometryIds()), Role.kProximity):
        body = plant.GetBodyFromFrameId(inspector.GetFrameId(geometry))
        X_BG = inspector.GetPoseInFrame(geometry)
        p_BV = X_BG.multiply(shape_vertices(inspector.GetShape(geometry)).T).T
        points.setdefault(body.name(), []).append(p_BV)
    boxes = {}
    for name, chunks in points.items():
        p = np.vstack(chunks)
        low, high = p.min(axis=0), p.max(axis=0)
        boxes[name] = (high - low, (high + low) / 2)
    return boxes
