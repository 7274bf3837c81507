"""rosbag2 (MCAP) files of a run, written with ``rosbags`` (pure Python, no ROS needed to read them).

:func:`write_bag` takes sampled signals and writes one message per sample, stamped (bag time and
header) with the simulated time: joint states (``sensor_msgs/JointState``), points
(``geometry_msgs/PointStamped``: CoM, hand, target) and arrays (``std_msgs/Float64MultiArray``:
task errors). The bag is a directory ``<name>/`` holding ``<name>.mcap`` and ``metadata.yaml``.
A bag's topics are fully qualified names (``/joint_states``): a relative one (``state``, ``~/x``,
``{node}/x``) has no node to resolve it against, and is refused.
"""

from __future__ import annotations

import logging
import os
import re
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from ..exceptions import InvalidInput, check_count, os_reason
from .messages import check_topic

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
log = logging.getLogger("sotdrake.ros")

#: A series: its topic, message type, T rows, and the shape of one sample (an array's layout; None: not an array).
_Series = tuple[str, str, np.ndarray, tuple[int, ...] | None]


def _bag_topic(argument: str, topic: object) -> str:
    """``topic`` if it is a fully qualified ROS topic name, else :class:`InvalidInput` naming ``argument``."""
    if not isinstance(topic, str) or not topic.startswith("/"):
        raise InvalidInput(f"write_bag: {argument}: a bag's topic is a fully qualified name (starting with '/'), "
                           f"got {topic!r:.100}")
    try:
        return check_topic(topic)
    except InvalidInput as error:
        raise InvalidInput(f"write_bag: {argument}: {error}") from None


def _stamp(t: float):
    ns = round(t * 1e9)
    return TYPESTORE.types["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _header(t: float, frame: str = ""):
    return TYPESTORE.types["std_msgs/msg/Header"](stamp=_stamp(t), frame_id=frame)


def write_bag(directory: Path | str, time: Sequence[float] | np.ndarray, joint_states: tuple[Sequence[str], np.ndarray] | None = None,
              points: Mapping[str, np.ndarray] | None = None, arrays: Mapping[str, np.ndarray] | None = None,
              joint_topic: str = "/joint_states", frame: str = "world") -> Path:
    """Write the bag ``directory`` (replaced if it exists); returns its ``.mcap`` file.

    ``time``: T sample times (s); ``joint_states``: (names, T × len(names) positions);
    ``points``: topic → T × 3 (m); ``arrays``: topic → T × n (or T, or T × n1 × n2 …: each sample
    row-major, its dimensions in the message's layout; booleans as 0 and 1). Every topic is fully
    qualified (``/…``); a relative one, a bad size or value is an :class:`InvalidInput` naming the
    argument, and nothing is written."""
    t = np.asarray(time, dtype=float).ravel()
    if t.size == 0 or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0) or t[0] < 0 or t[-1] > MAX_BAG_TIME:
        raise InvalidInput(f"write_bag: time must be non-decreasing numbers in [0, {MAX_BAG_TIME:g}] s, not empty")
    series: list[_Series] = []
    names: list[str] = []
    if not isinstance(frame, str):
        raise InvalidInput(f"write_bag: frame is a string, got {frame!r:.60}")
    try:  # (the sizes are checked below, the values here: numbers)
        if joint_states is not None:
            joint_states = (list(joint_states[0]), np.asarray(joint_states[1], dtype=float))
        points = {topic: np.asarray(values, dtype=float) for topic, values in (points or {}).items()}
        arrays = {topic: np.asarray(values, dtype=float) for topic, values in (arrays or {}).items()}
    except (TypeError, ValueError, IndexError):
        raise InvalidInput("write_bag: joint_states is (names, positions), points and arrays map topics to numbers") from None
    if joint_states is not None:
        names, positions = joint_states
        if not all(isinstance(name, str) for name in names):
            raise InvalidInput(f"write_bag: joint names are strings, got {names!r:.100}")
        if positions.shape != (t.size, len(names)):
            raise InvalidInput(f"write_bag: joint positions are {positions.shape}, want {(t.size, len(names))}")
        series.append((_bag_topic("joint_topic", joint_topic), "sensor_msgs/msg/JointState", positions, None))
    for topic, values in points.items():
        if values.shape != (t.size, 3):
            raise InvalidInput(f"write_bag: {topic} is {values.shape}, want {(t.size, 3)}")
        series.append((_bag_topic("points", topic), "geometry_msgs/msg/PointStamped", values, None))
    for topic, values in arrays.items():
        if values.ndim < 1 or len(values) != t.size:
            raise InvalidInput(f"write_bag: {topic} is {values.shape}, want {t.size} rows")
        series.append((_bag_topic("arrays", topic), "std_msgs/msg/Float64MultiArray", values.reshape(t.size, -1),
                       values.shape[1:]))
    topics = [topic for topic, _, _, _ in series]
    if len(set(topics)) != len(topics):
        raise InvalidInput(f"write_bag: a topic is given twice: {sorted(topics)}")
    directory = Path(directory)
    if directory.exists() and not _replaceable_bag(directory):
        raise InvalidInput(f"write_bag: {str(directory)!r} exists and is not a bag (no metadata.yaml): not replaced")
    # Written beside it, then moved in place: a failed write leaves the old bag as it was.
    try:
        staging = Path(tempfile.mkdtemp(prefix=".bag-", dir=directory.parent))
    except (OSError, ValueError) as error:
        raise InvalidInput(f"write_bag: cannot write in {str(directory.parent)!r}: {os_reason(error)}") from None
    try:
        _write_series(staging / directory.name, t, series, names, frame)
        if directory.exists():
            shutil.rmtree(directory)
        os.replace(staging / directory.name, directory)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return directory / f"{directory.name}.mcap"


