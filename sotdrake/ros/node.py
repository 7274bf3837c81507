"""rclpy in this process: one context, one node, an executor spinning in a daemon thread.

The pip wheels of ROS 2 Jazzy need no setup file: ``rclpy`` finds its libraries and message types
by itself and uses Fast DDS (``rmw_fastrtps_cpp``) unless ``RMW_IMPLEMENTATION`` says otherwise.
``ROS_DOMAIN_ID`` and ``ROS_AUTOMATIC_DISCOVERY_RANGE`` (``LOCALHOST`` keeps the traffic on this
host) are read from the environment when the node is created, as by any ROS 2 program.
"""

from __future__ import annotations

import threading

import rclpy
from rclpy.context import Context
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node

from ..exceptions import InvalidInput


class RosNode:
    """A node with its own rclpy context and an executor thread (callbacks run there, never in the
    simulation thread); :meth:`close` ends both."""

    def __init__(self, name: str = "sotdrake"):
        if not name or not name.replace("_", "a").isalnum() or name[0].isdigit():
            raise InvalidInput(f"a ROS node name is letters, digits and '_' (not first a digit), got {name!r}")
        self.context = Context()
        rclpy.init(context=self.context)
        self.node: Node = rclpy.create_node(name, context=self.context)
        self.executor = MultiThreadedExecutor(num_threads=2, context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, name=f"ros-{name}", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            self.executor.spin()
        except Exception:  # the context was shut down under the executor
            pass

    def close(self) -> None:
        if self.context.ok():
            self.executor.shutdown(timeout_sec=1.0)
            self.node.destroy_node()
            rclpy.shutdown(context=self.context)
        self._thread.join(timeout=2.0)


_shared: RosNode | None = None
_lock = threading.Lock()


def ros_node() -> RosNode:
    """The process's shared node (``sotdrake``), created on first use."""
    global _shared
    with _lock:
        if _shared is None or not _shared.context.ok():
            _shared = RosNode("sotdrake")
        return _shared


def shutdown() -> None:
    """Close the shared node (a new one is created on the next :func:`ros_node`)."""
    global _shared
    with _lock:
        if _shared is not None:
            _shared.close()
            _shared = None
