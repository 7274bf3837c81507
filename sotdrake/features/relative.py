"""Relative pose feature (sot-core ``FeaturePoint6dRelative``): frame A with respect to frame B.

``X_BA = X_WB⁻¹ X_WA = (R_BA, p_BA)`` against a desired ``X_BA*`` (``R*, p*``), expressed in the
desired frame: ``e = (R*ᵀ(p_BA - p*), log(R*ᵀ R_BA))``. With the world-frame spatial Jacobians
``J_WA = (JωA; JvA)`` and ``J_WB``::

    d p_BA/dt = R_WBᵀ (v_A - v_B + [p_A - p_B]× ω_B)     →  J_t = R*ᵀ R_WBᵀ (JvA - JvB + [p_A - p_B]× JωB)
    ω of A relative to B, in A: R_WAᵀ (ω_A - ω_B)         →  J_r = Jr⁻¹(e_r) R_WAᵀ (JωA - JωB)

For a moving desired pose, with its spatial velocity ``(ω*, ṗ*)`` in B's axes (how ``X_BA*``
moves in B) and ``ω*_F* = R*ᵀ ω*``, the reference's part of ``ė`` (as the 6D feature's ``desired``
frame, B in place of the world)::

    ė_ref = (-R*ᵀ ṗ* + [e_t]× ω*_F* ; -Jl⁻¹(e_r) ω*_F*)

E.g. one hand with respect to the other (``MetaTaskKine6dRel``). Inputs ``position``/``Jq`` (A),
``positionRef``/``JqRef`` (B), ``reference`` (``X_BA*``) and, optional, ``reference_velocity``
(``(ω*, ṗ*)``, rad/s and m/s in B); outputs as every feature.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import Context

from ..lie import hat, log_so3, right_jacobian_inverse_so3
from .base import Feature, usual_input


class FeatureRelative6d(Feature):
    """Pose of frame A in frame B against ``X_BA*`` (m, rad; 6 rows ``(x, y, z, rx, ry, rz)``): see
    the module docstring. Inputs ``position``, ``Jq``, ``positionRef``, ``JqRef``, ``reference`` and,
    optional, ``reference_velocity`` (``(ω*, ṗ*)`` in B's axes)."""

    def __init__(self, name: str, nv: int):
        Feature.__init__(self, name, 6, nv)
        self.position = self.DeclareAbstractInputPort("position", AbstractValue.Make(RigidTransform()))
        self.Jq = self.DeclareAbstractInputPort("Jq", AbstractValue.Make(np.zeros((6, nv))))
        self.positionRef = self.DeclareAbstractInputPort("positionRef", AbstractValue.Make(RigidTransform()))
        self.JqRef = self.DeclareAbstractInputPort("JqRef", AbstractValue.Make(np.zeros((6, nv))))
        self.reference = self.DeclareAbstractInputPort("reference", AbstractValue.Make(RigidTransform()))
        self.reference_velocity = self.DeclareVectorInputPort("reference_velocity", 6)
        self._declare_outputs()

    def _compute(self, context: Context, settings, rows):
        return relative_pose_error_and_jacobian(
            self.position.Eval(context).GetAsMatrix4(), self.Jq.Eval(context),
            self.positionRef.Eval(context).GetAsMatrix4(), self.JqRef.Eval(context),
            self.reference.Eval(context).GetAsMatrix4(), usual_input(self.reference_velocity, context, None))


def relative_pose_error_and_jacobian(
    X_WA: np.ndarray, J_A: np.ndarray, X_WB: np.ndarray, J_B: np.ndarray, X_BAd: np.ndarray,
    V_BAd: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The error of ``X_BA`` against ``X_BA*``, its Jacobian and ``ė_ref`` (see the module
    docstring), from the 4×4 poses ``X_WA``, ``X_WB``, ``X_BA*``, the 6×nv spatial Jacobians ``J_A``,
    ``J_B`` and the desired pose's velocity ``V_BAd = (ω*, ṗ*)`` in B (None: a fixed one)."""
    R_WA, p_WA = X_WA[:3, :3], X_WA[:3, 3]
    R_WB, p_WB = X_WB[:3, :3], X_WB[:3, 3]
    Rd, pd = X_BAd[:3, :3], X_BAd[:3, 3]
    R_BA, p_BA = R_WB.T @ R_WA, R_WB.T @ (p_WA - p_WB)
    e_t = Rd.T @ (p_BA - pd)
    e_r = log_so3(Rd.T @ R_BA)
    r = p_WA - p_WB
    J_t = Rd.T @ R_WB.T @ (J_A[3:] - J_B[3:] + hat(r) @ J_B[:3])
    J_r = right_jacobian_inverse_so3(e_r) @ R_WA.T @ (J_A[:3] - J_B[:3])
    e_dot = np.zeros(6)
    if V_BAd is not None and np.any(V_BAd):
        w = Rd.T @ V_BAd[:3]
        e_dot[:3] = np.cross(e_t, w) - Rd.T @ V_BAd[3:]
        e_dot[3:] = -right_jacobian_inverse_so3(-e_r) @ w  # (Jr⁻¹(-φ) = Jl⁻¹(φ))
    return np.concatenate([e_t, e_r]), np.vstack([J_t, J_r]), e_dot