#: The latest sample time a bag takes (s): a header's stamp holds its seconds in a signed 32-bit integer.
MAX_BAG_TIME = 2.1e9


def _replaceable_bag(directory: Path) -> bool:
    """Whether ``write_bag`` may replace ``directory``: an empty folder or a bag (``metadata.yaml``)."""
    return directory.is_dir() and (not any(directory.iterdir()) or (directory / "metadata.yaml").is_file())


def _layout(shape: tuple[int, ...]):
    """The ``MultiArrayLayout`` of one sample of ``shape`` (row-major): one dimension ``signal`` for a
    number or a vector, ``rows`` and ``cols`` for a matrix, ``dim0``, ``dim1`` … beyond."""
    types = TYPESTORE.types
    sizes = [int(np.prod(shape, dtype=int))] if len(shape) < 2 else [int(n) for n in shape]
    labels = ["signal"] if len(shape) < 2 else ["rows", "cols"] if len(shape) == 2 else [f"dim{i}" for i in range(len(shape))]
    dims = [types["std_msgs/msg/MultiArrayDimension"](label=label, size=size, stride=int(np.prod(sizes[i:], dtype=int)))
            for i, (label, size) in enumerate(zip(labels, sizes, strict=True))]
    return types["std_msgs/msg/MultiArrayLayout"](dim=dims, data_offset=0)


