"""The simulated TALOS' actuators: the plant's PD controllers and their references.

Every actuator is PD-controlled by the plant (as ros_control's position controllers), with
``kp = stiffness · effort_limit`` and ``kd = damping · kp`` (defaults 30 rad⁻¹ and 0.05 s), set after
``Finalize()`` and checked: a missing or non-positive gain is an error, never a silent fall. Torques
are saturated at the URDF effort limits by the plant. The SoT device's ``q`` (and its velocity
command) become the PD references of the actuated joints (:class:`DesiredState`).
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import PdControllerGains
from pydrake.systems.framework import BasicVector, Context, DiagramBuilder, LeafSystem, OutputPort
from pydrake.systems.primitives import ZeroOrderHold

from ..atomic import check_new_names, check_vector_port
from ..exceptions import InvalidInput, SotError, check_name, check_number, finite_number

#: Accepted ranges of the PD gains: stiffness (rad⁻¹, kp = stiffness · effort limit) and damping (s).
STIFFNESS_RANGE = (1e-3, 1e4)
DAMPING_RANGE = (0.0, 10.0)


def check_pd_gain_values(stiffness: float, damping: float) -> None:
    """:class:`InvalidInput` unless ``stiffness`` and ``damping`` are numbers in ``STIFFNESS_RANGE``
    (rad⁻¹) and ``DAMPING_RANGE`` (s)."""
    ok = finite_number(stiffness) and finite_number(damping)
    if not (ok and STIFFNESS_RANGE[0] <= stiffness <= STIFFNESS_RANGE[1] and DAMPING_RANGE[0] <= damping <= DAMPING_RANGE[1]):
        raise InvalidInput(
            f"PD gains: stiffness in [{STIFFNESS_RANGE[0]}, {STIFFNESS_RANGE[1]}] rad⁻¹ and damping in "
            f"[{DAMPING_RANGE[0]}, {DAMPING_RANGE[1]}] s, got {stiffness!r}, {damping!r}")


def set_pd_gains(plant: MultibodyPlant, stiffness: float, damping: float) -> None:
    """``kp = stiffness · effort_limit``, ``kd = damping · kp`` on every actuator, then
    :func:`check_pd_gains`."""
    check_pd_gain_values(stiffness, damping)
    for index in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(index)
        kp = stiffness * actuator.effort_limit()
        actuator.set_controller_gains(PdControllerGains(p=kp, d=damping * kp))
    check_pd_gains(plant)


def check_pd_gains(plant: MultibodyPlant) -> None:
    """Every actuator must have a PD controller with finite ``kp > 0`` and ``kd ≥ 0`` (else the
    plant ignores its desired state for that joint and the robot falls without a word)."""
    bad = []
    for index in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(index)
        if not actuator.has_controller():
            bad.append(f"{actuator.name()}: no PD controller")
            continue
        gains = actuator.get_controller_gains()
        if not (np.isfinite(gains.p) and gains.p > 0 and np.isfinite(gains.d) and gains.d >= 0):
            bad.append(f"{actuator.name()}: kp = {gains.p}, kd = {gains.d}")
    if bad:
        raise SotError("PD gains not set on every actuator: " + "; ".join(bad))


class DesiredState(LeafSystem):
    """The PD references: inputs ``position`` (the device's ``q``) and ``velocity`` (the solver's
    ``v``); output ``desired_state`` = ``(q, v)`` of the actuated joints, in actuator order."""

    def __init__(self, robot, name: str = "desired_state"):
        LeafSystem.__init__(self)
        self.set_name(name)
        self._q, self._v = robot.actuated_q, robot.actuated_v
        self.position = self.DeclareVectorInputPort("position", robot.plant.num_positions())
        self.velocity = self.DeclareVectorInputPort("velocity", robot.plant.num_velocities())
        self.DeclareVectorOutputPort("desired_state", 2 * len(self._q), self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(np.concatenate([self.position.Eval(context)[self._q], self.velocity.Eval(context)[self._v]]))


def hold_one_tick(builder: DiagramBuilder, port: OutputPort, name: str, dt: float) -> OutputPort:
    """``port``'s value held one tick (a Drake ``ZeroOrderHold`` named ``name`` sampling it every
    ``dt``). The plant's step (sampled outputs) is applied before the diagram's discrete updates of
    its instant: when the solver's inputs change with that step (the plan's update, a closed loop),
    the servos take the velocity the device integrated at the last tick, held, rather than a command
    of their own, and the stack is solved once per tick (the held value is 0 before the first).

    Refused with :class:`InvalidInput` before anything is added: a ``builder`` that is not a
    ``DiagramBuilder`` (:class:`SotError` once built), a ``name`` empty or already a system's of the
    builder, a ``port`` that is not a vector-valued output port of a system of the builder, a ``dt``
    out of [1e-6, 1] s."""
    if not isinstance(builder, DiagramBuilder):
        raise InvalidInput(f"hold_one_tick: builder must be a DiagramBuilder, got {type(builder).__name__}")
    check_name("hold_one_tick: name", name)
    check_new_names(builder, [name], what="hold_one_tick")
    check_number(f"{name}: dt (s)", dt, 1e-6, 1.0)
    check_vector_port(f"hold_one_tick {name!r}: port", builder, port)
    hold = builder.AddNamedSystem(name, ZeroOrderHold(dt, port.size()))
    builder.Connect(port, hold.get_input_port())
    return hold.get_output_port()
