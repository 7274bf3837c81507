"""The collision shapes as the pair schedule (:mod:`.schedule`) and its kernels (:mod:`.kernels`) see
them: a sphere holding each shape (for the bounds on how far a motion can bring a pair closer) and
each shape's support function ``max uᵀv`` over its points (for the support gaps that bound a pair's
signed distance from below), packed as the compiled kernel takes them."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydrake.geometry import Box, Capsule, Cylinder, Ellipsoid, Sphere

#: The coefficient (m per unit of motion) of a motion the bound cannot follow: large, finite (no NaN).
UNBOUNDED = 1e9
#: The shape kind codes of :func:`.kernels.gaps`, by :func:`support_data`'s name.
SUPPORT_KINDS = {"points": 0, "ellipsoid": 1, "cylinder": 2, "capsule": 3}


def bounding_sphere(shape: object) -> tuple[np.ndarray, float]:
    """Centre (in the geometry's frame, m) and radius (m) of a sphere holding ``shape`` (its convex
    hull for a mesh); an unbounded shape gets the radius :data:`UNBOUNDED`."""
    if isinstance(shape, Sphere):
        return np.zeros(3), shape.radius()
    if isinstance(shape, Box):
        return np.zeros(3), 0.5 * float(np.linalg.norm(shape.size()))
    if isinstance(shape, Cylinder):
        return np.zeros(3), float(np.hypot(shape.radius(), 0.5 * shape.length()))
    if isinstance(shape, Capsule):
        return np.zeros(3), shape.radius() + 0.5 * shape.length()
    if isinstance(shape, Ellipsoid):
        return np.zeros(3), max(shape.a(), shape.b(), shape.c())
    hull = getattr(shape, "GetConvexHull", None)
    if hull is None:
        return np.zeros(3), UNBOUNDED
    vertices = np.array([hull().vertex(i) for i in range(hull().num_vertices())])
    centre = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    return centre, float(np.linalg.norm(vertices - centre, axis=1).max())


class PackedSupports:
    """The shapes' :func:`support_data` as :func:`.kernels.gaps` takes them: per shape its kind code
    (``kinds``, -1 for a shape without a support function), ``params`` (3) and its vertices
    ``points[offsets[s]:offsets[s + 1]]``."""

    def __init__(self, data: Sequence[tuple | None]):
        self.kinds = np.full(len(data), -1, dtype=np.int64)
        self.params = np.zeros((len(data), 3))
        vertices = [np.zeros((0, 3))]
        self.offsets = np.zeros(len(data) + 1, dtype=np.int64)
        for s, item in enumerate(data):
            count = 0
            if item is not None:
                self.kinds[s] = SUPPORT_KINDS[item[0]]
                if item[0] == "points":
                    vertices.append(np.asarray(item[1], dtype=float).reshape(-1, 3))
                    count = len(vertices[-1])
                elif item[0] == "ellipsoid":
                    self.params[s] = item[1]
                else:  # a cylinder, a capsule: radius, half-length
                    self.params[s, :2] = item[1], item[2]
            self.offsets[s + 1] = self.offsets[s] + count
        self.points = np.ascontiguousarray(np.vstack(vertices))


def support_data(shape: object) -> tuple | None:
    """What :func:`support` needs of ``shape``: its hull's vertices (a mesh, a box) or its sizes (a
    sphere, a cylinder, a capsule, an ellipsoid); None for another shape."""
    if isinstance(shape, Sphere):
        return ("ellipsoid", np.full(3, shape.radius()))
    if isinstance(shape, Ellipsoid):
        return ("ellipsoid", np.array([shape.a(), shape.b(), shape.c()]))
    if isinstance(shape, Box):
        half = 0.5 * np.asarray(shape.size())
        return ("points", np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half)
    if isinstance(shape, Cylinder):
        return ("cylinder", shape.radius(), 0.5 * shape.length())
    if isinstance(shape, Capsule):
        return ("capsule", shape.radius(), 0.5 * shape.length())
    hull = getattr(shape, "GetConvexHull", None)
    if hull is None:
        return None
    mesh = hull()
    return ("points", np.array([mesh.vertex(i) for i in range(mesh.num_vertices())]))


def support(data: tuple, u: np.ndarray) -> float:
    """``max u·v`` over the points ``v`` of a shape (its frame; ``data`` from :func:`support_data`)."""
    kind = data[0]
    if kind == "points":
        return float((data[1] @ u).max())
    if kind == "ellipsoid":
        return float(np.linalg.norm(data[1] * u))
    radial = float(np.hypot(u[0], u[1])) if kind == "cylinder" else float(np.linalg.norm(u))
    return data[1] * radial + data[2] * abs(float(u[2]))
