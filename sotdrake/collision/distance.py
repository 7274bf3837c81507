"""Signed distances of the collision pairs in range, their normals, witness points and Jacobians.

For a pair of geometries A (on the robot) and B (on the robot or an obstacle), Drake gives the
signed distance ``d`` (m, negative when they overlap), the witness points ``Ca`` on A and ``Cb``
on B, and the unit normal ``n̂ = n̂_BA_W`` (world frame) pointing from B towards A: moving A along
``n̂`` increases ``d``. With ``J_A``, ``J_B`` the translational Jacobians (3×nv, with respect to
the generalized velocities ``v``, world frame) of the points of A's and B's bodies that coincide
with ``Ca`` and ``Cb``,

    ḋ = n̂ᵀ (v_Ca − v_Cb) = n̂ᵀ (J_A − J_B) v = J_d v,

which holds wherever the witness points move continuously (away from a switch between two faces or
vertices, where ``d`` has a kink). ``J_d`` is 1×nv; an obstacle's ``J_B`` is zero.

:func:`pair_distances` gathers every pair closer than ``max_distance`` (the influence distance);
:func:`minimum_distance` is the independent check the tests and scripts use.
"""

from __future__ import annotations

import weakref
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import GeometryId
from pydrake.multibody.tree import BodyIndex, JacobianWrtVariable, JointIndex
from pydrake.systems.framework import Context

from ..compiled import kernels
from ..exceptions import InvalidInput, check_finite
from ..lie import check_base_quaternion
from .world import CollisionWorld


@dataclass
class PairDistances:
    """The pairs in range at one configuration, one row each: ``names`` (body or obstacle names,
    A then B), ``distance`` (k, m), ``normal`` (k×3, ``n̂_BA_W``), ``p_WCa`` and ``p_WCb`` (k×3, m,
    world), ``jacobian`` (k×nv, ``J_d``, m per unit of ``v``)."""

    names: list[tuple[str, str]] = field(default_factory=list)
    distance: np.ndarray = field(default_factory=lambda: np.zeros(0))
    normal: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    p_WCa: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    p_WCb: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    jacobian: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))
    #: ``J̇_d v`` (k, m/s²): ``n̂ᵀ (J̇_A − J̇_B) v``, the witness points fixed in their bodies and the
    #: normal's own rotation left out; zeros unless asked for (``bias=True``)
    bias: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def minimum(self) -> float:
        """The smallest signed distance (m), +inf when no pair is in range."""
        return float(self.distance.min()) if self.distance.size else float("inf")


def signed_distance_pairs(world: CollisionWorld, context: Context, max_distance: float,
                          geometry_pairs: Sequence | None = None) -> list:
    """Drake's ``SignedDistancePair`` results closer than ``max_distance`` (m, a number ≥ 0, +inf
    for every pair): of every unfiltered candidate pair (``geometry_pairs`` None, one broad-phase
    query) or of the given geometry pairs (``(GeometryId, GeometryId)`` of this world,
    :meth:`CollisionWorld.geometry_pairs`). Anything else, or positions in ``context`` that are not
    finite or hold a quaternion of norm < 1e-6: :class:`InvalidInput` naming it."""
    _check_world("signed_distance_pairs", world)
    return _query(world, context, _max_distance("signed_distance_pairs", max_distance),
                  _checked_pairs("signed_distance_pairs", world, geometry_pairs), "signed_distance_pairs")


def _query(world: CollisionWorld, context: Context, max_distance: float, geometry_pairs: list | None, what: str,
           positions_checked: bool = False) -> list:
    """:func:`signed_distance_pairs` once its arguments are checked (and here, unless
    ``positions_checked``, the positions in ``context``)."""
    if not positions_checked:
        _check_positions(f"{what}: the positions in context", world, world.plant.GetPositions(world.plant_context(context)))
    query = world.query(context)
    if geometry_pairs is None:
        return list(query.ComputeSignedDistancePairwiseClosestPoints(max_distance))
    results = (query.ComputeSignedDistancePairClosestPoints(a, b) for a, b in geometry_pairs)
    return [r for r in results if r.distance < max_distance]


