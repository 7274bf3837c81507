"""The SoT drives a physically simulated TALOS standing on the ground.

The tutorial's control graph (feet, CoM, and for ``--scenario reach`` the right hand pushed at 1 s
towards (0.5, -0.2, 1.0)) integrates its velocity command into joint references at 1 kHz; the
plant's PD-controlled actuators track them on a discrete ``MultibodyPlant`` (2 ms steps:
:data:`~sotdrake.physics.PLANT_STEP`) with gravity and ground contact (see :mod:`sotdrake.physics`).
``--loop open`` (default, as sot-talos on the robot) or ``closed`` (the SoT reads the simulated
joints, and the base pose estimated by leg odometry: see ``KinematicBaseEstimator``). ``--push F``
pushes the torso with F newtons along +x for 0.1 s at t = 2 s.

    python diagrams/talos_physics.py --scenario reach --duration 8 --out out/physics
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams
from pydrake.multibody.meshcat import ContactVisualizer, ContactVisualizerParams
from pydrake.systems.framework import Diagram, DiagramBuilder

from sotdrake import (
    SOT,
    TALOS_GRIPPERS,
    InvalidInput,
    MetaTaskKine6d,
    MetaTaskKineCom,
    Robot,
    Tracer,
    add_sot,
    attime,
    desired_position,
    fall_report,
    gotoNd,
    hold_feet_and_com,
    load_talos,
    save_figure,
    script_arguments,
    simulate,
    start,
    tilt_of_quaternions,
    write_run,
)
from sotdrake.physics import (
    PLANT_STEP,
    SOLE_BOX,
    KinematicBaseEstimator,
    PhysicalTalos,
    TalosStation,
    add_talos_station,
    hold_one_tick,
)
from sotdrake.scenarios.common import HAND_OFFSET, gripping_hand, point_drift, point_on, translation_drift

TARGET = (0.5, -0.2, 1.0)


@dataclass
class Physics:
    diagram: Diagram
    robot: Robot
    physical: PhysicalTalos
    station: TalosStation
    sot: SOT
    taskRH: MetaTaskKine6d
    tracer: Tracer
    scenario: str
    visualizer: object = None
    taskCom: MetaTaskKineCom | None = None
    loop: str = "open"


def build_diagram(scenario: str = "stand", loop: str = "open", push=0.0,
                  meshcat: Meshcat | None = None, dt: float = 1e-3,
                  push_start: float = 2.0, push_duration: float = 0.1, plant_step: float = PLANT_STEP) -> Physics:
    """``push``: a force on the torso (N, world) during ``[push_start, push_start + push_duration)``,
    a number (along +x) or a 3-vector; 0: no push. ``dt``: the SoT's tick (s); ``plant_step``: the
    plant's (s)."""
    if scenario not in ("stand", "reach") or loop not in ("open", "closed"):
        raise ValueError(f"scenario is 'stand' or 'reach', loop 'open' or 'closed'; got {scenario!r}, {loop!r}")
    builder = DiagramBuilder()
    model = load_talos("reduced")
    force = np.array([push, 0.0, 0.0]) if np.ndim(push) == 0 else np.asarray(push, dtype=float)
    station = add_talos_station(builder, model.half_sitting, plant_step, push_force=force if np.any(force) else None,
                                push_start=push_start, push_duration=push_duration)
    physical, plant = station.physical, station.physical.plant
    measured = None
    if loop == "closed":  # measured joints, base by leg odometry (see KinematicBaseEstimator)
        estimator = builder.AddNamedSystem("estimator", KinematicBaseEstimator(model, model.half_sitting))
        builder.Connect(plant.get_state_output_port(), estimator.get_input_port())
        measured = estimator.get_output_port()
    robot = Robot(builder, model, dt, measured_position=measured)
    sot = add_sot(robot)
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS))
    _, _, taskCom = hold_feet_and_com(robot, sot)  # contactRF, contactLF, taskCom as in the tutorial (gain 10)
    taskRH = gripping_hand(robot, "rh", HAND_OFFSET, desired_frame=False)
    if scenario == "reach":
        gotoNd(taskRH, TARGET, "111", (4.9, 0.9, 0.01, 0.9))
        attime(1.0, lambda: sot.push(taskRH.task.name), "push taskrh: move the right hand")

    builder.Connect(robot.device.GetOutputPort("state"), station.position)
    velocity, scale = sot.GetOutputPort("control"), sot.GetOutputPort("velocity_scale")
    if loop == "closed":
        # The plant's step is applied before the device's update of its instant, and the closed-loop
        # SoT reads the stepped plant: the servos' velocity and the traced scale are those of the
        # device's last update, held one tick, so that nothing else asks for a solve of its own.
        velocity, scale = (hold_one_tick(builder, port, name, dt) for port, name in
                           ((velocity, "held_velocity"), (scale, "held_velocity_scale")))
    builder.Connect(velocity, station.velocity)

    tracer = Tracer(builder, dt)
    tracer.add(plant.get_state_output_port(), "x_plant")
    tracer.add(robot.device.GetOutputPort("state"), "q_device")
    tracer.add(station.feet, "feet")
    tracer.add(station.other_contact, "other_contact")
    tracer.add(scale, "velocity_scale")
    visualizer = None
    if meshcat is not None:
        visualizer = MeshcatVisualizer.AddToBuilder(builder, physical.scene_graph, meshcat, MeshcatVisualizerParams(publish_period=1 / 60))
        ContactVisualizer.AddToBuilder(builder, plant, meshcat, ContactVisualizerParams(publish_period=1 / 60, newtons_per_meter=1000))
        if scenario == "reach":
            from sotdrake import add_target_marker

            add_target_marker(meshcat, "/target", taskRH)  # follows every gotoNd (timed, live)
        meshcat.SetCameraPose(camera_in_world=[1.5, -1.6, 1.3], target_in_world=[0.15, -0.1, 0.65])
    diagram = builder.Build()
    diagram.set_name("talos_physics")
    return Physics(diagram, robot, physical, station, sot, taskRH, tracer, scenario, visualizer, taskCom, loop)


