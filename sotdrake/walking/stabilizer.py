"""The walking stabiliser: DCM feedback on the CoM reference, from the measured CoM.

On the physics plant the SoT runs open loop: its kinematics reads the device's ``q``, so the CoM
task makes the *device's* CoM follow its reference while the robot's real CoM ``c_m`` differs by
whatever the servos' sag, the soles' compliance and the swing leg's reaction add. The linear
inverted pendulum (``c̈ = ω² (c − p)``, ``ω = √(g/z)``, ``p`` the ZMP) makes that error diverge
(``e^{ωt}``, ×10 in a 0.7 s stance). Walking controllers close the loop on the divergent
component of motion (DCM) ``ξ = c + ċ/ω`` (Englsberger et al. 2015; Kajita et al. 2010's
stabiliser): with the plan's ``(c_r, ċ_r, c̈_r)`` and its ZMP ``p_r = c_r − c̈_r/ω²``, the ZMP
asked of the robot is

    ``p_d = p_r + k (ξ_m − ξ_r)``,  ``k > 1``,

(``ξ̇ = ω (ξ − p)`` then makes the DCM error decay at ``ω (k − 1)``), and the CoM reference given to
the SoT's CoM task is the pendulum that realises it from the measured CoM:
``c_cmd = c_r + δ`` with

    ``δ̈ = ω² (c_m − c_r) − k ω² (ξ_m − ξ_r)``   (i.e. ``c̈_cmd = ω² (c_m − p_d)``),

integrated every tick (semi-implicit Euler on ``(δ, δ̇)``, discrete state), ``|δ| ≤ max_offset``
per axis. When the robot tracks exactly (``c_m = c_cmd``) this is ``δ̈ = −ω²(k − 1) δ − k ω δ̇``:
``δ`` stays 0 from 0 (the plan unchanged, as in kinematic mode) and any offset decays (critically
damped at ``k = 2``). A constant error ``c_m = c_cmd + e`` is cancelled: ``δ → −e``, ``c_m → c_r``.
Horizontal axes only (x, y; world; m, m/s); the height is the plan's.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, LeafSystem

from ..exceptions import InvalidInput
from .com_planner import GRAVITY

#: DCM gain ``k`` (dimensionless, > 1): the DCM error decays at ``ω (k − 1)``.
DCM_GAIN = 2.0
#: Largest correction of the CoM reference (m, per horizontal axis).
MAX_OFFSET = 0.05


def dcm(position: np.ndarray, velocity: np.ndarray, omega: float) -> np.ndarray:
    """The divergent component of motion ``ξ = c + ċ/ω`` (xy, m)."""
    return np.asarray(position, dtype=float) + np.asarray(velocity, dtype=float) / omega


def offset_acceleration(reference: tuple[np.ndarray, np.ndarray], measured: tuple[np.ndarray, np.ndarray],
                        omega: float, gain: float) -> np.ndarray:
    """``δ̈ = ω² (c_m − c_r) − k ω² (ξ_m − ξ_r)`` (xy, m/s²) for ``reference = (c_r, ċ_r)`` and
    ``measured = (c_m, ċ_m)`` (see the module docstring)."""
    (c_r, v_r), (c_m, v_m) = reference, measured
    return omega**2 * (np.asarray(c_m) - np.asarray(c_r)) - gain * omega**2 * (dcm(c_m, v_m, omega) - dcm(c_r, v_r, omega))


def com_feedback_rate(reference: np.ndarray, measured: np.ndarray, gain: float) -> np.ndarray:
    """``δ̇ = k (c_r − c_m)`` (xy, m/s): the CoM error integrated into the command."""
    return gain * (np.asarray(reference, dtype=float) - np.asarray(measured, dtype=float))


def step_offset(offset: np.ndarray, rate: np.ndarray, acceleration: np.ndarray, dt: float,
                max_offset: float) -> tuple[np.ndarray, np.ndarray]:
    """One semi-implicit Euler step of ``(δ, δ̇)``; ``δ`` clamped to ``±max_offset`` (and its rate
    zeroed on an axis held at the bound)."""
    rate = rate + dt * acceleration
    offset = offset + dt * rate
    held = np.abs(offset) > max_offset
    return np.clip(offset, -max_offset, max_offset), np.where(held, 0.0, rate)


class DcmStabilizer(LeafSystem):
    """The stabiliser entity (see the module docstring).

    Inputs: ``com_reference``, ``com_velocity_reference`` (3, the plan), ``measured_com``,
    ``measured_com_velocity`` (3, the robot's). Outputs: ``com`` and ``com_velocity`` (3: the plan
    plus ``δ``, ``δ̇`` in x, y), ``offset`` (2: ``δ``), ``dcm_error`` (2: ``ξ_m − ξ_r``).
    ``height``: the CoM height of the pendulum (m).
    """

    def __init__(self, height: float, dt: float, gain: float = DCM_GAIN, max_offset: float = MAX_OFFSET,
                 name: str = "stabilizer", law: str = "dcm"):
        LeafSystem.__init__(self)
        self.set_name(name)
        if not (np.isfinite(height) and height > 0):
            raise InvalidInput(f"{name}: height must be finite and > 0 m, got {height}")
        if not (np.isfinite(dt) and dt > 0):
            raise InvalidInput(f"{name}: dt must be finite and > 0 s, got {dt}")
        self.law = law
        if law == "com":
            pass
        elif not (np.isfinite(gain) and gain > 1):
            raise InvalidInput(f"{name}: the DCM gain k must be finite and > 1 (the DCM error decays at ω(k − 1)), got {gain}")
        if not (np.isfinite(max_offset) and max_offset > 0):
            raise InvalidInput(f"{name}: max_offset must be finite and > 0 m, got {max_offset}")
        self.omega = float(np.sqrt(GRAVITY / height))
        self.dt, self.gain, self.max_offset = float(dt), float(gain), float(max_offset)
        vector = self.DeclareVectorInputPort
        self.com_reference = vector("com_reference", 3)
        self.com_velocity_reference = vector("com_velocity_reference", 3)
        self.measured_com = vector("measured_com", 3)
        self.measured_com_velocity = vector("measured_com_velocity", 3)
        self._state = self.DeclareDiscreteState(4)  # (δ, δ̇), xy each
        self.DeclarePeriodicDiscreteUpdateEvent(self.dt, 0.0, self._update)
        self.DeclareVectorOutputPort("com", 3, self._calc_com, {self.all_input_ports_ticket(), self.xd_ticket()})
        self.DeclareVectorOutputPort("com_velocity", 3, self._calc_com_velocity, {self.all_input_ports_ticket(), self.xd_ticket()})
        self.DeclareVectorOutputPort("offset", 2, lambda c, o: o.SetFromVector(self._offset(c)[0]), {self.xd_ticket()})
        self.DeclareVectorOutputPort("dcm_error", 2, self._calc_dcm_error, {self.all_input_ports_ticket()})

    def _offset(self, context: Context) -> tuple[np.ndarray, np.ndarray]:
        x = context.get_discrete_state(self._state).get_value()
        return x[:2], x[2:]

    def _inputs(self, context: Context) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]:
        return ((self.com_reference.Eval(context)[:2], self.com_velocity_reference.Eval(context)[:2]),
                (self.measured_com.Eval(context)[:2], self.measured_com_velocity.Eval(context)[:2]))

    def _update(self, context: Context, state: DiscreteValues) -> None:
        reference, measured = self._inputs(context)
        offset, rate = self._offset(context)
        if self.law == "com":
            rate = com_feedback_rate(reference[0], measured[0], self.gain)
            offset = np.clip(offset + self.dt * rate, -self.max_offset, self.max_offset)
        else:
            acceleration = offset_acceleration(reference, measured, self.omega, self.gain)
            offset, rate = step_offset(offset, rate, acceleration, self.dt, self.max_offset)
        state.get_mutable_vector(self._state).SetFromVector(np.concatenate([offset, rate]))

    def _calc_com(self, context: Context, output: BasicVector) -> None:
        c = np.array(self.com_reference.Eval(context), dtype=float)
        c[:2] += self._offset(context)[0]
        output.SetFromVector(c)

    def _calc_com_velocity(self, context: Context, output: BasicVector) -> None:
        v = np.array(self.com_velocity_reference.Eval(context), dtype=float)
        v[:2] += self._offset(context)[1]
        output.SetFromVector(v)

    def _calc_dcm_error(self, context: Context, output: BasicVector) -> None:
        (c_r, v_r), (c_m, v_m) = self._inputs(context)
        output.SetFromVector(dcm(c_m, v_m, self.omega) - dcm(c_r, v_r, self.omega))
