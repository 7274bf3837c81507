"""``RosSubscribe``: ROS 2 topics as output ports holding the last value received.

| kind | message | output |
| --- | --- | --- |
| ``vector`` | ``std_msgs/Float64MultiArray`` | its ``data`` (``size`` numbers) |
| ``double`` | ``std_msgs/Float64`` | 1 number |
| ``joint_states`` | ``sensor_msgs/JointState`` | the positions of ``names``, in that order |
| ``pose`` | ``geometry_msgs/PoseStamped`` | ``(x, y, z, qw, qx, qy, qz)`` (m, unit quaternion: normalised) |

Before the first message the port holds its ``default``, and one warning says so. A message is
dropped, with a warning saying why, when it has the wrong number of values, a value that is not
finite (the warning names them), a quaternion whose norm is outside (0.5, 2), a ``header.frame_id``
other than the pose's ``frame`` (``world`` by default; an empty one is taken as that frame), or,
for joint states, a wanted joint missing, a joint named twice, or not one position per name; the
port then keeps the last value it held (the last valid message's, or the default).

Messages arrive on the ROS executor's thread. Drake caches an output port's value: the port is
computed anew (and so is its age) when the context's time (or its state, parameters or fixed
inputs) changes, from the
latest message at that moment, and evaluating it again at the same time gives the same value. In a
simulation it thus takes the latest message once per step; a message that arrives while the time
stays put is seen from the next time on. The value is not a function of the context alone: a run
that reads it is as repeatable as the traffic it receives.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from geometry_msgs.msg import PoseStamped
from pydrake.systems.framework import BasicVector, LeafSystem, OutputPort
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64, Float64MultiArray

from ..exceptions import MAX_COUNT, InvalidInput, check_count, check_finite, check_name
from .messages import check_topic, check_topic_type
from .node import RosNode, check_not_built, ros_node

log = logging.getLogger("sotdrake.ros")

SUBSCRIBE_KINDS = {"vector": Float64MultiArray, "double": Float64, "joint_states": JointState, "pose": PoseStamped}
#: The frame a subscribed pose is expressed in unless ``add(..., frame=)`` says otherwise: Drake's world frame.
WORLD_FRAME = "world"
#: The components of a subscribed pose, as the drop warnings name them.
POSE_FIELDS = ("x", "y", "z", "qw", "qx", "qy", "qz")


@dataclass
class _Slot:
    kind: str
    topic: str
    default: np.ndarray
    names: list[str] | None
    frame: str | None = None
    value: np.ndarray | None = None
    received_at: float | None = None
    count: int = 0
    warned: bool = False
    lock: threading.Lock = field(default_factory=threading.Lock)


class RosSubscribe(LeafSystem):
    """Output ports fed from ROS 2 topics (the last value) and their ages.

    Inputs: none.
    Outputs: per :meth:`add`, ``<signal>`` (the last value, or the default before any) and
    ``<signal>_age`` (wall seconds since the last message; ``inf`` before any).
    """

    def __init__(self, name: str = "ros_subscribe", node: RosNode | None = None, depth: int = 10):
        LeafSystem.__init__(self)
        self.set_name(check_name("name", name))
        self.depth = check_count(f"{name}: depth (the queue depth)", depth)
        self.ros = node or ros_node()
        self.slots: dict[str, _Slot] = {}

    def add(self, kind: str, signal: str, topic: str, default: Sequence[float] | None = None,
            size: int | None = None, names: Sequence[str] | None = None, frame: str | None = None) -> OutputPort:
        """An output ``signal`` fed from ``topic``; returns the port. ``size`` for a ``vector``,
        ``names`` for ``joint_states`` (``size`` and the number of names at most ``MAX_COUNT``);
        ``frame`` for a ``pose``: the ``header.frame_id`` it takes (default :data:`WORLD_FRAME`;
        an empty one is taken as it, another is dropped); ``default`` (zeros, or the identity pose)
        before any message.

        Checked before anything is created (:class:`InvalidInput`, nothing added): the kind, the
        signal (a new identifier), the topic (ROS's refusal too), the size or names, the frame, the
        default; :class:`SotError` once this system is in a built diagram."""
        check_not_built(self, f"the signal {signal!r:.60}")
        if kind not in SUBSCRIBE_KINDS:
            raise InvalidInput(f"unknown subscription type {kind!r}: one of {', '.join(SUBSCRIBE_KINDS)}")
        if not isinstance(signal, str) or not signal.isidentifier() or signal in self.slots:
            raise InvalidInput(f"{self.get_name()}: signal {signal!r} is not a new identifier")
        for port in (signal, f"{signal}_age"):
            if self.HasOutputPort(port):
                raise InvalidInput(f"{self.get_name()}: signal {signal!r}: an output named {port!r} exists already")
        check_topic(topic)
        if kind == "joint_states":
            if (isinstance(names, str) or not names or not all(isinstance(n, str) for n in names)
                    or len(set(names)) != len(names) or len(names) > MAX_COUNT):
                raise InvalidInput(f"{self.get_name()}: 'joint_states' needs names=[distinct joint names], got {names!r:.100}")
            n = len(names)
        elif kind == "vector":
            n = check_count(f"{self.get_name()}: a 'vector' size", size)
        else:
            n = 1 if kind == "double" else 7
        if kind == "pose":
            frame = WORLD_FRAME if frame is None else frame
            if not isinstance(frame, str) or not frame or len(frame) > 255:
                raise InvalidInput(f"{self.get_name()}: frame of {signal!r} is a frame name (1 to 255 characters), got {frame!r:.60}")
        elif frame is not None:
            raise InvalidInput(f"{self.get_name()}: frame is for a 'pose' (a PoseStamped's header), not a {kind!r}")
        value = self._default(kind, signal, n, default)
        try:
            check_topic_type(self.ros.node, topic, SUBSCRIBE_KINDS[kind])
        except InvalidInput as error:
            raise InvalidInput(f"{self.get_name()}: topic: {error}") from None
        slot = _Slot(kind, topic, value, list(names) if names is not None else None, frame)
        try:  # (the subscription first: a topic ROS refuses leaves no slot or port behind)
            self.ros.node.create_subscription(SUBSCRIBE_KINDS[kind], topic, lambda m: self._receive(slot, m), self.depth)
        except Exception as error:
            raise InvalidInput(f"{self.get_name()}: ROS refused the topic {topic!r} for {kind!r}: {error}") from None
        self.slots[signal] = slot
        port = self.DeclareVectorOutputPort(signal, n, lambda c, out: out.SetFromVector(self.value(signal)))
        self.DeclareVectorOutputPort(f"{signal}_age", 1, lambda c, out: self._age(signal, out))
        return port

    def _default(self, kind: str, signal: str, n: int, default: Sequence[float] | None) -> np.ndarray:
        """The checked ``default`` of ``signal`` (``n`` finite numbers; a pose's quaternion a unit one),
        or zeros (the identity pose) when it is None; :class:`InvalidInput` otherwise."""
        if default is None:
            value = np.zeros(n)
            if kind == "pose":
                value[3] = 1.0
            return value
        value = check_finite(f"{self.get_name()}: default of {signal!r}", default).ravel()
        if value.size != n:
            raise InvalidInput(f"{self.get_name()}: default of {signal!r} must be {n} finite numbers, got {default!r}")
        if kind == "pose" and abs(float(np.linalg.norm(value[3:])) - 1.0) > 1e-6:
            raise InvalidInput(f"{self.get_name()}: default of {signal!r}: (x, y, z, qw, qx, qy, qz) with a unit "
                               f"quaternion, got one of norm {np.linalg.norm(value[3:]):.6g}")
        return value

    def _receive(self, slot: _Slot, message) -> None:
        value = self._decode(slot, message)
        if value is None:
            return
        with slot.lock:
            slot.value, slot.received_at, slot.count = value, time.monotonic(), slot.count + 1

    def _decode(self, slot: _Slot, message) -> np.ndarray | None:
        """The value of ``message`` for ``slot``, or None (with a warning saying why) to drop it."""
        labels: Sequence[str] | None = None
        if slot.kind == "joint_states":
            twice = sorted(n for n, k in Counter(message.name).items() if k > 1)
            if twice:
                return self._drop(slot, f"a JointState naming {', '.join(map(repr, twice[:8]))} more than once")
            index = {n: i for i, n in enumerate(message.name)}
            missing = [n for n in slot.names or () if n not in index]
            if missing or len(message.position) != len(message.name):
                return self._drop(slot, f"a JointState without {missing or 'one position per name'}")
            value = np.array([message.position[index[n]] for n in slot.names or ()], dtype=float)
            labels = slot.names
        elif slot.kind == "pose":
            frame = message.header.frame_id
            if frame not in ("", slot.frame):
                return self._drop(slot, f"a pose in frame {frame!r:.100}, not {slot.frame!r}")
            p, o = message.pose.position, message.pose.orientation
            value = np.array([p.x, p.y, p.z, o.w, o.x, o.y, o.z], dtype=float)
            norm = float(np.linalg.norm(value[3:]))
            if not 0.5 < norm < 2.0:  # (NaN too) a quaternion, not a rotation: dropped, not scaled from noise
                return self._drop(slot, f"a pose whose quaternion has norm {norm:.3g}")
            value[3:] /= norm
            labels = POSE_FIELDS
        elif slot.kind == "double":
            value = np.array([message.data], dtype=float)
            labels = ("data",)
        else:
            value = np.asarray(message.data, dtype=float)
        if value.size != slot.default.size:
            return self._drop(slot, f"a message of {value.size} values (want {slot.default.size})")
        bad = np.flatnonzero(~np.isfinite(value))
        if bad.size:
            named = [f"{labels[i] if labels is not None else f'data[{i}]'}={value[i]}" for i in bad[:8]]
            more = f" (and {bad.size - 8} more)" if bad.size > 8 else ""
            return self._drop(slot, f"a message whose values are not all finite: {', '.join(named)}{more}")
        return value

    def _drop(self, slot: _Slot, what: str) -> np.ndarray | None:
        """Warn that ``what`` was dropped (the port keeps its last value); None (no value)."""
        log.warning("%s: %s: dropped %s", self.get_name(), slot.topic, what)
        return None

    def value(self, signal: str) -> np.ndarray:
        """The last value of ``signal`` (the default, with one warning, before any message)."""
        slot = self.slots[signal]
        with slot.lock:
            if slot.value is not None:
                return slot.value
            if not slot.warned:
                slot.warned = True
                log.warning("%s: nothing received on %s yet: holding the default %s", self.get_name(), slot.topic,
                            np.array2string(slot.default, precision=4, threshold=8))
            return slot.default

    def age(self, signal: str) -> float:
        """Wall seconds since the last message on ``signal`` (``inf``: none yet)."""
        slot = self.slots[signal]
        with slot.lock:
            return math.inf if slot.received_at is None else time.monotonic() - slot.received_at

    def _age(self, signal: str, out: BasicVector) -> None:
        out.SetAtIndex(0, self.age(signal))

    def count(self, signal: str) -> int:
        """How many messages ``signal`` has received."""
        return self.slots[signal].count
