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

from ..compiled import kernels
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
    by pair). Each body's pose and Jacobian are taken once (and with ``bias`` every body's bias
    acceleration in one call), then the rows are assembled by one compiled call
    (:func:`.kernels.assemble`)."""
    plant = world.plant
    plant_context = world.plant_context(context)
    k, nv = len(results), plant.num_velocities()
    if k == 0:
        return PairDistances(names=[], distance=np.empty(0), normal=np.empty((0, 3)), p_WCa=np.empty((0, 3)),
                             p_WCb=np.empty((0, 3)), jacobian=np.zeros((0, nv)), bias=np.zeros(0))
    geometries = _geometries(world)
    sides: tuple[list[_Geometry], list[_Geometry]] = ([], [])
    distance, normal, p_GC = np.empty(k), np.empty((k, 3)), np.empty((2, k, 3))
    for i, r in enumerate(results):
        a, b = geometries.get(r.id_A) or _geometry(world, r.id_A), geometries.get(r.id_B) or _geometry(world, r.id_B)
        distance[i] = r.distance
        if a.obstacle:  # keep the robot on side A
            a, b = b, a
            normal[i], p_GC[0, i], p_GC[1, i] = -r.nhat_BA_W, r.p_BCb, r.p_ACa
        else:
            normal[i], p_GC[0, i], p_GC[1, i] = r.nhat_BA_W, r.p_ACa, r.p_BCb
        sides[0].append(a)
        sides[1].append(b)
    slot: dict[int, _Geometry] = {}  # body index -> a geometry of it; its row in the per-body arrays below
    for side in sides:
        for g in side:
            if not g.obstacle:
                slot.setdefault(g.body_index, g)
    rows = {index: j for j, index in enumerate(slot)}
    m = max(len(slot), 1)
    X_WB, J = np.empty((m, 4, 4)), np.empty((m, 6, nv))  # body origins' poses and spatial Jacobians (ω; v), world
    A_bias, omega = np.zeros((m, 6)), np.zeros((m, 3))  # bias spatial accelerations (α; a) and angular velocities
    world_frame = plant.world_frame()
    accelerations = plant.CalcSpatialAccelerationsFromVdot(plant_context, np.zeros(nv)) if bias else None
    for j, g in enumerate(slot.values()):
        X_WB[j] = plant.EvalBodyPoseInWorld(plant_context, g.body).GetAsMatrix4()
        J[j] = plant.CalcJacobianSpatialVelocity(plant_context, JacobianWrtVariable.kV, g.frame, _ORIGIN, world_frame, world_frame)
        if accelerations is not None:  # (v̇ = 0: each body's bias spatial acceleration, by body index)
            A = accelerations[g.body_index]
            A_bias[j, :3], A_bias[j, 3:] = A.rotational(), A.translational()
            omega[j] = plant.EvalBodySpatialVelocityInWorld(plant_context, g.body).rotational()
    slots = np.array([[-1 if g.obstacle else rows[g.body_index] for g in side] for side in sides], dtype=np.int64)
    X_BG = np.array([[g.X_BG for g in side] for side in sides])
    out = PairDistances(names=[(a.name, b.name) for a, b in zip(*sides, strict=True)], distance=distance, normal=normal,
                        p_WCa=np.empty((k, 3)), p_WCb=np.empty((k, 3)), jacobian=np.empty((k, nv)), bias=np.zeros(k))
    points = np.empty((2, k, 3))
    _kernels().assemble(X_WB, J, A_bias, omega, slots, X_BG, p_GC, normal, bias, out.jacobian, out.bias, points)
    out.p_WCa[:], out.p_WCb[:] = points[0], points[1]
    return out


_kernels = kernels(".kernels", __package__, "assemble", "the collision rows' assembly", "a few seconds")


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
