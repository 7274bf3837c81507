"""The project's smallest example: one task on TALOS' left arm (not one of the seed's scripts).

sot-dyninv has no one-arm example: its ``kinesimple.py`` scripts are whole-body stacks (both
contacts, the CoM, the right hand with ``opmodif`` (0, 0, −0.21) sent to (0.5, −0.2, 1.3)), and the
seed's slides name ``ros-kineromeo.py`` as the minimal example (``diagrams/kineromeo.py``). This
script is the step before: one arm, one task, and the interactive prompt.

The ``left_arm`` model (shoulder welded to the world, six arm joints and the gripper), the device
at 1 kHz, the basic ``SOT``, and one ``MetaTaskKine6d`` on the hand (``left-wrist`` moved by
``opmodif`` (0.1, 0, 0), as in the tutorial) driven by ``gotoNd`` to a point 0.245 m away, with a
constant gain. (The wrist's own origin would be a poor choice here: its position depends on three
joints only, which half-sitting aligns, a singular start.) Interactive use, as in the seed::

    python -i diagrams/kinesimple.py --interactive
    >>> step(100); go(1.0); displaySignals(sot, context())

or a whole run::

    python diagrams/kinesimple.py --duration 3 --out out/kinesimple
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.framework import Diagram, DiagramBuilder

from sotdrake import (
    SOT,
    MetaTaskKine6d,
    Robot,
    Tracer,
    add_sot,
    desired_position,
    gotoNd,
    script_arguments,
    simulate,
    start,
    talos,
    write_run,
)
from sotdrake.configuration import velocity_names

OFFSET = (0.1, 0.1, 0.2)  # the target, from the hand's initial position (m, world)


@dataclass
class KineSimple:
    diagram: Diagram
    robot: Robot
    sot: SOT
    taskLW: MetaTaskKine6d
    tracer: Tracer
    target: np.ndarray
    visualizer: object = None


def build_diagram(meshcat: Meshcat | None = None, dt: float = 1e-3) -> KineSimple:
    builder = DiagramBuilder()
    robot = talos(builder, "left_arm", dt)
    sot = add_sot(robot)
    sot.setControlSelection(robot.velocity_selection(excluding=["gripper_left_joint"]))
    taskLW = MetaTaskKine6d("lw", robot, "lw", robot.OperationalPointsMap["left-wrist"])
    handMgrip = np.eye(4)
    handMgrip[0:3, 3] = (0.1, 0.0, 0.0)
    taskLW.opmodif = handMgrip
    target = taskLW.current_pose().translation() + OFFSET
    gotoNd(taskLW, target, "111", 3.0)
    sot.push(taskLW.task.name)
    tracer = Tracer(builder, dt)
    tracer.add(robot.device.GetOutputPort("state"), "q")
    tracer.add(taskLW.task.GetOutputPort("error_norm"), "error_tasklw")
    tracer.add(sot.GetOutputPort("control"), "control")
    visualizer = None
    if meshcat is not None:
        from sotdrake import add_robot_visualizer, add_target_marker

        visualizer = add_robot_visualizer(robot, meshcat)
        add_target_marker(meshcat, "/target", taskLW)  # follows every gotoNd (timed, live)
        meshcat.SetCameraPose(camera_in_world=[1.2, 1.0, 0.3], target_in_world=[0.15, 0.2, -0.35])
    return KineSimple(builder.Build(), robot, sot, taskLW, tracer, target, visualizer)


def summarize(kine: KineSimple, simulator, duration: float, wall: float) -> tuple[dict, dict]:
    context = simulator.get_context()
    trace = kine.tracer.data(context)
    final = kine.taskLW.current_pose(context).translation()
    limits = kine.robot.model.joint_limits()
    q = trace["q"][:, :-1]  # the arm joints (the gripper is last, not controlled)
    margin = np.minimum(q - limits["position_lower"][:-1], limits["position_upper"][:-1] - q).min()
    summary = {
        "hand_error_m": float(np.linalg.norm(final - desired_position(kine.taskLW, context))),  # the last target
        "hand_initial_error_m": float(np.linalg.norm(OFFSET)),
        "min_joint_limit_margin_rad": float(margin),
        "duration_s": duration,
        "ticks": len(trace["time"]),
        "wall_s": wall,
        "realtime_factor": duration / wall,
    }
    return summary, trace


def main(argv: list[str] | None = None):
    parser = script_arguments(__doc__, "out/kinesimple", duration=3.0)
    parser.add_argument("--interactive", action="store_true", help="build, then hand over to the prompt (python -i)")
    args = parser.parse_args(argv)
    meshcat = start(args, live=args.interactive)  # a live view at the prompt, else a recording
    kine = build_diagram(meshcat)
    if args.interactive:
        from sotdrake import Runner

        return kine, Runner(kine.diagram, kine.robot.dt)
    simulator, wall = simulate(kine.diagram, args.duration, kine.visualizer, not args.quiet)
    summary, trace = summarize(kine, simulator, args.duration, wall)
    args.out.mkdir(parents=True, exist_ok=True)
    joints = velocity_names(kine.robot.model.plant)
    kine.tracer.plot(simulator.get_context(), args.out / "plots.png", ["error_tasklw", "control"],
                     title=f"kinesimple: left hand to a point {np.linalg.norm(OFFSET):.3f} m away (basic SOT, left_arm)",
                     labels={"error_tasklw": "hand error ‖e‖ (m)", "control": "joint velocity command (rad/s)"},
                     legends={"error_tasklw": ["hand to target"], "control": joints}, log=("error_tasklw",))
    kine.tracer.save_csv(simulator.get_context(), args.out / "trace.csv")
    write_run(args.out, kine.diagram, summary, trace, meshcat, kine.visualizer, bag=args.bag)
    return summary

