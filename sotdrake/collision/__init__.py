"""Collision avoidance as a strict level of the stack: distances from Drake's geometry queries,
self-collision pairs from the SRDF, obstacles, and the velocity-damper task.

* :mod:`.world`: :class:`CollisionWorld`, the robot's collision geometry and the obstacles;
* :mod:`.pairs`: which pairs are checked (SRDF ``disable_collisions`` and adjacency);
* :mod:`.distance`: signed distances, normals, witness points, ``J_d = n̂ᵀ (J_A − J_B)``;
* :mod:`.obstacles`: :func:`add_obstacle`, :func:`draw_obstacles`;
* :mod:`.scene`: :func:`add_scene` (every collision shape of a URDF/SDF), :func:`obstacle_geometries`
  (the obstacles for the physics plant), :data:`SHELF`;
* :mod:`.task`: :class:`TaskCollision` (rows ``J_d v ≥ −ξ (d − d_s)/(d_i − d_s)``);
* :mod:`.meta_task`: :class:`MetaTaskKineCollision` and :class:`MetaTaskDynCollision`, the one-line builders;
* :mod:`.reach`: :func:`build_collision_reach`, :func:`run_collision_reach`, the checked scenario
  of the tests, ``diagrams/talos_collisions.py`` and the bench.
"""

from __future__ import annotations

from .distance import PairDistances, minimum_distance, pair_distances
from .meta_task import MetaTaskDynCollision, MetaTaskKineCollision
from .obstacles import add_obstacle, draw_obstacles
from .pairs import adjacent_pairs, srdf_disabled_pairs
from .reach import TABLE, ReachReport, build_collision_reach, run_collision_reach
from .scene import SHELF, SHELF_COMPARTMENTS, add_scene, obstacle_geometries, scene_shapes
from .task import CollisionMargins, TaskCollision, acceleration_rows, check_margins, damper_rows
from .world import CollisionWorld, NoCollisionGeometry, collision_world

__all__ = [
    "SHELF",
    "SHELF_COMPARTMENTS",
    "TABLE",
    "CollisionMargins",
    "CollisionWorld",
    "MetaTaskDynCollision",
    "MetaTaskKineCollision",
    "NoCollisionGeometry",
    "PairDistances",
    "ReachReport",
    "TaskCollision",
    "acceleration_rows",
    "add_obstacle",
    "add_scene",
    "adjacent_pairs",
    "build_collision_reach",
    "check_margins",
    "collision_world",
    "damper_rows",
    "draw_obstacles",
    "minimum_distance",
    "obstacle_geometries",
    "pair_distances",
    "run_collision_reach",
    "scene_shapes",
    "srdf_disabled_pairs",
]
