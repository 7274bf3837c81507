"""The SoT's ``RosPublish`` as a Drake system, the joint states, and a builder helper.

The seed's three lines::

    ros_publish_state = RosPublish("ros_publish_state")
    ros_publish_state.add("vector", "state", "/sot_control/state")
    plug(robot.device.state, ros_publish_state.state)
    robot.device.after.addDownsampledSignal("ros_publish_state.trigger", 100)

read here (a Drake vector port needs its size, given once)::

    ros_publish_state = robot.add(RosPublish("ros_publish_state"))
    ros_publish_state.add("vector", "state", "/sot_control/state", size=robot.model.plant.num_positions())
    builder.Connect(robot.device.GetOutputPort("state"), ros_publish_state.GetInputPort("state"))
    ros_publish_state.trigger(every=100, dt=robot.dt)

or in one call, with ``/joint_states`` too: ``add_ros_publisher(robot)``.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from builtin_interfaces.msg import Time
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Context, EventStatus, InputPort, LeafSystem
from sensor_msgs.msg import JointState

from ..exceptions import InvalidInput, check_count, check_name, finite_number
from ..robot import Robot
from .messages import check_topic, check_topic_type, message_type, port_size, to_message
from .node import RosNode, check_not_built, ros_node


def stamp(t: float) -> Time:
    """A ROS time from simulated seconds (the stamps of the messages published here: simulated time,
    published on ``/clock`` with them)."""
    nanoseconds = round(t * 1e9)
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


class _Triggered(LeafSystem):
    """A system that publishes every ``every`` ticks of ``dt`` (``addDownsampledSignal``)."""

    def __init__(self, name: str, node: RosNode | None):
        LeafSystem.__init__(self)
        self.set_name(check_name("name", name))
        self.ros = node or ros_node()
        self.period: float | None = None
        self.every, self.dt = 0, 0.0
        self.published = 0
        self.publish_seconds = 0.0  # wall time spent publishing
        self._publishers: list[Any] = []

    def _publisher(self, message: type, topic: str, depth: int, argument: str = "topic") -> Any:
        """A ROS publisher of ``message`` on ``topic`` (checked first), owned by this system; a
        topic ROS refuses is an :class:`InvalidInput` naming ``argument``."""
        check_topic(topic)
        try:
            check_topic_type(self.ros.node, topic, message)
        except InvalidInput as error:
            raise InvalidInput(f"{self.get_name()}: {argument}: {error}") from None
        try:
            publisher = self.ros.node.create_publisher(message, topic, depth)
        except Exception as error:  # (rclpy's own errors: a substitution it cannot expand, a reserved topic …)
            raise InvalidInput(f"{self.get_name()}: {argument}: ROS refused the topic {topic!r} for "
                               f"{message.__name__}: {error}") from None
        self._publishers.append(publisher)
        return publisher

    def release(self) -> None:
        """Destroy this system's ROS publishers (it is not to be used: a refused construction)."""
        if self.ros.context.ok():
            for publisher in self._publishers:
                self.ros.node.destroy_publisher(publisher)
        self._publishers.clear()

    def trigger(self, every: int, dt: float) -> float:
        """Publish every ``every`` ticks of ``dt`` s of simulated time (from t = 0: at t = 0,
        ``every·dt``, …) — the seed's ``addDownsampledSignal(…, every)``; returns the period (s)."""
        if self.period is not None:
            raise InvalidInput(f"{self.get_name()}: the trigger is already set (every {self.period} s)")
        every = check_count(f"{self.get_name()}: every (ticks)", every, high=2**31)
        if not finite_number(dt) or not dt > 0:
            raise InvalidInput(f"{self.get_name()}: dt must be a finite number > 0 (s), got {dt!r:.100}")
        self.period, self.every, self.dt = every * float(dt), every, float(dt)
        # An event every tick, publishing every ``every``-th: tick times are k·dt exactly as the
        # device's, where k·(every·dt) would drift off the grid by round-off (0.1·3 > 0.3).
        self.DeclarePeriodicPublishEvent(self.dt, 0.0, self._on_tick)
        return self.period

    def _on_tick(self, context: Context) -> EventStatus:
        if round(context.get_time() / self.dt) % self.every:
            return EventStatus.DidNothing()
        self.ros.check_open(self.get_name())
        start = time.perf_counter()
        self.send(context)
        self.publish_seconds += time.perf_counter() - start
        self.published += 1
        return EventStatus.Succeeded()

    def send(self, context: Context) -> None:  # pragma: no cover - overridden
        raise NotImplementedError


