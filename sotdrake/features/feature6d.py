"""6D pose feature (sot-core ``FeaturePoint6d``/``Feature6d``) and its desired value.

Let F be the controlled frame: the op point Op moved by ``opmodif`` (``X_WF = X_WOp · X_OpF``,
the seed's ``handMgrip``), ``X_WF = (R, p)`` and the desired ``X_WF* = (R*, p*)``. The full error has
six components ``(X, Y, Z, RX, RY, RZ)``, as sot-core defines them:

* ``frame('desired')``: ``e = (R*ᵀ(p - p*), log(R*ᵀ R))``, the pose of F seen from F*; with ``R* = I``
  the translation error is ``p - p*`` in world axes;
* ``frame('current')``: ``e = (Rᵀ(p* - p), log(Rᵀ R*))``, the pose of F* seen from F.

``log`` is the SO(3) logarithm (rotation vector). With ``J_WF = (Jω; Jv)`` (world frame, rows of
Drake's spatial Jacobian), ``ω_F = Rᵀ ω_W`` and, for a moving target, its spatial velocity
``(ω*, ṗ*)`` (world) with ``ω*_F* = R*ᵀ ω*``, the exact derivatives are

* desired: ``J = (R*ᵀ Jv ; Jr⁻¹(e_r) Rᵀ Jω)``, ``ė_ref = (-R*ᵀ ṗ* + [e_t]× ω*_F* ; -Jl⁻¹(e_r) ω*_F*)``;
* current: ``J = (-Rᵀ Jv + [e_t]× Rᵀ Jω ; -Jl⁻¹(e_r) Rᵀ Jω)``, ``ė_ref = (Rᵀ ṗ* ; Jr⁻¹(e_r) ω*_F*)``,

and only the rows chosen by the selection mask are output (see :mod:`sotdrake.selection`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.systems.framework import Context

from ..entity import Entity
from ..exceptions import InvalidInput, check_finite
from ..lie import hat, left_jacobian_inverse_so3, log_so3, right_jacobian_inverse_so3
from .base import Feature, FeatureSettings, optional_input

FRAMES = ("desired", "current")


def pose_error_and_jacobian(
    X_WF: RigidTransform, J_WF: np.ndarray, X_WFd: RigidTransform, frame: str, V_WFd: np.ndarray | None = None,
    rotation: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Full 6D error ``e``, its Jacobian ``∂e/∂v`` (6×nv) and ``ė_ref`` for the target's spatial
    velocity ``V_WFd = (ω*, ṗ*)`` (zero when None); see the module docstring. With
    ``rotation=False`` the rotation rows are left at zero (a selection without them: no log to take)."""
    R, p = X_WF.rotation().matrix(), X_WF.translation()
    Rd, pd = X_WFd.rotation().matrix(), X_WFd.translation()
    moving = V_WFd is not None and V_WFd.any()
    if not rotation:
        if frame == "desired":
            e_t, J_t = Rd.T @ (p - pd), Rd.T @ J_WF[3:]
            e_dot_t = -Rd.T @ V_WFd[3:] + hat(e_t) @ (Rd.T @ V_WFd[:3]) if moving else np.zeros(3)
        else:
            e_t = R.T @ (pd - p)
            J_t = -R.T @ J_WF[3:] + hat(e_t) @ (R.T @ J_WF[:3])
            e_dot_t = R.T @ V_WFd[3:] if moving else np.zeros(3)
        zeros = np.zeros(3)
        return np.concatenate([e_t, zeros]), np.vstack([J_t, np.zeros_like(J_t)]), np.concatenate([e_dot_t, zeros])
    Jw_F = R.T @ J_WF[:3]  # body angular-velocity rows
    wd = Rd.T @ V_WFd[:3] if moving else None
    if frame == "desired":
        e_t = Rd.T @ (p - pd)
        e_r = log_so3(Rd.T @ R)
        J = np.vstack([Rd.T @ J_WF[3:], right_jacobian_inverse_so3(e_r) @ Jw_F])
        e_dot = np.concatenate([-Rd.T @ V_WFd[3:] + hat(e_t) @ wd, -left_jacobian_inverse_so3(e_r) @ wd]) if moving else np.zeros(6)
    else:
        e_t = R.T @ (pd - p)
        e_r = log_so3(R.T @ Rd)
        J = np.vstack([-R.T @ J_WF[3:] + hat(e_t) @ Jw_F, -left_jacobian_inverse_so3(e_r) @ Jw_F])
        e_dot = np.concatenate([R.T @ V_WFd[3:], right_jacobian_inverse_so3(e_r) @ wd]) if moving else np.zeros(6)
    return np.concatenate([e_t, e_r]), J, e_dot


def shift_jacobian(X_WOp: RigidTransform, J_WOp: np.ndarray, X_OpF: RigidTransform):
    """Pose and spatial Jacobian of ``F = Op · X_OpF`` (``v_WF = v_WOp + ω × p_OpF_W``)."""
    p_OpF_W = X_WOp.rotation().multiply(X_OpF.translation())
    J = J_WOp.copy()
    J[3:] -= hat(p_OpF_W) @ J_WOp[:3]
    return X_WOp.multiply(X_OpF), J


