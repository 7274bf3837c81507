"""PR2, the seed's wheeled robot: it reaches an object on a table with its right arm while its base
drives up to the table, under ``SolverKine`` (joint limits hard).

* the robot: ``robot(builder, "pr2")``, its base a planar joint (``root_joint``: x, y, yaw in
  the world), arms tucked (the SRDF's ``tuck_left_arm`` and ``tuck_right_arm``);
* the solver: ``SolverKine`` over the base, the torso lift and the right arm (casters, wheels,
  head, laser, left arm and grippers are left out of the control); joint position and velocity
  limits are hard constraints above every task;
* the tasks, in priority order: the base (``waist``: X, Y and yaw, ``selec = '100011'``) driven
  to a stand-off pose in front of the table (gain 1), then the right gripper's tool frame
  (``right-gripper``, position only) sent to the object by ``gotoNd`` with the tutorial's adaptive
  gain. Both start at t = 0: the arm unfolds while the base moves.

    python diagrams/pr2_reach.py --duration 6 --out out/pr2_reach

writes ``recording.html``, ``trace.npz``, ``plots.png``, ``control_graph.svg`` and ``summary.json``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import Box, Meshcat, Rgba
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder

from sotdrake import (
    SOT,
    MetaTaskKine6d,
    Robot,
    Tracer,
    add_robot_visualizer,
    add_sot,
    add_target_marker,
    desired_position,
    gotoNd,
    save_figure,
    script_arguments,
    simulate,
    start,
    write_run,
)
from sotdrake import robot as make_robot

#: The table: centre of its top surface (m, world) and its size (m).
TABLE_TOP = np.array([1.45, 0.0, 0.72])
TABLE_SIZE = np.array([0.6, 1.0, 0.04])
#: The object on the table (the gripper's tool frame goes there) and the base's stand-off pose.
OBJECT = np.array([1.3, -0.25, 0.78])
BASE_GOAL = np.array([0.75, 0.0])  # x, y of base_link (m); yaw 0
#: The joints the solver moves: the planar base, the torso lift and the right arm.
CONTROLLED = re.compile(r"^(root_joint|torso_lift_joint|r_(shoulder_pan|shoulder_lift|upper_arm_roll|elbow_flex|"
                        r"forearm_roll|wrist_flex|wrist_roll)_joint)$")


@dataclass
class Pr2Reach:
    diagram: Diagram
    robot: Robot
    sot: SOT
    taskBase: MetaTaskKine6d
    taskRH: MetaTaskKine6d
    tracer: Tracer
    target: np.ndarray
    visualizer: object = None


def controlled_joints(robot: Robot) -> list[str]:
    plant = robot.model.plant
    return [plant.get_joint(j).name() for j in plant.GetJointIndices()
            if plant.get_joint(j).num_velocities() > 0 and CONTROLLED.match(plant.get_joint(j).name())]


def build_diagram(meshcat: Meshcat | None = None, dt: float = 1e-3, solver: str = "hqp",
                  target=OBJECT, base_goal=BASE_GOAL) -> Pr2Reach:
    builder = DiagramBuilder()
    robot = make_robot(builder, "pr2", dt=dt)
    plant = robot.model.plant
    sot = add_sot(robot, "sot", solver=solver)
    controlled = set(controlled_joints(robot))
    excluded = [plant.get_joint(j).name() for j in plant.GetJointIndices()
                if plant.get_joint(j).num_velocities() > 0 and plant.get_joint(j).name() not in controlled]
    sot.setControlSelection(robot.velocity_selection(excluding=excluded))

    # --- the base: X, Y and yaw of base_link, to its stand-off pose in front of the table
    taskBase = MetaTaskKine6d("base", robot, "base", robot.OperationalPointsMap["waist"])
    taskBase.feature.frame("desired")
    z_base = taskBase.current_pose().translation()[2]
    gotoNd(taskBase, (base_goal[0], base_goal[1], z_base), "100011", 1.0)

    # --- the right gripper's tool frame to the object (position)
    taskRH = MetaTaskKine6d("rh", robot, "right-gripper", robot.OperationalPointsMap["right-gripper"])
    taskRH.feature.frame("desired")
    gotoNd(taskRH, target, "111", (4.9, 0.9, 0.01, 0.9))

    sot.push(taskBase.task.name)
    sot.push(taskRH.task.name)

    tracer = Tracer(builder, dt)
    tracer.add(robot.device.GetOutputPort("state"), "q")
    tracer.add(sot.GetOutputPort("control"), "control")
    for meta in (taskBase, taskRH):
        tracer.add(meta.task.GetOutputPort("error_norm"), f"error_{meta.task.name}")

    visualizer = None
    if meshcat is not None:

        visualizer = add_robot_visualizer(robot, meshcat)
        add_target_marker(meshcat, "/object", target, radius=0.03, rgba=Rgba(0.9, 0.15, 0.1, 1.0))
        meshcat.SetObject("/table/top", Box(*TABLE_SIZE), Rgba(0.55, 0.4, 0.25, 1.0))
        meshcat.SetTransform("/table/top", RigidTransform(TABLE_TOP - [0, 0, TABLE_SIZE[2] / 2]))
        for i, (sx, sy) in enumerate([(1, 1), (1, -1), (-1, 1), (-1, -1)]):
            height = TABLE_TOP[2] - TABLE_SIZE[2]
            corner = TABLE_TOP + [sx * (TABLE_SIZE[0] / 2 - 0.04), sy * (TABLE_SIZE[1] / 2 - 0.04), 0]
            meshcat.SetObject(f"/table/leg{i}", Box(0.04, 0.04, height), Rgba(0.45, 0.32, 0.2, 1.0))
            meshcat.SetTransform(f"/table/leg{i}", RigidTransform([corner[0], corner[1], height / 2]))
        meshcat.SetCameraPose(camera_in_world=[0.2, -2.6, 1.9], target_in_world=[0.9, 0.0, 0.6])
    diagram = builder.Build()
    diagram.set_name("pr2_reach")
    return Pr2Reach(diagram, robot, sot, taskBase, taskRH, tracer, np.asarray(target, dtype=float), visualizer)


def summarize(kine: Pr2Reach, simulator: Simulator, duration: float, wall: float) -> tuple[dict, dict]:
    context = simulator.get_context()
    trace = kine.tracer.data(context)
    robot = kine.robot
    plant = robot.model.plant
    qs = np.vstack([robot.device.initial_position, trace["q"]])
    path = robot.dynamic.trajectory(["right-gripper", "base"], qs)
    hand = path["right-gripper"][:, :3, 3]
    base = path["base"][:, :3, 3]
    target = desired_position(kine.taskRH, context)  # the last gotoNd's (the object's unless moved live)
    hand_error = np.linalg.norm(hand - target, axis=1)
    base_joint = plant.GetJointByName("root_joint")
    yaw = qs[:, base_joint.position_start() + 2]
    # Joint-limit margin over the joints the solver moves (finite limits only).
    limits = robot.model.joint_limits()
    lower, upper = limits["position_lower"], limits["position_upper"]
    moved = np.zeros(robot.model.nq, dtype=bool)
    for name in controlled_joints(robot):
        joint = plant.GetJointByName(name)
        moved[joint.position_start() : joint.position_start() + joint.num_positions()] = True
    finite = moved & np.isfinite(lower) & np.isfinite(upper)
    margin = np.minimum(qs[:, finite] - lower[finite], upper[finite] - qs[:, finite]).min()
    v_up = limits["velocity_upper"]
    speeds = np.abs(trace["control"])
    finite_v = np.isfinite(v_up) & (v_up > 0)
    reached = np.flatnonzero(hand_error[1:] < 5e-3)
    ticks = len(trace["time"])
    sot_context = kine.sot.GetMyContextFromRoot(context)
    summary = {
        "robot": "pr2",
        "base": robot.model.base,
        "solver": type(kine.sot).__name__,
        "hand_initial_error_m": float(hand_error[0]),
        "hand_error_m": float(hand_error[-1]),
        "hand_within_5mm_at_s": float(trace["time"][reached[0]]) if reached.size else None,
        "base_travel_m": float(np.linalg.norm(base[-1, :2] - base[0, :2])),
        "base_error_m": float(np.linalg.norm(base[-1, :2] - BASE_GOAL)),
        "max_base_yaw_rad": float(np.abs(yaw).max()),
        "min_joint_limit_margin_rad": float(margin),
        "max_joint_velocity_ratio": float((speeds[:, finite_v] / v_up[finite_v]).max()),
        "final_stack": kine.sot.stack(context),
        "final_level_residuals": kine.sot.GetOutputPort("residuals").Eval(sot_context).tolist(),
        "object_m": kine.target.tolist(),
        "duration_s": duration,
        "dt_s": robot.dt,
        "ticks": ticks,
        "wall_s": wall,
        "realtime_factor": duration / wall,
    }
    trace.update(hand_position=hand[1:], base_position=base[1:])
    return summary, trace


def plot(trace: dict, target: np.ndarray, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = trace["time"]
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    axes[0].semilogy(t, np.linalg.norm(trace["hand_position"] - target, axis=1), label="gripper to object")
    axes[0].semilogy(t, np.linalg.norm(trace["base_position"][:, :2] - BASE_GOAL, axis=1), label="base to stand-off")
    for name in sorted(k for k in trace if k.startswith("error_")):
        axes[0].semilogy(t, np.maximum(trace[name][:, 0], 1e-16), "--", label=f"‖e‖ {name[6:]}")
    axes[0].set_ylabel("error (m or m+rad)")
    axes[0].legend(fontsize=8)
    axes[0].set_title("PR2 reach: SolverKine, base task above the gripper task")
    for i, axis in enumerate("xyz"):
        axes[1].plot(t, trace["hand_position"][:, i], label=f"gripper {axis}")
        axes[1].axhline(target[i], color=f"C{i}", lw=0.8, ls=":")
    axes[1].plot(t, trace["base_position"][:, 0], "k--", label="base x")
    axes[1].set_ylabel("position (m)")
    axes[1].legend(fontsize=8)
    axes[2].plot(t, trace["control"], lw=0.8)
    axes[2].set_ylabel("velocity command (rad/s, m/s)")
    axes[2].set_xlabel("time (s)")
    return save_figure(fig, path, dpi=110)


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/pr2_reach", duration=6.0, solver="hqp")
    args = parser.parse_args(argv)
    meshcat = start(args)
    kine = build_diagram(meshcat, solver=args.solver)
    simulator, wall = simulate(kine.diagram, args.duration, kine.visualizer, not args.quiet)
    summary, trace = summarize(kine, simulator, args.duration, wall)
    args.out.mkdir(parents=True, exist_ok=True)
    plot(trace, kine.target, args.out / "plots.png")
    write_run(args.out, kine.diagram, summary, trace, meshcat, kine.visualizer, bag=args.bag)
    return summary

