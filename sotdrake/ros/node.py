"""rclpy in this process: one context, one node, an executor spinning in a daemon thread.

The pip wheels of ROS 2 Jazzy need no setup file: ``rclpy`` finds its libraries and message types
by itself and uses Fast DDS (``rmw_fastrtps_cpp``) unless ``RMW_IMPLEMENTATION`` says otherwise.
``ROS_DOMAIN_ID`` and ``ROS_AUTOMATIC_DISCOVERY_RANGE`` (``LOCALHOST`` keeps the traffic on this
host) are read from the environment when the node is created, as by any ROS 2 program.

Messages stamped with simulated time come with that time on ``/clock`` (:meth:`RosNode.publish_clock`,
``rosgraph_msgs/Clock``), so that a node run with ``use_sim_time`` follows the simulation.
"""

from __future__ import annotations

import logging
import re
import threading
from typing import Any

import rclpy
from builtin_interfaces.msg import Time
from pydrake.systems.framework import LeafSystem
from rclpy.context import Context
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node

from ..atomic import in_built_diagram
from ..exceptions import InvalidInput, SotError

log = logging.getLogger("sotdrake.ros")

#: The topic of simulated time (``rosgraph_msgs/Clock``), as ROS 2's ``use_sim_time`` reads it.
CLOCK_TOPIC = "/clock"
#: The longest node name ROS 2 takes.
MAX_NODE_NAME = 255
_NODE_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def check_node_name(name: object) -> str:
    """``name`` if it is a ROS node name (a str of ASCII letters, digits and ``_``, not first a
    digit, at most :data:`MAX_NODE_NAME` characters), else :class:`InvalidInput`."""
    if not isinstance(name, str) or len(name) > MAX_NODE_NAME or not _NODE_NAME.fullmatch(name):
        raise InvalidInput(f"name: a ROS node name is 1 to {MAX_NODE_NAME} ASCII letters, digits and '_' "
                           f"(not first a digit), got {name!r:.100}")
    return name


def check_not_built(system: LeafSystem, what: str) -> None:
    """:class:`SotError` if ``system`` is in a diagram (which is built: its contexts would not have
    a port added now)."""
    if in_built_diagram(system):
        raise SotError(f"{system.get_name()}: cannot add {what}: the diagram is already built "
                       "(add signals before builder.Build())")


#: The nodes of this process that are open, by name (two nodes of one name confuse ROS' graph).
_open: dict[str, RosNode] = {}


class RosNode:
    """A node with its own rclpy context and an executor thread (callbacks run there, never in the
    simulation thread); :meth:`close` ends both. ``name`` is checked (:func:`check_node_name`), and
    refused while another node of this process has it (:func:`ros_node` shares one), before
    anything is created."""

    def __init__(self, name: str = "sotdrake"):
        self.name = check_node_name(name)
        other = _open.get(name)
        if other is not None and other.is_open():
            raise InvalidInput(f"name: a ROS node named {name!r} is already open in this process "
                               "(close it first, or share it with sotdrake.ros.ros_node(name))")
        self.context = Context()
        rclpy.init(context=self.context)
        try:
            self.node: Node = rclpy.create_node(name, context=self.context)
        except BaseException:
            rclpy.shutdown(context=self.context)
            raise
        self._clock: Any = None  # the /clock publisher, made on first use
        self._clock_ns: int | None = None  # the time last published on /clock (ns)
        self._clock_lock = threading.Lock()
        self.executor = MultiThreadedExecutor(num_threads=2, context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, name=f"ros-{name}", daemon=True)
        self._thread.start()
        _open[name] = self

    def _spin(self) -> None:
        """Spin until the node is closed: a callback's exception is logged, and spinning goes on
        (the node keeps answering)."""
        while self.context.ok():
            try:
                self.executor.spin()
                return  # (the executor was shut down)
            except Exception:
                if not self.context.ok():  # the context was shut down under the executor
                    return
                log.exception("%s: a ROS callback raised; the node goes on", self.name)

    def clock_publisher(self) -> Any:
        """This node's publisher on :data:`CLOCK_TOPIC` (``rosgraph_msgs/Clock``, reliable, depth
        10), made on first use: a system that stamps messages makes it when it is made, so that
        readers match it before the first tick."""
        from rosgraph_msgs.msg import Clock  # (comes with rclpy; imported here: the docs build without ROS)

        with self._clock_lock:
            if self._clock is None:
                self._clock = self.node.create_publisher(Clock, CLOCK_TOPIC, 10)
            return self._clock

    def publish_clock(self, stamp: Time) -> bool:
        """Publish ``stamp`` (simulated time) on :data:`CLOCK_TOPIC` unless it is the time this
        node published last (several systems stamping one tick: one message); returns whether it
        published. Systems call it before the messages they stamp with that time."""
        from rosgraph_msgs.msg import Clock

        publisher = self.clock_publisher()
        ns = stamp.sec * 1_000_000_000 + stamp.nanosec
        with self._clock_lock:
            if ns == self._clock_ns:
                return False
            publisher.publish(Clock(clock=stamp))
            self._clock_ns = ns
        return True

    def is_open(self) -> bool:
        """Whether this node is open (not shut down or closed)."""
        return bool(self.context.ok())

    def check_open(self, who: str) -> None:
        """:class:`SotError` naming ``who`` if this node is closed (``shutdown()``, :meth:`close`)."""
        if not self.context.ok():
            raise SotError(f"{who}: the ROS node it was made with ({self.name}) is shut down "
                           "(sotdrake.ros.shutdown() or close()); build the diagram again")

    def close(self) -> None:
        if self.context.ok():
            self.executor.shutdown(timeout_sec=1.0)
            self.node.destroy_node()
            rclpy.shutdown(context=self.context)
        self._thread.join(timeout=2.0)
        if _open.get(self.name) is self:
            del _open[self.name]


_shared: dict[str, RosNode] = {}
_lock = threading.Lock()


def ros_node(name: str = "sotdrake") -> RosNode:
    """The process's shared node named ``name`` (default ``sotdrake``), created on first use."""
    with _lock:
        node = _shared.get(name)
        if node is None or not node.context.ok():
            if node is not None:
                node.close()
            node = _shared[name] = RosNode(name)
        return node


def shutdown() -> None:
    """Close the shared nodes (a new one is created on the next :func:`ros_node`)."""
    with _lock:
        for node in _shared.values():
            node.close()
        _shared.clear()