@dataclass
class _Signal:
    kind: str
    topic: str
    port: InputPort
    shape: tuple[int, int] | None
    publisher: Any


class RosPublish(_Triggered):
    """Publishes input signals on ROS 2 topics every N ticks (the SoT's ``RosPublish``).

    Inputs: one per :meth:`add`, named as the signal (``state``), sized by its kind (see
    :mod:`.messages`; SI units as the signal it is plugged to).
    Outputs: none. Messages go out on :meth:`trigger`'s period of simulated time.
    """

    def __init__(self, name: str = "ros_publish", node: RosNode | None = None, depth: int = 10):
        super().__init__(name, node)
        self.depth = check_count(f"{name}: depth (the queue depth)", depth)
        self.signals: dict[str, _Signal] = {}

    def add(self, kind: str, signal: str, topic: str, size: int | None = None,
            shape: Sequence[int] | None = None) -> InputPort:
        """An input port ``signal`` of ``kind`` published on ``topic`` (``size`` for a ``vector``,
        ``shape=(rows, cols)`` for a ``matrix``, at most ``MAX_COUNT`` numbers); returns the port.

        Checked before anything is created (:class:`InvalidInput`, nothing added): the signal is a
        new identifier, the kind and its size, the topic (ROS's refusal too); :class:`SotError`
        once this system is in a built diagram."""
        check_not_built(self, f"the signal {signal!r:.60}")
        if not isinstance(signal, str) or not signal.isidentifier():
            raise InvalidInput(f"{self.get_name()}: a signal name is an identifier, got {signal!r}")
        if signal in self.signals:
            raise InvalidInput(f"{self.get_name()}: signal {signal!r} already added (topic {self.signals[signal].topic})")
        n = port_size(kind, size, shape)
        check_topic(topic)
        if self.HasInputPort(signal):
            raise InvalidInput(f"{self.get_name()}: an input named {signal!r} exists already")
        # (the publisher after every check, before the port: a topic ROS refuses leaves no port behind)
        publisher = self._publisher(message_type(kind), topic, self.depth)
        try:
            port = self.DeclareVectorInputPort(signal, n)
        except BaseException:
            self._publishers.remove(publisher)
            self.ros.node.destroy_publisher(publisher)
            raise
        self.signals[signal] = _Signal(kind, topic, port, (int(shape[0]), int(shape[1])) if shape is not None else None, publisher)
        return port

    def send(self, context: Context) -> None:
        for signal in self.signals.values():
            if signal.port.HasValue(context):
                signal.publisher.publish(to_message(signal.kind, signal.port.Eval(context), signal.shape))


def joint_coordinates(plant: MultibodyPlant) -> tuple[list[str], np.ndarray]:
    """The one-coordinate joints' names and their indices in ``q`` (plant order)."""
    joints = [plant.get_joint(i) for i in plant.GetJointIndices()]
    ones = [j for j in joints if j.num_positions() == 1]
    return [j.name() for j in ones], np.array([j.position_start() for j in ones], dtype=int)


