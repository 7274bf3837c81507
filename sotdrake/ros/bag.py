"""rosbag2 (MCAP) files of a run, written with ``rosbags`` (pure Python, no ROS needed to read them).

:func:`write_bag` takes sampled signals and writes one message per sample, stamped (bag time and
header) with the simulated time: joint states (``sensor_msgs/JointState``), points
(``geometry_msgs/PointStamped``: CoM, hand, target) and arrays (``std_msgs/Float64MultiArray``:
task errors). The bag is a directory ``<name>/`` holding ``<name>.mcap`` and ``metadata.yaml``.
"""

from __future__ import annotations

import os
import re
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from ..exceptions import InvalidInput
from .messages import check_topic

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)


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
    ``points``: topic → T × 3 (m); ``arrays``: topic → T × n (or T)."""
    t = np.asarray(time, dtype=float).ravel()
    if t.size == 0 or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0) or t[0] < 0 or t[-1] > MAX_BAG_TIME:
        raise InvalidInput(f"write_bag: time must be non-decreasing numbers in [0, {MAX_BAG_TIME:g}] s, not empty")
    series: list[tuple[str, str, np.ndarray]] = []
    names: list[str] = []
    if joint_states is not None:
        names, positions = list(joint_states[0]), np.asarray(joint_states[1], dtype=float)
        if positions.shape != (t.size, len(names)):
            raise InvalidInput(f"write_bag: joint positions are {positions.shape}, want {(t.size, len(names))}")
        series.append((check_topic(joint_topic), "sensor_msgs/msg/JointState", positions))
    for topic, values in (points or {}).items():
        values = np.asarray(values, dtype=float)
        if values.shape != (t.size, 3):
            raise InvalidInput(f"write_bag: {topic} is {values.shape}, want {(t.size, 3)}")
        series.append((check_topic(topic), "geometry_msgs/msg/PointStamped", values))
    for topic, values in (arrays or {}).items():
        values = np.asarray(values, dtype=float)
        if values.ndim not in (1, 2) or len(values) != t.size:
            raise InvalidInput(f"write_bag: {topic} is {values.shape}, want {t.size} rows")
        series.append((check_topic(topic), "std_msgs/msg/Float64MultiArray", values.reshape(t.size, -1)))
    topics = [topic for topic, _, _ in series]
    if len(set(topics)) != len(topics):
        raise InvalidInput(f"write_bag: a topic is given twice: {sorted(topics)}")
    directory = Path(directory)
    if directory.exists() and not _replaceable_bag(directory):
        raise InvalidInput(f"write_bag: {str(directory)!r} exists and is not a bag (no metadata.yaml): not replaced")
    # Written beside it, then moved in place: a failed write leaves the old bag as it was.
    staging = Path(tempfile.mkdtemp(prefix=".bag-", dir=directory.parent))
    try:
        _write_series(staging / directory.name, t, series, names, frame)
        if directory.exists():
            shutil.rmtree(directory)
        os.replace(staging / directory.name, directory)
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return directory / f"{directory.name}.mcap"


#: The latest sample time a bag takes (s): its stamps are nanoseconds in a signed 64-bit integer.
MAX_BAG_TIME = 9.2e9


def _replaceable_bag(directory: Path) -> bool:
    """Whether ``write_bag`` may replace ``directory``: an empty folder or a bag (``metadata.yaml``)."""
    return directory.is_dir() and (not any(directory.iterdir()) or (directory / "metadata.yaml").is_file())


def _write_series(directory: Path, t: np.ndarray, series: list[tuple[str, str, np.ndarray]], names: list[str],
                  frame: str) -> None:
    """The messages of ``series`` (topic, message type, T rows) at the times ``t``, into a new bag."""
    types = TYPESTORE.types
    with Writer(directory, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        connections = [writer.add_connection(topic, kind, typestore=TYPESTORE) for topic, kind, _ in series]
        for k, tk in enumerate(t):
            ns = round(tk * 1e9)
            for connection, (_topic, kind, values) in zip(connections, series, strict=True):
                row = values[k]
                if kind == "sensor_msgs/msg/JointState":
                    message = types[kind](header=_header(tk), name=names, position=row.copy(),
                                          velocity=np.zeros(0), effort=np.zeros(0))
                elif kind == "geometry_msgs/msg/PointStamped":
                    point = types["geometry_msgs/msg/Point"](x=row[0], y=row[1], z=row[2])
                    message = types[kind](header=_header(tk, frame), point=point)
                else:
                    dim = types["std_msgs/msg/MultiArrayDimension"](label="signal", size=row.size, stride=row.size)
                    layout = types["std_msgs/msg/MultiArrayLayout"](dim=[dim], data_offset=0)
                    message = types[kind](layout=layout, data=row.copy())
                writer.write(connection, ns, TYPESTORE.serialize_cdr(message, kind))


def read_bag(directory: Path | str) -> dict[str, list[tuple[int, object]]]:
    """Every message of a bag by topic: ``(bag time in ns, message)`` in order."""
    from rosbags.rosbag2 import Reader, ReaderError

    messages: dict[str, list[tuple[int, object]]] = {}
    try:
        with Reader(Path(directory)) as reader:
            for connection, timestamp, data in reader.messages():
                message = TYPESTORE.deserialize_cdr(data, connection.msgtype)
                messages.setdefault(connection.topic, []).append((timestamp, message))
    except (OSError, ValueError, ReaderError) as error:  # (a missing folder, not a bag)
        raise InvalidInput(f"read_bag: {str(directory)!r} is not a readable bag: {error}") from None
    return messages


def write_trace_bag(directory: Path | str, trace: Mapping[str, np.ndarray], joints: tuple[Sequence[str], np.ndarray],
                    targets: Mapping[str, Sequence[float]] | None = None, every: int = 1) -> Path:
    """A diagram script's trace as a bag: ``trace['q']`` → ``/joint_states`` (the joints
    ``(names, indices in q)``), ``error_<task>`` → ``/sot/error/<task>``, ``<name>_position`` →
    ``/sot/<name>``, ``targets`` (name → constant point) → ``/sot/target/<name>``, any other numeric
    series of the trace (a CoP, a ZMP, contact wrenches, …) → ``/sot/<key>`` (``Float64MultiArray``);
    every ``every``-th sample."""
    if not (isinstance(every, int) and every > 0):
        raise InvalidInput(f"write_trace_bag: every must be a positive int, got {every!r}")
    missing = [key for key in ("time", "q") if key not in trace]
    if missing:
        raise InvalidInput(f"write_trace_bag: the trace has no {missing} (a diagram script's trace: time, q, …)")
    time = np.asarray(trace["time"])[::every]
    names, indices = joints
    if len(names) != len(indices) or not all(0 <= int(i) < np.shape(trace["q"])[-1] for i in indices):
        raise InvalidInput(f"write_trace_bag: joints are (names, indices in q), with indices below {np.shape(trace['q'])[-1]}")
    arrays = {f"/sot/error/{k[6:]}": np.asarray(v)[::every] for k, v in trace.items() if k.startswith("error_")}
    as_points = [k for k, v in trace.items() if k.endswith("_position") and np.ndim(v) == 2 and np.shape(v)[1] == 3]
    points = {f"/sot/{k[:-9]}": np.asarray(trace[k])[::every] for k in as_points}
    for name, point in (targets or {}).items():
        points[f"/sot/target/{name}"] = np.tile(np.asarray(point, dtype=float), (time.size, 1))
    samples = np.asarray(trace["time"]).size
    for key, value in trace.items():  # every other series of the trace (CoP, ZMP, wrenches, …), as arrays
        value = np.asarray(value)
        topic = "/sot/" + re.sub(r"[^A-Za-z0-9_]", "_", key)
        if (key not in ("time", "q", *as_points) and not key.startswith("error_") and value.ndim in (1, 2)
                and value.shape[0] == samples and np.issubdtype(value.dtype, np.number) and topic not in points
                and re.fullmatch(r"/sot/[A-Za-z_]\w*", topic)):
            arrays[topic] = value[::every]
    return write_bag(directory, time, (names, np.asarray(trace["q"])[::every][:, indices]), points, arrays)
