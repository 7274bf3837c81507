"""Posture feature (sot-core ``FeaturePosture``): the configuration against a reference posture.

One error component per generalized velocity ``v_i`` (so ``selectDof(i)`` speaks of Drake's
velocity index ``i``):

* joint coordinate: ``e_i = q_i - q*_i``, Jacobian row ``e_iᵀ`` (identity), ``ė_ref,i = -q̇*_i``;
  for a revolute joint without position limits (a URDF ``continuous`` joint), the angle is wrapped
  into ``[-π, π]``: the joint turns the short way to ``q*`` (as sot-core's Pinocchio difference does);
* floating base (Drake order ``ω``, then ``v``): rotation ``log(R*ᵀ R)`` with rows
  ``Jr⁻¹(e_r) Rᵀ`` on ``ω_W``; translation ``p - p*`` (world) with identity rows on ``v_WB``; the
  reference's base velocity (``ω*, ṗ*``, world) enters ``ė_ref`` as ``(-Jl⁻¹(e_r) R*ᵀ ω*, -ṗ*)``.

By default every joint is selected and the floating base is not (it is usually what the other
tasks move). Input ``state`` (``q``); the posture ``q*`` and its velocity ``v*`` are settings, or
the optional inputs ``posture_in`` (nq) and ``postureDot_in`` (nv).
"""

from __future__ import annotations

import numbers
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from pydrake.systems.framework import Context

from ..configuration import Layout, check_base_quaternion
from ..exceptions import InvalidInput, check_finite
from ..lie import left_jacobian_inverse_so3, log_so3, quaternion_wxyz_to_rotation, right_jacobian_inverse_so3
from ..ranges import MAX_JOINT_TARGET, MAX_TARGET_VELOCITY
from .base import Feature, FeatureSettings, optional_input


@dataclass
class PostureSettings(FeatureSettings):
    posture: np.ndarray = field(default_factory=lambda: np.zeros(0))
    postureDot: np.ndarray = field(default_factory=lambda: np.zeros(0))


class FeaturePosture(Feature):
    """``e = q ⊖ q*`` per velocity component (joints selected, floating base not, by default): see
    the module docstring. Input ``state`` (``q``) and optional ``posture_in``, ``postureDot_in``;
    outputs ``signals``, ``error``, ``jacobian``, ``errordot``."""

    def __init__(self, name: str, plant, posture: np.ndarray):
        self.layout = Layout.of(plant)
        nq, nv = plant.num_positions(), plant.num_velocities()
        mask = np.zeros(nv, dtype=bool)
        mask[self.layout.joints_v] = True
        settings = PostureSettings(_mask(mask), check_finite("posture", posture, (nq,)).copy(), np.zeros(nv))
        Feature.__init__(self, name, nv, nv, settings)
        self.nq = nq
        self._joint_q = np.full(nv, -1)  # the q index of each joint velocity (-1: the floating base)
        self._joint_q[self.layout.joints_v] = self.layout.joints_q
        self.wrapped = unbounded_revolute(plant)
        self.state = self.DeclareVectorInputPort("state", nq)
        self.posture_in = self.DeclareVectorInputPort("posture_in", nq)
        self.postureDot_in = self.DeclareVectorInputPort("postureDot_in", nv)
        self._declare_outputs()

    def _compute(self, context: Context, s, rows):
        q_star = optional_input(self.posture_in, context, s.posture)
        v_star = optional_input(self.postureDot_in, context, s.postureDot)
        q = self.state.Eval(context)
        if rows is not None and self._joint_q[rows].min() >= 0:  # joints only: the selected rows
            return joint_rows(q, q_star, v_star, self._joint_q, rows, self.wrapped)
        if q_star is not s.posture:  # (a posture from the port: its base quaternion checked as setPosture's)
            check_base_quaternion(f"{self.name}: posture_in at t = {context.get_time():g}", q_star, self.layout)
        return posture_error_and_jacobian(q, q_star, v_star, self.layout, self.wrapped)

    def selectDof(self, index: int, selected: bool, context: Context | None = None) -> None:
        """Select (or not) the component of velocity index ``index`` (sot-core ``selectDof``)."""
        if isinstance(index, bool) or not isinstance(index, numbers.Integral) or not 0 <= index < self.nv:
            raise InvalidInput(f"{self.name}.selectDof: index must be an integer in 0..{self.nv - 1}, got {index!r:.50}")
        if not isinstance(selected, (bool, np.bool_)):
            raise InvalidInput(f"{self.name}.selectDof: selected must be True or False, got {selected!r:.50}")

        def change(s):
            flags = [c == "1" for c in reversed(s.selection)][: self.nv]  # (a shorter mask: the rest unselected)
            mask = np.zeros(self.nv, dtype=bool)
            mask[: len(flags)] = flags
            mask[index] = selected
            if not mask.any():
                raise InvalidInput(f"{self.name}.selectDof: no component would be left selected")
            s.selection = _mask(mask)

        self._command(context, change)

    def setPosture(self, posture, context: Context | None = None) -> None:
        q_star = check_finite(f"{self.name}.posture", posture, (self.nq,), MAX_JOINT_TARGET).copy()
        check_base_quaternion(f"{self.name}.setPosture", q_star, self.layout)
        self._command(context, lambda s: setattr(s, "posture", q_star))

    def setPostureDot(self, velocity, context: Context | None = None) -> None:
        v_star = check_finite(f"{self.name}.postureDot", velocity, (self.nv,), MAX_TARGET_VELOCITY).copy()
        self._command(context, lambda s: setattr(s, "postureDot", v_star))


