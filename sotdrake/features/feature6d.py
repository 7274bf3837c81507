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

from ..compiled import compiled_input, kernels
from ..entity import Entity
from ..exceptions import InvalidInput, check_finite
from ..lie import check_rotation, hat, log_so3_list, right_jacobian_inverse_list
from ..ranges import MAX_TARGET_ANGLE, MAX_TARGET_POSITION, MAX_TARGET_VELOCITY
from .base import Feature, FeatureSettings, optional_input, usual_input

FRAMES = ("desired", "current")


def _matrix(X) -> np.ndarray:
    """A 4×4 homogeneous matrix from a ``RigidTransform`` or a 4×4 array."""
    return X.GetAsMatrix4() if isinstance(X, RigidTransform) else np.asarray(X)


def _flat(X) -> tuple[tuple, tuple]:
    """``(R, p)`` of a 4×4 homogeneous matrix (or ``RigidTransform``): R as 9 Python floats, row
    by row, p as 3."""
    a, b, c = _matrix(X).tolist()[:3]
    return (a[0], a[1], a[2], b[0], b[1], b[2], c[0], c[1], c[2]), (a[3], b[3], c[3])


# 3×3 matrices as 9 floats row by row, 3-vectors as 3 floats: the features' hot path is a few dozen
# products, cheaper written out on Python floats than through numpy calls at this size.
def _t(A) -> tuple:
    """``Aᵀ``."""
    return (A[0], A[3], A[6], A[1], A[4], A[7], A[2], A[5], A[8])


def _mm(A, B) -> tuple:
    """``A·B``."""
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = A
    b0, b1, b2, b3, b4, b5, b6, b7, b8 = B
    return (a0 * b0 + a1 * b3 + a2 * b6, a0 * b1 + a1 * b4 + a2 * b7, a0 * b2 + a1 * b5 + a2 * b8,
            a3 * b0 + a4 * b3 + a5 * b6, a3 * b1 + a4 * b4 + a5 * b7, a3 * b2 + a4 * b5 + a5 * b8,
            a6 * b0 + a7 * b3 + a8 * b6, a6 * b1 + a7 * b4 + a8 * b7, a6 * b2 + a7 * b5 + a8 * b8)


def _mv(A, x) -> tuple:
    """``A·x``."""
    x0, x1, x2 = x
    return (A[0] * x0 + A[1] * x1 + A[2] * x2, A[3] * x0 + A[4] * x1 + A[5] * x2, A[6] * x0 + A[7] * x1 + A[8] * x2)


def _cross(a, b) -> tuple:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _hat(a) -> tuple:
    return (0.0, -a[2], a[1], a[2], 0.0, -a[0], -a[1], a[0], 0.0)


def _log(A) -> tuple:
    """``log`` of the rotation ``A`` (9 floats)."""
    return tuple(log_so3_list((A[0:3], A[3:6], A[6:9])))


def _jr_inv(phi) -> tuple:
    """``Jr⁻¹(φ)`` as 9 floats."""
    a, b, c = right_jacobian_inverse_list(phi)
    return (*a, *b, *c)


def _neg(x) -> tuple:
    return (-x[0], -x[1], -x[2])


_ZERO3 = (0.0, 0.0, 0.0)
_ZERO18 = (0.0,) * 18


