"""Contacts as entities (sot-dyninv ``addContact``): a 6D sole contact, or a point contact.

A contact C is a frame of the robot (a sole: z up out of the ground, origin on the sole plane)
held still on the environment. Its unknown is the contact wrench ``w = (n, f)`` (torque about C's
origin, force; N·m and N) *expressed in C*. The world wrench is ``W = diag(R, R) w`` with
``R = R_WC``; the generalized force it produces is ``J_Cᵀ W`` (``J_C`` the spatial-velocity
Jacobian of C, rows ``(ω; v)``, world).

Constraints on ``w`` (all linear: rows of the contacts' level, met exactly whenever that level can
be met under the hard bounds; ``f_z ≥ f_min`` is a hard bound):

* unilateral: ``f_z ≥ f_min`` (a bound), and ``f_z ≤ f_max`` while it is released (a ramp);
* friction pyramid inscribed in the cone of coefficient ``μ``: ``|f_x|, |f_y| ≤ μ/√2 · f_z``, so
  ``‖f_t‖ ≤ μ f_z``;
* centre of pressure ``p = (−n_y/f_z, n_x/f_z)`` inside the sole rectangle ``[x_min, x_max] ×
  [y_min, y_max]`` (C's frame) shrunk by ``cop_margin``: ``−n_y − x_max f_z ≤ 0``,
  ``n_y + x_min f_z ≤ 0``, ``n_x − y_max f_z ≤ 0``, ``−n_x + y_min f_z ≤ 0``;
* yaw torque: the contact wrench cone's bounds (Caron, Pham and Nakamura, RSS 2015), exactly the
  wrenches that forces at the rectangle's corners, each in the pyramid above, produce: the torsional
  friction shrinks as the CoP nears an edge and as the shear grows (eight rows).

A point contact (``rectangle=None``) has only the force ``f`` (3 unknowns, friction rows only) and
only the translational rows of ``J_C``. The contact's motion constraint is
``J_C q̈ + J̇_C v = −K_v J_C v − K_p e`` (zero acceleration, with an optional damping of any
residual contact velocity, ``velocity_gain`` K_v ≥ 0, 1/s; default 30, at most ``0.15/dt``: on
the compliant soles of the physics plant, K_v = 0 lets the ankles chatter within 30 ms, and
``K_v dt`` beyond 0.2 to 0.4 makes the stance unstable, :data:`.checks.COMPLIANT_CONTACT_RATE`;
and an optional return to where the contact is kept, ``position_gain`` K_p ≥ 0, 1/s², default 0,
as the seed's contact tasks keep their pose with a gain). ``e = (e_R; p_C − p*)`` (world) is the contact frame's
displacement from its kept pose ``X_WC* = (R*, p*)`` (:meth:`Contact6d.keep`; by default the op
point at the robot's reference posture, set by ``RobotDyn.add_contact``): ``e_R = ½ vee(R R*ᵀ −
R* Rᵀ)``, the rotation's axis times the sine of its angle (the rotation vector for the small
drifts it corrects). With K_p = 0 nothing but velocity is corrected, and the integration's
second-order error accumulates on the soles (about 0.1 mm in 0.3 s of a fast whole-body swing).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import Context

from ..entity import Entity
from ..exceptions import InvalidInput, StackError, check_count, check_finite, check_flag, check_name, check_number
from ..lie import check_rotation
from .checks import (
    COMPLIANT_CONTACT_RATE,
    CONTACT_VELOCITY_GAIN,
    MAX_DT,
    MAX_FRICTION,
    MAX_NORMAL_FORCE,
    MAX_RATE_GAIN,
    MAX_SOLE,
    check_positive,
    check_stable_gains,
    default_contact_velocity_gain,
    unconnected_input,
)
from .terms import OpPointMotion

log = logging.getLogger(__name__)


class ContactRows(NamedTuple):
    """What the solver needs of one contact (see the module docstring): ``wrench_rows`` ``A w ≤ 0``
    on the local wrench (size k = 6, or 3 for a point contact); ``f_min`` the normal force's lower
    bound (N); ``jacobian`` (k×nv), ``acceleration`` (k: the reference ``J_C q̈ = acceleration``),
    ``rotation`` ``R_WC``; ``centre`` the sole's centre. The normal force is the wrench's last component."""

    jacobian: np.ndarray
    acceleration: np.ndarray
    rotation: np.ndarray
    wrench_rows: np.ndarray
    f_min: float
    mu: float
    centre: tuple[float, float] = (0.0, 0.0)  # the sole rectangle's centre (m, in C): where the CoP is best


@lru_cache(maxsize=64)
def wrench_constraints(mu: float, rectangle: tuple[float, float, float, float] | None, cop_margin: float) -> np.ndarray:
    """Rows ``A w ≤ 0`` (friction, CoP, yaw) on ``w = (n_x, n_y, n_z, f_x, f_y, f_z)``, or on
    ``w = f`` for a point contact (``rectangle=None``). Read-only and cached: contacts ask at every
    tick."""
    A = _wrench_constraints(mu, rectangle, cop_margin)
    A.flags.writeable = False
    return A


def _wrench_constraints(mu: float, rectangle: tuple[float, float, float, float] | None, cop_margin: float) -> np.ndarray:
    k = mu / math.sqrt(2.0)
    rows = [
        [0, 0, 0, 1, 0, -k], [0, 0, 0, -1, 0, -k],
        [0, 0, 0, 0, 1, -k], [0, 0, 0, 0, -1, -k],
    ]
    if rectangle is None:
        return np.array(rows, dtype=float)[:, 3:]
    else:
        x_min, x_max, y_min, y_max = rectangle
        x_min, x_max, y_min, y_max = x_min + cop_margin, x_max - cop_margin, y_min + cop_margin, y_max - cop_margin
        rows += [
            [0, -1, 0, 0, 0, -x_max], [0, 1, 0, 0, 0, x_min],
            [1, 0, 0, 0, 0, -y_max], [-1, 0, 0, 0, 0, y_min],
        ]
        rows += _yaw_rows(k, (x_min, x_max, y_min, y_max)).tolist()
    return np.array(rows, dtype=float)


def _yaw_rows(k: float, rectangle: tuple[float, float, float, float]) -> np.ndarray:
    """The yaw-torque rows of the contact wrench cone (Caron, Pham and Nakamura, RSS 2015) of the
    rectangle of half-sizes ``X``, ``Y`` about its centre ``c``, its corners' forces in friction
    pyramids ``|f_x|, |f_y| ≤ k f_z``: with ``(τ, f)`` the wrench about ``c``,
    ``−k(X+Y) f_z + |Y f_x − k τ_x| + |X f_y − k τ_y| ≤ τ_z ≤ k(X+Y) f_z − |Y f_x + k τ_x| − |X f_y + k τ_y|``,
    eight rows; about C's origin, ``τ = n − c × f``."""
    x_min, x_max, y_min, y_max = rectangle
    cx, cy, X, Y = (x_min + x_max) / 2, (y_min + y_max) / 2, (x_max - x_min) / 2, (y_max - y_min) / 2
    about_centre = np.eye(6)  # w ↦ (n − c × f, f), c = (cx, cy, 0)
    about_centre[0, 5], about_centre[1, 5], about_centre[2, 3], about_centre[2, 4] = -cy, cx, cy, -cx
    rows = [[s * side * k, t * side * k, side, s * Y, t * X, -k * (X + Y)]
            for s in (1, -1) for t in (1, -1) for side in (1, -1)]
    return np.array(rows) @ about_centre


