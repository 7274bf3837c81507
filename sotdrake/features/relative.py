"""Relative pose feature (sot-core ``FeaturePoint6dRelative``): frame A with respect to frame B.

``X_BA = X_WB⁻¹ X_WA = (R_BA, p_BA)`` against a desired ``X_BA*`` (``R*, p*``), expressed in the
desired frame: ``e = (R*ᵀ(p_BA - p*), log(R*ᵀ R_BA))``. With the world-frame spatial Jacobians
``J_WA = (JωA; JvA)`` and ``J_WB``::

    d p_BA/dt = R_WBᵀ (v_A - v_B + [p_A - p_B]× ω_B)     →  J_t = R*ᵀ R_WBᵀ (JvA - JvB + [p_A - p_B]× JωB)
    ω of A relative to B, in A: R_WAᵀ (ω_A - ω_B)         →  J_r = Jr⁻¹(e_r) R_WAᵀ (JωA - JωB)

E.g. one hand with respect to the other (``MetaTaskKine6dRel``). Inputs ``position``/``Jq`` (A),
``positionRef``/``JqRef`` (B) and ``reference`` (``X_BA*``); outputs as every feature.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import Context

from ..lie import hat, log_so3, right_jacobian_inverse_so3
from .base import Feature


class FeatureRelative6d(Feature):
    """Pose of frame A in frame B against ``X_BA*`` (m, rad; 6 rows ``(x, y, z, rx, ry, rz)``): see
    the module docstring. Inputs ``position``, ``Jq``, ``positionRef``, ``JqRef``, ``reference``."""

    def __init__(self, name: str, nv: int):
        Feature.__init__(self, name, 6, nv)
        self.position = self.DeclareAbstractInputPort("position", AbstractValue.Make(RigidTransform()))
        self.Jq = self.DeclareAbstractInputPort("Jq", AbstractValue.Make(np.zeros((6, nv))))
        self.positionRef = self.DeclareAbstractInputPort("positionRef", AbstractValue.Make(RigidTransform()))
        self.JqRef = self.DeclareAbstractInputPort("JqRef", AbstractValue.Make(np.zeros((6, nv))))
        self.reference = self.DeclareAbstractInputPort("reference", AbstractValue.Make(RigidTransform()))
        self._declare_outputs()

    def _compute(self, context: Context, settings, rows):
        return relative_pose_error_and_jacobian(
            self.position.Eval(context).GetAsMatrix4(), self.Jq.Eval(context),
            self.positionRef.Eval(context).GetAsMatrix4(), self.JqRef.Eval(context),
            self.reference.Eval(context).GetAsMatrix4())


def relative_pose_error_and_jacobian(
    X_WA: np.ndarray, J_A: np.ndarray, X_WB: np.ndarray, J_B: np.ndarray, X_BAd: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The error of ``X_BA`` against ``X_BA*`` and its Jacobian (see the module docstring), from the
    4×4 poses ``X_WA``, ``X_WB``, ``X_BA*`` and the 6×nv spatial Jacobians ``J_A``, ``J_B``."""
    R_WA, p_WA = X_WA[:3, :3], X_WA[:3, 3]
    R_WB, p_WB = X_WB[:3, :3], X_WB[:3, 3]
    Rd, pd = X_BAd[:3, :3], X_BAd[:3, 3]
    R_BA, p_BA = R_WB.T @ R_WA, R_WB.T @ (p_WA - p_WB)
    e_t = Rd.T @ (p_BA - pd)
    e_r = log_so3(Rd.T @ R_BA)
    r = p_WA - p_WB
    J_t = Rd.T @ R_WB.T @ (J_A[3:] - J_B[3:] + hat(r) @ J_B[:3])
    J_r = right_jacobian_inverse_so3(e_r) @ R_WA.T @ (J_A[:3] - J_B[:3])
    return np.concatenate([e_t, e_r]), np.vstack([J_t, J_r]), np.zeros(6)
