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
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import Context

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
    """Drake's ``SignedDistancePair`` results closer than ``max_distance``: of every unfiltered
    candidate pair (``geometry_pairs`` None, one broad-phase query) or of the given geometry pairs."""
    query = world.query(context)
    if geometry_pairs is None:
        return list(query.ComputeSignedDistancePairwiseClosestPoints(max_distance))
    results = (query.ComputeSignedDistancePairClosestPoints(a, b) for a, b in geometry_pairs)
    return [r for r in results if r.distance < max_distance]


def pair_distances(world: CollisionWorld, context: Context, max_distance: float,
                   geometry_pairs: Sequence | None = None, bias: bool = False) -> PairDistances:
    """:class:`PairDistances` of the pairs closer than ``max_distance`` (m) in the collision diagram
    ``context`` (its plant's positions, and with ``bias`` its velocities, set by the caller). A pair
    whose side A is an obstacle is swapped, so that A is always on the robot.

    With ``bias``, ``J̇_d v`` of each pair: the bias acceleration of a point ``C`` fixed in body
    ``B`` is ``a_Bo + α × r + ω × (ω × r)`` (``r = p_BoC``, the body's bias spatial acceleration
    ``(α, a_Bo)`` and angular velocity ``ω``, world frame)."""
    return distances_of(world, context, signed_distance_pairs(world, context, max_distance, geometry_pairs), bias)


def distances_of(world: CollisionWorld, context: Context, results: Sequence, bias: bool = False) -> PairDistances:
    """:class:`PairDistances` of Drake's ``SignedDistancePair`` ``results`` (as
    :func:`pair_distances`, which gathers them with one query; :mod:`.schedule` gathers them pair
    by pair)."""
    plant = world.plant
    plant_context = world.plant_context(context)
    k, nv = len(results), plant.num_velocities()
    if k == 0:
        return PairDistances(names=[], distance=np.empty(0), normal=np.empty((0, 3)), p_WCa=np.empty((0, 3)),
                             p_WCb=np.empty((0, 3)), jacobian=np.zeros((0, nv)), bias=np.zeros(0))
    geometries = _geometries(world)
    sides = [[geometries.get(r.id_A) or _geometry(world, r.id_A) for r in results],
             [geometries.get(r.id_B) or _geometry(world, r.id_B) for r in results]]
    p_GC = np.array([[r.p_ACa for r in results], [r.p_BCb for r in results]])  # witness points, geometry frames
    n = np.array([r.nhat_BA_W for r in results])
    distance = np.array([r.distance for r in results])
    swap = np.array([a.obstacle for a in sides[0]])
    if swap.any():  # keep the robot on side A
        sides = [[gb if s else ga for ga, gb, s in zip(*sides, swap, strict=True)],
                 [ga if s else gb for ga, gb, s in zip(*sides, swap, strict=True)]]
        p_GC[:, swap] = p_GC[::-1, swap]
        n[swap] = -n[swap]
    slot: dict = {}  # body index -> its row in the per-body arrays below
    for side in sides:
        for g in side:
            slot.setdefault(g.body_index, g)
    m = len(slot)
    X_WB = np.tile(np.eye(4), (m, 1, 1))
    J = np.zeros((m, 6, nv))  # spatial Jacobians (ω; v) of the body origins, world frame
    A_bias = np.zeros((m, 6))  # bias spatial accelerations (α; a) of the body origins
    omega = np.zeros((m, 3))
    world_frame = plant.world_frame()
    for j, g in enumerate(slot.values()):
        if g.obstacle:  # the world body: identity pose, no motion
            continue
        X_WB[j] = plant.EvalBodyPoseInWorld(plant_context, g.body).GetAsMatrix4()
        J[j] = plant.CalcJacobianSpatialVelocity(plant_context, JacobianWrtVariable.kV, g.frame, _ORIGIN, world_frame, world_frame)
        if bias:
            A = plant.CalcBiasSpatialAcceleration(plant_context, JacobianWrtVariable.kV, g.frame, _ORIGIN, world_frame, world_frame)
            A_bias[j] = np.concatenate([A.rotational(), A.translational()])
            omega[j] = plant.EvalBodySpatialVelocityInWorld(plant_context, g.body).rotational()
    rows = {index: j for j, index in enumerate(slot)}
    out = PairDistances(names=[(a.name, b.name) for a, b in zip(*sides, strict=True)], distance=distance, normal=n,
                        p_WCa=np.empty((k, 3)), p_WCb=np.empty((k, 3)), jacobian=np.zeros((k, nv)), bias=np.zeros(k))
    for side_index, (sign, points) in enumerate(((1.0, out.p_WCa), (-1.0, out.p_WCb))):
        side = sides[side_index]
        b = np.array([rows[g.body_index] for g in side])
        X_BG = np.array([g.X_BG for g in side])
        p_BC = np.einsum("kij,kj->ki", X_BG[:, :3, :3], p_GC[side_index]) + X_BG[:, :3, 3]
        # r = p_BoC (world frame): the witness point from its body's origin
        r = np.einsum("kij,kj->ki", X_WB[b, :3, :3], p_BC)
        points[:] = X_WB[b, :3, 3] + r
        # v_WC = v_WBo + ω_WB × r, so n̂ᵀ v_WC = n̂ᵀ J_v + (r × n̂)ᵀ J_ω.
        out.jacobian += sign * (np.einsum("ki,kin->kn", n, J[b, 3:]) + np.einsum("ki,kin->kn", np.cross(r, n), J[b, :3]))
        if bias:
            w = omega[b]
            a_C = A_bias[b, 3:] + np.cross(A_bias[b, :3], r) + np.cross(w, np.cross(w, r))
            out.bias += sign * np.einsum("ki,ki->k", n, a_C)
    return out


_ORIGIN = np.zeros(3)


@dataclass(frozen=True)
class _Geometry:
    """What :func:`distances_of` needs of a geometry: its body's (or obstacle's) ``name``, the
    ``body`` (the world body for an obstacle), its index and frame, and ``X_BG`` (4×4)."""

    name: str
    body: object
    body_index: int
    frame: object
    X_BG: np.ndarray
    obstacle: bool


#: Per collision world, its geometries as :class:`_Geometry` (filled on first use).
_GEOMETRIES: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _geometries(world: CollisionWorld) -> dict:
    table = _GEOMETRIES.get(world)
    if table is None:
        table = _GEOMETRIES[world] = {}
    return table


def _geometry(world: CollisionWorld, geometry: object) -> _Geometry:
    name, body, X_BG = world.geometry_info(geometry)
    info = _Geometry(name, body, int(body.index()), body.body_frame(), X_BG.GetAsMatrix4(),
                     geometry in world.obstacle_ids)
    _geometries(world)[geometry] = info
    return info


def minimum_distance(world: CollisionWorld, context: Context, q: np.ndarray, max_distance: float = 1.0,
                     geometry_pairs: Sequence | None = None) -> float:
    """The smallest signed distance (m) over the world's pairs at configuration ``q`` (+inf when
    none is closer than ``max_distance``): Drake's query alone, for checking a run."""
    world.plant.SetPositions(world.plant_context(context), q)
    results = signed_distance_pairs(world, context, max_distance, geometry_pairs)
    return min((r.distance for r in results), default=float("inf"))
