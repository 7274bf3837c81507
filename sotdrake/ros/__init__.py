"""ROS 2 for a sotdrake diagram: the SoT's ``RosPublish``, topics in, ``run_command`` and
``start_dynamic_graph``, bags (an optional extra: ``pip install ".[ros2]"``).

One concept a module:

* :mod:`.node`: rclpy in this process (one context, one node, an executor thread);
* :mod:`.messages`: the SoT's signal types (``vector``, ``matrix``, ``matrixHomo``, ``double``) as messages;
* :mod:`.publish`: :class:`RosPublish`, :class:`JointStatePublisher`, :func:`add_ros_publisher`;
* :mod:`.subscribe`: :class:`RosSubscribe` (the last value of a topic, its age, a stated default);
* :mod:`.services`: ``run_command`` and ``start_dynamic_graph`` on a live run (:func:`run_ros`);
* :mod:`.commands`: commands for a real robot's controllers, a joint-state watchdog;
* :mod:`.client`: the other side of the services, for a script in another process;
* :mod:`.bag`: rosbag2 (MCAP) files of a run's trace.

Importing this package without rclpy raises an ImportError that names the install line.
"""

from __future__ import annotations

INSTALL = 'pip install ".[ros2]"'

try:
    import rclpy  # noqa: F401
except ImportError as error:  # pragma: no cover - depends on the environment
    raise ImportError(f"sotdrake.ros needs ROS 2's Python client (rclpy): {INSTALL}") from error

from .bag import read_bag, write_bag, write_trace_bag  # noqa: E402
from .client import RunCommandClient, wait_for_services  # noqa: E402
from .commands import JointCommandPublisher, JointStateWatchdog, TorqueCommandPublisher  # noqa: E402
from .messages import KINDS, to_message  # noqa: E402
from .node import RosNode, ros_node, shutdown  # noqa: E402
from .publish import JointStatePublisher, RosPublish, add_ros_publisher, joint_coordinates  # noqa: E402
from .services import RUN_COMMAND_REQUEST, RUN_COMMAND_RESPONSE, START_SERVICE, RosServices, run_ros  # noqa: E402
from .subscribe import RosSubscribe  # noqa: E402

__all__ = [
    "INSTALL",
    "KINDS",
    "RUN_COMMAND_REQUEST",
    "RUN_COMMAND_RESPONSE",
    "START_SERVICE",
    "JointCommandPublisher",
    "JointStatePublisher",
    "JointStateWatchdog",
    "RosNode",
    "RosPublish",
    "RosServices",
    "RosSubscribe",
    "RunCommandClient",
    "TorqueCommandPublisher",
    "add_ros_publisher",
    "joint_coordinates",
    "read_bag",
    "ros_node",
    "run_ros",
    "shutdown",
    "to_message",
    "wait_for_services",
    "write_bag",
    "write_trace_bag",
]