def summarize(run: Physics, simulator, duration: float, wall: float) -> tuple[dict, dict]:
    context = simulator.get_context()
    trace = run.tracer.data(context)
    robot, nq = run.robot, run.robot.model.nq
    q = trace["x_plant"][:, :nq]
    q0 = robot.device.initial_position
    path = robot.dynamic.trajectory(["rh", "left-sole", "right-sole"], np.vstack([q0, q]))
    hand = point_on(path["rh"], HAND_OFFSET)
    feet = trace["feet"]
    # In the closed loop the traced scale is the last update's, held: its first sample precedes any.
    scales = trace["velocity_scale"][1:] if run.loop == "closed" else trace["velocity_scale"]
    slips = np.max([translation_drift(path[s], 2) for s in ("left-sole", "right-sole")], axis=0)
    slip = slips.max()
    base = np.vstack([q0, q])[:, 4:7]
    size, centre = SOLE_BOX
    # The support polygon: the bounding rectangle of both soles (their initial poses, yaw ≈ 0).
    corners = np.array([path[s][0, :3, 3] + path[s][0, :3, :3] @ (centre + size * np.array([sx, sy, 0]) / 2)
                        for s in ("left-sole", "right-sole") for sx in (-1, 1) for sy in (-1, 1)])
    low, high = corners[:, :2].min(axis=0), corners[:, :2].max(axis=0)
    cop = feet[:, 6:8]
    cop_margin = np.nanmin(np.minimum(cop - low, high - cop))
    # Reaching, the hand is measured against its last target (a live gotoNd moves it).
    target = desired_position(run.taskRH, context) if run.scenario == "reach" else np.asarray(TARGET)
    fall = fall_report(trace["time"], tilt_of_quaternions(q[:, :4]), q[:, 6], slips[1:], trace["other_contact"][:, 0])
    summary = {
        "scenario": run.scenario,
        "hand_error_m": float(np.linalg.norm(hand[-1] - target)),
        "hand_initial_error_m": float(np.linalg.norm(hand[0] - target)),
        "base_drift_m": float(point_drift(base, 2).max()),
        "base_height_drop_m": float(max(0.0, (base[0, 2] - base[:, 2]).max())),
        # From the first step on: at t = 0 the soles just touch the ground and carry nothing yet.
        "min_normal_force_n": float(min(feet[1:, 2].min(), feet[1:, 5].min())),
        "max_foot_slip_m": float(slip),
        "min_cop_margin_m": float(cop_margin),
        "support_polygon_m": [low.tolist(), high.tolist()],
        # fell, fell_at_s, fall_reason and the margins: sotdrake.fall's criterion (tilt, base drop, slip, other contact).
        **fall,
        "min_base_height_m": float(base[:, 2].min()),
        # The command scaled into the velocity limits (1: never): the smallest factor, and how often.
        "min_velocity_scale": float(scales.min()),
        "scaled_ticks": int(np.count_nonzero(scales < 1.0)),
        "duration_s": duration,
        "ticks": len(trace["time"]),
        "wall_s": wall,
        "realtime_factor": duration / wall,
    }
    joints = robot.device.layout.joints_q
    trace.update(hand_position=hand[1:], base_position=base[1:], cop=cop, support_low=low, support_high=high,
                 joint_tracking_error=trace["q_device"][:, joints] - q[:, joints])
    return summary, trace


