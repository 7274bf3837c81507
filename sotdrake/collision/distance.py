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
                        p_WCb=np.empty((k, 3)), jacobian=np.empty((k, nv)), bias=np.zeros(k))
    obstacles = world.obstacle_ids
    jacobians: dict = {}  # body index -> J_WB (spatial, 6×nv), once per body
    biases: dict = {}  # body index -> (α, a_Bo, ω), once per body
    world_frame, world_body = plant.world_frame(), plant.world_body().index()
    for i, r in enumerate(results):
        id_A, id_B, p_ACa, p_BCb, n = r.id_A, r.id_B, r.p_ACa, r.p_BCb, r.nhat_BA_W
        if id_A in obstacles:  # keep the robot on side A
            id_A, id_B, p_ACa, p_BCb, n = id_B, id_A, p_BCb, p_ACa, -n
        row = np.zeros(nv)
        names = []
        for sign, geometry, p_GC in ((1.0, id_A, p_ACa), (-1.0, id_B, p_BCb)):
            name, body, X_BG = world.geometry_info(geometry)
            names.append(name)
            X_WB = plant.EvalBodyPoseInWorld(plant_context, body)
            p_WC = X_WB @ (X_BG @ p_GC)
            (out.p_WCa if sign > 0 else out.p_WCb)[i] = p_WC
            if body.index() == world_body:
                continue
            if body.index() not in jacobians:
                jacobians[body.index()] = plant.CalcJacobianSpatialVelocity(
                    plant_context, JacobianWrtVariable.kV, body.body_frame(), np.zeros(3), world_frame, world_frame)
            J = jacobians[body.index()]
            # v_WC = v_WBo + ω_WB × p_BoC, so n̂ᵀ v_WC = n̂ᵀ J_v + (p_BoC × n̂)ᵀ J_ω.
            r_x, r_y, r_z = p_WC - X_WB.translation()
            n_x, n_y, n_z = n
            arm = np.array([r_y * n_z - r_z * n_y, r_z * n_x - r_x * n_z, r_x * n_y - r_y * n_x])
            row += sign * (n @ J[3:] + arm @ J[:3])
            if bias:
                if body.index() not in biases:
                    A = plant.CalcBiasSpatialAcceleration(plant_context, JacobianWrtVariable.kV, body.body_frame(), np.zeros(3),
                                                          world_frame, world_frame)
                    omega = plant.EvalBodySpatialVelocityInWorld(plant_context, body).rotational()
                    biases[body.index()] = (A.rotational(), A.translational(), omega)
                alpha, a_Bo, omega = biases[body.index()]
                p_BC = p_WC - X_WB.translation()
                out.bias[i] += sign * n @ (a_Bo + np.cross(alpha, p_BC) + np.cross(omega, np.cross(omega, p_BC)))
        out.names.append((names[0], names[1]))
        out.distance[i], out.normal[i], out.jacobian[i] = r.distance, n, row
    return out


def minimum_distance(world: CollisionWorld, context: Context, q: np.ndarray, max_distance: float = 1.0,
                     geometry_pairs: Sequence | None = None) -> float:
    """The smallest signed distance (m) over the world's pairs at configuration ``q`` (+inf when
    none is closer than ``max_distance``): Drake's query alone, for checking a run."""
    world.plant.SetPositions(world.plant_context(context), q)
    results = signed_distance_pairs(world, context, max_distance, geometry_pairs)
    return min((r.distance for r in results), default=float("inf"))
