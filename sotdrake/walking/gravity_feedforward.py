"""The servos' feed-forward torque while walking: the static torques that hold the planned posture.

A position servo only produces torque from its error: ``τ = kp (q_d − q) + kd (v_d − v)``. Holding a
leg against gravity therefore costs a sag ``τ_g / kp``, and the swing foot lands centimetres early or
late. Position-controlled humanoids add a feed-forward torque to each servo; here it is the
static one of the reference posture ``q`` (the SoT device's), on the support the pattern generator
plans.

Statics of a floating-base robot at ``q``, with ``g(q)`` the generalized gravity forces (Drake's
``CalcGravityGeneralizedForces``, on the side of the applied forces), each supporting sole ``i``
applying the wrench ``w_i = (n_i, f_i)`` (world, about the sole's origin) through its spatial
Jacobian ``J_i`` (rows ``(ω, v)``, world):

    ``0 = g(q) + Σ J_iᵀ w_i + Bᵀ τ``.

The floating base's 6 rows carry no actuator: on one sole, ``w = −J_{i,b}⁻ᵀ g_b`` (``J_{i,b}`` the
6×6 base block: invertible). On two soles the wrenches are the blend ``α w_L + (1 − α) w_R`` of the
two single-support ones (each balances the base rows, so does their blend). ``α`` is the planned
share, the ZMP reference's position along the segment from the right sole's centre (0) to the left
one's (1), gated by the *measured* contact (the ankles' force sensors): a sole carrying less than
``CONTACT_FORCE`` gets no share. So a sole that lands late or leaves early gets no load-bearing
torque while it is in the air (with the planned support alone it was pushed into the ground and
bounced); the measured forces only switch a share off (their ratio as the share would be a positive
feedback: more load, more leg torque, more load).
The joints' rows then give ``τ = −(g_j + Σ J_{i,j}ᵀ w_i)`` (N·m): the torque each joint carries
when the robot stands still in ``q`` with that support, a swing leg holding its own weight.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import BasicVector, Context, LeafSystem, ValueProducer

from ..configuration import PlantContextHolder
from ..exceptions import FrameNotFound, InvalidInput, all_numbers, check_finite, check_name, check_type
from ..robots import RobotModel

SIDES = ("left", "right")


def support_wrench(gravity_base: np.ndarray, jacobian_base: np.ndarray) -> np.ndarray:
    """The one sole's wrench ``w`` (6, world, about the sole) balancing the base rows of gravity:
    ``J_bᵀ w = −g_b``."""
    return np.linalg.solve(jacobian_base.T, -gravity_base)


def static_torques(gravity: np.ndarray, jacobians: dict, shares: dict, base: slice) -> np.ndarray:
    """``τ`` on every velocity coordinate (nv, zero on the base rows) for the soles' ``jacobians``
    (side → 6×nv) weighted by ``shares`` (side → α, summing to 1)."""
    torque = -np.array(gravity, dtype=float)
    for side, share in shares.items():
        if share:
            J = jacobians[side]
            torque -= share * (J.T @ support_wrench(gravity[base], J[:, base]))
    torque[base] = 0.0
    return torque


#: A sole carrying less than this normal force (N) is in the air for the feed-forward.
CONTACT_FORCE = 20.0


def left_share(zmp: np.ndarray, left_centre: np.ndarray, right_centre: np.ndarray) -> float:
    """The planned ``α``: the ZMP's position along the segment from the right sole's centre (0) to
    the left one's (1), clamped to [0, 1]."""
    axis = np.asarray(left_centre, dtype=float) - np.asarray(right_centre, dtype=float)
    return float(np.clip((np.asarray(zmp, dtype=float) - right_centre) @ axis / (axis @ axis), 0.0, 1.0))


def gated_share(planned: float, left_force: float, right_force: float, minimum: float = CONTACT_FORCE) -> float:
    """``α`` with a sole carrying less than ``minimum`` (N) given no share (the planned one if both
    or neither carry it)."""
    left, right = left_force >= minimum, right_force >= minimum
    return planned if left == right else (1.0 if left else 0.0)