def pose_error_and_jacobian(
    X_WOp, J_WOp: np.ndarray, X_WFd, frame: str = "desired", V_WFd: np.ndarray | None = None,
    X_OpF=None, rows: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """6D error ``e``, its Jacobian ``∂e/∂v`` and ``ė_ref`` of the frame ``F = Op · X_OpF``: the
    arguments and the answer of :func:`python_pose_error_and_jacobian`, computed by the compiled
    :func:`.jit_pose.pose_error` (the same operations; the first call after an install compiles it,
    once)."""
    if frame not in FRAMES:
        raise InvalidInput(f"frame: expected one of {FRAMES}, got {frame!r}")
    J = np.asarray(J_WOp)
    if J.ndim != 2 or J.shape[0] != 6:
        raise InvalidInput(f"J_WOp: expected a 6×nv spatial Jacobian, got shape {J.shape}")
    if rows is None:
        selected = _ALL_ROWS
    else:
        selected = _compiled_rows(rows)  # (checked: increasing indices of the six components)
    # The transposes: Drake's matrices are column-major, so these are C-ordered views (no copy).
    X, X_d = compiled_input(_matrix(X_WOp).T), compiled_input(_matrix(X_WFd).T)
    X_shift = _IDENTITY if X_OpF is None else compiled_input(_matrix(X_OpF).T)
    V = _NO_VELOCITY if V_WFd is None else compiled_input(V_WFd)
    if X.shape != (4, 4) or X_d.shape != (4, 4) or X_shift.shape != (4, 4) or V.shape != (6,):
        raise InvalidInput(f"poses are 4×4 homogeneous matrices and V_WFd a 6-vector, got {X.shape}, {X_d.shape}, "
                           f"{X_shift.shape} and {V.shape}")
    return _jit_pose().pose_error(X, compiled_input(J.T), X_d, frame == "current", V, X_shift, X_OpF is not None, selected)


def _compiled_rows(rows: np.ndarray) -> np.ndarray:
    """``compiled_input(rows, np.int64)``, kept for the read-only arrays of
    :func:`~..selection.parse_selection` (cached, the same object at every tick): a pure cache."""
    hit = _ROWS.get(id(rows))
    if hit is not None and hit[0] is rows:
        return hit[1]
    selected = compiled_input(rows, np.int64)
    if selected.ndim != 1 or not selected.size or not (np.diff(selected) > 0).all() or selected[0] < 0 or selected[-1] > 5:
        raise InvalidInput(f"rows: expected increasing indices of the six components (0 … 5), got {rows!r:.80}")
    if isinstance(rows, np.ndarray) and not rows.flags.writeable and len(_ROWS) < 256:
        _ROWS[id(rows)] = (rows, selected)  # (rows kept alive: its id cannot be reused)
    return selected


_ROWS: dict[int, tuple[np.ndarray, np.ndarray]] = {}

# Constant arguments of the compiled function (writeable, as compiled_input's arrays: it never writes them).
_ALL_ROWS = np.arange(6, dtype=np.int64)
_NO_VELOCITY = np.zeros(6)
_IDENTITY = np.eye(4)


_jit_pose = kernels(".jit_pose", __package__, "pose_error", "the 6D feature's error and Jacobian", "about ten seconds")


def python_pose_error_and_jacobian(
    X_WOp, J_WOp: np.ndarray, X_WFd, frame: str = "desired", V_WFd: np.ndarray | None = None,
    X_OpF=None, rows: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """6D error ``e``, its Jacobian ``∂e/∂v`` and ``ė_ref`` of the frame ``F = Op · X_OpF``, in
    Python: the reference of the compiled :func:`pose_error_and_jacobian`.

    ``X_WOp`` (pose of the op point), ``X_WFd`` (desired pose of F) and ``X_OpF`` (the ``opmodif``,
    None for the identity) are 4×4 homogeneous matrices (or ``RigidTransform``); ``J_WOp`` is the
    op point's 6×nv spatial Jacobian (rows ``(ω; v)``, world); ``V_WFd = (ω*, ṗ*)`` the target's
    spatial velocity (world; None or zero for a fixed target). ``rows``: the components to return
    (None: all six); without rotation rows no logarithm is taken. See the module docstring for the
    formulas. The Jacobian is ``M·S·J_WOp`` with ``S = [[I, 0], [-[r]×, I]]`` the shift to F
    (``r = R_WOp p_OpF``) and ``M`` the 6×6 map of the error's frame: the 3×3 algebra is done on
    Python floats (cheaper than numpy at this size) and ``J_WOp`` is touched by one product.
    """
    R, p = _flat(X_WOp)
    Rd, pd = _flat(X_WFd)
    r = None
    if X_OpF is not None:
        R_OpF, p_OpF = _flat(X_OpF)
        r = _mv(R, p_OpF)  # p_OpF in world axes
        p = (p[0] + r[0], p[1] + r[1], p[2] + r[2])
        R = _mm(R, R_OpF)
    rotation = rows is None or rows[-1] >= 3
    V: list[float] = [] if V_WFd is None else V_WFd.tolist()
    moving = any(V)
    if moving:
        w_star, p_star_dot = V[0:3], V[3:6]
    RdT, RT = _t(Rd), _t(R)
    e_r = e_dot_t = e_dot_r = _ZERO3
    bottom = _ZERO18  # rows 3-5 of M, flat
    if frame == "desired":
        e_t = _mv(RdT, (p[0] - pd[0], p[1] - pd[1], p[2] - pd[2]))
        if r is None:
            top = (0.0, 0.0, 0.0, *RdT[0:3], 0.0, 0.0, 0.0, *RdT[3:6], 0.0, 0.0, 0.0, *RdT[6:9])
        else:
            left = _mm(RdT, _hat(_neg(r)))
            top = (*left[0:3], *RdT[0:3], *left[3:6], *RdT[3:6], *left[6:9], *RdT[6:9])
        if rotation:
            e_r = _log(_mm(RdT, R))
            a = _mm(_jr_inv(e_r), RT)
            bottom = (*a[0:3], 0.0, 0.0, 0.0, *a[3:6], 0.0, 0.0, 0.0, *a[6:9], 0.0, 0.0, 0.0)
        if moving:
            wd = _mv(RdT, w_star)
            c, d = _cross(e_t, wd), _mv(RdT, p_star_dot)
            e_dot_t = (c[0] - d[0], c[1] - d[1], c[2] - d[2])
            if rotation:
                e_dot_r = _neg(_mv(_jr_inv(_neg(e_r)), wd))
    elif frame == "current":
        e_t = _mv(RT, (pd[0] - p[0], pd[1] - p[1], pd[2] - p[2]))
        left = _mm(_hat(e_t), RT)
        if r is not None:
            left = tuple(a + b for a, b in zip(left, _mm(RT, _hat(r)), strict=True))
        top = (*left[0:3], -RT[0], -RT[1], -RT[2], *left[3:6], -RT[3], -RT[4], -RT[5], *left[6:9], -RT[6], -RT[7], -RT[8])
        if rotation:
            e_r = _log(_mm(RT, Rd))
            a = _mm(_jr_inv(_neg(e_r)), RT)
            bottom = (-a[0], -a[1], -a[2], 0.0, 0.0, 0.0, -a[3], -a[4], -a[5], 0.0, 0.0, 0.0, -a[6], -a[7], -a[8], 0.0, 0.0, 0.0)
        if moving:
            e_dot_t = _mv(RT, p_star_dot)
            if rotation:
                e_dot_r = _mv(_jr_inv(e_r), _mv(RdT, w_star))
    else:
        raise InvalidInput(f"frame: expected one of {FRAMES}, got {frame!r}")
    M = np.array(top + bottom).reshape(6, 6)
    if rows is None:
        return np.array(e_t + e_r), M @ J_WOp, np.array(e_dot_t + e_dot_r)
    return np.array(e_t + e_r)[rows], M[rows] @ J_WOp, np.array(e_dot_t + e_dot_r)[rows]


def shift_jacobian(X_WOp: RigidTransform, J_WOp: np.ndarray, X_OpF: RigidTransform):
    """Pose and spatial Jacobian of ``F = Op · X_OpF`` (``v_WF = v_WOp + ω × p_OpF_W``)."""
    p_OpF_W = X_WOp.rotation().multiply(X_OpF.translation())
    J = J_WOp.copy()
    J[3:] -= hat(p_OpF_W) @ J_WOp[:3]
    return X_WOp.multiply(X_OpF), J


def as_transform(value, what: str) -> RigidTransform:
    """A ``RigidTransform`` from a 4×4 homogeneous matrix, a ``RigidTransform``, a 3-vector
    (translation, identity rotation) or a 6-vector ``(x, y, z, roll, pitch, yaw)``, as sot-core's
    ``generic6dReference`` accepts. A ``RigidTransform`` is copied: one read from a port of a
    Context refers into that Context and keeps it alive, and settings holding it would keep their
    own Context alive through it (a reference cycle that Python's collector cannot see)."""
    if isinstance(value, RigidTransform):  # (pydrake builds one from any 4×4 matrix: checked as a matrix)
        value = value.GetAsMatrix4()
    array = check_finite(what, value)
    if array.shape == (4, 4):
        if not np.allclose(array[3], [0, 0, 0, 1]):
            raise InvalidInput(f"{what}: last row of a homogeneous matrix must be (0, 0, 0, 1)")
        R = check_rotation(f"{what}: the 3×3 block", array[:3, :3])
        check_finite(f"{what} translation (m)", array[:3, 3], bound=MAX_TARGET_POSITION)
        return RigidTransform(RotationMatrix(R), array[:3, 3])
    if array.shape == (3,):
        return RigidTransform(check_finite(f"{what} (m)", array, bound=MAX_TARGET_POSITION))
    if array.shape == (6,):
        check_finite(f"{what} translation (m)", array[:3], bound=MAX_TARGET_POSITION)
        check_finite(f"{what} roll, pitch, yaw (rad)", array[3:], bound=MAX_TARGET_ANGLE)
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
        # Narrow prerequisites: computed once, until a setting or a connected input changes.
        settings = self.abstract_state_ticket(self._settings_index)
        self.DeclareAbstractOutputPort(
            "position", lambda: AbstractValue.Make(RigidTransform()), self._position,
            prerequisites_of_calc={settings, self.input_port_ticket(self.pose_in.get_index()),
                                   self.input_port_ticket(self.translation_in.get_index())})
        self.DeclareVectorOutputPort(
            "velocity", 6, self._velocity,
            prerequisites_of_calc={settings, self.input_port_ticket(self.spatial_velocity_in.get_index()),
                                   self.input_port_ticket(self.translation_velocity_in.get_index())})

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
        V = check_finite(f"{self.name}.velocity (rad/s, m/s)", velocity, (6,), MAX_TARGET_VELOCITY).copy()
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
        V = usual_input(self.reference_velocity, context, None)
        return pose_error_and_jacobian(self.position.Eval(context).GetAsMatrix4(), self.Jq.Eval(context),
                                       self.reference.Eval(context).GetAsMatrix4(), s.frame, V, s.opmodif, rows)

    def frame(self, which: str, context: Context | None = None) -> None:
        """Frame in which the error is expressed: ``'desired'`` or ``'current'``."""
        if which not in FRAMES:
            raise InvalidInput(f"{self.name}.frame: expected one of {FRAMES}, got {which!r}")
        self._command(context, lambda s: setattr(s, "frame", which))

    def setOpmodif(self, value, context: Context | None = None) -> None:
        """Controlled frame offset ``X_OpF`` (the seed's ``opmodif``); ``None`` removes it."""
        X = None if value is None else as_transform(value, f"{self.name}.opmodif")
        self._command(context, lambda s: setattr(s, "opmodif", X))