def _write_series(directory: Path, t: np.ndarray, series: list[_Series], names: list[str], frame: str) -> None:
    """The messages of ``series`` (topic, message type, T rows, sample shape) at the times ``t``, into a new bag."""
    types = TYPESTORE.types
    layouts: list[Any] = [None if shape is None else _layout(shape) for _, _, _, shape in series]
    with Writer(directory, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = [writer.add_connection(topic, kind, typestore=TYPESTORE) for topic, kind, _, _ in series]
        for k, tk in enumerate(t):
            ns = round(tk * 1e9)
            for connection, (_topic, kind, values, _), layout in zip(connections, series, layouts, strict=True):
                row = values[k]
                if kind == "sensor_msgs/msg/JointState":
                    message = types[kind](header=_header(tk), name=names, position=row.copy(),
                                          velocity=np.zeros(0), effort=np.zeros(0))
                elif kind == "geometry_msgs/msg/PointStamped":
                    point = types["geometry_msgs/msg/Point"](x=row[0], y=row[1], z=row[2])
                    message = types[kind](header=_header(tk, frame), point=point)
                else:
                    message = types[kind](layout=layout, data=row.copy())
                writer.write(connection, ns, TYPESTORE.serialize_cdr(message, kind))


def read_bag(directory: Path | str) -> dict[str, list[tuple[int, object]]]:
    """Every message of a bag by topic: ``(bag time in ns, message)`` in order."""
    from rosbags.rosbag2 import Reader, ReaderError

    messages: dict[str, list[tuple[int, object]]] = {}
    if not isinstance(directory, str | Path):
        raise InvalidInput(f"read_bag: a bag folder's path, got {directory!r:.60}")
    try:
        with Reader(Path(directory)) as reader:
            for connection, timestamp, data in reader.messages():
                message = TYPESTORE.deserialize_cdr(data, connection.msgtype)
                messages.setdefault(connection.topic, []).append((timestamp, message))
    except (OSError, ValueError, ReaderError) as error:  # (a missing folder, not a bag)
        raise InvalidInput(f"read_bag: {str(directory)!r} is not a readable bag: {error}") from None
    return messages


def write_trace_bag(directory: Path | str, trace: Mapping[str, np.ndarray], joints: tuple[Sequence[str], np.ndarray],
                    targets: Mapping[str, Sequence[float] | np.ndarray] | None = None, every: int = 1) -> Path:
    """A diagram script's trace as a bag: ``trace['q']`` → ``/joint_states`` (the joints
    ``(names, indices in q)``), ``error_<task>`` → ``/sot/error/<task>``, ``<name>_position`` →
    ``/sot/<name>``, ``targets`` (name → a point, or T × 3 points: the target in force at each of
    the trace's samples) → ``/sot/target/<name>``, any other series of the trace sampled at its
    times (a CoP, a ZMP, contact wrenches, …; numbers or booleans, of any shape per sample) →
    ``/sot/<key>`` (``Float64MultiArray``, the sample's shape in its layout, booleans as 0 and 1);
    every ``every``-th sample. A series sampled at the trace's times that is not numbers (text,
    complex) is left out with a warning naming it. A character a topic name does not take becomes
    ``_`` (a leading digit gets one before it); a topic already used gets ``_2``, ``_3`` …: every
    other series is written."""
    every = check_count("write_trace_bag: every", every, high=2**31)
    missing = [key for key in ("time", "q") if key not in trace]
    if missing:
        raise InvalidInput(f"write_trace_bag: the trace has no {missing} (a diagram script's trace: time, q, …)")
    time = np.asarray(trace["time"])[::every]
    names, indices = joints
    if len(names) != len(indices) or not all(0 <= int(i) < np.shape(trace["q"])[-1] for i in indices):
        raise InvalidInput(f"write_trace_bag: joints are (names, indices in q), with indices below {np.shape(trace['q'])[-1]}")
    taken = {"/joint_states"}
    arrays = {_topic("/sot/error/", k[6:], taken): np.asarray(v)[::every] for k, v in trace.items() if k.startswith("error_")}
    as_points = [k for k, v in trace.items() if k.endswith("_position") and np.ndim(v) == 2 and np.shape(v)[1] == 3]
    points = {_topic("/sot/", k[:-9], taken): np.asarray(trace[k])[::every] for k in as_points}
    samples = np.asarray(trace["time"]).size
    for name, point in (targets or {}).items():
        point = np.asarray(point, dtype=float)
        series = point.ndim == 2 and point.shape[0] == samples  # (the target at each sample, else a constant one)
        points[_topic("/sot/target/", name, taken)] = point[::every] if series else np.tile(point, (time.size, 1))
    for key, value in trace.items():  # every other series of the trace (CoP, ZMP, wrenches, …), as arrays
        value = np.asarray(value)
        if key in ("time", "q", *as_points) or key.startswith("error_") or value.ndim < 1 or value.shape[0] != samples:
            continue
        if value.dtype == np.bool_ or np.issubdtype(value.dtype, np.integer) or np.issubdtype(value.dtype, np.floating):
            arrays[_topic("/sot/", key, taken)] = value[::every]
        else:
            log.warning("write_trace_bag: the series %r (%s) is not numbers: left out of the bag", key, value.dtype)
    return write_bag(directory, time, (names, np.asarray(trace["q"])[::every][:, indices]), points, arrays)


def _topic(prefix: str, name: str, taken: set[str]) -> str:
    """A ROS topic ``prefix + name`` for a trace key, new in ``taken`` (added to it): each character
    that a topic name does not take as ``_``, a leading digit after ``_``, then ``_2``, ``_3`` … until
    it is new (``cop left`` and ``cop_left``, ``com`` beside ``com_position``: two topics)."""
    base = prefix + re.sub(r"[^A-Za-z0-9_]", "_", str(name) or "_")
    if base[len(prefix)].isdigit():
        base = prefix + "_" + base[len(prefix):]
    topic, count = base, 1
    while topic in taken:
        count += 1
        topic = f"{base}_{count}"
    taken.add(topic)
    return topic
