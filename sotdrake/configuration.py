"""Configuration space of a plant: the ground floor that the device, features, solvers and physics share.

* :class:`Layout`: where the floating base sits in ``q`` and ``v`` and which coordinates are joints.
* :func:`integrate`: ``q ⊕ v·dt`` on SE(3) × joints, and its inverse :func:`difference`.
* :func:`position_names`, :func:`velocity_names`: a name for every coordinate of ``q`` and ``v``.
* :class:`PlantContextHolder`: a plant context as the value of a cache entry.

Drake's coordinates: a floating base has ``q_B = (qw, qx, qy, qz, x, y, z)`` (unit quaternion of
``R_WB``, then ``p_WB`` in m) and ``v_B = (ω_WB, v_WBo)`` (rad/s, m/s), *both expressed in the world
frame*. Every other joint has as many positions as velocities, and ``q̇_j = v_j``.

``q ⊕ v·dt`` is exact for Drake's generalized velocity ``v`` held constant over the tick (the flow
of ``q̇ = N(q) v``, the meaning of ``v`` the solvers' Jacobians are taken with respect to):

* joint coordinates: ``q_j ← q_j + v_j dt``;
* the floating base ``X_WB = (R, p)`` with Drake's ``(ω_W, v_WBo)`` (both in the world frame):
  ``R ← exp([ω_W]× dt) R`` (the quaternion as ``q ← exp(ω_W dt) ⊗ q``, continuous, re-normalised)
  and ``p ← p + v_WBo dt``.

(Integrating instead the body twist ``(Rᵀω_W, Rᵀv_WBo)`` on SE(3), as Pinocchio's ``integrate``
does with its body-frame ``v``, bends the base's path by ``½ ω × v dt²`` per tick, a second-order
term no Drake Jacobian accounts for: TALOS' feet drifted by 8 µm in 0.3 s that way while reaching
at the velocity limits.) :func:`difference` is the inverse of ``⊕``.
"""

from __future__ import annotations

import copy
import logging
import math
from typing import NamedTuple

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context

from .compiled import compiled_input, kernels
from .exceptions import InvalidInput, check_type
from .lie import log_so3, quaternion_exp_list, quaternion_multiply_list, quaternion_wxyz_to_rotation

BASE_POSITION_SUFFIXES = ("qw", "qx", "qy", "qz", "x", "y", "z")
BASE_VELOCITY_SUFFIXES = ("wx", "wy", "wz", "vx", "vy", "vz")

log = logging.getLogger(__name__)


class Layout(NamedTuple):
    """Where the floating base sits in ``q`` and ``v`` (None: fixed base), and the joint indices."""

    base_q: int | None
    base_v: int | None
    joints_q: np.ndarray
    joints_v: np.ndarray
    joints_q_slice: slice | None = None  # the same indices as a slice, when contiguous
    joints_v_slice: slice | None = None

    @property
    def nq(self) -> int:
        return len(self.joints_q) + (7 if self.base_q is not None else 0)

    @property
    def nv(self) -> int:
        return len(self.joints_v) + (6 if self.base_v is not None else 0)

    @property
    def base_q_index(self) -> int:
        """``base_q``, -1 for none (as the compiled code takes it)."""
        return -1 if self.base_q is None else self.base_q

    @property
    def base_v_index(self) -> int:
        return -1 if self.base_v is None else self.base_v

    @staticmethod
    def of(plant: MultibodyPlant) -> Layout:
        """The layout of ``plant``'s q and v (:class:`InvalidInput` if it is not a MultibodyPlant)."""
        check_type("plant", plant, MultibodyPlant, "a MultibodyPlant (e.g. robot.model.plant)")
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
        return Layout(base_q, base_v, joints_q, joints_v, contiguous_slice(joints_q), contiguous_slice(joints_v))


def contiguous_slice(indices: np.ndarray) -> slice | None:
    """``indices`` as a slice if they are contiguous and increasing (None otherwise): a view of an
    array's entries instead of a copy."""
    if indices.size and np.array_equal(indices, np.arange(indices[0], indices[0] + indices.size)):
        return slice(int(indices[0]), int(indices[0]) + indices.size)
    return None


def check_base_quaternion(name: str, q: np.ndarray, layout: Layout) -> None:
    """The floating base's quaternion in ``q`` must have norm 1 (± 1e-3), else :class:`InvalidInput`."""
    if layout.base_q is not None:
        norm = float(np.linalg.norm(q[layout.base_q : layout.base_q + 4]))
        if abs(norm - 1.0) > 1e-3:
            raise InvalidInput(f"{name}: the base quaternion must have norm 1 (± 1e-3), got {norm:g}")


