"""Drake Meshcat for a SoT diagram, standalone HTML recordings, and the control graph picture.

The kinematic diagram has no simulated plant: the device's ``q`` is turned into geometry poses by
Drake's ``MultibodyPositionToGeometryPose`` over a meshed copy of the robot, and drawn by
``MeshcatVisualizer``.
"""

from __future__ import annotations

import logging
import shutil
import subprocess
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams, Rgba, Sphere
from pydrake.math import RigidTransform
from pydrake.systems.framework import System
from pydrake.systems.rendering import MultibodyPositionToGeometryPose

from .drake_logging import drake_log_level
from .exceptions import InvalidInput, SotError, check_finite, check_number
from .robot import Robot
from .target_marker import TargetMarker
from .writable import check_writable, writing

if TYPE_CHECKING:
    from .dynamics.robot_dyn import RobotDyn

log = logging.getLogger("sotdrake.visualization")


def start_meshcat(live: bool = False) -> Meshcat:
    """Drake's Meshcat, for a recording (``live=False``: nothing printed, since its URL stops working
    when the script exits; save the run with :func:`save_recording`) or for watching the run live
    (``live=True``: the URL is printed, labelled as such)."""
    from pydrake.geometry import StartMeshcat

    with drake_log_level(logging.WARNING):
        meshcat = StartMeshcat()
    if live:
        print(f"Meshcat, live while this process runs: {meshcat.web_url()}")
    return meshcat


def add_robot_visualizer(robot: Robot | RobotDyn, meshcat: Meshcat, publish_period: float = 1 / 60) -> MeshcatVisualizer:
    """Draw ``robot.device.state`` in ``meshcat`` (illustration geometry, OBJ meshes): ``q`` (the
    kinematic device) or ``(q, v)`` (the dynamic SoT's ``RobotDynSimu``)."""
    if not isinstance(meshcat, Meshcat):
        raise InvalidInput(f"add_robot_visualizer: expected a Meshcat (start_meshcat()), got {type(meshcat).__name__}")
    publish_period = check_number("add_robot_visualizer: publish_period", publish_period, 1e-4, 10.0, " s")
    builder = robot.builder
    taken = {system.get_name() for system in builder.GetSystems()} & {"scene_graph", "robot_pose"}
    if taken or builder.already_built():  # (checked first: Drake would end the process at Build())
        raise SotError(f"add_robot_visualizer: the diagram is built or has a visualizer already ({sorted(taken)})")
    visual = robot.model.with_meshes()
    state = robot.device.GetOutputPort("state")
    scene_graph = builder.AddNamedSystem("scene_graph", visual.scene_graph)
    to_pose = builder.AddNamedSystem("robot_pose", MultibodyPositionToGeometryPose(
        visual.plant, input_multibody_state=state.size() == visual.plant.num_multibody_states()))
    to_pose.visual_model = visual  # keeps the plant alive as long as the system
    builder.Connect(state, to_pose.get_input_port())
    builder.Connect(to_pose.get_output_port(), scene_graph.get_source_pose_port(visual.plant.get_source_id()))
    params = MeshcatVisualizerParams(publish_period=publish_period)
    return MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, params)


TARGET_COLOR = Rgba(0.9, 0.15, 0.1, 0.8)


def add_target_marker(meshcat: Meshcat, path: str, position, radius: float = 0.025,
                      rgba: Rgba | None = None) -> TargetMarker | None:
    """A marker in ``meshcat`` at ``path``: for a point (world frame, m), a sphere there, red by
    default; for a task (a ``MetaTaskKine6d``, before the diagram is built), a
    ``sotdrake.target_marker.TargetMarker`` added to the task's diagram: its target
    (bright sphere and crosshair) read from the Context at every publish, so it follows ``gotoNd``
    and is recorded, and the point the task controls (the op point moved by the task's ``opmodif``
    as set now). Returns that system, or None for a point."""
    if not (hasattr(meshcat, "SetObject") and hasattr(meshcat, "SetTransform")):
        raise InvalidInput(f"add_target_marker: expected a Meshcat (start_meshcat()), got {type(meshcat).__name__}")
    if not isinstance(path, str) or not path:
        raise InvalidInput(f"add_target_marker: path must be a Meshcat path such as '/target', got {path!r:.60}")
    radius = check_number("add_target_marker: radius", radius, 1e-6, 100.0, " m")
    if rgba is not None and not isinstance(rgba, Rgba):
        raise InvalidInput(f"add_target_marker: rgba must be None or an Rgba (pydrake.geometry.Rgba(r, g, b, a)), got {rgba!r:.60}")
    if hasattr(position, "featureDes") and hasattr(position, "opPoint"):
        return _add_task_marker(meshcat, path, position, radius, rgba)
    point = check_finite("add_target_marker: position (m)", position, (3,))
    meshcat.SetObject(path, Sphere(radius), TARGET_COLOR if rgba is None else rgba)
    meshcat.SetTransform(path, RigidTransform(point))
    return None


