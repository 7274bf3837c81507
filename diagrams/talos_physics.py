#!/usr/bin/env python3
"""The SoT drives a physically simulated TALOS standing on the ground.

The tutorial's control graph (feet, CoM, and for ``--scenario reach`` the right hand pushed at 1 s
towards (0.5, -0.2, 1.0)) integrates its velocity command into joint references at 1 kHz; the
plant's PD-controlled actuators track them on a discrete ``MultibodyPlant`` (1 ms) with gravity and
ground contact (see :mod:`sotdrake.physics`). ``--loop open`` (default, as sot-talos on the robot) or
``closed`` (the SoT reads the simulated joints, and the base pose estimated by leg odometry: see
``KinematicBaseEstimator``). ``--push F`` pushes the torso
with F newtons along +x for 0.1 s at t = 2 s.

    python diagrams/talos_physics.py --scenario reach --duration 8 --out out/physics
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams
from pydrake.multibody.meshcat import ContactVisualizer, ContactVisualizerParams
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from sotdrake.meta_tasks import MetaTaskKine6d, gotoNd, hold_feet_and_com
from sotdrake.physics import (
    SOLE_BOX,
    ContactMonitor,
    DesiredState,
    KinematicBaseEstimator,
    PhysicalTalos,
    Push,
    add_physical_talos,
)
from sotdrake.robot import Robot, add_sot
from sotdrake.robots import load_talos
from sotdrake.sequencer import attime
from sotdrake.simulation import script_arguments, simulate, start, write_run
from sotdrake.solvers import SOT
from sotdrake.tracing import Tracer

TARGET = (0.5, -0.2, 1.0)
HAND_OFFSET = (0.1, 0.0, 0.0)
GRIPPERS = ["gripper_left_joint", "gripper_right_joint"]


@dataclass
class Physics:
    diagram: Diagram
    robot: Robot
    physical: PhysicalTalos
    sot: SOT
    taskRH: MetaTaskKine6d
    tracer: Tracer
    scenario: str
    visualizer: object = None


def build_diagram(scenario: str = "stand", loop: str = "open", push=0.0,
                  meshcat: Meshcat | None = None, dt: float = 1e-3,
                  push_start: float = 2.0, push_duration: float = 0.1) -> Physics:
    """``push``: a force on the torso (N, world) during ``[push_start, push_start + push_duration)``,
    a number (along +x) or a 3-vector; 0: no push."""
    if scenario not in ("stand", "reach") or loop not in ("open", "closed"):
        raise ValueError(f"scenario is 'stand' or 'reach', loop 'open' or 'closed'; got {scenario!r}, {loop!r}")
    builder = DiagramBuilder()
    physical = add_physical_talos(builder, time_step=dt)
    plant = physical.plant
    model = load_talos("reduced")
    plant.SetDefaultPositions(model.half_sitting)
    measured = None
    if loop == "closed":  # measured joints, base by leg odometry (see KinematicBaseEstimator)
        estimator = builder.AddNamedSystem("estimator", KinematicBaseEstimator(model, model.half_sitting))
        builder.Connect(plant.get_state_output_port(), estimator.get_input_port())
        measured = estimator.get_output_port()
    robot = Robot(builder, model, dt, measured_position=measured)
    sot = add_sot(robot)
    sot.setControlSelection(robot.velocity_selection(excluding=GRIPPERS))
    hold_feet_and_com(robot, sot)  # contactRF, contactLF, taskCom as in the tutorial (gain 10)
    taskRH = MetaTaskKine6d("rh", robot.dynamic, "rh", robot.OperationalPointsMap["right-wrist"])
    handMgrip = np.eye(4)
    handMgrip[0:3, 3] = HAND_OFFSET
    taskRH.opmodif = handMgrip
    if scenario == "reach":
        gotoNd(taskRH, TARGET, "111", (4.9, 0.9, 0.01, 0.9))
        attime(1.0, lambda: sot.push(taskRH.task.name), "push taskrh: move the right hand")

    desired = robot.add(DesiredState(physical))
    builder.Connect(robot.device.GetOutputPort("state"), desired.GetInputPort("position"))
    builder.Connect(sot.GetOutputPort("control"), desired.GetInputPort("velocity"))
    builder.Connect(desired.get_output_port(), plant.get_desired_state_input_port(physical.instance))
    feedforward = robot.add(ConstantVectorSource(np.zeros(plant.num_actuated_dofs(physical.instance))), "feedforward_torque")
    builder.Connect(feedforward.get_output_port(), plant.get_actuation_input_port(physical.instance))
    monitor = robot.add(ContactMonitor(physical))
    builder.Connect(plant.get_contact_results_output_port(), monitor.get_input_port())
    force = np.array([push, 0.0, 0.0]) if np.ndim(push) == 0 else np.asarray(push, dtype=float)
    if np.any(force):
        pusher = robot.add(Push(plant, "torso_2_link", force, start=push_start, duration=push_duration))
        builder.Connect(pusher.get_output_port(), plant.get_applied_spatial_force_input_port())

    tracer = Tracer(builder, dt)
    tracer.add(plant.get_state_output_port(), "x_plant")
    tracer.add(robot.device.GetOutputPort("state"), "q_device")
    tracer.add(monitor.get_output_port(), "feet")
    visualizer = None
    if meshcat is not None:
        visualizer = MeshcatVisualizer.AddToBuilder(builder, physical.scene_graph, meshcat, MeshcatVisualizerParams(publish_period=1 / 60))
        ContactVisualizer.AddToBuilder(builder, plant, meshcat, ContactVisualizerParams(publish_period=1 / 60, newtons_per_meter=1000))
        if scenario == "reach":
            from sotdrake.visualization import add_target_marker

            add_target_marker(meshcat, "/target", TARGET)
        meshcat.SetCameraPose(camera_in_world=[1.6, -2.2, 1.3], target_in_world=[0.1, -0.1, 0.7])
    diagram = builder.Build()
    diagram.set_name("talos_physics")
    return Physics(diagram, robot, physical, sot, taskRH, tracer, scenario, visualizer)


def summarize(run: Physics, simulator, duration: float, wall: float) -> tuple[dict, dict]:
    context = simulator.get_context()
    trace = run.tracer.data(context)
    robot, nq = run.robot, run.robot.model.nq
    q = trace["x_plant"][:, :nq]
    q0 = robot.device.initial_position
    path = robot.dynamic.trajectory(["rh", "left-sole", "right-sole"], np.vstack([q0, q]))
    hand = path["rh"][:, :3, :3] @ np.asarray(HAND_OFFSET) + path["rh"][:, :3, 3]
    feet = trace["feet"]
    slip = max(np.linalg.norm(path[s][:, :2, 3] - path[s][0, :2, 3], axis=1).max() for s in ("left-sole", "right-sole"))
    base = np.vstack([q0, q])[:, 4:7]
    size, centre = SOLE_BOX
    # The support polygon: the bounding rectangle of both soles (their initial poses, yaw ≈ 0).
    corners = np.array([path[s][0, :3, 3] + path[s][0, :3, :3] @ (centre + size * np.array([sx, sy, 0]) / 2)
                        for s in ("left-sole", "right-sole") for sx in (-1, 1) for sy in (-1, 1)])
    low, high = corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)
    cop = feet[:, 6:8]
    cop_margin = np.nanmin(np.minimum(cop - low, high - cop))
    summary = {
        "scenario": run.scenario,
        "hand_error_m": float(np.linalg.norm(hand[-1] - np.asarray(TARGET))),
        "hand_initial_error_m": float(np.linalg.norm(hand[0] - np.asarray(TARGET))),
        "base_drift_m": float(np.linalg.norm(base[:, :2] - base[0, :2], axis=1).max()),
        "base_height_drop_m": float(max(0.0, (base[0, 2] - base[:, 2]).max())),
        # From the first step on: at t = 0 the soles just touch the ground and carry nothing yet.
        "min_normal_force_n": float(min(feet[1:, 2].min(), feet[1:, 5].min())),
        "max_foot_slip_m": float(slip),
        "min_cop_margin_m": float(cop_margin),
        "support_polygon_m": [low.tolist(), high.tolist()],
        "duration_s": duration,
        "ticks": len(trace["time"]),
        "wall_s": wall,
        "realtime_factor": duration / wall,
    }
    trace.update(hand_position=hand[1:], base_position=base[1:], cop=cop, support_low=low, support_high=high)
    return summary, trace


def plot(trace: dict, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    t, feet = trace["time"], trace["feet"]
    fig, axes = plt.subplots(2, 2, figsize=(12, 8))
    axes[0, 0].plot(t, feet[:, 2], label="left sole")
    axes[0, 0].plot(t, feet[:, 5], label="right sole")
    axes[0, 0].set_ylabel("normal force (N)")
    axes[0, 0].legend()
    low, high = trace["support_low"], trace["support_high"]
    axes[0, 1].add_patch(Rectangle(low, *(high - low), fill=False, color="k", label="support polygon"))
    axes[0, 1].plot(trace["cop"][:, 0], trace["cop"][:, 1], ".", ms=1, label="CoP")
    axes[0, 1].set_aspect("equal")
    axes[0, 1].set_xlabel("x (m)")
    axes[0, 1].set_ylabel("y (m)")
    axes[0, 1].legend()
    axes[1, 0].plot(t, trace["base_position"] - trace["base_position"][0])
    axes[1, 0].set_ylabel("base displacement (m)")
    axes[1, 0].legend(["x", "y", "z"])
    axes[1, 1].plot(t, trace["cop"])
    axes[1, 1].set_ylabel("CoP (m)")
    axes[1, 1].legend(["x", "y"])
    for axis in (axes[1, 0], axes[1, 1], axes[0, 0]):
        axis.set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/physics")
    parser.add_argument("--scenario", choices=["stand", "reach"], default="reach")
    parser.add_argument("--loop", choices=["open", "closed"], default="open")
    parser.add_argument("--push", type=float, default=0.0, help="push the torso with this force (N) at t = 2 s for 0.1 s")
    args = parser.parse_args(argv)
    meshcat = start(args)
    run = build_diagram(args.scenario, args.loop, args.push, meshcat)
    simulator, wall = simulate(run.diagram, args.duration, run.visualizer, not args.quiet)
    summary, trace = summarize(run, simulator, args.duration, wall)
    summary.update(loop=args.loop, push_n=args.push)
    args.out.mkdir(parents=True, exist_ok=True)
    plot(trace, args.out / "plots.png")
    write_run(args.out, run.diagram, summary, trace, meshcat, run.visualizer)
    print(json.dumps({k: v for k, v in summary.items() if k != "outputs"}, indent=2))
    return summary


if __name__ == "__main__":
    main()