def as_transform(value, what: str) -> RigidTransform:
    """A ``RigidTransform`` from a 4×4 homogeneous matrix, a ``RigidTransform``, a 3-vector
    (translation, identity rotation) or a 6-vector ``(x, y, z, roll, pitch, yaw)``, as sot-core's
    ``generic6dReference`` accepts."""
    if isinstance(value, RigidTransform):
        return value
    array = check_finite(what, value)
    if array.shape == (4, 4):
        if not np.allclose(array[3], [0, 0, 0, 1]):
            raise InvalidInput(f"{what}: last row of a homogeneous matrix must be (0, 0, 0, 1)")
        R = array[:3, :3]
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or np.linalg.det(R) < 0:
            raise InvalidInput(f"{what}: the 3×3 block is not a rotation matrix")
        return RigidTransform(RotationMatrix(R), array[:3, 3])
    if array.shape == (3,):
        return RigidTransform(array)
    if array.shape == (6,):
        return RigidTransform(RollPitchYaw(array[3:]), array[:3])
    raise InvalidInput(f"{what}: expected a 4×4 matrix, 3 or 6 numbers, got shape {array.shape}")


@dataclass
class Feature6dDesiredSettings:
    position: RigidTransform = field(default_factory=RigidTransform)
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(6))  # (ω*, ṗ*), world frame


class Feature6dDesired(Entity[Feature6dDesiredSettings]):
    """Desired pose ``X_WF*`` (the SoT ``featureDes``). Outputs ``position`` and ``velocity``
    (``(ω*, ṗ*)``, world frame).

    Optional inputs for a moving target: ``pose_in`` (``X_WF*``) and ``spatial_velocity_in``
    (``(ω*, ṗ*)``), which override the settings' pose and velocity; ``translation_in`` (``p*``, m)
    and ``translation_velocity_in`` (``ṗ*``, m/s), which override the translation and
    translational velocity only (applied after ``pose_in``/``spatial_velocity_in``).
    """

    def __init__(self, name: str):
        Entity.__init__(self, name, Feature6dDesiredSettings())
        self.pose_in = self.DeclareAbstractInputPort("pose_in", AbstractValue.Make(RigidTransform()))
        self.spatial_velocity_in = self.DeclareVectorInputPort("spatial_velocity_in", 6)
        self.translation_in = self.DeclareVectorInputPort("translation_in", 3)
        self.translation_velocity_in = self.DeclareVectorInputPort("translation_velocity_in", 3)
        self.DeclareAbstractOutputPort("position", lambda: AbstractValue.Make(RigidTransform()), self._position)
        self.DeclareVectorOutputPort("velocity", 6, self._velocity)

    def _position(self, context: Context, output: AbstractValue) -> None:
        X = optional_input(self.pose_in, context, self._settings_of(context).position)
        if self.translation_in.HasValue(context):
            X = RigidTransform(X.rotation(), self.translation_in.Eval(context))
        output.set_value(X)

    def _velocity(self, context: Context, output) -> None:
        V = np.array(optional_input(self.spatial_velocity_in, context, self._settings_of(context).velocity))
        if self.translation_velocity_in.HasValue(context):
            V[3:] = self.translation_velocity_in.Eval(context)
        output.SetFromVector(V)

    def setPosition(self, value, context: Context | None = None) -> None:
        """Set ``X_WF*`` (any form :func:`as_transform` accepts)."""
        X = as_transform(value, f"{self.name}.position")
        self._command(context, lambda s: setattr(s, "position", X))

    def setVelocity(self, velocity, context: Context | None = None) -> None:
        """Set the target's spatial velocity ``(ω*, ṗ*)`` (world frame) for the feed-forward."""
        V = check_finite(f"{self.name}.velocity", velocity, (6,)).copy()
        self._command(context, lambda s: setattr(s, "velocity", V))


@dataclass
class Feature6dSettings(FeatureSettings):
    frame: str = "desired"
    opmodif: RigidTransform | None = None


class Feature6d(Feature):
    """Error between an op point and its desired pose.

    Inputs: ``position`` (``X_WOp``), ``Jq`` (``J_WOp``, 6×nv), ``reference`` (``X_WF*``) and,
    optional, ``reference_velocity`` (``(ω*, ṗ*)``). Outputs: ``error``, ``jacobian``, ``errordot``.
    """

    def __init__(self, name: str, nv: int):
        Feature.__init__(self, name, 6, nv, Feature6dSettings("111111"))
        self.position = self.DeclareAbstractInputPort("position", AbstractValue.Make(RigidTransform()))
        self.Jq = self.DeclareAbstractInputPort("Jq", AbstractValue.Make(np.zeros((6, nv))))
        self.reference = self.DeclareAbstractInputPort("reference", AbstractValue.Make(RigidTransform()))
        self.reference_velocity = self.DeclareVectorInputPort("reference_velocity", 6)
        self._declare_outputs()

    def _compute(self, context: Context, s, rows):
        X_WF, J_WF = self.position.Eval(context), self.Jq.Eval(context)
        if s.opmodif is not None:
            X_WF, J_WF = shift_jacobian(X_WF, J_WF, s.opmodif)
        V = optional_input(self.reference_velocity, context, None)
        return pose_error_and_jacobian(X_WF, J_WF, self.reference.Eval(context), s.frame, V, rotation=rows[-1] >= 3)

    def frame(self, which: str, context: Context | None = None) -> None:
        """Frame in which the error is expressed: ``'desired'`` or ``'current'``."""
        if which not in FRAMES:
            raise InvalidInput(f"{self.name}.frame: expected one of {FRAMES}, got {which!r}")
        self._command(context, lambda s: setattr(s, "frame", which))

    def setOpmodif(self, value, context: Context | None = None) -> None:
        """Controlled frame offset ``X_OpF`` (the seed's ``opmodif``); ``None`` removes it."""
        X = None if value is None else as_transform(value, f"{self.name}.opmodif")
        self._command(context, lambda s: setattr(s, "opmodif", X))
