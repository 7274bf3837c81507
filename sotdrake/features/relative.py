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
    def __init__(self, name: str, nv: int):
        Feature.__init__(self, name, 6, nv)
        self.position = self.DeclareAbstractInputPort("position", AbstractValue.Make(RigidTransform()))
        self.Jq = self.DeclareAbstractInputPort("Jq", AbstractValue.Make(np.zeros((6, nv))))
        self.positionRef = self.DeclareAbstractInputPort("positionRef", AbstractValue.Make(RigidTransform()))
        self.JqRef = self.DeclareAbstractInputPort("JqRef", AbstractValue.Make(np.zeros((6, nv))))
        self.reference = self.DeclareAbstractInputPort("reference", AbstractValue.Make(RigidTransform()))
        self._declare_outputs()

    def _compute(self, context: Context, settings, rows):
        X_WA, J_A = self.position.Eval(context), self.Jq.Eval(context)
        X_WB, J_B = self.positionRef.Eval(context), self.JqRef.Eval(context)
        X_BAd = self.reference.Eval(context)
        R_WA, R_WB = X_WA.rotation().matrix(), X_WB.rotation().matrix()
        X_BA = X_WB.inverse().multiply(X_WA)
        Rd = X_BAd.rotation().matrix()
        e_t = Rd.T @ (X_BA.translation() - X_BAd.translation())
        e_r = log_so3(Rd.T @ X_BA.rotation().matrix())
        r = X_WA.translation() - X_WB.translation()
        J_t = Rd.T @ R_WB.T @ (J_A[3:] - J_B[3:] + hat(r) @ J_B[:3])
        J_r = right_jacobian_inverse_so3(e_r) @ R_WA.T @ (J_A[:3] - J_B[:3])
        return np.concatenate([e_t, e_r]), np.vstack([J_t, J_r]), np.zeros(6)
