#!/usr/bin/env python3
"""The seed's sot-concept experiment: TALOS grasps a ball with its right hand, the free flyer
relaxed, under the seed's seven configurations, which show what a strict hierarchy does (and what
it cannot), and one more with a manipulability floor.

=====================  ==========================================================================
configuration          stack (highest priority first) and what it shows
=====================  ==========================================================================
under_constrained      hand only: nothing holds the feet or the CoM, the whole body (free flyer
                       included) flies to the ball
balance_held           feet, CoM, hand (damped); the ball is out of reach with the CoM held: the
                       hand stops short (its level keeps a residual) and balance is kept
balance_broken         feet, hand (damped); same ball, CoM not held: the hand gets closer by moving
                       the CoM out of the support polygon (rupture of balance)
singular_undamped      feet, CoM, hand; the ball is straight out along the arm, beyond reach: the
                       arm stretches into a singularity and, undamped, the solution chatters
                       between opposite velocity limits from one tick to the next
singular_damped        the same with damping on the hand's level: smooth, bounded velocities
singular_floor         the same, undamped, with the right arm's manipulability kept above 0.01 by an
                       inequality above the hand (not one of the seed's: ``MetaTaskKineManipulability``)
joint_limits           feet, CoM, hand; a ball behind the back: joints stop at their limits (HQP)
joint_limits_cascade   the same with the basic SOT (pseudo-inverse cascade): limits are crossed
=====================  ==========================================================================

    python diagrams/sot_concept.py --config all --out out/concept

writes ``DIR/summary.json`` (one entry per configuration: ``hand_error_m``, ``com_error_m``,
``level_slacks``, ``min_joint_limit_margin_rad``, ``max_joint_velocity_ratio``,
``max_right_arm_speed_rad_s``, ``min_right_arm_manipulability``, …),
``DIR/plots.png``, ``DIR/control_graph.svg`` and ``DIR/<config>/recording.html`` + ``trace.npz``.
"""

from __future__ import annotations

import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder

from sotdrake import (
    SOT,
    TALOS_GRIPPERS,
    MetaTaskKine6d,
    MetaTaskKineManipulability,
    Robot,
    Tracer,
    add_sot,
    gotoNd,
    hold_feet_and_com,
    manipulability,
    save_figure,
    script_arguments,
    simulate,
    start,
    talos,
    write_control_graph,
    write_run,
)
from sotdrake.configuration import velocity_names

HAND_OFFSET = (0.1, 0.0, 0.0)
RIGHT_ARM = [f"arm_right_{i}_joint" for i in range(1, 8)]


@dataclass(frozen=True)
class Configuration:
    description: str
    ball: tuple[float, float, float]
    contacts: bool = True
    com: bool = True
    solver: str = "hqp"
    damping: float = 0.0
    duration: float = 4.0
    manipulability_floor: float = 0.0  # > 0: the right arm's manipulability kept above it, above the hand

    def __post_init__(self):
        if self.com and not self.contacts:
            raise ValueError("holding the CoM without the feet is not one of the seed's configurations")


CONFIGURATIONS: dict[str, Configuration] = {
    "under_constrained": Configuration("hand only: the free flyer and every joint follow the hand",
                                       (0.65, -0.45, 1.15), contacts=False, com=False),
    # The arm stretches toward an unreachable ball, hence a singularity: the balance configurations
    # damp the hand's level so that only the CoM differs between them (see singular_undamped).
    "balance_held": Configuration("ball out of reach, CoM held: the hand stops short, balance kept",
                                  (1.05, -0.35, 0.75), damping=1e-2),
    "balance_broken": Configuration("same ball, CoM free: the hand gets closer, the CoM leaves the support",
                                    (1.05, -0.35, 0.75), com=False, damping=1e-2),
    "singular_undamped": Configuration("ball beyond reach along the arm: a stretched, singular arm",
                                       (-0.03, -1.25, 1.37)),
    "singular_damped": Configuration("the same with damping 1e-2 on the hand's level",
                                     (-0.03, -1.25, 1.37), damping=1e-2),
    "singular_floor": Configuration("the same with the right arm's manipulability kept above 0.01 (above the hand)",
                                    (-0.03, -1.25, 1.37), manipulability_floor=0.01),
    "joint_limits": Configuration("ball behind the back: joints stop at their limits (HQP)",
                                  (-0.45, -0.35, 1.0)),
    "joint_limits_cascade": Configuration("the same with the basic SOT: limits are crossed",
                                          (-0.45, -0.35, 1.0), solver="cascade"),
}


