"""Sound pair scheduling: which collision pairs need Drake's exact query at a tick.

A pair whose signed distance was ``D`` at the configuration ``q₀`` cannot be closer than

    d(q) ≥ D − Σ_j ρ_j |Δq_j| − ρ_b φ − |Δp|                                        (1)

at a later configuration ``q``: ``Δq_j`` is the motion of each revolute joint ``j`` on the
kinematic path between the pair's two bodies (rad; a prismatic joint counts ``|Δq_j|`` m with
``ρ_j = 1``), and when one side is an obstacle (fixed in the world), ``|Δp|`` (m) and ``φ`` (rad)
are the translation of the floating base and the angle of its rotation. Only the joints on that
path change the pair's relative pose. Moving one revolute joint by ``Δθ`` moves any point at
distance ``r`` from its axis by ``2 r sin(|Δθ|/2) ≤ r |Δθ|``; ``ρ_j`` bounds ``r`` for every
configuration: the length of the shortest chain of segments, each fixed in one body (from the
joint's origin to the next joint's origin, and to the centre of the geometry's bounding sphere),
from the axis to the centre of either geometry's bounding sphere, plus that sphere's radius (the
smaller of the two sides: the relative motion is the same seen from either body). Moving the
joints one after the other and adding the displacements (triangle inequality) gives (1), whatever
the path between ``q₀`` and ``q``; the bound is accumulated tick by tick. A joint of another kind
(ball, universal, planar) or a geometry without a bounded hull makes the pair's bound drop to
``-inf`` at the first motion: that pair is queried at every tick it moves.

At each tick the pairs whose bound is below the influence distance ``d_i`` (at the acceleration
level, a distance per pair that grows with its approach speed, :meth:`PairSchedule.approach_bound`)
are queried exactly
(``ComputeSignedDistancePairClosestPoints``), the others are out of range (their distance is at
least the bound, ``≥ d_i``) and need no row. A pair found out of range gets as bound the smaller of
its distance and its *support gap* along the query's normal ``n̂`` (:func:`.kernels.gaps`): the gap
of two convex shapes along any direction is at most their signed distance, so the bound holds even
when GJK has stopped on a non-closest pair of features (a symmetric posture can make it). The first
tick queries every pair. So the pairs in range are exactly those the full broad-phase query
``ComputeSignedDistancePairwiseClosestPoints(d_i)`` returns, at a fraction of its cost.

Which pairs are in range, and Drake's answers for them, do not depend on the bounds the step
starts from (any earlier configuration gives true lower bounds); only how many pairs are queried
does. The bounds are therefore a warm start: they live in the Context (:class:`ScheduleMemory`,
the collision task's abstract state), and the task's step replaces them in place, as the solvers
update their warm starts, with no update event of its own (a periodic unrestricted update costs
about 60 µs per tick in the tutorial's diagram). A cloned context replays the run.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import GeometryId
from pydrake.multibody.tree import BodyIndex, Joint, JointIndex
from pydrake.systems.framework import Context

from ..compiled import compiled_input, kernels, read_only
from ..exceptions import InvalidInput
from .distance import PairTable, body_tree
from .shapes import UNBOUNDED, PackedSupports, bounding_sphere, support_data
from .world import CollisionWorld

_kernels = kernels(".kernels", __package__, "gaps", "the collision pairs' support gaps", "a few seconds")


@dataclass(frozen=True)
class ScheduleState:
    """The schedule's run-time state: ``q`` the configuration the bounds are at (None before the
    first tick), ``lower`` the lower bound of each pair's signed distance there (m), ``in_range``
    the Drake results of the pairs in range there (for ``max_distance``) and ``in_range_pairs``
    their indices in the schedule's pairs, ``queried`` how many pairs were queried exactly to get
    there. Never changed once made (each tick makes a new one, its arrays read-only), so the copies
    Drake makes of the state (context clones, through :class:`ScheduleMemory`) share it."""

    q: np.ndarray | None = None
    lower: np.ndarray = field(default_factory=lambda: np.zeros(0))
    in_range: Sequence = ()
    max_distance: float | np.ndarray = -np.inf
    queried: int = 0
    in_range_pairs: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __deepcopy__(self, memo: dict) -> ScheduleState:
        return self


class ScheduleMemory:
    """The schedule's warm start in a Context: ``state``, the :class:`ScheduleState` of the last
    step, replaced (never changed) by the next. A copy (a cloned context) gets a memory of its
    own, starting from the same state."""

    __slots__ = ("state",)

    def __init__(self, state: ScheduleState | None = None):
        self.state = ScheduleState() if state is None else state

    def __deepcopy__(self, memo: dict) -> ScheduleMemory:
        return ScheduleMemory(self.state)


@dataclass
class ScheduleStep:
    """One tick of the schedule: the ``state`` after it, the Drake results of the pairs in range,
    and how many pairs were ``queried`` exactly."""

    state: ScheduleState
    in_range: Sequence
    queried: int

    def __deepcopy__(self, memo: dict) -> ScheduleStep:  # (Drake's results are immutable: shared)
        return ScheduleStep(copy.deepcopy(self.state, memo), list(self.in_range), self.queried)


class PairSchedule:
    """The fixed part of the schedule for ``world``'s candidate pairs (``geometry_pairs``: None for
    every pair its SceneGraph does not filter out): the coefficients of bound (1) (see the module
    docstring), one row per pair, over the motion vector of :meth:`motion`. Each pair is kept in
    increasing id order, the order in which Drake answers it; ``table`` holds what the pairs' rows
    need of them (:class:`~.distance.PairTable`)."""

    def __init__(self, world: CollisionWorld, geometry_pairs: Sequence[tuple[GeometryId, GeometryId]] | None = None):
        inspector = world.scene_graph.model_inspector()
        if geometry_pairs is None:
            candidates = inspector.GetCollisionCandidates()
            geometry_pairs = sorted(candidates, key=lambda pair: (pair[0].get_value(), pair[1].get_value()))
        self.pairs = [(a, b) if a.get_value() < b.get_value() else (b, a) for a, b in geometry_pairs]
        self.table = PairTable.of(world, self.pairs)
        self.world = world
        plant = world.plant
        joints = [plant.get_joint(JointIndex(i)) for i in range(plant.num_joints())]
        self._children = np.array([int(j.child_body().index()) for j in joints], dtype=int)
        # Motion vector: |Δq| of each 1-dof joint, then |Δp| and φ of each floating joint.
        self._one_dof = [j for j in joints if j.num_positions() == 1 and j.type_name() in ("revolute", "prismatic")]
        self._floating = [j for j in joints if j.type_name() in ("quaternion_floating", "rpy_floating")]
        self._one_dof_q = np.array([j.position_start() for j in self._one_dof], dtype=np.int64)
        self._floating_q = np.array([j.position_start() for j in self._floating], dtype=np.int64)
        self._quaternion = np.array([j.type_name() == "quaternion_floating" for j in self._floating], dtype=np.bool_)
        self._one_dof_v = np.array([j.velocity_start() for j in self._one_dof], dtype=np.int64)
        self._floating_v = np.array([j.velocity_start() for j in self._floating], dtype=np.int64)
        nodes, lengths = self._graph(world, joints)
        geometries = sorted({g for pair in self.pairs for g in pair}, key=lambda g: g.get_value())
        spheres = {g: bounding_sphere(inspector.GetShape(g)) for g in geometries}
        self._shapes = PackedSupports([support_data(inspector.GetShape(g)) for g in geometries])
        self._shape_X_BG = np.array([world.geometry_info(g)[2].GetAsMatrix4() for g in geometries]).reshape(-1, 4, 4)
        for g in geometries:
            nodes[("geometry", g)] = len(nodes)
        graph = np.full((len(nodes), len(nodes)), np.inf)
        for (a, b), length in lengths.items():
            graph[nodes[a], nodes[b]] = graph[nodes[b], nodes[a]] = length
        for g in geometries:  # the sphere's centre is fixed in its body: joined to that body's points
            _, body, X_BG = world.geometry_info(g)
            centre = X_BG.multiply(spheres[g][0])
            for point, p_B in self._body_points[body.index()]:
                graph[nodes[("geometry", g)], nodes[point]] = graph[nodes[point], nodes[("geometry", g)]] = \
                    float(np.linalg.norm(centre - p_B))
        # Each geometry's bounding sphere in its body (for the approach speed bound): centre, radius.
        index = {g: k for k, g in enumerate(geometries)}
        self._sphere_body = [world.geometry_info(g)[1].index() for g in geometries]
        self._sphere_centre = np.array([world.geometry_info(g)[2].multiply(spheres[g][0]) for g in geometries]).reshape(-1, 3)
        self._sphere_radius = np.array([spheres[g][1] for g in geometries])
        world_body = world.plant.world_body().index()
        # The spheres on a moving body (not an obstacle's), and each one's slot in the list of those bodies.
        self._moving_spheres = np.array([k for k, body in enumerate(self._sphere_body) if body != world_body], dtype=int)
        bodies = sorted({int(self._sphere_body[k]) for k in self._moving_spheres})
        self._moving_bodies = [world.plant.get_body(BodyIndex(b)) for b in bodies]
        slot = {b: j for j, b in enumerate(bodies)}
        self._moving_slot = np.array([slot[int(self._sphere_body[k])] for k in self._moving_spheres], dtype=int)
        self._pair_spheres = np.array([[index[a], index[b]] for a, b in self.pairs], dtype=int).reshape(-1, 2)
        # A pair can have a support gap when both its shapes have a support function.
        self._gapped = self._shapes.kinds[self._pair_spheres].min(axis=1) >= 0 if self.pairs else np.zeros(0, bool)
        self._pair_shapes = self._pair_spheres.astype(np.int64)
        distance = _shortest_paths(graph)
        self.coefficients = np.zeros((len(self.pairs), len(self._one_dof) + 2 * len(self._floating)))
        for p, (ga, gb) in enumerate(self.pairs):
            self.coefficients[p] = self._pair_row(world, joints, nodes, distance, spheres, ga, gb)
        # A floating joint on no pair's path (a robot's base, for self pairs only) moves no bound.
        first = len(self._one_dof)
        self._bounding = np.array([self.coefficients[:, first + 2 * k:first + 2 * k + 2].any() for k in range(len(self._floating))],
                                  dtype=np.bool_)

    def _graph(self, world: CollisionWorld, joints: list) -> tuple[dict, dict]:
        """The points fixed in each body (joint origins, on both sides of each joint) and the
        constant lengths between the points of one body, and across welds and revolute joints."""
        plant = world.plant
        nodes: dict = {("world",): 0}
        lengths: dict = {}
        points: dict = {plant.world_body().index(): [(("world",), np.zeros(3))]}
        for j in joints:
            for side, body, X in (("F", j.parent_body(), j.frame_on_parent()), ("M", j.child_body(), j.frame_on_child())):
                nodes.setdefault((side, j.index()), len(nodes))
                p_B = X.GetFixedPoseInBodyFrame().translation()
                points.setdefault(body.index(), []).append(((side, j.index()), p_B))
            if j.type_name() == "revolute":  # both origins on the axis, at the same point
                lengths[(("F", j.index()), ("M", j.index()))] = 0.0
            elif j.type_name() == "weld":
                lengths[(("F", j.index()), ("M", j.index()))] = float(np.linalg.norm(j.X_FM().translation()))
            elif j.type_name() == "prismatic":
                reach = max(abs(j.position_lower_limits()[0]), abs(j.position_upper_limits()[0]))
                if np.isfinite(reach):
                    lengths[(("F", j.index()), ("M", j.index()))] = float(reach)
        for body_points in points.values():
            for i, (a, p_a) in enumerate(body_points):
                for b, p_b in body_points[i + 1:]:
                    lengths[(a, b)] = float(np.linalg.norm(p_a - p_b))
        self._body_points = points
        return nodes, lengths

    def _pair_row(self, world: CollisionWorld, joints: list, nodes: dict, distance: np.ndarray, spheres: dict,
                  ga: GeometryId, gb: GeometryId) -> np.ndarray:
        """The coefficients of bound (1) for the pair ``(ga, gb)``."""
        a, b = (int(world.geometry_info(g)[1].index()) for g in (ga, gb))
        ancestors = body_tree(world).ancestors  # ([L, c]: body c is L or on its way to the world)
        row = np.zeros(self.coefficients.shape[1])
        on_path = [j for j, on in zip(joints, ancestors[a, self._children] != ancestors[b, self._children], strict=True) if on]

        def reach(j: Joint) -> float:  # ρ_j: from the joint's origin to the nearer sphere's far side
            ends = [distance[nodes[("M", j.index())], nodes[("geometry", g)]] + spheres[g][1] for g in (ga, gb)]
            return float(min(min(ends), UNBOUNDED))

        one_dof = {j.index(): k for k, j in enumerate(self._one_dof)}
        floating = {j.index(): len(one_dof) + 2 * k for k, j in enumerate(self._floating)}
        for j in on_path:
            if j.index() in one_dof:
                row[one_dof[j.index()]] = reach(j) if j.type_name() == "revolute" else 1.0
            elif j.index() in floating:
                k = floating[j.index()]
                row[k], row[k + 1] = 1.0, reach(j)
            elif j.num_positions() > 0:
                row[:] = UNBOUNDED
        return row

    def motion(self, q0: np.ndarray, q1: np.ndarray) -> np.ndarray:
        """The motion vector from ``q0`` to ``q1``: ``|Δq_j|`` of each one-dof joint, then ``|Δp|``
        (m) and the rotation angle ``φ`` (rad) of each floating joint (zeros for one whose
        coefficients are all zero: it moves no pair's bound). The schedule's step takes it in one
        compiled call with the bounds (:func:`.kernels.lowered`); this is that call's reference."""
        out = [np.abs(q1[self._one_dof_q] - q0[self._one_dof_q])]
        for j, bounding in zip(self._floating, self._bounding, strict=True):
            if not bounding:
                out.append(np.zeros(2))
                continue
            s = j.position_start()
            if j.type_name() == "quaternion_floating":
                aw, ax, ay, az = (float(x) for x in q0[s:s + 4])
                bw, bx, by, bz = (float(x) for x in q1[s:s + 4])
                w = aw * bw + ax * bx + ay * by + az * bz
                # the vector part of conj(a)·b: aw b⃗ − bw a⃗ − a⃗ × b⃗ (scalars: np.cross costs more here)
                vx = aw * bx - bw * ax - (ay * bz - az * by)
                vy = aw * by - bw * ay - (az * bx - ax * bz)
                vz = aw * bz - bw * az - (ax * by - ay * bx)
                angle = 2.0 * math.atan2(math.sqrt(vx * vx + vy * vy + vz * vz), abs(w))
                dx, dy, dz = (float(x) for x in q1[s + 4:s + 7] - q0[s + 4:s + 7])
                out.append(np.array([math.sqrt(dx * dx + dy * dy + dz * dz), angle]))
            else:  # roll-pitch-yaw: each angle's change bounds its rotation; the sum bounds theirs
                out.append(np.array([np.linalg.norm(q1[s + 3:s + 6] - q0[s + 3:s + 6]),
                                     float(np.abs(q1[s:s + 3] - q0[s:s + 3]).sum())]))
        return np.concatenate(out)

    def approach_bound(self, context: Context) -> np.ndarray:
        """Per pair, a bound (m/s) of its approach speed ``−ḋ`` at the positions and velocities of
        the collision diagram's ``context``: the largest speed of a point of A's bounding sphere plus
        that of B's, each ``|v_WBo + ω_WB × c| + |ω_WB| r`` (``c`` the sphere's centre from the
        body's origin, world frame; ``r`` its radius; 0 for an obstacle)."""
        plant = self.world.plant
        plant_context = self.world.plant_context(context)
        m = len(self._moving_bodies)
        R, w, v = np.empty((m, 3, 3)), np.empty((m, 3)), np.empty((m, 3))
        for j, body in enumerate(self._moving_bodies):
            V = plant.EvalBodySpatialVelocityInWorld(plant_context, body)
            w[j], v[j] = V.rotational(), V.translational()
            R[j] = plant.EvalBodyPoseInWorld(plant_context, body).rotation().matrix()
        spheres, slot = self._moving_spheres, self._moving_slot
        centres = np.einsum("kij,kj->ki", R[slot], self._sphere_centre[spheres])  # from each body's origin, world
        speed = np.zeros(len(self._sphere_body))
        w = w[slot]
        speed[spheres] = np.linalg.norm(v[slot] + np.cross(w, centres), axis=1) + np.linalg.norm(w, axis=1) * self._sphere_radius[spheres]
        return speed[self._pair_spheres[:, 0]] + speed[self._pair_spheres[:, 1]]

    def tick_approach(self, step: np.ndarray) -> np.ndarray:
        """Per pair, how much closer (m) one tick can bring it at most: bound (1) for a motion of at
        most ``step[j]`` (rad or m; inf: unbounded) in each velocity ``j`` (a floating joint's
        rotation at most ``‖step[ω]‖``, its translation ``‖step[v]‖``, world frame)."""
        step = np.asarray(step, dtype=float)
        motion = np.zeros(self.coefficients.shape[1])
        u = len(self._one_dof_v)
        motion[:u] = step[self._one_dof_v]
        for k, v in enumerate(self._floating_v.tolist()):
            motion[u + 2 * k], motion[u + 2 * k + 1] = np.linalg.norm(step[v + 3:v + 6]), np.linalg.norm(step[v:v + 3])
        unbounded = np.isinf(motion)
        approach = self.coefficients[:, ~unbounded] @ motion[~unbounded]
        approach[(self.coefficients[:, unbounded] > 0).any(axis=1)] = np.inf
        return approach

    def gaps(self, context: Context, pairs: np.ndarray, normal: np.ndarray) -> np.ndarray:
        """The support gap (m) of each pair index in ``pairs`` along its row of ``normal`` (unit,
        world, from B to A) at the positions of the collision diagram's ``context``: a lower bound of
        its signed distance (see :mod:`.kernels`). Every pair must have a support gap (``_gapped``)."""
        k = len(pairs)
        out = np.empty(k)
        if k == 0:
            return out
        if normal.shape != (k, 3) or not self._gapped[pairs].all():
            raise InvalidInput(f"gaps: {k} pairs with support functions and a k × 3 normal, got {normal.shape}, "
                               f"pairs without: {[p for p in pairs.tolist() if not self._gapped[p]]}")
        plant, plant_context = self.world.plant, self.world.plant_context(context)
        shapes = self._pair_shapes[pairs]
        X_WB = np.empty((k, 2, 4, 4))
        poses: dict = {}
        for i, sides in enumerate(shapes.tolist()):
            for side, shape in enumerate(sides):
                body = self._sphere_body[shape]  # (an obstacle's: the world body)
                X = poses.get(body)
                if X is None:
                    X = poses[body] = plant.EvalBodyPoseInWorld(plant_context, plant.get_body(body)).GetAsMatrix4()
                X_WB[i, side] = X
        packed = self._shapes
        _kernels().gaps(shapes, compiled_input(normal), X_WB, self._shape_X_BG, packed.kinds, packed.params,
                        packed.offsets, packed.points, out)
        return out

    def step(self, state: ScheduleState, context: Context, q: np.ndarray, max_distance: float | np.ndarray) -> ScheduleStep:
        """Advance ``state`` to the configuration ``q`` (set in the collision diagram ``context``
        by the caller) and query exactly the pairs whose bound is below ``max_distance`` (m; one
        distance, or one per pair)."""
        n = len(self.pairs)
        if state.q is not None and _same(state.max_distance, max_distance) and _same(state.q, q):
            return ScheduleStep(state, state.in_range, 0)  # (already at q: a re-evaluation, e.g. after a settings change)
        if state.q is None or state.lower.shape != (n,):
            lower = np.full(n, -np.inf)
        else:
            lower = _kernels().lowered(state.lower, self.coefficients, state.q, compiled_input(q), self._one_dof_q,
                                       self._floating_q, self._quaternion, self._bounding)
        scalar = np.ndim(max_distance) == 0
        if scalar:
            max_distance = float(max_distance)
        due = np.flatnonzero(lower < max_distance)
        query = self.world.query(context) if due.size else None  # (the query object updates every pose)
        in_range, pairs_in_range, out, normals = [], [], [], []
        for p in due.tolist():
            result = query.ComputeSignedDistancePairClosestPoints(*self.pairs[p])  # type: ignore[union-attr]
            lower[p] = distance = result.distance
            if distance < (max_distance if scalar else max_distance[p]):  # type: ignore[index]
                in_range.append(result)
                pairs_in_range.append(p)
            elif self._gapped[p]:  # (answered in the pair's order: n̂ from its second geometry to its first)
                out.append(p)
                normals.append(result.nhat_BA_W)
        if out:  # skipped from now on: a bound that does not trust the query's convergence
            pairs = np.array(out, dtype=np.int64)
            lower[pairs] = np.minimum(lower[pairs], self.gaps(context, pairs, np.array(normals)))
        state = ScheduleState(read_only(q.copy()), read_only(lower), tuple(in_range),
                              max_distance if scalar else read_only(np.array(max_distance)),
                              len(due), read_only(np.array(pairs_in_range, dtype=np.int64)))
        return ScheduleStep(state, in_range, len(due))


def _same(a: float | np.ndarray, b: float | np.ndarray) -> bool:
    """``a`` and ``b`` equal (two numbers, or two arrays of one shape)."""
    if type(a) is float and type(b) is float:  # (the usual case, first: np.ndim costs more)
        return a == b
    if np.ndim(a) == 0 and np.ndim(b) == 0:
        return bool(a == b)
    return np.shape(a) == np.shape(b) and bool((a == b).all())  # type: ignore[union-attr]


def _shortest_paths(graph: np.ndarray) -> np.ndarray:
    """Floyd–Warshall: the shortest path lengths of a symmetric edge-length matrix (inf: no edge)."""
    distance = graph.copy()
    np.fill_diagonal(distance, 0.0)
    for k in range(len(distance)):
        distance = np.minimum(distance, distance[:, k:k + 1] + distance[k:k + 1, :])
    return distance