def _max_distance(what: str, value: object) -> float:
    """``value`` as a float if it is a number ≥ 0 (+inf included), else :class:`InvalidInput`: NaN or
    a negative distance would leave every pair out, as if none were in range."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) or not value >= 0:
        raise InvalidInput(f"{what}: max_distance must be a number ≥ 0 (m; inf: every pair), got {value!r:.60}")
    return float(value)


def _checked_pairs(what: str, world: CollisionWorld, geometry_pairs: object) -> list | None:
    """``geometry_pairs`` as a list if each is a pair of proximity geometries of ``world``, else
    :class:`InvalidInput` naming the first that is not (None: None)."""
    if geometry_pairs is None:
        return None
    if isinstance(geometry_pairs, (str, bytes)) or not isinstance(geometry_pairs, Iterable):
        raise InvalidInput(f"{what}: geometry_pairs must be None or a list of (GeometryId, GeometryId) "
                           f"(world.geometry_pairs(pairs)), got {type(geometry_pairs).__name__}")
    pairs = list(geometry_pairs)
    known = world.proximity_geometries()
    for i, pair in enumerate(pairs):
        if not (isinstance(pair, (tuple, list)) and len(pair) == 2 and all(isinstance(g, GeometryId) for g in pair)):
            raise InvalidInput(f"{what}: geometry_pairs[{i}] must be a pair (GeometryId, GeometryId) "
                               f"(world.geometry_pairs(pairs)), got {pair!r:.80}")
        if pair[0] not in known or pair[1] not in known:
            raise InvalidInput(f"{what}: geometry_pairs[{i}] = {pair!r:.80} names a geometry that is not a collision "
                               "geometry of this world (world.geometry_pairs(pairs) gives them)")
    return pairs


def _check_positions(what: str, world: CollisionWorld, q: np.ndarray) -> None:
    """``q`` finite with each free body's quaternion of norm ≥ 1e-6 (Drake normalises it; a zero one
    is no rotation), else :class:`InvalidInput` naming ``what``: the check of ``pose_at``."""
    if not np.isfinite(q).all():
        raise InvalidInput(f"{what}: expected finite numbers; contains NaN or infinity: {q}")
    for start in world.quaternion_starts:
        check_base_quaternion(what, q, start)


def pair_distances(world: CollisionWorld, context: Context, max_distance: float,
                   geometry_pairs: Sequence | None = None, bias: bool = False) -> PairDistances:
    """:class:`PairDistances` of the pairs closer than ``max_distance`` (m) in the collision diagram
    ``context`` (its plant's positions, and with ``bias`` its velocities, set by the caller). A pair
    whose side A is an obstacle is swapped, so that A is always on the robot.

    With ``bias``, ``J̇_d v`` of each pair: the bias acceleration of a point ``C`` fixed in body
    ``B`` is ``a_Bo + α × r + ω × (ω × r)`` (``r = p_BoC``, the body's bias spatial acceleration
    ``(α, a_Bo)`` and angular velocity ``ω``, world frame).

    A ``world`` that is not a :class:`CollisionWorld`, a ``context`` that is not one of its
    collision diagram (:meth:`CollisionWorld.new_context`) or whose positions are not finite (or
    hold a zero quaternion), a ``max_distance`` that is not a number ≥ 0 or ``geometry_pairs`` that
    are not pairs of its geometries: :class:`InvalidInput` naming it."""
    _check_world("pair_distances", world)
    checked = _max_distance("pair_distances", max_distance), _checked_pairs("pair_distances", world, geometry_pairs)
    return distances_of(world, context, _query(world, context, *checked, "pair_distances"), bias)


def distances_of(world: CollisionWorld, context: Context, results: Sequence, bias: bool = False) -> PairDistances:
    """:class:`PairDistances` of Drake's ``SignedDistancePair`` ``results`` (as
    :func:`pair_distances`, which gathers them with one query), each geometry looked up (the
    collision task's schedule, which knows its pairs, looks them up once: :class:`PairTable`)."""
    table = PairTable.of(world, [(r.id_A, r.id_B) for r in results])
    return table.distances(world, context, results, np.arange(len(results)), bias)


@dataclass(frozen=True)
class PairTable:
    """What :func:`distances_of` looks up for each result, looked up once for a fixed list of
    geometry pairs (the collision task's candidates, :class:`~.schedule.PairSchedule`): per pair,
    its ``names`` (robot side first), each side's body index (``bodies``, n×2; -1 for an obstacle),
    each side's geometry pose in its body (``X_BG``, n×2×4×4) and whether the pair's first geometry
    is the obstacle (``swapped``: its sides are exchanged in the rows)."""

    names: list[tuple[str, str]]
    bodies: np.ndarray
    X_BG: np.ndarray
    swapped: np.ndarray

    @classmethod
    def of(cls, world: CollisionWorld, geometry_pairs: Sequence) -> PairTable:
        infos = [[_geometry(world, g) for g in pair] for pair in geometry_pairs]
        swapped = np.array([a.obstacle for a, _ in infos], dtype=bool)
        infos = [pair[::-1] if pair[0].obstacle else pair for pair in infos]
        bodies = np.array([[-1 if g.obstacle else g.body_index for g in pair] for pair in infos], dtype=np.int64)
        X_BG = np.array([[g.X_BG for g in pair] for pair in infos])
        return cls([(a.name, b.name) for a, b in infos], bodies.reshape(-1, 2), X_BG.reshape(-1, 2, 4, 4), swapped)

    def distances(self, world: CollisionWorld, context: Context, results: Sequence, pairs: np.ndarray,
                  bias: bool = False) -> PairDistances:
        """:class:`PairDistances` of ``results``, Drake's answers for the pairs of index ``pairs``
        (int array) in this table, each for its pair in the table's order (``id_A`` the pair's first
        geometry: Drake answers a pair in increasing id order, the order the schedule keeps). A
        pair whose first geometry is an obstacle is swapped, so that side A is on the robot."""
        k = len(results)
        if k == 0:
            return PairDistances(jacobian=np.zeros((0, world.plant.num_velocities())), bias=np.zeros(0))
        distance, normal, p_GC = np.empty(k), np.empty((k, 3)), np.empty((2, k, 3))
        for i, r in enumerate(results):
            distance[i], normal[i], p_GC[0, i], p_GC[1, i] = r.distance, r.nhat_BA_W, r.p_ACa, r.p_BCb
        swapped = self.swapped[pairs]
        if swapped.any():  # keep the robot on side A
            normal[swapped] *= -1.0
            p_GC[:, swapped] = p_GC[::-1, swapped]
        return _rows(world, context, [self.names[p] for p in pairs.tolist()], distance, normal, p_GC,
                     np.ascontiguousarray(self.bodies[pairs].T), np.ascontiguousarray(self.X_BG[pairs].transpose(1, 0, 2, 3)),
                     bias)


def _rows(world: CollisionWorld, context: Context, names: list, distance: np.ndarray, normal: np.ndarray,
          p_GC: np.ndarray, bodies: np.ndarray, X_BG: np.ndarray, bias: bool) -> PairDistances:
    """The rows of ``k`` pairs (robot on side A) from Drake's numbers (``distance``, ``normal``,
    the witness points ``p_GC``, 2×k×3, in their geometries' frames), each side's body index
    (``bodies``, 2×k, -1 for an obstacle) and geometry pose in its body (``X_BG``, 2×k×4×4).

    Each moving body's pose is taken once. The Jacobians are taken once per *leaf* of the bodies
    involved (a body that is no other one's ancestor among them, :func:`.kernels.cover`), of the
    point fixed in the leaf that is at the world's origin: a joint's column there is the same for
    every body downstream of it, so an ancestor's Jacobian is the leaf's with the columns of the
    joints below it zeroed (the bodies' ``columns``). The rows are assembled by one compiled call
    (:func:`.kernels.assemble`); with ``bias``, every body's bias acceleration is taken in one call."""
    plant = world.plant
    plant_context = world.plant_context(context)
    k, nv = len(distance), plant.num_velocities()
    out = PairDistances(names=names, distance=distance, normal=normal, p_WCa=np.empty((k, 3)), p_WCb=np.empty((k, 3)),
                        jacobian=np.empty((k, nv)), bias=np.zeros(k))
    if k == 0:
        return out
    tree = body_tree(world)
    needed, slots = np.empty(2 * k, dtype=np.int64), np.empty((2, k), dtype=np.int64)
    leaves, leaf_of = np.empty(2 * k, dtype=np.int64), np.empty(2 * k, dtype=np.int64)
    m, count = _kernels().cover(bodies, tree.depth, tree.ancestors, needed, slots, leaves, leaf_of)
    needed = needed[:m]
    X_WB, J = np.empty((m, 4, 4)), np.empty((count, 6, nv))  # poses; leaves' spatial Jacobians (ω; v) at W's origin
    A_bias, omega = np.zeros((m, 6)), np.zeros((m, 3))  # bias spatial accelerations (α; a) and angular velocities
    for j, b in enumerate(needed.tolist()):
        X_WB[j] = plant.EvalBodyPoseInWorld(plant_context, tree.bodies[b]).GetAsMatrix4()
    world_frame = plant.world_frame()
    leaves = leaves[:count]
    X_WL = X_WB[leaves]
    p_LO = -np.matmul(X_WL[:, None, :3, 3], X_WL[:, :3, :3])[:, 0]  # W's origin in each leaf's frame: −R_WLᵀ p_WLo
    for leaf, j in enumerate(leaves.tolist()):
        J[leaf] = plant.CalcJacobianSpatialVelocity(plant_context, JacobianWrtVariable.kV, tree.frames[needed[j]],
                                                    p_LO[leaf], world_frame, world_frame)
    if bias:  # (v̇ = 0: each body's bias spatial acceleration, by body index)
        accelerations = plant.CalcSpatialAccelerationsFromVdot(plant_context, np.zeros(nv))
        for j, b in enumerate(needed.tolist()):
            A = accelerations[b]
            A_bias[j, :3], A_bias[j, 3:] = A.rotational(), A.translational()
            omega[j] = plant.EvalBodySpatialVelocityInWorld(plant_context, tree.bodies[b]).rotational()
    points = np.empty((2, k, 3))
    _kernels().assemble(X_WB, J, leaf_of, tree.columns[needed], A_bias, omega, slots, X_BG, p_GC, normal, bias,
                        out.jacobian, out.bias, points)
    out.p_WCa[:], out.p_WCb[:] = points[0], points[1]
    return out


_kernels = kernels(".kernels", __package__, "assemble", "the collision rows' assembly", "a few seconds")


@dataclass(frozen=True)
class _Geometry:
    """What :func:`distances_of` needs of a geometry: its body's (or obstacle's) ``name``, the
    body's index (the world body's for an obstacle), ``X_BG`` (4×4) and whether it is an obstacle."""

    name: str
    body_index: int
    X_BG: np.ndarray
    obstacle: bool


@dataclass(frozen=True)
class BodyTree:
    """The robot's kinematic tree, by body index (the rows' leaves, the schedule's paths): the
    bodies and their frames, ``depth`` (the number of joints from the world), ``ancestors[L, b]``
    (body ``b`` is ``L`` or on its way to the world) and ``columns[b, c]`` (velocity ``c`` belongs
    to a joint on ``b``'s way to the world)."""

    bodies: list
    frames: list
    depth: np.ndarray
    ancestors: np.ndarray
    columns: np.ndarray


#: Per collision world, its geometries as :class:`_Geometry` (filled on first use) and its :class:`BodyTree`.
_GEOMETRIES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_TREES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _geometries(world: CollisionWorld) -> dict:
    table = _GEOMETRIES.get(world)
    if table is None:
        table = _GEOMETRIES[world] = {}
    return table


def _geometry(world: CollisionWorld, geometry: object) -> _Geometry:
    info = _geometries(world).get(geometry)
    if info is None:
        name, body, X_BG = world.geometry_info(geometry)
        info = _geometries(world)[geometry] = _Geometry(name, int(body.index()), X_BG.GetAsMatrix4(),
                                                        geometry in world.obstacle_ids)
    return info


def body_tree(world: CollisionWorld) -> BodyTree:
    """``world``'s :class:`BodyTree`, made on first use (the rows' leaves, the schedule's paths)."""
    tree = _TREES.get(world)
    if tree is None:
        plant = world.plant
        nb, nv = plant.num_bodies(), plant.num_velocities()
        inboard = {}  # body index -> the joint whose child it is
        for i in range(plant.num_joints()):
            joint = plant.get_joint(JointIndex(i))
            inboard[int(joint.child_body().index())] = joint
        depth, ancestors, columns = np.zeros(nb, dtype=np.int64), np.zeros((nb, nb), dtype=bool), np.zeros((nb, nv), dtype=bool)
        for b in range(nb):
            body = b
            while True:
                ancestors[b, body] = True
                joint = inboard.get(body)
                if joint is None:
                    break
                depth[b] += 1
                columns[b, joint.velocity_start():joint.velocity_start() + joint.num_velocities()] = True
                body = int(joint.parent_body().index())
        bodies = [plant.get_body(BodyIndex(b)) for b in range(nb)]
        tree = _TREES[world] = BodyTree(bodies, [body.body_frame() for body in bodies], depth, ancestors, columns)
    return tree


def minimum_distance(world: CollisionWorld, context: Context, q: np.ndarray, max_distance: float = 1.0,
                     geometry_pairs: Sequence | None = None) -> float:
    """The smallest signed distance (m) over the world's pairs at configuration ``q`` (+inf when
    none is closer than ``max_distance``): Drake's query alone, for checking a run. A ``world``
    that is not a :class:`CollisionWorld`, a ``context`` that is not one of its collision diagram,
    a ``q`` of another size, not finite or with a quaternion of norm < 1e-6 (as ``pose_at``), a
    ``max_distance`` that is not a number ≥ 0 (NaN would report no pair in range) or
    ``geometry_pairs`` that are not pairs of its geometries: :class:`InvalidInput` naming it, the
    context left as it was."""
    _check_world("minimum_distance", world)
    max_distance = _max_distance("minimum_distance", max_distance)
    pairs = _checked_pairs("minimum_distance", world, geometry_pairs)
    q = check_finite("minimum_distance: q (the world plant's positions)", q, (world.plant.num_positions(),))
    _check_positions("minimum_distance: q", world, q)
    world.plant.SetPositions(world.plant_context(context), q)
    results = _query(world, context, max_distance, pairs, "minimum_distance", positions_checked=True)
    return min((r.distance for r in results), default=float("inf"))


def _check_world(what: str, world: object) -> None:
    if not isinstance(world, CollisionWorld):
        raise InvalidInput(f"{what}: world must be a CollisionWorld (collision_world(robot)), got {type(world).__name__}")