@dataclass
class Concept:
    diagram: Diagram
    robot: Robot
    sot: SOT
    taskRH: MetaTaskKine6d
    tracer: Tracer
    config: Configuration
    visualizer: object = None


def build_diagram(config: Configuration, meshcat: Meshcat | None = None, dt: float = 1e-3) -> Concept:
    builder = DiagramBuilder()
    robot = talos(builder, "reduced", dt)
    sot = add_sot(robot, "sot", solver=config.solver, damping=config.damping)
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS))
    if config.contacts:
        hold_feet_and_com(robot, sot, com=config.com)
    if config.manipulability_floor > 0:
        floor = MetaTaskKineManipulability("rhManipulability", robot, "right-wrist", config.manipulability_floor, joints=RIGHT_ARM)
        sot.push(floor.task.name)
    taskRH = MetaTaskKine6d("rh", robot, "rh", robot.OperationalPointsMap["right-wrist"])
    handMgrip = np.eye(4)
    handMgrip[0:3, 3] = HAND_OFFSET
    taskRH.opmodif = handMgrip
    gotoNd(taskRH, config.ball, "111", (4.9, 0.9, 0.01, 0.9))
    sot.push(taskRH.task.name)

    tracer = Tracer(builder, dt)
    tracer.add(robot.device.GetOutputPort("state"), "q")
    tracer.add(sot.GetOutputPort("control"), "v")
    visualizer = None
    if meshcat is not None:
        from sotdrake import add_robot_visualizer, add_target_marker

        visualizer = add_robot_visualizer(robot, meshcat)
        add_target_marker(meshcat, "/ball", config.ball, radius=0.05)
        meshcat.SetCameraPose(camera_in_world=[1.6, -2.2, 1.6], target_in_world=[0.1, -0.2, 0.8])
    diagram = builder.Build()
    return Concept(diagram, robot, sot, taskRH, tracer, config, visualizer)


def run(concept: Concept, progress: bool = True) -> tuple[Simulator, float]:
    return simulate(concept.diagram, concept.config.duration, concept.visualizer, progress)


def summarize(concept: Concept, simulator: Simulator, wall: float) -> tuple[dict, dict]:
    context = simulator.get_context()
    trace = concept.tracer.data(context)
    robot = concept.robot
    q0 = robot.device.initial_position
    qs = np.vstack([q0, trace["q"]])
    path = robot.dynamic.trajectory(["rh"], qs)
    hand = path["rh"][:, :3, :3] @ np.asarray(HAND_OFFSET) + path["rh"][:, :3, 3]
    ball = np.asarray(concept.config.ball)
    limits = robot.model.joint_limits()
    layout = robot.device.layout
    # Joints the solver controls (the grippers are excluded, and sit on their limit by design).
    selection = concept.sot.settings(context).control_selection
    controlled = selection[layout.joints_v] if selection is not None else np.ones(len(layout.joints_v), dtype=bool)
    joints_q, joints_v = layout.joints_q[controlled], layout.joints_v[controlled]
    lower, upper = limits["position_lower"][joints_q], limits["position_upper"][joints_q]
    margins = np.minimum(qs[:, joints_q] - lower, upper - qs[:, joints_q])
    ratio = np.abs(trace["v"][:, joints_v]) / limits["velocity_upper"][joints_v]
    names = [name for name, keep in zip(_joint_names(robot), controlled, strict=False) if keep]
    worst_margin = np.unravel_index(np.argmin(margins), margins.shape)
    residuals = concept.sot.GetOutputPort("residuals").Eval(concept.sot.GetMyContextFromRoot(context))
    summary = {
        "description": concept.config.description,
        "solver": type(concept.sot).__name__,
        "stack": concept.sot.stack(context),
        "ball_m": list(concept.config.ball),
        "hand_error_m": float(np.linalg.norm(hand[-1] - ball)),
        "hand_initial_error_m": float(np.linalg.norm(hand[0] - ball)),
        "com_error_m": float(np.linalg.norm(path["com"][-1] - path["com"][0])),
        "com_horizontal_shift_m": float(np.linalg.norm(path["com"][-1, :2] - path["com"][0, :2])),
        "base_displacement_m": float(np.linalg.norm(qs[-1, 4:7] - qs[0, 4:7])),
        "level_slacks": [float(x) for x in residuals],
        "min_joint_limit_margin_rad": float(margins[worst_margin]),
        "min_margin_joint": names[worst_margin[1]],
        "max_joint_velocity_ratio": float(ratio.max()),
        "max_velocity_joint": names[int(np.argmax(ratio.max(axis=0)))],
        "max_joint_speed_rad_s": float(np.abs(trace["v"][:, joints_v]).max()),
        "max_right_arm_speed_rad_s": float(np.abs(trace["v"][:, _arm_velocities(robot)]).max()),
        "min_right_arm_manipulability": _min_arm_manipulability(robot, qs),
        "duration_s": concept.config.duration,
        "wall_s": wall,
        "realtime_factor": concept.config.duration / wall,
    }
    trace.update(hand_position=hand[1:], com_position=path["com"][1:], hand_error=np.linalg.norm(hand[1:] - ball, axis=1),
                 velocity_ratio=ratio.max(axis=1), min_margin=margins[1:].min(axis=1))
    return summary, trace


