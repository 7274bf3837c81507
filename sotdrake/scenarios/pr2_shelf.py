"""PR2 reaches into the compartments of a shelf with its right arm, with and without the collision
level: the summary gives the smallest signed distance each way and whether each target was reached.

* the robot: ``robot(builder, "pr2")``, arms tucked, base fixed; ``SolverKine`` over the torso lift
  and the right arm (joint position and velocity limits hard);
* the shelf: ``sotdrake/data/shelf.sdf`` (:data:`sotdrake.collision.SHELF`, 0.8 × 0.4 × 1.2 m, three
  compartments) loaded by :func:`sotdrake.collision.add_scene` at :data:`SHELF_POSE`, open towards
  the robot;
* the tasks, in priority order: with the constraint, the collision level (every right-arm link from
  the upper arm to the finger tips against every board of the shelf; ``d_s`` = 1 cm, ``d_i`` = 5 cm,
  ``ξ`` = 0.5 m/s), then the right gripper's tool frame (position) sent to a point 8 cm deep in a
  compartment by ``gotoNd`` (the tutorial's adaptive gain).

Every tick is checked with Drake's query on a collision world of its own (not the task's numbers)::

    python diagrams/pr2_shelf.py --out out/pr2_shelf --duration 4

writes ``summary.json`` (a smallest distance of no pair in range, +inf, as ``null``) and, unless
``--no-meshcat``, ``recording_<target>.html`` per run with the constraint (the shelf drawn).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder

from sotdrake import (
    SHELF,
    SHELF_COMPARTMENTS,
    CollisionWorld,
    MetaTaskKine6d,
    MetaTaskKineCollision,
    Robot,
    add_robot_visualizer,
    add_scene,
    add_sot,
    gotoNd,
    minimum_distance,
    save_recording,
    script_arguments,
    start,
    write_run,
)
from sotdrake import robot as make_robot

#: The shelf's frame in the world (m): its front 0.55 m ahead of the base, a little to the right.
SHELF_POSE = RigidTransform([0.75, -0.2, 0.0])
#: The targets: a point 8 cm deep in each compartment, centred (shelf frame, m).
TARGETS = {name: SHELF_POSE @ np.array([centre[0] - 0.12, centre[1], centre[2]]) for name, centre in SHELF_COMPARTMENTS.items()}
#: The joints the solver moves, and the links the collision level keeps off the shelf.
CONTROLLED = re.compile(r"^(torso_lift_joint|r_(shoulder_pan|shoulder_lift|upper_arm_roll|elbow_flex|forearm_roll|"
                        r"wrist_flex|wrist_roll)_joint)$")
ARM_LINKS = re.compile(r"^r_(upper_arm|forearm|elbow_flex|wrist_flex|gripper)")
REACHED = 0.01  # m: a target is reached when the tool frame ends within this distance


@dataclass
class ShelfReach:
    diagram: Diagram
    robot: Robot
    hand: MetaTaskKine6d
    checker: CollisionWorld
    pairs: list[tuple[str, str]]
    visualizer: object = None


def build_diagram(collision: bool = True, meshcat: Meshcat | None = None, dt: float = 1e-3) -> ShelfReach:
    """The PR2, the shelf, and the stack (see the module docstring)."""
    builder = DiagramBuilder()
    robot = make_robot(builder, "pr2", dt=dt)
    plant = robot.model.plant
    sot = add_sot(robot, "sot", solver="hqp")
    joints = [plant.get_joint(j) for j in plant.GetJointIndices() if plant.get_joint(j).num_velocities() > 0]
    sot.setControlSelection(robot.velocity_selection(excluding=[j.name() for j in joints if not CONTROLLED.match(j.name())]))
    checker = CollisionWorld(robot.model)
    shelf = add_scene(robot, SHELF, SHELF_POSE, "shelf", meshcat)
    add_scene(checker, SHELF, SHELF_POSE, "shelf")
    pairs = [(link, board) for link in checker.links if ARM_LINKS.match(link) for board in shelf]
    if collision:
        sot.push(MetaTaskKineCollision(robot, pairs=pairs))
    hand = MetaTaskKine6d("rh", robot, "right-gripper", robot.OperationalPointsMap["right-gripper"])
    hand.feature.frame("desired")
    sot.push(hand.task.name)
    visualizer = add_robot_visualizer(robot, meshcat) if meshcat is not None else None
    return ShelfReach(builder.Build(), robot, hand, checker, pairs, visualizer)


def run(reach: ShelfReach, target: np.ndarray, duration: float) -> dict:
    """Drive the tool frame to ``target`` for ``duration`` s from the tucked posture; every tick, the
    smallest signed distance of the arm–shelf pairs by Drake's query."""
    simulator = Simulator(reach.diagram)
    context = simulator.get_mutable_context()
    gotoNd(reach.hand, target, "111", (4.9, 0.9, 0.01, 0.9), context=context)
    if reach.visualizer is not None:
        reach.visualizer.StartRecording(False)  # type: ignore[attr-defined]
    simulator.Initialize()
    device_context = reach.robot.device.GetMyContextFromRoot(context)
    checker_context = reach.checker.new_context()
    geometry_pairs = reach.checker.geometry_pairs(reach.pairs)
    smallest = np.inf
    for k in range(1, round(duration / reach.robot.dt) + 1):
        simulator.AdvanceTo(k * reach.robot.dt)
        q = reach.robot.device.GetOutputPort("state").Eval(device_context)
        smallest = min(smallest, minimum_distance(reach.checker, checker_context, q, 0.1, geometry_pairs))
    error = float(np.linalg.norm(reach.hand.current_pose(context).translation() - target))
    return {"min_signed_distance_m": smallest, "hand_error_m": error, "reached": error < REACHED}


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/pr2_shelf", duration=4.0, bag=False)
    args = parser.parse_args(argv)
    if args.duration < 1e-3:
        raise SystemExit(f"--duration must be at least one tick (0.001 s), got {args.duration}")
    meshcat = start(args)
    args.out.mkdir(parents=True, exist_ok=True)
    reaches = {"without": build_diagram(collision=False), "with": build_diagram(collision=True, meshcat=meshcat)}
    summary: dict = {"duration_s": args.duration, "safety_m": 0.01, "shelf_pose_m": SHELF_POSE.translation().tolist(), "runs": {}}
    for name, target in TARGETS.items():
        runs = {}
        for label, reach in reaches.items():
            runs[label] = run(reach, target, args.duration)
            if not args.quiet:
                print(f"{name:7s} {label:7s} min signed distance {runs[label]['min_signed_distance_m'] * 1e3:8.2f} mm, "
                      f"tool frame {runs[label]['hand_error_m'] * 1e3:6.1f} mm from its target")
            if label == "with" and reach.visualizer is not None and meshcat is not None:
                runs[label]["recording"] = str(save_recording(reach.visualizer, meshcat, args.out / f"recording_{name}.html"))
        summary["runs"][name] = {"target_m": target.tolist(), **runs}
    write_run(args.out, reaches["with"].diagram, summary, graph=False)  # (summary.json: inf, no pair in range, as null)
    return summary
