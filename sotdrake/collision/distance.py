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
    plant = world.plant
    plant_context = world.plant_context(context)
    results = signed_distance_pairs(world, context, max_distance, geometry_pairs)
    k, nv = len(results), plant.num_velocities()
    out = PairDistances(names=[], distance=np.empty(k), normal=np.empty((k, 3)), p_WCa=np.empty((k, 3)),
                        p_WCb=np.empty((k, 3)), jacobian=np.zeros((k, nv)), bias=np.zeros(k))
    if k == 0:
        return out
    obstacles = world.obstacle_ids
    p_GC = np.empty((2, k, 3))  # witness points in their geometry's frame, side A then side B
    geometries: list[list] = [[], []]
    for i, r in enumerate(results):
        id_A, id_B, p_ACa, p_BCb, n = r.id_A, r.id_B, r.p_ACa, r.p_BCb, r.nhat_BA_W
        if id_A in obstacles:  # keep the robot on side A
            id_A, id_B, p_ACa, p_BCb, n = id_B, id_A, p_BCb, p_ACa, -n
        geometries[0].append(id_A)
        geometries[1].append(id_B)
        p_GC[0, i], p_GC[1, i] = p_ACa, p_BCb
        out.distance[i], out.normal[i] = r.distance, n
    n = out.normal
    world_frame, world_body = plant.world_frame(), plant.world_body().index()
    bodies: dict = {}  # body index -> its slot in the per-body arrays below
    infos = [[world.geometry_info(g) for g in side] for side in geometries]
    for side_infos in infos:
        for _, body, _ in side_infos:
            bodies.setdefault(body.index(), body)
    slot = {index: j for j, index in enumerate(bodies)}
    R_WB = np.empty((len(bodies), 3, 3))
    p_WB = np.empty((len(bodies), 3))
    J = np.zeros((len(bodies), 6, nv))  # spatial Jacobians (ω; v) of the body origins, world frame
    A_bias = np.zeros((len(bodies), 6))  # bias spatial accelerations (α; a) of the body origins
    omega = np.zeros((len(bodies), 3))
    for index, body in bodies.items():
        j = slot[index]
        X_WB = plant.EvalBodyPoseInWorld(plant_context, body)
        R_WB[j], p_WB[j] = X_WB.rotation().matrix(), X_WB.translation()
        if index == world_body:
            continue
        frame = body.body_frame()
        J[j] = plant.CalcJacobianSpatialVelocity(plant_context, JacobianWrtVariable.kV, frame, np.zeros(3), world_frame, world_frame)
        if bias:
            A = plant.CalcBiasSpatialAcceleration(plant_context, JacobianWrtVariable.kV, frame, np.zeros(3), world_frame, world_frame)
            A_bias[j] = np.concatenate([A.rotational(), A.translational()])
            omega[j] = plant.EvalBodySpatialVelocityInWorld(plant_context, body).rotational()
    for side, (sign, points) in enumerate(((1.0, out.p_WCa), (-1.0, out.p_WCb))):
        b = np.array([slot[body.index()] for _, body, _ in infos[side]])
        R_BG = np.array([X_BG.rotation().matrix() for _, _, X_BG in infos[side]])
        p_BG = np.array([X_BG.translation() for _, _, X_BG in infos[side]])
        # r = p_BoC (world frame): the witness point from its body's origin
        r = np.einsum("kij,kj->ki", R_WB[b], np.einsum("kij,kj->ki", R_BG, p_GC[side]) + p_BG)
        points[:] = p_WB[b] + r
        # v_WC = v_WBo + ω_WB × r, so n̂ᵀ v_WC = n̂ᵀ J_v + (r × n̂)ᵀ J_ω.
        out.jacobian += sign * (np.einsum("ki,kin->kn", n, J[b, 3:]) + np.einsum("ki,kin->kn", np.cross(r, n), J[b, :3]))
        if bias:
            w = omega[b]
            a_C = A_bias[b, 3:] + np.cross(A_bias[b, :3], r) + np.cross(w, np.cross(w, r))
            out.bias += sign * np.einsum("ki,ki->k", n, a_C)
    out.names = [(a[0], b[0]) for a, b in zip(infos[0], infos[1], strict=True)]
    return out


def minimum_distance(world: CollisionWorld, context: Context, q: np.ndarray, max_distance: float = 1.0,
                     geometry_pairs: Sequence | None = None) -> float:
    """The smallest signed distance (m) over the world's pairs at configuration ``q`` (+inf when
    none is closer than ``max_distance``): Drake's query alone, for checking a run."""
    world.plant.SetPositions(world.plant_context(context), q)
    results = signed_distance_pairs(world, context, max_distance, geometry_pairs)
    return min((r.distance for r in results), default=float("inf"))