def _add_task_marker(meshcat: Meshcat, path: str, task, radius: float, rgba: Rgba | None) -> TargetMarker:
    builder = task.robot.builder
    if builder.already_built() or any(system.get_name() == f"marker{task.name}" for system in builder.GetSystems()):
        raise SotError(f"add_target_marker: task {task.name!r} has a marker already, or the diagram is built")
    marker = builder.AddNamedSystem(f"marker{task.name}", TargetMarker(meshcat, path, task.opmodif, radius, rgba))
    builder.Connect(task.featureDes.GetOutputPort("position"), marker.desired_pose)
    builder.Connect(task.dyn.GetOutputPort(task.opPoint), marker.op_point_pose)
    return marker


def save_recording(visualizer: MeshcatVisualizer, meshcat: Meshcat, path: str | Path) -> Path:
    """Stop the recording, publish it and write Meshcat's standalone HTML to ``path``. The path is
    checked first (a file that can be written, in an existing folder): otherwise
    :class:`InvalidInput` and the recording is left as it was."""
    if not isinstance(visualizer, MeshcatVisualizer) or not isinstance(meshcat, Meshcat):
        raise InvalidInput("save_recording: expected the visualizer (add_robot_visualizer) and its Meshcat")
    if not isinstance(path, (str, Path)) or Path(path).is_dir() or not Path(path).parent.is_dir():
        raise InvalidInput(f"save_recording: {str(path)!r:.100} is a folder or its folder does not exist: give a file path")
    target = check_writable("save_recording", path)
    visualizer.StopRecording()
    visualizer.PublishRecording()
    with writing("save_recording", target):
        target.write_text(meshcat.StaticHtml())
    return target


def graphviz_dot() -> list[str] | None:
    """The command that lays out a GraphViz graph with the ``dot`` engine: Graphviz's own ``dot`` if it
    is on the PATH, else the ``graphviz-pure`` wheel's command (a dependency of sotdrake, installed
    beside the Python interpreter), else None."""
    dot = shutil.which("dot")
    if dot is not None:
        return [dot]
    beside_python = Path(sys.executable).parent / "graphviz-pure"
    pure = str(beside_python) if beside_python.exists() else shutil.which("graphviz-pure")
    return None if pure is None else [pure, "-Kdot"]


def write_control_graph(diagram: System, path: str | Path) -> Path:
    """Drake's GraphViz of ``diagram`` (one level deep) as ``path`` (.svg); the ``.dot`` source is
    always written beside it. The SVG is laid out by :func:`graphviz_dot`; without any ``dot``
    command only the source is written and a warning says how to get the SVG. Both paths are
    checked first: a system that is not one, a path that does not end in ``.svg`` (``x.dot`` would
    be overwritten by the SVG, ``x.png`` would hold SVG text), or a path that cannot be written, is
    refused with :class:`InvalidInput` and nothing is written."""
    if not isinstance(diagram, System):
        raise InvalidInput(f"write_control_graph: expected a Drake diagram or system, got {type(diagram).__name__}")
    path = check_writable("write_control_graph", path)
    if path.suffix.lower() != ".svg":
        raise InvalidInput(f"write_control_graph: path must end in .svg (the .dot source is written beside it), "
                           f"got {str(path)!r:.100}")
    source = check_writable("write_control_graph", path.with_suffix(".dot"))
    text = diagram.GetGraphvizString(max_depth=1)
    with writing("write_control_graph", source):
        source.write_text(text)
    dot = graphviz_dot()
    if dot is None:
        log.warning("no 'dot' command: wrote %s only (`pip install graphviz-pure` or install Graphviz "
                    "for %s)", source, path.name)
        return source
    done = subprocess.run([*dot, "-Tsvg", str(source), "-o", str(path)], capture_output=True, text=True)
    if done.returncode != 0:
        reason = (done.stderr.strip().splitlines() or [f"exit status {done.returncode}"])[-1]
        raise SotError(f"write_control_graph: {dot[0]} could not lay out {str(source)!r}: {reason:.200}")
    return path
