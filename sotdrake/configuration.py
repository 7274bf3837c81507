"""Configuration space of a plant: the ground floor that the device, features, solvers and physics share.

* :class:`Layout`: where the floating base sits in ``q`` and ``v`` and which coordinates are joints.
* :func:`integrate`: ``q ⊕ v·dt`` on SE(3) × joints.
* :func:`position_names`, :func:`velocity_names`: a name for every coordinate of ``q`` and ``v``.
* :class:`PlantContextHolder`: a plant context as the value of a cache entry.

Drake's coordinates: a floating base has ``q_B = (qw, qx, qy, qz, x, y, z)`` (unit quaternion of
``R_WB``, then ``p_WB`` in m) and ``v_B = (ω_WB, v_WBo)`` (rad/s, m/s), *both expressed in the world
frame*. Every other joint has as many positions as velocities, and ``q̇_j = v_j``.

``q ⊕ v·dt`` is exact for a velocity held constant over the tick:

* joint coordinates: ``q_j ← q_j + v_j dt``;
* the floating base ``X_WB = (R, p)``: the body twist ``ξ = (Rᵀ v_WBo, Rᵀ ω_WB)`` is integrated on
  SE(3), ``X_WB ← X_WB · exp(ξ dt)``; the quaternion as ``q ← q ⊗ exp(ω_B dt)`` (continuous, no
  sign flips), re-normalised.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context

from .exceptions import InvalidInput
from .lie import quaternion_exp, quaternion_multiply, quaternion_wxyz_to_rotation, se3_translation

BASE_POSITION_SUFFIXES = ("qw", "qx", "qy", "qz", "x", "y", "z")
BASE_VELOCITY_SUFFIXES = ("wx", "wy", "wz", "vx", "vy", "vz")


class Layout(NamedTuple):
    """Where the floating base sits in ``q`` and ``v`` (None: fixed base), and the joint indices."""

    base_q: int | None
    base_v: int | None
    joints_q: np.ndarray
    joints_v: np.ndarray

    @staticmethod
    def of(plant: MultibodyPlant) -> Layout:
        bases = list(plant.GetFloatingBaseBodies())
        if len(bases) > 1:
            raise InvalidInput("a plant with at most one floating base is supported")
        base_q = base_v = None
        joints_q, joints_v = np.arange(plant.num_positions()), np.arange(plant.num_velocities())
        if bases:
            body = plant.get_body(bases[0])
            base_q, base_v = body.floating_positions_start(), body.floating_velocities_start_in_v()
            joints_q = np.setdiff1d(joints_q, np.arange(base_q, base_q + 7))
            joints_v = np.setdiff1d(joints_v, np.arange(base_v, base_v + 6))
        if joints_q.size != joints_v.size:
            raise InvalidInput("every joint but the floating base must have as many positions as velocities")
        return Layout(base_q, base_v, joints_q, joints_v)


def integrate(q: np.ndarray, v: np.ndarray, dt: float, layout: Layout) -> np.ndarray:
    """``q ⊕ v·dt`` (see the module docstring); ``q`` is not modified."""
    out = q.copy()
    out[layout.joints_q] += dt * v[layout.joints_v]
    if layout.base_q is not None:
        iq, iv = layout.base_q, layout.base_v
        R = quaternion_wxyz_to_rotation(q[iq : iq + 4])
        omega_B = R.T @ v[iv : iv + 3]
        v_B = R.T @ v[iv + 3 : iv + 6]
        dp = se3_translation(v_B * dt, omega_B * dt)
        quaternion = quaternion_multiply(q[iq : iq + 4], quaternion_exp(omega_B * dt))
        out[iq : iq + 4] = quaternion / np.linalg.norm(quaternion)
        out[iq + 4 : iq + 7] = q[iq + 4 : iq + 7] + R @ dp
    return out


def _names(plant: MultibodyPlant, size: int, start, count, base_start, suffixes) -> list[str]:
    names = [""] * size
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        n = count(joint)
        for k in range(n):
            names[start(joint) + k] = joint.name() if n == 1 else f"{joint.name()}[{k}]"
    for body_index in plant.GetFloatingBaseBodies():  # the base's own names win over its joint's
        body = plant.get_body(body_index)
        for k, suffix in enumerate(suffixes):
            names[base_start(body) + k] = f"{body.name()}_{suffix}"
    return names


def position_names(plant: MultibodyPlant) -> list[str]:
    """A name for every coordinate of ``q``: a one-position joint by its joint name, another joint as
    ``<joint>[k]``, the floating base as ``<body>_qw, _qx, _qy, _qz, _x, _y, _z``."""
    return _names(plant, plant.num_positions(), lambda j: j.position_start(), lambda j: j.num_positions(),
                  lambda b: b.floating_positions_start(), BASE_POSITION_SUFFIXES)


def velocity_names(plant: MultibodyPlant) -> list[str]:
    """A name for every coordinate of ``v``: a one-velocity joint by its joint name, another joint as
    ``<joint>[k]``, the floating base as ``<body>_wx, _wy, _wz, _vx, _vy, _vz`` (world frame)."""
    return _names(plant, plant.num_velocities(), lambda j: j.velocity_start(), lambda j: j.num_velocities(),
                  lambda b: b.floating_velocities_start_in_v(), BASE_VELOCITY_SUFFIXES)


class PlantContextHolder:
    """A plant context as the value of a cache entry: a system computing kinematics sets its
    positions in the entry's ``calc``; a copy (for a cloned system context) gets a fresh one."""

    def __init__(self, plant: MultibodyPlant):
        self.plant = plant
        self.context: Context = plant.CreateDefaultContext()

    def __deepcopy__(self, memo: dict) -> PlantContextHolder:
        return PlantContextHolder(self.plant)
