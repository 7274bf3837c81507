"""The SoT's signal types as ROS 2 messages, and checked topic names.

| kind | port size | message |
| --- | --- | --- |
| ``vector`` | ``size`` | ``std_msgs/Float64MultiArray`` (one dimension, label ``signal``) |
| ``matrix`` | ``rows × cols`` (row-major) | ``std_msgs/Float64MultiArray`` (dimensions ``rows``, ``cols``) |
| ``matrixHomo`` | 16 (a 4×4 homogeneous matrix, row-major) | ``std_msgs/Float64MultiArray`` (4 × 4) |
| ``double`` | 1 | ``std_msgs/Float64`` |
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence
from typing import Any

import numpy as np
from rclpy.exceptions import InvalidTopicNameException
from rclpy.validate_full_topic_name import validate_full_topic_name
from rclpy.validate_topic_name import validate_topic_name
from std_msgs.msg import Float64, Float64MultiArray, MultiArrayDimension

from ..exceptions import MAX_COUNT, InvalidInput

#: The kinds ``RosPublish.add`` takes (the SoT's names).
KINDS = ("vector", "matrix", "matrixHomo", "double")


def check_topic(topic: str) -> str:
    """``topic`` if it is a valid ROS 2 topic name, else :class:`InvalidInput` saying why."""
    if not isinstance(topic, str):
        raise InvalidInput(f"a topic name is a string, got {topic!r}")
    try:
        (validate_full_topic_name if topic.startswith("/") else validate_topic_name)(topic)
    except InvalidTopicNameException as error:
        raise InvalidInput(f"bad ROS topic name {topic!r}: {error}") from None
    return topic


def message_type_name(message: type) -> str:
    """ROS' name of a message class, e.g. ``std_msgs/msg/Float64``."""
    return f"{message.__module__.split('.')[0]}/msg/{message.__name__}"


def check_topic_type(node: Any, topic: str, message: type) -> None:
    """:class:`InvalidInput` if ``topic`` (resolved in ``node``'s namespace) is already known to
    ``node``'s graph with another message type than ``message``'s: ROS would connect nothing, with
    no error on either side. (A topic that appears later with another type is not seen here.)"""
    try:
        resolved = node.resolve_topic_name(topic)
        known = dict(node.get_topic_names_and_types())
    except Exception:  # (a name rclpy cannot resolve is refused where the topic is created)
        return
    wanted = message_type_name(message)
    types = known.get(resolved, [])
    if types and wanted not in types:
        raise InvalidInput(f"topic {topic!r} carries {', '.join(types)}, not {wanted}: ROS would connect nothing")


def port_size(kind: str, size: int | None = None, shape: Sequence[int] | None = None) -> int:
    """The input port size of a signal of ``kind`` (see the module table): ``size`` (a ``vector``)
    and ``rows × cols`` (a ``matrix``) are positive ints of at most ``MAX_COUNT`` numbers, else
    :class:`InvalidInput`."""
    if kind not in KINDS:
        raise InvalidInput(f"unknown signal type {kind!r}: one of {', '.join(KINDS)}")
    if kind == "double":
        return 1
    if kind == "matrixHomo":
        return 16
    if kind == "matrix":
        if (not isinstance(shape, (tuple, list)) or len(shape) != 2
                or not all(isinstance(n, numbers.Integral) and not isinstance(n, bool) and 0 < int(n) <= MAX_COUNT for n in shape)
                or int(shape[0]) * int(shape[1]) > MAX_COUNT):
            raise InvalidInput(f"a 'matrix' signal needs shape=(rows, cols) of positive ints, at most {MAX_COUNT} "
                               f"numbers, got {shape!r:.100}")
        return int(shape[0]) * int(shape[1])
    if isinstance(size, bool) or not (isinstance(size, numbers.Integral) and 0 < int(size) <= MAX_COUNT):
        raise InvalidInput(f"a 'vector' signal needs size=<positive int ≤ {MAX_COUNT}> (e.g. robot.dimension), got {size!r:.100}")
    return int(size)


def to_message(kind: str, value: np.ndarray, shape: tuple[int, int] | None = None) -> Float64 | Float64MultiArray:
    """The message of one value of ``kind`` (``shape`` for ``matrix``)."""
    value = np.asarray(value, dtype=float).ravel()
    if kind == "double":
        return Float64(data=float(value[0]))
    message = Float64MultiArray()
    if kind == "vector":
        message.layout.dim = [MultiArrayDimension(label="signal", size=value.size, stride=value.size)]
    else:
        rows, cols = (4, 4) if kind == "matrixHomo" else shape or (value.size, 1)
        message.layout.dim = [MultiArrayDimension(label="rows", size=rows, stride=rows * cols),
                              MultiArrayDimension(label="cols", size=cols, stride=cols)]
    message.data = value.tolist()
    return message


def message_type(kind: str) -> type:
    return Float64 if kind == "double" else Float64MultiArray
