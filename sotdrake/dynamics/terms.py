"""Dynamics terms of the control model, and the pure maths built on them.

Equations of motion (Drake's generalized coordinates, ``v`` with the floating base first as
``(ω_WB, v_WBo)`` in the world frame)::

    M(q) q̈ + h(q, v) = B τ + Σ_c J_cᵀ W_c

``h = C(q, v) v − τ_g(q) + D v`` (Coriolis/centrifugal bias, minus the generalized gravity
forces, plus the joints' viscous damping ``D`` from the URDF, which the plant applies; N or N·m),
``B`` the actuation matrix (nv × na: actuator order to velocities), ``W_c`` the contact
wrench ``(torque about the contact frame's origin; force)`` in the world frame and ``J_c`` the
spatial-velocity Jacobian of that frame (rows ``(ω; v)``, world).

CoM from the floating-base rows: the base's translational velocity rows of the equations of motion
are Newton's law for the whole robot, ``m p̈_CoM = Σ F_ext`` (the partial velocity of every point
with respect to ``v_WBo`` is the identity). Hence, with ``M_t`` and ``(C v)_t`` those three rows,
``J_CoM = M_t / m`` and ``J̇_CoM v = (C v)_t / m`` (exact; tested against Drake's CoM functions).

Gravity from the same rows: in a uniform field ``g`` the generalized gravity forces are
``τ_g = Σ_i J_iᵀ m_i g = m J_CoMᵀ g = M_tᵀ g`` (``J_i`` the Jacobian of body i's centre of mass),
i.e. ``M[:, t] g`` since ``M`` is symmetric: three columns of ``M`` instead of Drake's
``CalcGravityGeneralizedForces`` (a pass over the tree; on TALOS about a third of the cost of the
dynamics terms). :func:`gravity_columns` checks the identity on the plant before it is used.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from pydrake.math import RigidTransform

from ..configuration import Layout
from ..exceptions import InvalidInput


class DynamicsTerms(NamedTuple):
    """``M`` (nv×nv, kg·m² / kg), ``h`` (nv), ``Cv`` (nv, the bias without gravity and damping), ``B``
    (nv×na), the state ``q``, ``v`` and the total mass ``mass`` (kg)."""

    M: np.ndarray
    h: np.ndarray
    Cv: np.ndarray
    B: np.ndarray
    q: np.ndarray
    v: np.ndarray
    mass: float


class OpPointMotion(NamedTuple):
    """An op point F at the measured state ``(q, v)``: ``pose`` ``X_WF``; ``jacobian`` ``J_WF``
    (6×nv, rows ``(ω; v)`` world, ``v`` the velocity of F's origin); ``drift`` ``J̇_WF v`` (6, the
    bias spatial acceleration ``(α; a)`` of F's origin, world); ``velocity`` ``J_WF v`` (6, F's
    spatial velocity ``(ω; v)``, world)."""

    pose: RigidTransform
    jacobian: np.ndarray
    drift: np.ndarray
    velocity: np.ndarray


def base_translation_rows(layout: Layout) -> slice | None:
    """The velocity rows (and columns of ``M``) of the floating base's translation, world frame;
    None without a floating base."""
    return None if layout.base_v is None else slice(layout.base_v + 3, layout.base_v + 6)


def com_terms(M: np.ndarray, Cv: np.ndarray, mass: float, layout: Layout) -> tuple[np.ndarray, np.ndarray]:
    """``(J_CoM, J̇_CoM v)`` from the base's translational rows (see the module docstring)."""
    rows = base_translation_rows(layout)
    if rows is None:
        raise InvalidInput("the dynamic CoM task needs a floating base (its Jacobian and drift are the base's translation "
                           "rows of M and of the bias over the mass): the robot's base is fixed or planar")
    return M[rows] / mass, Cv[rows] / mass


def gravity_columns(plant, layout: Layout) -> tuple[slice, np.ndarray] | None:
    """``(t, g)`` such that ``M(q)[:, t] @ g`` is the plant's generalized gravity forces ``τ_g(q)``
    (see the module docstring), or None when that does not hold for this plant (no floating base,
    gravity off for some model instance, …): checked against ``CalcGravityGeneralizedForces`` at a
    random configuration."""
    columns = base_translation_rows(layout)
    if columns is None:
        return None
    g = np.array(plant.gravity_field().gravity_vector(), dtype=float)
    context = plant.CreateDefaultContext()
    rng = np.random.default_rng(0)
    plant.SetPositions(context, plant.GetPositions(context) + 0.1 * rng.standard_normal(plant.num_positions()))
    reference = plant.CalcGravityGeneralizedForces(context)
    scale = max(1.0, float(np.abs(reference).max()))
    if not np.allclose(plant.CalcMassMatrix(context)[:, columns] @ g, reference, rtol=0, atol=1e-9 * scale):
        return None
    g.flags.writeable = False
    return columns, g


