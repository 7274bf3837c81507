"""Support polygons and the margin of a point inside them.

A sole's footprint is the rectangle of :class:`GaitParameters` (``sole_length × sole_width``
around ``sole_centre`` in the sole frame) placed at the sole pose ``(x, y, yaw)``. In double
support the polygon is the convex hull of both footprints. The margin of a point ``p`` in a convex
polygon is its signed distance to the boundary: ``min_i n_iᵀ (p - a_i)`` over the edges (``a_i`` a
vertex, ``n_i`` the inward unit normal), positive inside (m).
"""

from __future__ import annotations

import numpy as np

from ..exceptions import InvalidInput, check_finite, check_type
from .gait import GaitParameters


def _checked(what: str, pose, gait: GaitParameters) -> np.ndarray:
    """``pose`` as a float array once it is three finite numbers and ``gait`` a :class:`GaitParameters`."""
    check_type(f"{what}: gait", gait, GaitParameters, "GaitParameters")
    return check_finite(f"{what}: pose (x, y, yaw; m, rad)", pose, (3,))


def sole_centre(pose, gait: GaitParameters) -> np.ndarray:
    """The footprint's centre (world xy) for a sole at ``(x, y, yaw)`` (finite; else :class:`InvalidInput`)."""
    return centre_of(_checked("sole_centre", pose, gait), gait)


def centre_of(pose, gait: GaitParameters) -> np.ndarray:
    """:func:`sole_centre` for arguments already checked (the walk plans' own)."""
    x, y, yaw = pose
    c, s = np.cos(yaw), np.sin(yaw)
    cx, cy = gait.sole_centre
    return np.array([x + c * cx - s * cy, y + s * cx + c * cy])


def footprint(pose, gait: GaitParameters) -> np.ndarray:
    """The footprint's four corners (4×2, counter-clockwise) for a sole at ``(x, y, yaw)`` (finite;
    else :class:`InvalidInput`)."""
    x, y, yaw = _checked("footprint", pose, gait)
    c, s = np.cos(yaw), np.sin(yaw)
    half = np.array([gait.sole_length, gait.sole_width]) / 2
    local = np.array(gait.sole_centre) + half * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]])
    return np.array([x, y]) + local @ np.array([[c, s], [-s, c]])


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise hull of 2D ``points`` (Andrew's monotone chain)."""
    pts = sorted(map(tuple, np.asarray(points, dtype=float)))

    def turn(o, a, b) -> float:  # z of (a - o) × (b - o)
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    def half(sequence):
        chain: list = []
        for p in sequence:
            while len(chain) >= 2 and turn(chain[-2], chain[-1], p) <= 0:
                chain.pop()
            chain.append(p)
        return chain

    lower, upper = half(pts), half(reversed(pts))
    return np.array(lower[:-1] + upper[:-1])


def support_polygon(poses: list, gait: GaitParameters) -> np.ndarray:
    """The convex hull of the footprints of the soles at ``poses`` (one or two finite ``(x, y, yaw)``;
    none, or anything else: :class:`InvalidInput`)."""
    array = check_finite("support_polygon: poses (one or two (x, y, yaw); m, rad)", poses)
    if array.ndim != 2 or array.shape[1] != 3 or not 1 <= len(array) <= 2:
        raise InvalidInput(f"support_polygon: poses must be the (x, y, yaw) of one or two soles, got shape {array.shape}")
    return convex_hull(np.vstack([footprint(p, gait) for p in array]))


def polygon_margin(point, polygon: np.ndarray) -> float:
    """Signed distance (m) from ``point`` to the boundary of the counter-clockwise convex
    ``polygon``: positive inside. ``point``: two finite numbers; ``polygon``: n ≥ 3 finite vertices
    (n×2), each given once, turning counter-clockwise and convex; anything else is an
    :class:`InvalidInput` naming the argument (a NaN point used to give NaN)."""
    p = check_finite("polygon_margin: point", point, (2,))
    vertices = check_finite("polygon_margin: polygon", polygon)
    if vertices.ndim != 2 or vertices.shape[1:] != (2,) or len(vertices) < 3:
        raise InvalidInput(f"polygon_margin: polygon must be n ≥ 3 vertices (an n×2 array, m), got shape {vertices.shape}")
    edges = np.roll(vertices, -1, axis=0) - vertices
    lengths = np.linalg.norm(edges, axis=1)
    following = np.roll(edges, -1, axis=0)
    turns = edges[:, 0] * following[:, 1] - edges[:, 1] * following[:, 0]  # > 0: a left turn
    if not lengths.min() > 0 or turns.min() < -1e-12 * lengths.max() ** 2 or not turns.sum() > 0:
        raise InvalidInput("polygon_margin: polygon must be convex, counter-clockwise, each vertex given once (not "
                           f"closed), got {vertices.tolist()!s:.200}")
    normals = np.column_stack([-edges[:, 1], edges[:, 0]]) / lengths[:, None]
    return float(np.min(np.einsum("ij,ij->i", normals, p - vertices)))