def plot(trace: dict, path: Path, title: str = "talos_physics", target=TARGET) -> Path:
    """Contact forces, the CoP in the support polygon, base motion, the CoP along time, the hand
    (its distance to the target for ``reach``) and how well the PD actuators track the SoT's joints."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    t, feet = trace["time"], trace["feet"]
    fig, axes = plt.subplots(3, 2, figsize=(12, 11))
    axes[0, 0].plot(t, feet[:, 2], label="left sole")
    axes[0, 0].plot(t, feet[:, 5], label="right sole")
    axes[0, 0].set_ylabel("normal force (N)")
    axes[0, 0].set_title("contact forces")
    low, high = trace["support_low"], trace["support_high"]
    axes[0, 1].add_patch(Rectangle(low, *(high - low), fill=False, color="k", label="support polygon"))
    axes[0, 1].plot(trace["cop"][:, 0], trace["cop"][:, 1], ".", ms=1, label="CoP")
    axes[0, 1].set_aspect("equal")
    axes[0, 1].set_xlabel("x (m)")
    axes[0, 1].set_ylabel("y (m)")
    axes[0, 1].set_title("centre of pressure (top view)")
    axes[1, 0].plot(t, trace["base_position"] - trace["base_position"][0], label=["x", "y", "z"])
    axes[1, 0].set_ylabel("base displacement (m)")
    axes[1, 0].set_title("floating base")
    axes[1, 1].plot(t, trace["cop"], label=["x", "y"])
    axes[1, 1].set_ylabel("CoP (m)")
    axes[1, 1].set_title("centre of pressure")
    hand_error = np.linalg.norm(trace["hand_position"] - np.asarray(target), axis=1)
    axes[2, 0].semilogy(t, hand_error, label="hand (wrist + 0.1 m) to target")
    axes[2, 0].axhline(5e-3, color="grey", lw=0.8, ls=":", label="5 mm")
    axes[2, 0].set_ylabel("hand error (m)")
    axes[2, 0].set_title("right hand (simulated robot)")
    sag = np.abs(trace["joint_tracking_error"])
    axes[2, 1].semilogy(t, np.maximum(sag.max(axis=1), 1e-6), label="max over joints")
    axes[2, 1].semilogy(t, np.maximum(np.sqrt((sag ** 2).mean(axis=1)), 1e-6), label="RMS over joints")
    axes[2, 1].set_ylabel("|q_device − q_plant| (rad)")
    axes[2, 1].set_title("PD tracking of the SoT's joint references")
    for axis in axes.flat:
        axis.legend(fontsize=8)
        axis.grid(True, alpha=0.3)
        if axis is not axes[0, 1]:
            axis.set_xlabel("time (s)")
    fig.suptitle(title)
    return save_figure(fig, path)


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/physics")
    parser.add_argument("--scenario", choices=["stand", "reach"], default="reach",
                        help="stand: feet and CoM held; reach: the right hand also pushed at 1 s towards (0.5, -0.2, 1.0)")
    parser.add_argument("--loop", choices=["open", "closed"], default="open",
                        help="open: the SoT reads its device's q; closed: the simulated joints and a leg-odometry base")
    parser.add_argument("--push", type=float, default=0.0, help="push the torso with this force (N) at t = 2 s for 0.1 s")
    parser.add_argument("--plant-step", type=float, default=PLANT_STEP,
                        help="the plant's time step (s); the SoT ticks every 1 ms")
    args = parser.parse_args(argv)
    meshcat = start(args)
    try:
        run = build_diagram(args.scenario, args.loop, args.push, meshcat, plant_step=args.plant_step)
    except InvalidInput as error:  # (the plant's own check of --plant-step, the push's of --push)
        parser.error(str(error))
    simulator, wall = simulate(run.diagram, args.duration, run.visualizer, not args.quiet)
    summary, trace = summarize(run, simulator, args.duration, wall)
    summary.update(loop=args.loop, push_n=args.push, plant_step_s=args.plant_step)
    args.out.mkdir(parents=True, exist_ok=True)
    title = f"talos_physics: {args.scenario}, {args.loop} loop" + (f", {args.push:g} N push at 2 s" if args.push else "")
    plot(trace, args.out / "plots.png", title)
    write_run(args.out, run.diagram, summary, trace, meshcat, run.visualizer, bag=args.bag)
    return summary

