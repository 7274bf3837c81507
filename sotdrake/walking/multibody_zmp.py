"""The multibody ZMP: the whole body's momentum in the CoM plan (Kajita's multibody ZMP correction).

The linear inverted pendulum (:mod:`.com_planner`) sees the robot as one mass at the CoM, moving at
constant height: its ZMP is ``q = c − (z/g) c̈``. The real robot's ZMP on flat ground (world frame,
z up, ``g`` = 9.81 m/s², ``L`` the angular momentum about the CoM) is

    ``p_x = c_x − (m c_z c̈_x + L̇_y) / (m (c̈_z + g))``,  ``p_y = c_y − (m c_z c̈_y − L̇_x) / (m (c̈_z + g))``

(:func:`zmp_from_momentum`; :func:`motion_zmp` evaluates it along a motion with Drake's
``CalcSpatialMomentumInWorldAboutPoint`` and central differences). A leg swung 0.4 m in 0.7 s
carries ``L̇`` that the pendulum ignores: at 0.2 m per step TALOS' multibody ZMP strays centimetres
from the reference the CoM was planned for.

The plan's model of that (:class:`LegMasses`): three point masses, each leg's (``m_l``, at its
links' CoM) and the rest of the body's (``m_b``, at constant height, where the waist task holds
it). A leg's CoM follows its hip (which moves with the CoM) and a fixed share of the sole's motion
relative to the hip: ``s_l = s_l0 + Δc + K_l (Δf_l − Δc)`` (``Δ``: from the standing posture;
``Δc`` the horizontal CoM displacement; ``K_l`` (3×3) the leg's CoM displacement per sole
displacement with the hip fixed and the sole's orientation kept, from the leg's Jacobians at the
standing posture, turned with the walking frame's yaw; the legs' rest offsets are not turned, a
few millimetres' error on a turn). Links are points: their rotational inertia is left out. The
rest is where the total CoM ``c``
puts it: ``m_b b_xy = m c_xy − Σ m_l s_l,xy``. The ZMP of point masses ``i`` is

    ``p = Σ m_i (x_i (z̈_i + g) − z_i ẍ_i) / Σ m_i (z̈_i + g)``  (per horizontal axis).

Its error to the pendulum's, ``e = p − q``, depends on the plan only through the legs; by the
pendulum's linearity (superposition) the CoM planned for the reference ``p_d − e`` has a
multibody ZMP at ``p_d`` up to the change of ``e`` with the CoM, which a second pass corrects
(:meth:`LegMasses.lipm_reference`, used by :func:`~.plan.replan`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable, ModelInstanceIndex
from pydrake.trajectories import PiecewisePolynomial

from ..exceptions import FrameNotFound, InvalidInput, check_finite, check_type, finite_number
from ..robots import RobotModel
from .com_planner import GRAVITY, ComPlan

SIDES = ("left", "right")
#: Sampling period (s) of the corrected reference (first-order hold).
SAMPLE_PERIOD = 0.01
#: The corrected reference is sampled this close (s) on both sides of the soles' knots.
KNOT_SIDE = 1e-4
#: Passes of the correction (each replans the CoM from the previous pass' legs).
PASSES = 2


def zmp_from_momentum(com, com_acceleration, angular_momentum_rate, mass: float, gravity: float = GRAVITY) -> np.ndarray:
    """The ZMP on the ground ``z = 0`` (xy, m) from the CoM ``c`` (3, m), its acceleration ``c̈``
    (3, m/s²) and the rate of the angular momentum about the CoM ``L̇`` (3, N·m; world frame);
    arrays of shape ``(..., 3)`` give ``(..., 2)``. The arrays must be finite, of one shape, the
    ``mass`` (kg) and ``gravity`` (m/s²) positive, and the vertical force ``m (c̈_z + g)`` positive
    (the ZMP of a body in free fall does not exist); else :class:`InvalidInput` naming the argument."""
    c, a, dL = (check_finite(f"zmp_from_momentum: {name} (…, 3)", x) for name, x in
                (("com", com), ("com_acceleration", com_acceleration), ("angular_momentum_rate", angular_momentum_rate)))
    if c.ndim < 1 or c.shape[-1] != 3 or a.shape != c.shape or dL.shape != c.shape:
        raise InvalidInput(f"zmp_from_momentum: com, com_acceleration and angular_momentum_rate must be of one shape (…, 3), "
                           f"got {c.shape}, {a.shape} and {dL.shape}")
    for name, value in (("mass (kg)", mass), ("gravity (m/s²)", gravity)):
        if not (finite_number(value) and 0 < value <= 1e6):
            raise InvalidInput(f"zmp_from_momentum: {name} must be a number in (0, 1e6], got {value!r:.60}")
    vertical = mass * (a[..., 2] + gravity)
    if not np.all(vertical > 0):
        raise InvalidInput(f"zmp_from_momentum: the vertical force m (c̈_z + g) must be > 0 (no ZMP in free fall); "
                           f"c̈_z = {a[..., 2].min():g} m/s² against g = {gravity:g} m/s²")
    px = c[..., 0] - (mass * c[..., 2] * a[..., 0] + dL[..., 1]) / vertical
    py = c[..., 1] - (mass * c[..., 2] * a[..., 1] - dL[..., 0]) / vertical
    return np.stack([px, py], axis=-1)


def point_masses_zmp(masses, positions, accelerations, gravity: float = GRAVITY) -> np.ndarray:
    """The ZMP (``(..., 2)``, m) of point masses ``masses`` (k,) at ``positions`` with
    ``accelerations`` (``(..., k, 3)`` each, world)."""
    m = np.asarray(masses, dtype=float)
    x, a = np.asarray(positions, dtype=float), np.asarray(accelerations, dtype=float)
    vertical = m * (a[..., 2] + gravity)
    numerator = vertical[..., None] * x[..., :2] - (m * x[..., 2])[..., None] * a[..., :2]
    return numerator.sum(axis=-2) / vertical.sum(axis=-1)[..., None]


def motion_zmp(plant, times, positions) -> tuple[np.ndarray, np.ndarray]:
    """The multibody ZMP (k×2) and CoM (k×3) of ``plant`` along the motion ``positions`` (k×nq) at
    ``times`` (k,): velocities from central differences of ``q`` (mapped by Drake's
    ``MapQDotToVelocity``), ``L`` from ``CalcSpatialMomentumInWorldAboutPoint`` about the CoM,
    ``c̈`` and ``L̇`` by central differences (one-sided, hence less accurate, at the first two and
    last two samples)."""
    check_type("motion_zmp: plant", plant, MultibodyPlant, "MultibodyPlant (a robot model's plant)")
    t = check_finite("motion_zmp: times (s)", times)
    q = check_finite("motion_zmp: positions (k×nq)", positions)
    if t.ndim != 1 or len(t) < 3 or not np.all(np.diff(t) > 0):
        raise InvalidInput(f"motion_zmp: times must be k ≥ 3 increasing times (s, each once), got {times!r:.100}")
    if q.shape != (len(t), plant.num_positions()):
        raise InvalidInput(f"motion_zmp: positions must be k×nq = {len(t)}×{plant.num_positions()} (a q per time), got {q.shape}")
    _check_quaternions("motion_zmp: positions", plant, q)
    context = plant.CreateDefaultContext()
    qdot = np.gradient(q, t, axis=0)
    com, com_velocity, momentum = (np.zeros((len(t), 3)) for _ in range(3))
    for k in range(len(t)):
        plant.SetPositions(context, q[k])
        plant.SetVelocities(context, plant.MapQDotToVelocity(context, qdot[k]))
        com[k] = plant.CalcCenterOfMassPositionInWorld(context)
        com_velocity[k] = plant.CalcCenterOfMassTranslationalVelocityInWorld(context)
        momentum[k] = plant.CalcSpatialMomentumInWorldAboutPoint(context, com[k]).rotational()
    mass = plant.CalcTotalMass(context)
    zmp = zmp_from_momentum(com, np.gradient(com_velocity, t, axis=0), np.gradient(momentum, t, axis=0), mass)
    return zmp, com


@dataclass(frozen=True)
class LegMasses:
    """The three-mass model of the module docstring, at the standing posture (world; m, kg).

    ``leg_mass``: one leg's mass; ``total_mass``; ``leg_com`` and ``sole``: side → the leg's CoM
    and the sole's origin (3); ``com``: the whole CoM (3); ``share``: side → ``K_l`` (3×3), in the
    world frame of the standing posture, whose soles' mean yaw is ``yaw``."""

    leg_mass: float
    total_mass: float
    leg_com: dict
    sole: dict
    com: np.ndarray
    share: dict
    yaw: float = 0.0  # the soles' mean yaw at the standing posture (rad): the frame of ``K_l``

    @property
    def body_mass(self) -> float:
        return self.total_mass - 2 * self.leg_mass

    @property
    def body_height(self) -> float:
        """The rest of the body's CoM height (held constant)."""
        return float((self.total_mass * self.com[2] - self.leg_mass * sum(self.leg_com[s][2] for s in SIDES)) / self.body_mass)

    def masses_at(self, com, com_acceleration, feet, feet_acceleration,
                  yaw: float | np.ndarray = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(masses (3,), positions (k, 3, 3), accelerations (k, 3, 3))`` (left leg, right leg,
        rest) for the planned CoM ``com`` (k×2), ``com_acceleration`` (k×2), soles ``feet[side]``
        (k×3) and ``feet_acceleration[side]`` (k×3); ``yaw`` (k,) turns ``K_l`` with the walking frame."""
        c, ca = np.asarray(com, dtype=float), np.asarray(com_acceleration, dtype=float)
        n = len(c)
        yaws = np.broadcast_to(np.asarray(yaw, dtype=float), (n,))
        cy, sy = np.cos(yaws), np.sin(yaws)
        R = np.zeros((n, 3, 3))
        R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = cy, -sy, sy, cy, 1.0
        dc = np.column_stack([c - self.com[:2], np.zeros(n)])
        ddc = np.column_stack([ca, np.zeros(n)])
        positions, accelerations = np.zeros((n, 3, 3)), np.zeros((n, 3, 3))
        for i, side in enumerate(SIDES):
            K = R @ self.share[side] @ R.transpose(0, 2, 1)
            df = np.asarray(feet[side], dtype=float) - self.sole[side]
            positions[:, i] = self.leg_com[side] + dc + np.einsum("kij,kj->ki", K, df - dc)
            accelerations[:, i] = ddc + np.einsum("kij,kj->ki", K, np.asarray(feet_acceleration[side], dtype=float) - ddc)
        m, m_l, m_b = self.total_mass, self.leg_mass, self.body_mass
        positions[:, 2, :2] = (m * c - m_l * (positions[:, 0, :2] + positions[:, 1, :2])) / m_b
        positions[:, 2, 2] = self.body_height
        accelerations[:, 2, :2] = (m * ca - m_l * (accelerations[:, 0, :2] + accelerations[:, 1, :2])) / m_b
        return np.array([m_l, m_l, m_b]), positions, accelerations

    def zmp_error(self, times, com: ComPlan, feet: dict, feet_acceleration: dict) -> np.ndarray:
        """``e = p − q`` (k×2, m) at ``times``: the model's ZMP minus the pendulum's, along the plan
        (``feet``/``feet_acceleration``: side → trajectories of ``(x, y, z, yaw)``)."""
        states = [com.state(t) for t in times]
        c = np.array([s[0] for s in states])
        ca = np.array([s[2] for s in states])

        def sample(trajectory, t):
            return trajectory.value(min(max(t, trajectory.start_time()), trajectory.end_time())).ravel()

        pose = {s: np.array([sample(feet[s], t) for t in times]) for s in SIDES}
        acc = {s: np.array([sample(feet_acceleration[s], t) for t in times]) for s in SIDES}
        yaw = 0.5 * (pose["left"][:, 3] + pose["right"][:, 3]) - self.yaw
        masses, positions, accelerations = self.masses_at(c, ca, {s: pose[s][:, :3] for s in SIDES},
                                                          {s: acc[s][:, :3] for s in SIDES}, yaw)
        return point_masses_zmp(masses, positions, accelerations) - (c - com.height / GRAVITY * ca)

    def lipm_reference(self, zmp: PiecewisePolynomial, com: ComPlan, feet: dict, feet_acceleration: dict,
                       start: float) -> PiecewisePolynomial:
        """The reference ``p_d − e`` (first-order hold at :data:`SAMPLE_PERIOD`, and on both sides of
        the soles' knots, where their accelerations jump) on ``[start, end]``
        of ``zmp``, ``e`` along the plan ``com`` (see :meth:`zmp_error`), except on the reference's
        final hold (its last segment), which stays ``p_d``: the stationary end ``ZmpPlanner`` needs."""
        end, hold = zmp.end_time(), zmp.get_segment_times()[-2]
        if start >= hold:  # already on the final hold: nothing moves
            return zmp
        # The soles' accelerations jump at their knots (lift-off, mid-swing, touch-down): e jumps
        # there too, sampled on both sides.
        breaks = np.concatenate([feet_acceleration[s].get_segment_times() for s in SIDES])
        breaks = breaks[(breaks > start + KNOT_SIDE) & (breaks < hold - KNOT_SIDE)]
        times = np.unique(np.concatenate([np.arange(start, hold, SAMPLE_PERIOD), breaks - KNOT_SIDE, breaks + KNOT_SIDE, [hold, end]]))
        reference = np.array([zmp.value(t).ravel() for t in times])
        error = self.zmp_error(times, com, feet, feet_acceleration)
        error[times >= hold] = 0.0  # the reference's final hold stays stationary (ZmpPlanner's end condition)
        return PiecewisePolynomial.FirstOrderHold(times, (reference - error).T)


def leg_masses(model, q0: np.ndarray, soles=("left_sole_link", "right_sole_link"), prefixes=("leg_left_", "leg_right_")) -> LegMasses:
    """The :class:`LegMasses` of ``model`` (a :class:`~sotdrake.robots.RobotModel`) standing at
    ``q0``: each leg is the bodies whose names start with its prefix (TALOS: ``leg_left_``), from
    the hip to the sole; ``K_l`` solves the leg's joints for a sole translation with the sole's
    orientation kept and the base fixed (6×6 Jacobian), and maps it to the leg CoM's displacement."""
    plant = _check_leg_masses(model, q0, soles, prefixes)
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, q0)
    world = plant.world_frame()
    total = plant.CalcTotalMass(context)
    leg_mass, leg_com, sole, share = {}, {}, {}, {}
    bodies = [plant.get_body(b) for i in range(plant.num_model_instances()) for b in plant.GetBodyIndices(ModelInstanceIndex(i))]
    joints_of = [plant.get_joint(j) for i in range(plant.num_model_instances()) for j in plant.GetJointIndices(ModelInstanceIndex(i))]
    yaws = []
    for side, frame_name, prefix in zip(SIDES, soles, prefixes, strict=True):
        legs = [b for b in bodies if b.name().startswith(prefix)]
        if not legs:
            raise InvalidInput(f"leg_masses: no body named {prefix}* in {model.name}")
        joints = sorted(j.velocity_start() for j in joints_of if j.child_body().name().startswith(prefix) and j.num_velocities() == 1)
        mass, moment = 0.0, np.zeros(3)
        J_com = np.zeros((3, plant.num_velocities()))
        for body in legs:
            m = body.get_mass(context)
            p_BoBcm = body.CalcCenterOfMassInBodyFrame(context)
            mass += m
            moment += m * body.EvalPoseInWorld(context).multiply(p_BoBcm)
            J_com += m * plant.CalcJacobianTranslationalVelocity(context, JacobianWrtVariable.kV, body.body_frame(), p_BoBcm, world, world)
        frame = model.frame(frame_name)
        J_sole = plant.CalcJacobianSpatialVelocity(context, JacobianWrtVariable.kV, frame, np.zeros(3), world, world)
        if len(joints) != 6:
            raise InvalidInput(f"leg_masses: a leg needs 6 one-dof joints, {prefix}* has {len(joints)}")
        dq = np.linalg.solve(J_sole[:, joints], np.vstack([np.zeros((3, 3)), np.eye(3)]))  # sole (ω = 0, v = I)
        share[side] = (J_com[:, joints] / mass) @ dq
        leg_mass[side], leg_com[side] = mass, moment / mass
        X_WS = frame.CalcPoseInWorld(context)
        sole[side] = X_WS.translation()
        yaws.append(float(np.arctan2(X_WS.rotation().matrix()[1, 0], X_WS.rotation().matrix()[0, 0])))
    if abs(leg_mass["left"] - leg_mass["right"]) > 1e-6 * leg_mass["left"]:
        raise InvalidInput(f"leg_masses: legs of different masses {leg_mass}")
    return LegMasses(leg_mass["left"], total, leg_com, sole, plant.CalcCenterOfMassPositionInWorld(context), share,
                     float(np.mean(yaws)))


def _check_leg_masses(model, q0, soles, prefixes):
    """``model``'s plant once :func:`leg_masses`' arguments are checked (:class:`InvalidInput` or
    :class:`~sotdrake.exceptions.FrameNotFound` naming them)."""
    check_type("leg_masses: model", model, RobotModel, "RobotModel (robot.model)")
    plant = model.plant
    q = check_finite("leg_masses: q0", q0, (plant.num_positions(),))
    for what, names in (("soles", soles), ("prefixes", prefixes)):
        if isinstance(names, str) or not isinstance(names, (list, tuple)) or len(names) != 2 \
                or not all(isinstance(name, str) and name for name in names) or names[0] == names[1]:
            raise InvalidInput(f"leg_masses: {what} must be two different names, the left leg's then the right one's, "
                               f"got {names!r:.100}")
    for name in soles:
        try:
            model.frame(name)
        except FrameNotFound as error:
            raise error.but("leg_masses: soles") from None
    _check_quaternions("leg_masses: q0", plant, q[None])
    return plant


def _check_quaternions(what: str, plant, qs: np.ndarray) -> None:
    """:class:`InvalidInput` naming ``what`` if a floating base's quaternion in a row of ``qs`` (k×nq)
    is no rotation (norm < 1e-6: Drake would abort)."""
    for body in plant.GetFloatingBaseBodies():
        start = plant.get_body(body).floating_positions_start()
        norms = np.linalg.norm(qs[:, start : start + 4], axis=1)
        if not np.all(norms >= 1e-6):
            k = int(np.argmin(norms))
            raise InvalidInput(f"{what}: the floating base's quaternion [{start}:{start + 4}] = {qs[k, start : start + 4].tolist()} "
                               f"(row {k}) is no rotation; give a unit quaternion (qw, qx, qy, qz)")
