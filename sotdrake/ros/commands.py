"""Towards a real robot: the SoT's commands as ROS 2 messages, and a watchdog on the joint states.

* :class:`JointCommandPublisher` (kinematic SoT): the joint position references of the device, as a
  ``std_msgs/Float64MultiArray`` for a ``forward_command_controller`` (its ``commands`` topic; the
  joints in the controller's order).
* :class:`TorqueCommandPublisher` (``SolverDyn``): what a linear-feedback controller applies,
  ``τ = τ_ff + Kp (q_ref − q) + Kd (v_ref − v)``: the feed-forward torque, the reference state and
  the PD gains, each a ``std_msgs/Float64MultiArray`` per actuated joint, in actuator order.
* :class:`JointStateWatchdog`: when no joint state arrived within ``timeout`` s (the age output of
  :class:`~.subscribe.RosSubscribe`), the command is held at its last value, and a warning says so
  (another when they come back).
"""

from __future__ import annotations

import logging
from collections.abc import Sequence

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import BasicVector, Context, DiscreteValues, EventStatus, LeafSystem
from std_msgs.msg import Float64MultiArray

from ..exceptions import InvalidInput, check_count, check_finite, check_name, check_number
from .messages import check_topic, to_message
from .node import RosNode
from .publish import _Triggered, joint_coordinates

log = logging.getLogger("sotdrake.ros")


def _joint_indices(plant: MultibodyPlant, joints: Sequence[str] | None) -> tuple[list[str], np.ndarray]:
    names, indices = joint_coordinates(plant)
    if joints is None:
        return names, indices
    if isinstance(joints, str) or not isinstance(joints, Sequence) or not joints \
            or not all(isinstance(j, str) for j in joints) or len(set(joints)) != len(joints):
        raise InvalidInput(f"joints: a non-empty list of distinct joint names, got {joints!r:.100}")
    where = dict(zip(names, indices, strict=True))
    unknown = [j for j in joints if j not in where]
    if unknown:
        raise InvalidInput(f"joints: unknown joints {unknown}: one-coordinate joints of the model are {names}")
    return list(joints), np.array([where[j] for j in joints], dtype=int)


class JointCommandPublisher(_Triggered):
    """Joint position references for a ``forward_command_controller``.

    Inputs: ``position`` (``q``, size nq; rad or m).
    Outputs: none; publishes the positions of ``joints`` (default: every one-coordinate joint, plant
    order) on ``topic`` at :meth:`trigger`'s rate. A ``topic`` ROS refuses, unknown, repeated or no
    ``joints``: :class:`InvalidInput` naming the argument.
    """

    def __init__(self, plant: MultibodyPlant, topic: str = "/forward_position_controller/commands",
                 joints: Sequence[str] | None = None, name: str = "ros_joint_commands", node: RosNode | None = None):
        super().__init__(name, node)
        self.topic = check_topic(topic)
        self.joints, self.indices = _joint_indices(plant, joints)
        self.position = self.DeclareVectorInputPort("position", plant.num_positions())
        self.publisher = self._publisher(Float64MultiArray, topic, 10)

    def send(self, context: Context) -> None:
        self.publisher.publish(to_message("vector", self.position.Eval(context)[self.indices]))