def acceleration_bounds(
    q: np.ndarray,
    v: np.ndarray,
    position_lower: np.ndarray,
    position_upper: np.ndarray,
    velocity_lower: np.ndarray,
    velocity_upper: np.ndarray,
    horizon: float,
    margin: float,
    layout: Layout,
    *,
    dt: float,
    braking: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Joint limits as bounds on ``q̈`` (nv; the floating base free), for a device that integrates
    ``v' = v + q̈ dt``, ``q' = q + v' dt`` every tick ``dt`` (s).

    Position: with the acceleration held over ``horizon`` T, ``q + v T + ½ q̈ T² ≤ q_max − margin``
    gives ``q̈ ≤ 2 (q_max − margin − q − v T)/T²``; a joint already inside the margin gets
    ``q̈ ≤ min(0, 2 (q_max − q − v T)/T²)`` instead (it may stay on its limit, as the grippers start;
    moving into the limit it is stopped). Velocity: ``v + q̈ T ≤ v_max`` gives ``q̈ ≤ (v_max − v)/T``.
    Stopping: the horizon's bound alone lets a fast joint overshoot (held on it, the joint is a
    spring-damper of damping ratio 0.71); so ``v'`` is also bounded by the speed from which a
    braking of ``A = v_max/T`` (rad/s²) stops the joint by ``q_max`` after this tick
    (:func:`stopping_speed`): ``q̈ ≤ max((v_stop − v)/dt, −A)``. Lower bounds likewise. The stopping
    bounds come first: where a side's horizon or velocity bound would keep the other side from
    stopping (a joint near one limit of a narrow range), it gives way. A joint within its limits,
    able to stop (``v² ≤ 2 A (q_max − q)``, and likewise below), then never leaves them as long as
    the solver holds the bounds (braking at ``A`` keeps every later tick's bounds met); one that
    can no longer stop in time, or beyond a limit, brakes at ``A``, never asked more. Where the two
    sides would still cross, the lower bound is lowered to the upper one.

    ``braking`` (nv, rad/s² or m/s², None: none): what each joint's torque can brake
    (:func:`torque_braking`). Where it is below ``v_max/T`` it is the joint's ``A``, and the
    position's horizon grows to ``T_j = v_max/A`` in proportion: the joint slows down early enough
    that stopping at its limit needs no more than that torque, instead of asking the rest of the
    body (through the floating base and the contacts) for the difference.
    """
    nv = len(v)
    lower, upper = np.full(nv, -np.inf), np.full(nv, np.inf)
    iq, iv = layout.joints_q, layout.joints_v
    with np.errstate(invalid="ignore"):
        lower[iv], upper[iv] = joint_acceleration_bounds(q[iq], v[iv], position_lower[iq], position_upper[iq],
                                                         velocity_lower[iv], velocity_upper[iv], horizon, margin, dt=dt,
                                                         braking=None if braking is None else braking[iv])
    return lower, upper


def joint_acceleration_bounds(
    qj: np.ndarray, vj: np.ndarray, position_lower: np.ndarray, position_upper: np.ndarray, velocity_lower: np.ndarray,
    velocity_upper: np.ndarray, horizon: float, margin: float, *, dt: float, braking: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`acceleration_bounds` of the joints alone: ``(lower, upper)`` over the joints' velocities,
    from their positions ``qj``, velocities ``vj``, limits and ``braking`` (each already restricted to the joints)."""
    return mirrored_acceleration_bounds(qj, vj, *stacked_limits(position_lower, position_upper, velocity_lower, velocity_upper),
                                        horizon, margin, dt=dt, braking=braking)


def stacked_limits(position_lower: np.ndarray, position_upper: np.ndarray, velocity_lower: np.ndarray,
                   velocity_upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The joints' limits as :func:`mirrored_acceleration_bounds` takes them: ``(q_max, −q_min)`` and
    ``(v_max, −v_min)``, each 2 × joints (stack them once for limits that do not change)."""
    return np.stack((position_upper, -position_lower)), np.stack((velocity_upper, -velocity_lower))


def mirrored_acceleration_bounds(qj: np.ndarray, vj: np.ndarray, position_limits: np.ndarray, velocity_limits: np.ndarray,
                                 horizon: float, margin: float, *, dt: float, braking: np.ndarray | None = None
                                 ) -> tuple[np.ndarray, np.ndarray]:
    """:func:`joint_acceleration_bounds` from limits already :func:`stacked <stacked_limits>`: both sides
    in one evaluation of :func:`side_acceleration_bounds` (see :data:`SIDES`): each side's upper
    bound, raised to the other side's stopping bound where it is below, then lowered to its own."""
    shaping, stopping = side_acceleration_bounds(SIDES * qj, SIDES * vj, position_limits, velocity_limits, horizon, margin,
                                                 dt=dt, braking=braking)
    upper = np.minimum(shaping, stopping)
    upper[0] = np.minimum(np.maximum(upper[0], -stopping[1]), stopping[0])
    upper[1] = np.minimum(np.maximum(upper[1], -stopping[0]), stopping[1])
    return np.minimum(-upper[1], upper[0]), upper[0]


#: The two sides of a joint's limits as one computation: the lower bounds are minus the upper
#: bounds of the mirrored joint ``(−q, −v)`` with the limits ``(−q_min, −v_min)`` (exactly: negation
#: is exact in floating point, and so is every comparison and rounding of the formula under it).
SIDES = np.array([[1.0], [-1.0]])
SIDES.flags.writeable = False


def side_acceleration_bounds(q: np.ndarray, v: np.ndarray, position_upper: np.ndarray, velocity_upper: np.ndarray,
                             horizon: float, margin: float, *, dt: float, braking: np.ndarray | None = None
                             ) -> tuple[np.ndarray, np.ndarray]:
    """The two upper bounds of :func:`acceleration_bounds` from one side's limits (any array shape,
    elementwise): the horizon's and the velocity's, ``min(2 (q_max − margin − q − v T_j)/T_j², (v_max − v)/T)``
    (``min(0, 2 (q_max − q − v T_j)/T_j²)`` for the position part of a joint already inside the
    margin), and the stopping bound ``max((v_stop − v)/dt, −A)``, ``v_stop`` the :func:`stopping_speed`
    of ``q_max − q`` at the braking ``A = min(v_max/T, braking)`` (a joint that can no longer stop in
    time brakes at ``A``: it is never asked more); ``T_j = v_max/A`` where ``braking`` is the smaller
    (and ``v_max`` finite), else ``T``."""
    T = horizon
    brake = velocity_upper / T
    Tj: float | np.ndarray = T
    if braking is not None:
        rate = brake
        brake = np.minimum(rate, braking)
        Tj = np.where((brake < rate) & np.isfinite(velocity_upper), velocity_upper / brake, T)
    reach = q + v * Tj
    limit = position_upper - margin
    up = np.where(q > limit, np.minimum(0.0, position_upper - reach), limit - reach)
    up *= 2
    up /= Tj * Tj  # = 2 x / T_j² for each x above, min(0, ·) included (a monotone map that keeps 0)
    np.minimum(up, (velocity_upper - v) / T, out=up)
    return up, np.maximum((stopping_speed(position_upper - q, brake, dt) - v) / dt, -brake)


#: The share of a joint's effort limit that :func:`torque_braking` counts on to brake it: the rest
#: is left for gravity and for the reactions of the other joints' motion.
BRAKING_SHARE = 0.5


def torque_braking(M: np.ndarray, B: np.ndarray, effort: np.ndarray, share: float = BRAKING_SHARE) -> np.ndarray:
    """``share · τ_max / M_jj`` for each velocity j (rad/s² or m/s²; inf where no actuator acts):
    the acceleration a joint's own torque gives its own inertia, ``M`` the mass matrix (nv × nv, at
    a reference posture), ``B`` the actuation matrix (nv × na), ``effort`` the actuators' limits (na)."""
    effort_v = np.abs(B) @ np.asarray(effort, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(effort_v > 0, share * effort_v / np.diag(M), np.inf)


def stopping_speed(room: np.ndarray, brake: np.ndarray, dt: float) -> np.ndarray:
    """The largest ``v'`` (rad/s or m/s) after which a joint ``room`` away from its limit still
    stops by it: the tick moves it ``v' dt``, then braking at ``brake`` (> 0; ``inf``: at once)
    covers at most ``v'²/(2 brake)`` (the ticks' steps ``v_k dt`` sum to less than the braking's
    integral), so ``v' dt + v'²/(2 brake) ≤ room`` gives ``v' = 2 room/(dt + √(dt² + 2 room/brake))``;
    0 where ``room ≤ 0`` (on or beyond the limit) or ``brake`` is 0; ``inf`` where ``room`` is (a joint
    without that limit)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        speed = np.where(np.isposinf(room), np.inf, 2 * room / (dt + np.sqrt(dt * dt + 2 * room / brake)))
    return np.where((room > 0) & (brake > 0), speed, 0.0)