def unbounded_revolute(plant) -> np.ndarray | None:
    """nv booleans, True on the velocity of each revolute joint without position limits (the angles
    :func:`posture_error_and_jacobian` wraps), or None if there is none."""
    wrapped = np.zeros(plant.num_velocities(), dtype=bool)
    for index in plant.GetJointIndices():
        joint = plant.get_joint(index)
        if joint.type_name() == "revolute" and np.all(np.isinf(joint.position_lower_limits())) \
                and np.all(np.isinf(joint.position_upper_limits())):
            wrapped[joint.velocity_start()] = True
    return wrapped if wrapped.any() else None


def _wrap(angle: np.ndarray) -> np.ndarray:
    """``angle`` (rad) wrapped into ``[-π, π]``."""
    return angle - 2.0 * np.pi * np.round(angle / (2.0 * np.pi))


def posture_error_and_jacobian(
    q: np.ndarray, q_star: np.ndarray, v_star: np.ndarray, layout: Layout, wrapped: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every component of the posture error (one per velocity), its Jacobian and ``ė_ref`` for the
    reference's velocity ``v*``; see the module docstring. ``layout``: where the floating base is;
    ``wrapped``: nv booleans, the joint angles to wrap (:func:`unbounded_revolute`), or None."""
    nv = v_star.size
    e, J, e_dot = np.zeros(nv), np.eye(nv), -v_star
    e[layout.joints_v] = q[layout.joints_q] - q_star[layout.joints_q]
    if wrapped is not None:
        e[wrapped] = _wrap(e[wrapped])
    if layout.base_q is not None and layout.base_v is not None:
        iq, iv = layout.base_q, layout.base_v
        R = quaternion_wxyz_to_rotation(q[iq : iq + 4])
        Rd = quaternion_wxyz_to_rotation(q_star[iq : iq + 4])
        e_r = log_so3(Rd.T @ R)
        e[iv : iv + 3] = e_r
        e[iv + 3 : iv + 6] = q[iq + 4 : iq + 7] - q_star[iq + 4 : iq + 7]
        J[iv : iv + 3, iv : iv + 3] = right_jacobian_inverse_so3(e_r) @ R.T
        e_dot[iv : iv + 3] = -left_jacobian_inverse_so3(e_r) @ (Rd.T @ v_star[iv : iv + 3])
    return e, J, e_dot


@lru_cache(maxsize=32)
def _selection_rows(rows: bytes, nv: int) -> np.ndarray:
    """The rows ``rows`` (int64 bytes) of the nv × nv identity, read-only."""
    J = np.eye(nv)[np.frombuffer(rows, dtype=np.int64)]
    J.flags.writeable = False
    return J


def joint_rows(q: np.ndarray, q_star: np.ndarray, v_star: np.ndarray, joint_q: np.ndarray,
               rows: np.ndarray, wrapped: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rows ``rows`` (joint velocity indices only) of :func:`posture_error_and_jacobian`:
    ``e = q_j − q*_j`` (``wrapped`` as there), identity rows, ``ė_ref = −v*``; ``joint_q``: the q
    index of each velocity."""
    iq = joint_q[rows]
    e = q[iq] - q_star[iq]
    if wrapped is not None and (turns := wrapped[rows]).any():
        e[turns] = _wrap(e[turns])
    return e, _selection_rows(np.asarray(rows, dtype=np.int64).tobytes(), v_star.size), -v_star[rows]


def _mask(selected: np.ndarray) -> str:
    """A selection string (read right to left) from booleans in component order."""
    return "".join("1" if x else "0" for x in reversed(selected))