class TorqueCommandPublisher(_Triggered):
    """``SolverDyn``'s command for a linear-feedback controller: τ_ff, the reference state, PD gains.

    Inputs: ``torque`` (τ_ff, size na, N·m), ``state`` (the reference ``(q, v)``, size nq + nv).
    Outputs: none; publishes on ``<prefix>/feedforward`` (na values, N·m), ``<prefix>/reference``
    (the actuated joints' q then v: 2·na values, rad and rad/s) and ``<prefix>/gains`` (Kp then Kd:
    2·na values, N·m/rad and N·m·s/rad), all in actuator order. ``kp`` and ``kd`` (one or na finite
    numbers ≥ 0) and a ``prefix`` ROS refuses are :class:`InvalidInput` naming the argument; nothing
    is published then.
    """

    def __init__(self, plant: MultibodyPlant, kp: float | Sequence[float], kd: float | Sequence[float],
                 prefix: str = "/sot/command", name: str = "ros_torque_commands", node: RosNode | None = None):
        super().__init__(name, node)
        na = plant.num_actuators()
        if na == 0:
            raise InvalidInput("the plant has no actuator: nothing to command in torque")
        joints = [plant.get_joint_actuator(i).joint() for i in plant.GetJointActuatorIndices()]
        self.joints = [j.name() for j in joints]
        self.q_indices = np.array([j.position_start() for j in joints], dtype=int)
        self.v_indices = np.array([plant.num_positions() + j.velocity_start() for j in joints], dtype=int)
        gains = []
        for label, gain in (("kp", kp), ("kd", kd)):
            value = check_finite(f"{name}: {label} (one or {na} numbers ≥ 0)", gain)
            value = np.broadcast_to(value, (na,)) if value.ndim == 0 else value
            if value.shape != (na,) or np.any(value < 0):
                raise InvalidInput(f"{name}: {label} must be one or {na} finite numbers ≥ 0, got {gain!r:.200}")
            gains.append(value)
        self.gains = np.concatenate(gains)
        prefix = check_topic(prefix).rstrip("/")
        self.torque = self.DeclareVectorInputPort("torque", na)
        self.state = self.DeclareVectorInputPort("state", plant.num_positions() + plant.num_velocities())
        self.publishers = {}
        try:
            for part in ("feedforward", "reference", "gains"):
                self.publishers[part] = self._publisher(Float64MultiArray, f"{prefix}/{part}", 10, "prefix")
        except BaseException:
            self.release()
            raise

    def send(self, context: Context) -> None:
        x = self.state.Eval(context)
        self.publishers["feedforward"].publish(to_message("vector", self.torque.Eval(context)))
        self.publishers["reference"].publish(to_message("vector", np.concatenate([x[self.q_indices], x[self.v_indices]])))
        self.publishers["gains"].publish(to_message("vector", self.gains))


class JointStateWatchdog(LeafSystem):
    """Holds the command when the joint states stop coming.

    Inputs: ``command`` (size n), ``age`` (s since the last joint state: a ``RosSubscribe``
    ``<signal>_age`` output; ``inf`` before the first).
    Outputs: ``command`` (size n): the input while ``age ≤ timeout``, else the last command passed
    while the joint states were fresh (``initial`` before any); ``healthy`` (1: passing, 0: holding).
    """

    def __init__(self, size: int, timeout: float, dt: float, initial: Sequence[float] | None = None,
                 name: str = "joint_state_watchdog"):
        LeafSystem.__init__(self)
        self.set_name(check_name("name", name))
        size = check_count(f"{name}: size", size)
        timeout = check_number(f"{name}: timeout", timeout, 1e-9, 1e6, " s")
        dt = check_number(f"{name}: dt", dt, 1e-9, 1e6, " s")
        held = np.zeros(size) if initial is None else check_finite(f"{name}: initial", initial).ravel()
        if held.shape != (size,) or not np.all(np.isfinite(held)):
            raise InvalidInput(f"{name}: initial must be {size} finite numbers, got {initial!r}")
        self.timeout = float(timeout)
        self.command = self.DeclareVectorInputPort("command", size)
        self.age = self.DeclareVectorInputPort("age", 1)
        self._held = self.DeclareDiscreteState(np.append(held, 1.0))  # the held command, then 'healthy'
        self.DeclarePeriodicDiscreteUpdateEvent(dt, 0.0, self._update)
        self.DeclareVectorOutputPort("command", size, self._output)
        self.DeclareVectorOutputPort("healthy", 1, lambda c, o: o.SetAtIndex(0, float(self.fresh(c))))

    def fresh(self, context: Context) -> bool:
        return bool(self.age.Eval(context)[0] <= self.timeout)

    def _update(self, context: Context, state: DiscreteValues) -> EventStatus:
        previous = context.get_discrete_state(self._held).get_value()
        fresh = self.fresh(context)
        if fresh:
            state.set_value(self._held, np.append(self.command.Eval(context), 1.0))
        else:
            state.set_value(self._held, np.append(previous[:-1], 0.0))
        if fresh != bool(previous[-1]):
            if fresh:
                log.warning("%s: t = %.3f s: joint states are back: passing the command", self.get_name(), context.get_time())
            else:
                log.warning("%s: t = %.3f s: no joint state for %.3g s (> %g s): holding the command", self.get_name(),
                            context.get_time(), self.age.Eval(context)[0], self.timeout)
        return EventStatus.Succeeded()

    def _output(self, context: Context, output: BasicVector) -> None:
        if self.fresh(context):
            output.SetFromVector(self.command.Eval(context))
        else:
            output.SetFromVector(context.get_discrete_state(self._held).get_value()[:-1])
