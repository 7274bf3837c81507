"""The walking stabiliser: CoM and ZMP feedback on the CoM reference, from the measured robot.

On the physics plant the SoT runs open loop: its kinematics reads the device's ``q``, so the CoM
task makes the *device's* CoM follow its reference, while the robot's real CoM ``c_m`` and centre
of pressure ``p_m`` differ by whatever the servos' sag, the soles' compliance and the swing leg's
reaction add; the linear inverted pendulum (``c̈ = ω² (c − p)``, ``ω = √(g/z)``) lets the CoM error
grow as ``e^{ωt}``. The stabiliser is the kinematic CoM/ZMP feedback of Choi et al. (IEEE T-RO 2007,
"Posture/walking control for humanoid robot based on kinematic resolution of CoM Jacobian with
embedded motion"): the CoM velocity commanded to the SoT is

    ``ċ_cmd = ċ_r + k_c (c_r − c_m) − k_z (p_r − p_m)``,

``p_r = c_r − c̈_r/ω²`` the planned ZMP (the pendulum's), or the ``zmp_reference`` input when it is
connected: a CoM planned with the legs' momentum (:mod:`.multibody_zmp`) has its pendulum ZMP off
the reference by the legs' share, while the robot's CoP belongs at the reference itself. With the
CoM following its command, the closed loop is stable for ``k_c > ω`` and ``0 ≤ k_z < ω`` (their
Theorem 1). The correction is integrated every tick as an offset on the plan, ``c_cmd = c_r + δ``, ``δ̇ = k_c (c_r − c_m) − k_z (p_r − p_m)``
(discrete state, explicit Euler), clamped to ``±max_offset`` per axis; ``p_m`` is ignored (``k_z``
term dropped) while it is not finite (nothing on the ground). Horizontal axes only (x, y; world;
m, m/s); the height is the plan's.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from ..exceptions import InvalidInput, check_name, finite_number
from .com_planner import GRAVITY

#: ``k_c`` (1/s): the CoM error gain (> ω, ω ≈ 3.3 /s on TALOS).
COM_GAIN = 5.0
#: ``k_z`` (1/s): the ZMP error gain (< ω).
ZMP_GAIN = 0.0
#: Largest correction of the CoM reference (m, per horizontal axis).
MAX_OFFSET = 0.05
#: The ranges of the arguments (beyond them, a mistake): the CoM height and ``max_offset`` (m), ``dt``
#: (s, as the pattern generator's), ``com_gain`` (1/s).
MAX_HEIGHT, MAX_DT, MAX_GAIN = 1e3, 1.0, 1e4


def feedback_rate(com_reference: np.ndarray, com_measured: np.ndarray, zmp_reference: np.ndarray,
                  zmp_measured: np.ndarray, com_gain: float, zmp_gain: float) -> np.ndarray:
    """``δ̇ = k_c (c_r − c_m) − k_z (p_r − p_m)`` (xy, m/s); without the ZMP term if ``p_m`` is not finite."""
    rate = com_gain * (np.asarray(com_reference, dtype=float) - np.asarray(com_measured, dtype=float))
    if zmp_gain and np.all(np.isfinite(zmp_measured)):
        rate = rate - zmp_gain * (np.asarray(zmp_reference, dtype=float) - np.asarray(zmp_measured, dtype=float))
    return rate


class ComStabilizer(LeafSystem):
    """The stabiliser entity (see the module docstring).

    Inputs: ``com_reference``, ``com_velocity_reference``, ``com_acceleration_reference`` (3, the
    plan), ``measured_com`` (3), ``measured_cop`` (2, NaN when nothing touches) and, optional,
    ``zmp_reference`` (2: the ZMP the plan means, instead of the pendulum's). Outputs:
    ``com`` and ``com_velocity`` (3: the plan plus ``δ``, ``δ̇`` in x, y) and ``offset`` (2: ``δ``).
    ``height``: the pendulum's CoM height (m).
    """

    def __init__(self, height: float, dt: float, com_gain: float = COM_GAIN, zmp_gain: float = ZMP_GAIN,
                 max_offset: float = MAX_OFFSET, name: str = "stabilizer"):
        check_name("ComStabilizer: name", name)
        for what, value, high, unit in (("height", height, MAX_HEIGHT, "m"), ("dt", dt, MAX_DT, "s"),
                                        ("max_offset", max_offset, MAX_HEIGHT, "m")):
            if not (finite_number(value) and 0 < value <= high):
                raise InvalidInput(f"{name}: {what} must be a number in (0, {high:g}] {unit}, got {value!r:.60}")
        omega = float(np.sqrt(GRAVITY / height))
        if not (finite_number(com_gain) and omega < com_gain <= MAX_GAIN):
            raise InvalidInput(f"{name}: com_gain must be a number in (ω = √(g/z) = {omega:.3f}, {MAX_GAIN:g}] /s (stability), "
                               f"got {com_gain!r:.60}")
        if not (finite_number(zmp_gain) and 0 <= zmp_gain < omega):
            raise InvalidInput(f"{name}: zmp_gain must be a number in [0, ω = {omega:.3f}) /s (stability), got {zmp_gain!r:.60}")
        LeafSystem.__init__(self)
        self.set_name(name)
        self.omega = omega
        self.dt, self.com_gain, self.zmp_gain, self.max_offset = float(dt), float(com_gain), float(zmp_gain), float(max_offset)
        vector = self.DeclareVectorInputPort
        self.com_reference = vector("com_reference", 3)
        self.com_velocity_reference = vector("com_velocity_reference", 3)
        self.com_acceleration_reference = vector("com_acceleration_reference", 3)
        self.measured_com = vector("measured_com", 3)
        self.measured_cop = vector("measured_cop", 2)
        self.zmp_reference = vector("zmp_reference", 2)
        self._state = self.DeclareDiscreteState(2)  # δ (xy)
        self.DeclarePeriodicDiscreteUpdateEvent(self.dt, 0.0, self._update)
        self.DeclareVectorOutputPort("com", 3, self._calc_com, {self.all_input_ports_ticket(), self.xd_ticket()})
        self.DeclareVectorOutputPort("com_velocity", 3, self._calc_com_velocity, {self.all_input_ports_ticket(), self.xd_ticket()})
        self.DeclareVectorOutputPort("offset", 2, lambda c, o: o.SetFromVector(self._offset(c)), {self.xd_ticket()})

    def _offset(self, context: Context) -> np.ndarray:
        return context.get_discrete_state(self._state).get_value()

    def _rate(self, context: Context) -> np.ndarray:
        c_r = self.com_reference.Eval(context)[:2]
        if self.zmp_reference.HasValue(context):
            p_r = self.zmp_reference.Eval(context)
        else:
            p_r = c_r - self.com_acceleration_reference.Eval(context)[:2] / self.omega**2
        rate = feedback_rate(c_r, self.measured_com.Eval(context)[:2], p_r, self.measured_cop.Eval(context),
                             self.com_gain, self.zmp_gain)
        held = np.abs(self._offset(context)) >= self.max_offset
        return np.where(held & (np.sign(rate) == np.sign(self._offset(context))), 0.0, rate)

    def _update(self, context: Context, state: DiscreteValues) -> None:
        offset = np.clip(self._offset(context) + self.dt * self._rate(context), -self.max_offset, self.max_offset)
        state.get_mutable_vector(self._state).SetFromVector(offset)

    def _calc_com(self, context: Context, output: BasicVector) -> None:
        c = np.array(self.com_reference.Eval(context), dtype=float)
        c[:2] += self._offset(context)
        output.SetFromVector(c)

    def _calc_com_velocity(self, context: Context, output: BasicVector) -> None:
        v = np.array(self.com_velocity_reference.Eval(context), dtype=float)
        v[:2] += self._rate(context)
        output.SetFromVector(v)