def _arm_velocities(robot: Robot) -> list[int]:
    return [robot.model.plant.GetJointByName(name).velocity_start() for name in RIGHT_ARM]


def _min_arm_manipulability(robot: Robot, qs: np.ndarray) -> float:
    """The smallest manipulability of the right wrist's translation over the right arm's joints."""
    plant = robot.model.plant
    context, world, wrist = plant.CreateDefaultContext(), plant.world_frame(), robot.model.frame("right-wrist")
    columns = np.zeros(robot.dimension, dtype=bool)
    columns[_arm_velocities(robot)] = True
    values = []
    for q in qs[::10]:
        plant.SetPositions(context, q)
        J = plant.CalcJacobianSpatialVelocity(context, JacobianWrtVariable.kV, wrist, np.zeros(3), world, world)
        values.append(manipulability(J[3:][:, columns]))
    return float(min(values))


def _joint_names(robot: Robot) -> list[str]:
    names = velocity_names(robot.model.plant)
    return [names[i] for i in robot.device.layout.joints_v]


def plot(traces: dict[str, dict], path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(12, 8), sharex=True)
    for name, trace in traces.items():
        t = trace["time"]
        axes[0, 0].semilogy(t, np.maximum(trace["hand_error"], 1e-16), label=name)
        axes[0, 1].plot(t, np.linalg.norm(trace["com_position"][:, :2] - trace["com_position"][0, :2], axis=1), label=name)
        axes[1, 0].semilogy(t, np.maximum(trace["velocity_ratio"], 1e-16), label=name)
        axes[1, 1].plot(t, trace["min_margin"], label=name)
    axes[0, 0].set_ylabel("hand to ball (m)")
    axes[0, 1].set_ylabel("CoM horizontal shift (m)")
    axes[1, 0].set_ylabel("max |v| / velocity limit")
    axes[1, 0].axhline(1.0, color="grey", ls=":")
    axes[1, 1].set_ylabel("min joint-limit margin (rad)")
    axes[1, 1].axhline(0.0, color="grey", ls=":")
    for axis in axes[1]:
        axis.set_xlabel("time (s)")
    axes[0, 0].legend(fontsize=7)
    fig.suptitle("sot-concept: TALOS grasps a ball under seven configurations")
    return save_figure(fig, path)


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/concept", duration=None)
    parser.add_argument("--config", default="all", choices=["all", *CONFIGURATIONS], help="which configuration")
    args = parser.parse_args(argv)  # --duration, if given, overrides every configuration's
    meshcat = start(args)
    names = list(CONFIGURATIONS) if args.config == "all" else [args.config]
    args.out.mkdir(parents=True, exist_ok=True)
    summary, traces = {}, {}
    for name in names:
        config = CONFIGURATIONS[name]
        if args.duration is not None:
            config = Configuration(**{**config.__dict__, "duration": args.duration})
        if meshcat is not None:
            meshcat.Delete()
        concept = build_diagram(config, meshcat)
        if not args.quiet:
            print(f"{name}: {config.description}", file=sys.stderr)
        simulator, wall = run(concept, progress=not args.quiet)
        summary[name], traces[name] = summarize(concept, simulator, wall)
        entry = dict(summary[name])
        write_run(args.out / name, concept.diagram, entry, traces[name], meshcat, concept.visualizer, graph=False, bag=args.bag)
        if name == names[0]:
            write_control_graph(concept.diagram, args.out / "control_graph.svg")
    plot(traces, args.out / "plots.png")
    (args.out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    keys = ("hand_error_m", "com_horizontal_shift_m", "level_slacks", "min_joint_limit_margin_rad", "max_joint_velocity_ratio")
    for name, entry in summary.items():
        print(f"{name:22s} " + "  ".join(f"{k}={np.round(entry[k], 4).tolist()}" for k in keys))
    return summary


if __name__ == "__main__":
    main()
