"""TALOS looks at a moving point while holding its feet and its CoM; a posture task below.

Stack (highest first): ``contactRF``, ``contactLF``, ``com`` (held), ``gaze`` (a
``FeatureVisualPoint``: the point's image in the head camera ``rgbd_rgb_optical_frame`` driven to
the image centre, with the point's velocity as feed-forward), ``posture`` (half-sitting, joints
only). The point circles in front of the robot, from Drake's ``Sine`` plus a constant::

    p(t) = (1.5, 0.35 sin(2π f t), 1.35 + 0.2 cos(2π f t)) m,   f = 0.25 Hz

    python diagrams/posture_gaze.py --duration 8 --out out/posture_gaze
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Meshcat, Rgba
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import Adder, ConstantVectorSource, Sine

from sotdrake import (
    SOT,
    TALOS_GRIPPERS,
    MetaTaskKinePosture,
    MetaTaskVisualPoint,
    Robot,
    Tracer,
    add_sot,
    hold_feet_and_com,
    script_arguments,
    simulate,
    start,
    talos,
    write_run,
)

CENTER = np.array([1.5, 0.0, 1.35])
AMPLITUDE = np.array([0.0, 0.35, 0.2])
FREQUENCY = 0.25  # Hz


def point_at(t: np.ndarray) -> np.ndarray:
    """The point's position (k, 3) at times ``t``."""
    w = 2 * np.pi * FREQUENCY
    return CENTER + np.stack([0 * t, AMPLITUDE[1] * np.sin(w * t), AMPLITUDE[2] * np.cos(w * t)], axis=-1)


@dataclass
class PostureGaze:
    diagram: Diagram
    robot: Robot
    sot: SOT
    gaze: MetaTaskVisualPoint
    tracer: Tracer
    visualizer: object = None


def build_diagram(meshcat: Meshcat | None = None, dt: float = 1e-3, feedforward: bool = True) -> PostureGaze:
    builder = DiagramBuilder()
    robot = talos(builder, "reduced", dt)
    sot = add_sot(robot)
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS))
    hold_feet_and_com(robot, sot)

    # The moving point: Drake's Sine gives p and ṗ, a constant moves it in front of the robot.
    w = 2 * np.pi * FREQUENCY
    sine = robot.add(Sine(AMPLITUDE, np.full(3, w), np.array([0.0, 0.0, np.pi / 2])), "point_motion")
    center = robot.add(ConstantVectorSource(CENTER), "point_center")
    point = robot.add(Adder(2, 3), "point")
    builder.Connect(sine.get_output_port(0), point.get_input_port(0))
    builder.Connect(center.get_output_port(), point.get_input_port(1))
    gaze = MetaTaskVisualPoint("gaze", robot)
    gaze.plugPoint(point.get_output_port(), sine.get_output_port(1) if feedforward else None)
    gaze.gain.setConstant(8)
    sot.push(gaze.task.name)

    posture = MetaTaskKinePosture(robot)
    posture.gain.setConstant(2)
    sot.push(posture.task.name)

    tracer = Tracer(builder, dt)
    tracer.add(robot.device.GetOutputPort("state"), "q")
    for task in ("taskgaze", "taskcom", "taskposture"):
        tracer.add(robot.tasks[task].GetOutputPort("error_norm"), f"error_{task}")
    visualizer = None
    if meshcat is not None:
        from sotdrake import add_robot_visualizer, add_target_marker

        visualizer = add_robot_visualizer(robot, meshcat)
        circle = point_at(np.linspace(0, 1 / FREQUENCY, 100)).T
        meshcat.SetLine("/point_path", circle, 2.0, Rgba(0.9, 0.2, 0.1, 1))
        add_target_marker(meshcat, "/point_start", circle[:, 0], radius=0.03)
        meshcat.SetCameraPose(camera_in_world=[2.6, -2.0, 1.8], target_in_world=[0.6, 0.0, 1.0])
    return PostureGaze(builder.Build(), robot, sot, gaze, tracer, visualizer)


def summarize(run: PostureGaze, simulator, duration: float, wall: float) -> tuple[dict, dict]:
    context = simulator.get_context()
    trace = run.tracer.data(context)
    robot = run.robot
    qs = np.vstack([robot.device.initial_position, trace["q"]])
    path = robot.dynamic.trajectory(["RF", "LF", "camera"], qs)
    t = trace["time"]
    # The angle between the camera's optical axis and the direction to the point.
    to_point = point_at(np.concatenate([[0.0], t])) - path["camera"][:, :3, 3]
    axis = path["camera"][:, :3, 2]
    angle = np.arccos(np.clip(np.einsum("ki,ki->k", axis, to_point) / np.linalg.norm(to_point, axis=1), -1, 1))
    settled = t >= 2.0
    feet = max(np.linalg.norm(path[f][:, :3, 3] - path[f][0, :3, 3], axis=1).max() for f in ("RF", "LF"))
    summary = {
        "gaze_error_rad_after_2s_max": float(angle[1:][settled].max()) if settled.any() else None,
        "gaze_error_rad_final": float(angle[-1]),
        "gaze_error_rad_initial": float(angle[0]),
        "image_error_after_2s_max": float(trace["error_taskgaze"][settled].max()) if settled.any() else None,
        "max_foot_drift_m": float(feet),
        "max_com_drift_m": float(np.linalg.norm(path["com"] - path["com"][0], axis=1).max()),
        "posture_error_final": float(trace["error_taskposture"][-1, 0]),
        "duration_s": duration,
        "ticks": len(t),
        "wall_s": wall,
        "realtime_factor": duration / wall,
    }
    trace["gaze_angle_rad"] = angle[1:]
    return summary, trace


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/posture_gaze")
    parser.add_argument("--no-feedforward", action="store_true", help="ignore the point's velocity")
    args = parser.parse_args(argv)
    meshcat = start(args)
    run = build_diagram(meshcat, feedforward=not args.no_feedforward)
    simulator, wall = simulate(run.diagram, args.duration, run.visualizer, not args.quiet)
    summary, trace = summarize(run, simulator, args.duration, wall)
    args.out.mkdir(parents=True, exist_ok=True)
    run.tracer.plot(simulator.get_context(), args.out / "plots.png", ["error_taskgaze", "error_taskcom", "error_taskposture"],
                    title="posture_gaze: the head camera follows a point circling in front of TALOS"
                          + ("" if not args.no_feedforward else " (no feed-forward)"),
                    labels={"error_taskgaze": "image error ‖s − s*‖\n(normalised image units)",
                            "error_taskcom": "CoM error ‖e‖ (m)", "error_taskposture": "posture error ‖q − q*‖ (rad)"},
                    legends={"error_taskgaze": ["gaze (priority 4)"], "error_taskcom": ["CoM held (priority 3)"],
                             "error_taskposture": ["posture (priority 5)"]},
                    log=("error_taskgaze", "error_taskcom"))
    write_run(args.out, run.diagram, summary, trace, meshcat, run.visualizer, bag=args.bag)
    return summary