def integrate(q: np.ndarray, v: np.ndarray, dt: float, layout: Layout) -> np.ndarray:
    """``q ⊕ v·dt`` (see the module docstring); ``q`` is not modified. Compiled
    (:mod:`.jit_configuration`); :func:`python_integrate` is its reference."""
    q, v = compiled_input(q), compiled_input(v)
    if q.shape != (layout.nq,) or v.shape != (layout.nv,):  # (the compiled code reads them unchecked)
        raise InvalidInput(f"integrate: expected q of size {layout.nq} and v of size {layout.nv}, got {q.shape} and {v.shape}")
    return _jit_configuration().integrate(q, v, float(dt), layout.base_q_index, layout.base_v_index,
                                          layout.joints_q, layout.joints_v)


_jit_configuration = kernels(".jit_configuration", __package__, "integrate", "the configuration's integration", "a few seconds")


def python_integrate(q: np.ndarray, v: np.ndarray, dt: float, layout: Layout) -> np.ndarray:
    """:func:`integrate` in Python: its reference. The floating base's 3-vectors and quaternion are
    handled on Python floats (cheaper than numpy at this size)."""
    out = q.copy()
    if layout.joints_q_slice is not None and layout.joints_v_slice is not None:
        out[layout.joints_q_slice] += dt * v[layout.joints_v_slice]
    else:
        out[layout.joints_q] += dt * v[layout.joints_v]
    if layout.base_q is not None and layout.base_v is not None:
        iq, iv = layout.base_q, layout.base_v
        wx, wy, wz, vx, vy, vz = v[iv : iv + 6].tolist()
        quaternion = quaternion_multiply_list(quaternion_exp_list((wx * dt, wy * dt, wz * dt)), q[iq : iq + 4].tolist())
        n = math.sqrt(sum(c * c for c in quaternion))
        out[iq : iq + 4] = [c / n for c in quaternion]
        out[iq + 4 : iq + 7] = [q[iq + 4] + vx * dt, q[iq + 5] + vy * dt, q[iq + 6] + vz * dt]
    return out


def difference(q: np.ndarray, q_previous: np.ndarray, layout: Layout) -> np.ndarray:
    """``Δ`` (size nv) with ``q = q_previous ⊕ Δ`` (a velocity times ``dt``): joints ``q - q_prev``;
    the base ``(log(R R_prevᵀ), p - p_prev)``, world frame."""
    out = np.empty(layout.nv)
    out[layout.joints_v] = q[layout.joints_q] - q_previous[layout.joints_q]
    if layout.base_q is not None and layout.base_v is not None:
        iq, iv = layout.base_q, layout.base_v
        R = quaternion_wxyz_to_rotation(q[iq : iq + 4])
        R_previous = quaternion_wxyz_to_rotation(q_previous[iq : iq + 4])
        out[iv : iv + 3] = log_so3(R @ R_previous.T)
        out[iv + 3 : iv + 6] = q[iq + 4 : iq + 7] - q_previous[iq + 4 : iq + 7]
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


def warn_beyond_limits(plant: MultibodyPlant, q: np.ndarray, what: str) -> None:
    """A log warning naming the joints of ``plant`` whose positions in ``q`` are beyond their limits
    (by more than 1e-9): the solvers bring them back inside first, which a user rarely means."""
    lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
    beyond = np.flatnonzero((q < lower - 1e-9) | (q > upper + 1e-9))
    if beyond.size:
        names = position_names(plant)
        log.warning("%s: %s beyond the joint limits: the solver brings them back inside before anything else", what,
                    ", ".join(f"{names[i]} = {q[i]:g} not in [{lower[i]:g}, {upper[i]:g}]" for i in beyond[:6]))


def position_names(plant: MultibodyPlant) -> list[str]:
    """A name for every coordinate of ``q``: a one-position joint by its joint name, another joint as
    ``<joint>[k]``, the floating base as ``<body>_qw, _qx, _qy, _qz, _x, _y, _z``."""
    return _names(plant, plant.num_positions(), lambda j: j.position_start(), lambda j: j.num_positions(),
                  lambda b: b.floating_positions_start(), BASE_POSITION_SUFFIXES)


def velocity_names(plant: MultibodyPlant) -> list[str]:
    """A name for every coordinate of ``v``: a one-velocity joint by its joint name, another joint as
    ``<joint>[k]``, the floating base as ``<body>_wx, _wy, _wz, _vx, _vy, _vz`` (world frame)."""
    check_type("velocity_names: plant", plant, MultibodyPlant, "a MultibodyPlant (e.g. robot.model.plant)")
    return _names(plant, plant.num_velocities(), lambda j: j.velocity_start(), lambda j: j.num_velocities(),
                  lambda b: b.floating_velocities_start_in_v(), BASE_VELOCITY_SUFFIXES)


class PlantContextHolder:
    """A plant context as the value of a cache entry: a system computing kinematics sets its
    positions in the entry's ``calc``; a copy (for a cloned system context) gets a context of its
    own at the same state (Drake copies the entry as up to date: its value must be the original's)."""

    def __init__(self, plant: MultibodyPlant):
        self.plant = plant
        self.context: Context = plant.CreateDefaultContext()

    def __deepcopy__(self, memo: dict) -> PlantContextHolder:
        clone = copy.copy(self)
        clone.context = self.context.Clone()
        return clone