class GravityFeedforward(LeafSystem):
    """Inputs: ``position`` (the reference ``q``, nq), ``zmp_reference`` (2, world xy) and
    ``normal_forces`` (2: the measured normal force on the left and the right sole, N). Output
    ``torque``: the static torques (see the module docstring) of the joints at ``actuated_v`` (the
    velocity index of each actuator, in actuator order). ``soles``: the left and right sole frames' names; ``sole_centre``: the footprint's
    centre in the sole frame (xy, m)."""

    def __init__(self, model: RobotModel, actuated_v: np.ndarray, soles: tuple[str, str] = ("left-sole", "right-sole"),
                 sole_centre: tuple[float, float] = (0.0, 0.0), name: str = "gravity_feedforward"):
        check_name("GravityFeedforward: name", name)
        check_type(f"{name}: model", model, RobotModel, "RobotModel (robot.model)")
        plant = model.plant
        bodies = plant.GetFloatingBaseBodies()
        if len(bodies) != 1:
            raise InvalidInput(f"{name}: needs a robot with one floating base, found {len(bodies)}")
        actuated = np.asarray(actuated_v) if all_numbers(actuated_v) else None
        if actuated is None or actuated.ndim != 1 or (actuated.size and (
                actuated.dtype.kind not in "iu" or actuated.min() < 0 or actuated.max() >= plant.num_velocities())):
            raise InvalidInput(f"{name}: actuated_v must be integers indexing the {plant.num_velocities()} velocities, "
                               f"got {actuated_v!r:.100}")
        if isinstance(soles, str) or not isinstance(soles, (list, tuple)) or len(soles) != 2:
            raise InvalidInput(f"{name}: soles must be two names, the left sole's then the right one's, got {soles!r:.100}")
        try:
            frames = {side: model.frame(frame) for side, frame in zip(SIDES, soles, strict=True)}
        except FrameNotFound as error:
            raise error.but(f"{name}: soles") from None
        centre = check_finite(f"{name}: sole_centre (x, y in the sole frame, m)", sole_centre, (2,), 1e3)
        LeafSystem.__init__(self)
        self.set_name(name)
        self.plant = plant
        start = plant.get_body(next(iter(bodies))).floating_velocities_start_in_v()
        self._base = slice(start, start + 6)
        self._actuated_v = actuated.astype(int)
        self._soles = frames
        self._centre = np.array([*centre, 0.0])
        self.position = self.DeclareVectorInputPort("position", model.nq)
        self.zmp_reference = self.DeclareVectorInputPort("zmp_reference", 2)
        self.normal_forces = self.DeclareVectorInputPort("normal_forces", 2)
        self._plant_context = self.DeclareCacheEntry(
            "plant_context",
            ValueProducer(allocate=lambda: AbstractValue.Make(PlantContextHolder(self.plant)), calc=self._set_positions),
            prerequisites_of_calc={self.input_port_ticket(self.position.get_index())},
        )
        self.DeclareVectorOutputPort("torque", len(self._actuated_v), self._calc)

    def _set_positions(self, context: Context, value: AbstractValue) -> None:
        self.plant.SetPositions(value.get_mutable_value().context, self.position.Eval(context))

    def _calc(self, context: Context, output: BasicVector) -> None:
        plant, world = self.plant, self.plant.world_frame()
        plant_context = self._plant_context.Eval(context).context
        gravity = plant.CalcGravityGeneralizedForces(plant_context)
        jacobians = {side: plant.CalcJacobianSpatialVelocity(plant_context, JacobianWrtVariable.kV, frame, np.zeros(3), world, world)
                     for side, frame in self._soles.items()}
        centres = {side: plant.CalcPointsPositions(plant_context, frame, self._centre, world).ravel()[:2]
                   for side, frame in self._soles.items()}
        planned = left_share(self.zmp_reference.Eval(context), centres["left"], centres["right"])
        alpha = gated_share(planned, *self.normal_forces.Eval(context))
        shares = {"left": alpha, "right": 1.0 - alpha}
        output.SetFromVector(static_torques(gravity, jacobians, shares, self._base)[self._actuated_v])
