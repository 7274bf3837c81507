"""Visual-point feature (sot-core ``FeatureVisualPoint``): a 3D point seen by a camera.

The point ``p_W`` (world) in the camera frame C (optical convention: z forward, x right, y down)
is ``p_C = R_WCᵀ (p_W - p_WC) = (x, y, z)``; the feature is its normalized image position
``s = (x/z, y/z)``, against a desired ``s*`` (default ``(0, 0)``: the image centre, i.e. look at
the point). With ``L = (1/z) [[1, 0, -x/z], [0, 1, -y/z]]`` and the camera's spatial Jacobian
``J_WC = (Jω; Jv)``::

    ṗ_C = -R_WCᵀ (v_WC + ω_WC × (p_W - p_WC)) + R_WCᵀ ṗ_W
    J = -L R_WCᵀ (Jv - [p_W - p_WC]× Jω),      ė_ref = L R_WCᵀ ṗ_W

Inputs ``position``/``Jq`` (the camera frame, from the dynamic), ``point`` (``p_W``) and, optional,
``point_velocity`` (``ṗ_W``) for a moving point. The point must be in front of the camera.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import Context

from ..exceptions import InvalidInput, SolverError, check_finite
from ..lie import hat
from ..ranges import MAX_TARGET_POSITION
from .base import Feature, FeatureSettings, optional_input


@dataclass
class VisualPointSettings(FeatureSettings):
    desired: np.ndarray = field(default_factory=lambda: np.zeros(2))


class FeatureVisualPoint(Feature):
    """Normalized image position ``(x/z, y/z)`` of a world point in a camera frame, against ``s*``:
    see the module docstring. Inputs ``position``, ``Jq``, ``point``, ``point_velocity`` (optional)."""

    def __init__(self, name: str, nv: int):
        Feature.__init__(self, name, 2, nv, VisualPointSettings("11"))
        self.position = self.DeclareAbstractInputPort("position", AbstractValue.Make(RigidTransform()))
        self.Jq = self.DeclareAbstractInputPort("Jq", AbstractValue.Make(np.zeros((6, nv))))
        self.point = self.DeclareVectorInputPort("point", 3)
        self.point_velocity = self.DeclareVectorInputPort("point_velocity", 3)
        self._declare_outputs()

    def _compute(self, context: Context, settings, rows):
        try:
            return visual_point_error_and_jacobian(
                self.position.Eval(context).GetAsMatrix4(), self.Jq.Eval(context), self.point.Eval(context),
                settings.desired, optional_input(self.point_velocity, context, None))
        except SolverError as error:
            raise SolverError(f"{self.name}: {error}") from None

    def setDesired(self, image_point, context: Context | None = None) -> None:
        """Desired normalized image position ``s*`` (``(0, 0)``: the image centre)."""
        desired = check_finite(f"{self.name}.desired", image_point, (2,), MAX_TARGET_POSITION).copy()
        if np.any(np.abs(desired) > 10):
            raise InvalidInput(f"{self.name}: normalized image coordinates {desired} are implausible")
        self._command(context, lambda s: setattr(s, "desired", desired))


def visual_point_error_and_jacobian(
    X_WC: np.ndarray, J_WC: np.ndarray, p_W: np.ndarray, desired: np.ndarray, p_W_dot: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``e = s - s*``, ``J`` and ``ė_ref`` of the point ``p_W`` seen from the camera ``X_WC`` (4×4)
    with spatial Jacobian ``J_WC``; ``p_W_dot`` the point's velocity (None: fixed). See the module
    docstring. Raises :class:`SolverError` when the point is not in front of the camera."""
    R = X_WC[:3, :3]
    d = p_W - X_WC[:3, 3]
    x, y, z = R.T @ d
    if z <= 1e-6:
        raise SolverError(f"the point {p_W} is behind the camera (depth {z:.3g} m)")
    L = np.array([[1.0, 0.0, -x / z], [0.0, 1.0, -y / z]]) / z
    s = np.array([x / z, y / z])
    jacobian = -L @ R.T @ (J_WC[3:] - hat(d) @ J_WC[:3])
    e_dot = np.zeros(2) if p_W_dot is None else L @ R.T @ p_W_dot
    return s - desired, jacobian, e_dot