def world_wrench_map(R: np.ndarray, k: int = 6) -> np.ndarray:
    """``diag(R, R)`` (or ``R`` for a point contact, k = 3): the local wrench to the world wrench."""
    if k == 3:
        return R
    out = np.zeros((6, 6))
    out[:3, :3] = out[3:, 3:] = R
    return out


def world_wrench(R: np.ndarray, w: np.ndarray) -> np.ndarray:
    """``diag(R, R) w`` (k = 6: ``(R n, R f)``; k = 3: ``R f``) without forming the 6×6 map."""
    if len(w) == 3:
        return R @ w
    return (w.reshape(2, 3) @ R.T).reshape(6)


def local_to_generalized(J: np.ndarray, R: np.ndarray) -> np.ndarray:
    """``Jᵀ diag(R, R)`` (or ``Jᵀ R`` for a point contact, J with 3 rows): the generalized force of
    each component of the local wrench, ``J`` (k×p) the contact's Jacobian (or some of its columns)."""
    k, p = J.shape
    return (R.T @ J.reshape(k // 3, 3, p)).reshape(k, p).T  # each 3-row block: (Rᵀ J_b)ᵀ = J_bᵀ R


def friction_ratio(force_world: np.ndarray, normal: np.ndarray, mu: float) -> float:
    """``‖f_t‖ / (μ f_n)`` of a force (world) against a surface of unit ``normal``; inf if ``f_n ≤ 0`` (a
    force that pulls, or none: no friction cone holds it, so a largest ratio taken over forces shows it).
    ``force_world`` and ``normal``: three finite numbers each, ``normal`` of norm 1 (± 1e-6); ``μ``: a
    number in (0, MAX_FRICTION]; anything else is an :class:`InvalidInput` naming it (μ = 0 gave NaN)."""
    force_world = check_finite("friction_ratio: force_world", force_world, (3,))
    normal = check_finite("friction_ratio: normal", normal, (3,))
    if abs(float(np.linalg.norm(normal)) - 1.0) > 1e-6:
        raise InvalidInput(f"friction_ratio: normal must be a unit vector, got norm {np.linalg.norm(normal):g}")
    mu = check_positive("friction_ratio: mu", mu, MAX_FRICTION)
    fn = float(force_world @ normal)
    ft = np.linalg.norm(force_world - fn * normal)
    return float(ft / (mu * fn)) if fn > 0 else math.inf  # (a pulling or a zero force: no friction holds it)


MAX_POSITION_GAIN = MAX_RATE_GAIN**2 / 4
"""The largest contact ``K_p`` (1/s²): with ``K_v`` ≤ :data:`.checks.MAX_RATE_GAIN`, the error's
recurrence at a 1 ms tick (``K_p dt² + 2 K_v dt < 4``) stays stable."""


def pose_error(pose: RigidTransform, R_kept: np.ndarray, p_kept: np.ndarray) -> np.ndarray:
    """``(e_R; p − p*)`` (world, rad-like and m) of ``pose`` from the kept pose ``(R*, p*)``:
    ``e_R = ½ vee(R R*ᵀ − R* Rᵀ)``, the axis of ``R R*ᵀ`` times the sine of its angle."""
    E = pose.rotation().matrix() @ R_kept.T
    e = np.empty(6)
    e[0], e[1], e[2] = 0.5 * (E[2, 1] - E[1, 2]), 0.5 * (E[0, 2] - E[2, 0]), 0.5 * (E[1, 0] - E[0, 1])
    e[3:] = pose.translation() - p_kept
    return e


@dataclass
class ContactSettings:
    mu: float = 0.7
    f_min: float = 1.0
    cop_margin: float = 0.01
    velocity_gain: float = CONTACT_VELOCITY_GAIN
    position_gain: float = 0.0
    kept: tuple[np.ndarray, np.ndarray] | None = None  # (R*, p*): the pose the contact returns to (world)


class Contact6d(Entity[ContactSettings]):
    """A contact entity (sot-dyninv's ``contactLF``). Input ``kinematics``: the op point's
    :class:`~.terms.OpPointMotion` (``X_WC``, ``J_WC``, ``J̇_WC v``, ``J_WC v``; the dynamic
    entity's ``<name>_kinematics``). Output ``contact``: :class:`ContactRows`.
    ``rectangle = (x_min, x_max, y_min, y_max)`` (m, in C) is the sole; None for a point contact."""

    def __init__(self, name: str, nv: int, rectangle: tuple[float, float, float, float] | None,
                 mu: float = 0.7, f_min: float = 1.0, cop_margin: float = 0.01, dt: float | None = None,
                 compliant: bool = False):
        """``dt`` (s, the control tick, when known): the gains are also checked against it, as a task's
        (:func:`.checks.check_stable_gains`: ``K_p dt² + 2 K_v dt < 4``), and the default ``K_v`` is at
        most ``0.15/dt``. ``compliant`` (a contact on the physics plant's soles, with ``dt``): a ``K_v``
        set beyond :data:`.checks.COMPLIANT_CONTACT_RATE` ``/ dt`` is logged as a warning. ``dt``: None or a
        number in (0, :data:`.checks.MAX_DT`] s, as ``SolverDyn``'s and ``TaskDynPD``'s (else :class:`InvalidInput`)."""
        check_name(f"{type(self).__name__} name", name)
        dt = None if dt is None else check_positive(f"{name}: dt", dt, MAX_DT, " s")
        Entity.__init__(self, name, ContactSettings(velocity_gain=default_contact_velocity_gain(dt)))
        self.dt = dt
        self.compliant = check_flag(f"{name}: compliant", compliant) and dt is not None
        self.nv = check_count(f"{name}: nv", nv, 1, 10**6)
        self.rectangle: tuple[float, float, float, float] | None = None
        if rectangle is not None:
            values = tuple(check_finite(f"{name}: rectangle (x_min, x_max, y_min, y_max)", rectangle, (4,), MAX_SOLE).tolist())
            if not (values[0] < values[1] and values[2] < values[3]):
                raise InvalidInput(f"{name}: rectangle is (x_min, x_max, y_min, y_max) with min < max, got {values}")
            self.rectangle = (values[0], values[1], values[2], values[3])
        self.setFriction(mu)
        self.setMinimumNormalForce(f_min)
        self.setCopMargin(cop_margin)
        self.kinematics = self.DeclareAbstractInputPort(
            "kinematics", AbstractValue.Make(OpPointMotion(RigidTransform(), np.zeros((6, nv)), np.zeros(6), np.zeros(6))))
        k = 6 if rectangle is not None else 3
        self._rows = slice(0, 6) if self.rectangle is not None else slice(3, 6)  # of J_WC and J̇_WC v
        self._centre = (0.0, 0.0) if self.rectangle is None else \
            ((self.rectangle[0] + self.rectangle[1]) / 2, (self.rectangle[2] + self.rectangle[3]) / 2)
        empty = ContactRows(np.zeros((k, nv)), np.zeros(k), np.eye(3), np.zeros((0, k)), 0.0, 1.0)
        self.DeclareAbstractOutputPort("contact", lambda: AbstractValue.Make(empty), self._calc)

    def setFriction(self, mu: float, context: Context | None = None) -> None:
        """Friction coefficient μ in (0, :data:`.checks.MAX_FRICTION`] of the pyramid."""
        value = check_positive(f"{self.name}: friction coefficient μ", mu, MAX_FRICTION)
        self._command(context, lambda s: setattr(s, "mu", value))

    def setMinimumNormalForce(self, f_min: float, context: Context | None = None) -> None:
        """``f_min`` in [0, :data:`.checks.MAX_NORMAL_FORCE`] (N): the normal force never goes below it
        while the contact is held."""
        value = check_number(f"{self.name}: minimum normal force f_min", f_min, 0.0, MAX_NORMAL_FORCE, " N")
        self._command(context, lambda s: setattr(s, "f_min", value))

    def setCopMargin(self, margin: float, context: Context | None = None) -> None:
        """How far (m) the CoP stays inside the sole's edges: ``0 ≤ margin <`` half the sole's width."""
        if self.rectangle is None:
            limit = math.inf
        else:
            limit = min(self.rectangle[1] - self.rectangle[0], self.rectangle[3] - self.rectangle[2]) / 2
        value = check_number(f"{self.name}: CoP margin", margin, 0.0, min(limit, MAX_SOLE), " m")
        if not value < limit:
            raise InvalidInput(f"{self.name}: CoP margin must be in [0, {limit:g}) m, got {margin!r:.100}")
        self._command(context, lambda s: setattr(s, "cop_margin", value))

    def setVelocityGain(self, gain: float, context: Context | None = None) -> None:
        """``K_v`` in [0, :data:`.checks.MAX_RATE_GAIN`] (1/s): damping of a residual contact velocity."""
        value = check_number(f"{self.name}: velocity gain K_v", gain, 0.0, MAX_RATE_GAIN, " 1/s")
        if self.compliant and self.dt is not None and value * self.dt > COMPLIANT_CONTACT_RATE:
            log.warning("%s: velocity gain K_v = %g 1/s at a %g s tick: K_v dt = %g, beyond the %g measured stable on the "
                        "physics plant's compliant soles (the stance can go unstable); K_v ≤ %g keeps it", self.name, value,
                        self.dt, value * self.dt, COMPLIANT_CONTACT_RATE, COMPLIANT_CONTACT_RATE / self.dt)

        def change(s: ContactSettings) -> None:  # (checked with K_p as it is when the change applies: attime's too)
            if self.dt is not None:
                check_stable_gains(f"{self.name} (contact)", s.position_gain, value, self.dt)
            s.velocity_gain = value

        self._command(context, change)

    def setPositionGain(self, gain: float, context: Context | None = None) -> None:
        """``K_p`` in [0, :data:`MAX_POSITION_GAIN`] (1/s²): the return to the kept pose
        (:meth:`keep`; see the module docstring). ``K_p ≤ K_v²/4`` does not overshoot."""
        value = check_number(f"{self.name}: position gain K_p", gain, 0.0, MAX_POSITION_GAIN, " 1/s²")

        def change(s: ContactSettings) -> None:  # (checked with the settings as they are when it applies)
            if value and s.kept is None:
                raise InvalidInput(f"{self.name}: a position gain needs the pose to return to: call keep(X_WC) first")
            if self.dt is not None:
                check_stable_gains(f"{self.name} (contact)", value, s.velocity_gain, self.dt)
            s.position_gain = value

        self._command(context, change)

    def keep(self, pose: RigidTransform, context: Context | None = None) -> None:
        """The pose ``X_WC*`` (world) the contact returns to with :meth:`setPositionGain` (the
        seed's ``keep()`` of a contact task; ``RobotDyn.add_contact`` keeps the op point's pose at
        the robot's reference posture). ``pose``: a ``RigidTransform`` whose rotation is one
        (orthonormal to 1e-6, determinant +1: not a reflection) and whose position is finite, within
        1e6 m; else :class:`InvalidInput`, nothing changed."""
        if not isinstance(pose, RigidTransform):
            raise InvalidInput(f"{self.name}: keep takes a RigidTransform (X_WC), got {type(pose).__name__}")
        rotation = check_rotation(f"{self.name}: kept rotation", pose.rotation().matrix())
        position = check_finite(f"{self.name}: kept position", pose.translation(), (3,), 1e6)
        kept = (rotation.copy(), position.copy())
        self._command(context, lambda s: setattr(s, "kept", kept))

    def _calc(self, context: Context, output: AbstractValue) -> None:
        s = self._settings_of(context)
        rows = self._rows
        try:
            motion = self.kinematics.Eval(context)
        except RuntimeError as error:
            if unconnected_input(error, self.name) is None:
                raise
            raise StackError(f"contact {self.name!r}: its input 'kinematics' is not connected: connect its op point's "
                             f"kinematics to it, builder.Connect(dynamic.kinematics_port(name), contact.GetInputPort("
                             "'kinematics')) after dynamic.createOpPoint(name, frame), or make the contact with "
                             "RobotDyn.add_contact, which does") from None
        J = motion.jacobian[rows]
        acceleration = -motion.drift[rows]
        if s.velocity_gain:
            acceleration = acceleration - s.velocity_gain * motion.velocity[rows]
        if s.position_gain and s.kept is not None:
            acceleration = acceleration - s.position_gain * pose_error(motion.pose, *s.kept)[rows]
        A = wrench_constraints(s.mu, self.rectangle, s.cop_margin)
        output.set_value(ContactRows(J, acceleration, motion.pose.rotation().matrix(), A, s.f_min, s.mu, self._centre))