class JointStatePublisher(_Triggered):
    """``sensor_msgs/JointState`` of the robot's one-coordinate joints, stamped with simulated time.

    Inputs: ``state`` (``q``, size nq; rad or m per joint).
    Outputs: none. ``name`` and ``position`` per joint (velocity and effort empty).
    With ``clock`` (the default), each message's time is first published on ``/clock``
    (``rosgraph_msgs/Clock``, once per tick for every publisher of the node,
    :meth:`~.node.RosNode.publish_clock`): a node with ``use_sim_time`` reads the stamps in its time.
    A ``topic`` ROS refuses is an :class:`InvalidInput` naming it.
    """

    def __init__(self, plant: MultibodyPlant, topic: str = "/joint_states", name: str = "ros_publish_joint_states",
                 node: RosNode | None = None, depth: int = 10, clock: bool = True):
        super().__init__(name, node)
        depth = check_count(f"{name}: depth (the queue depth)", depth)
        if not isinstance(clock, bool):
            raise InvalidInput(f"{name}: clock is True or False, got {clock!r:.60}")
        self.clock = clock
        self.topic = check_topic(topic)
        self.names, self.indices = joint_coordinates(plant)
        self.state = self.DeclareVectorInputPort("state", plant.num_positions())
        self.publisher = self._publisher(JointState, topic, depth)
        if clock:
            self.ros.clock_publisher()

    def message(self, context: Context) -> JointState:
        q = self.state.Eval(context)
        message = JointState()
        message.header.stamp = stamp(context.get_time())
        message.name = self.names
        message.position = q[self.indices].tolist()
        return message

    def send(self, context: Context) -> None:
        message = self.message(context)
        if self.clock:
            self.ros.publish_clock(message.header.stamp)
        self.publisher.publish(message)


@dataclass
class RosPublishers:
    """What :func:`add_ros_publisher` added."""

    state: RosPublish
    joint_states: JointStatePublisher | None


def ticks_of(period: float, dt: float) -> int:
    """``period`` (s) as a whole number of ticks of ``dt`` (s); a period that is not a multiple of
    ``dt`` (to 1e-9 of a tick) raises :class:`~sotdrake.exceptions.InvalidInput`."""
    if not finite_number(period) or period <= 0:
        raise InvalidInput(f"publish period must be a number > 0 (s), got {period!r}")
    ticks = round(period / dt)
    if ticks < 1 or abs(period / dt - ticks) > 1e-9:
        raise InvalidInput(f"publish period {period!r} s is not a whole number of ticks of {dt} s")
    return int(ticks)


def add_ros_publisher(robot: Robot, topic: str = "/sot_control/state", joint_states: str | None = "/joint_states",
                      every: int | None = None, node: RosNode | None = None, period: float | None = None) -> RosPublishers:
    """``robot.device.state`` on ``topic`` (``std_msgs/Float64MultiArray``, system
    ``ros_publish_state``) and the joints on ``joint_states`` (None: not published), every
    ``every`` ticks of ``robot.dt`` (the seed's ``addDownsampledSignal(…, every)``; default 100)
    or every ``period`` s (a whole number of ticks); not both.

    Everything is checked, and the ROS publishers made, before any system is added: a refusal
    (:class:`InvalidInput`: the rate, a topic, ROS refusing one, the two topics equal; a built
    diagram: :class:`SotError`) leaves the builder as it was."""
    if every is not None and period is not None:
        raise InvalidInput(f"give the publishing rate as every (ticks) or as period (s), not both: every={every!r}, period={period!r}")
    if period is not None:
        every = ticks_of(period, robot.dt)
    every = 100 if every is None else every
    every = check_count("add_ros_publisher: every (ticks)", every, high=2**31)
    check_topic(topic)
    if joint_states is not None:
        check_topic(joint_states)
        if joint_states == topic:
            raise InvalidInput(f"add_ros_publisher: joint_states and topic must be two topics, both are {topic!r}")
    robot.check_new_names(["ros_publish_state"] + ["ros_publish_joint_states"] * (joint_states is not None))
    q = robot.device.GetOutputPort("state")
    made: list[_Triggered] = []
    try:  # (the systems, their publishers made, before any is added)
        state = RosPublish("ros_publish_state", node)
        made.append(state)
        state.add("vector", "state", topic, size=q.size())
        state.trigger(every, robot.dt)
        joints = None
        if joint_states is not None:
            joints = JointStatePublisher(robot.model.plant, joint_states, node=node)
            made.append(joints)
            joints.trigger(every, robot.dt)
    except BaseException:
        for system in made:
            system.release()
        raise
    robot.builder.Connect(q, robot.add(state).GetInputPort("state"))
    if joints is not None:
        robot.builder.Connect(q, robot.add(joints).state)
    return RosPublishers(state, joints)
