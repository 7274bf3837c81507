"""6D pose feature (sot-core ``FeaturePoint6d``/``Feature6d``) and its desired value.

Let F be the controlled frame: the op point Op moved by ``opmodif`` (``X_WF = X_WOp · X_OpF``,
the seed's ``handMgrip``), ``X_WF = (R, p)`` and the desired ``X_WF* = (R*, p*)``. The full error has
six components ``(X, Y, Z, RX, RY, RZ)``, as sot-core defines them:

* ``frame('desired')``: ``e = log6-like(X_WF*⁻¹ X_WF)``, i.e. ``(R*ᵀ(p - p*), log(R*ᵀ R))``: the
  pose of F seen from F*; with ``R* = I`` the translation error is ``p - p*`` in world axes;
* ``frame('current')``: ``e = (Rᵀ(p* - p), log(Rᵀ R*))``: the pose of F* seen from F.

``log`` is the SO(3) logarithm (rotation vector). With ``J_WF = (Jω; Jv)`` (world frame, rows of
Drake's spatial Jacobian) and ``ω_F = Rᵀ ω_W``, the exact Jacobians ``∂e/∂v`` are

* desired: ``(R*ᵀ Jv ; Jr⁻¹(e_r) Rᵀ Jω)``;
* current: ``(-Rᵀ Jv + [e_t]× Rᵀ Jω ; -Jl⁻¹(e_r) Rᵀ Jω)``,

and only the rows chosen by the selection mask are output (see :mod:`sotdrake.selection`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix
from pydrake.systems.framework import Context, ValueProducer

from ..entity import Entity
from ..exceptions import InvalidInput, check_finite
from ..lie import hat, left_jacobian_inverse_so3, log_so3, right_jacobian_inverse_so3
from ..selection import parse_selection

FRAMES = ("desired", "current")


def pose_error_and_jacobian(
    X_WF: RigidTransform, J_WF: np.ndarray, X_WFd: RigidTransform, frame: str
) -> tuple[np.ndarray, np.ndarray]:
    """Full 6D error ``e`` and its Jacobian ``∂e/∂v`` (6×nv), see the module docstring."""
    R, p = X_WF.rotation().matrix(), X_WF.translation()
    Rd, pd = X_WFd.rotation().matrix(), X_WFd.translation()
    Jw_F = R.T @ J_WF[:3]  # body angular-velocity rows
    if frame == "desired":
        e_t = Rd.T @ (p - pd)
        e_r = log_so3(Rd.T @ R)
        J_t = Rd.T @ J_WF[3:]
        J_r = right_jacobian_inverse_so3(e_r) @ Jw_F
    else:
        e_t = R.T @ (pd - p)
        e_r = log_so3(R.T @ Rd)
        J_t = -R.T @ J_WF[3:] + hat(e_t) @ Jw_F
        J_r = -left_jacobian_inverse_so3(e_r) @ Jw_F
    return np.concatenate([e_t, e_r]), np.vstack([J_t, J_r])


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


class Feature6dDesired(Entity[Feature6dDesiredSettings]):
    """Desired pose ``X_WF*`` (the SoT ``featureDes``). Output ``position``."""

    def __init__(self, name: str):
        Entity.__init__(self, name, Feature6dDesiredSettings())
        self.DeclareAbstractOutputPort(
            "position",
            lambda: AbstractValue.Make(RigidTransform()),
            lambda c, o: o.set_value(self._settings_of(c).position),
        )

    def setPosition(self, value, context: Context | None = None) -> None:
        """Set ``X_WF*`` (any form :func:`as_transform` accepts)."""
        X = as_transform(value, f"{self.name}.position")
        self._command(context, lambda s: setattr(s, "position", X))


@dataclass
class Feature6dSettings:
    selection: str = "111111"
    frame: str = "desired"
    opmodif: RigidTransform | None = None


class Feature6d(Entity[Feature6dSettings]):
    """Error between an op point and its desired pose.

    Inputs: ``position`` (``X_WOp``), ``Jq`` (``J_WOp``, 6×nv), ``reference`` (``X_WF*``).
    Outputs: ``error`` and ``jacobian``, the selected rows of ``e`` and ``∂e/∂v``.
    """

    def __init__(self, name: str, nv: int):
        Entity.__init__(self, name, Feature6dSettings())
        self.nv = nv
        self.position = self.DeclareAbstractInputPort("position", AbstractValue.Make(RigidTransform()))
        self.Jq = self.DeclareAbstractInputPort("Jq", AbstractValue.Make(np.zeros((6, nv))))
        self.reference = self.DeclareAbstractInputPort("reference", AbstractValue.Make(RigidTransform()))
        self._result = self.DeclareCacheEntry(
            "error_and_jacobian",
            ValueProducer(allocate=lambda: AbstractValue.Make((np.zeros(0), np.zeros((0, nv)))), calc=self._calc),
            prerequisites_of_calc={self.all_sources_ticket()},
        )
        self.DeclareAbstractOutputPort(
            "error", lambda: AbstractValue.Make(np.zeros(0)), lambda c, o: o.set_value(self._result.Eval(c)[0])
        )
        self.DeclareAbstractOutputPort(
            "jacobian", lambda: AbstractValue.Make(np.zeros((0, nv))), lambda c, o: o.set_value(self._result.Eval(c)[1])
        )

    def _calc(self, context: Context, value: AbstractValue) -> None:
        s = self._settings_of(context)
        X_WF, J_WF = self.position.Eval(context), self.Jq.Eval(context)
        if s.opmodif is not None:
            X_WF, J_WF = shift_jacobian(X_WF, J_WF, s.opmodif)
        e, J = pose_error_and_jacobian(X_WF, J_WF, self.reference.Eval(context), s.frame)
        rows = parse_selection(s.selection, 6)
        value.set_value((e[rows], J[rows]))

    # --- commands --------------------------------------------------------------------------
    def frame(self, which: str, context: Context | None = None) -> None:
        """Frame in which the error is expressed: ``'desired'`` or ``'current'``."""
        if which not in FRAMES:
            raise InvalidInput(f"{self.name}.frame: expected one of {FRAMES}, got {which!r}")
        self._command(context, lambda s: setattr(s, "frame", which))

    def selec(self, mask: str, context: Context | None = None) -> None:
        """Selection mask, read right to left (``'000011'`` selects X and Y)."""
        parse_selection(mask, 6)
        self._command(context, lambda s: setattr(s, "selection", mask))

    def setOpmodif(self, value, context: Context | None = None) -> None:
        """Controlled frame offset ``X_OpF`` (the seed's ``opmodif``); ``None`` removes it."""
        X = None if value is None else as_transform(value, f"{self.name}.opmodif")
        self._command(context, lambda s: setattr(s, "opmodif", X))
