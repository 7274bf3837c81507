"""The sot-talos tutorial (``appli.py``) on TALOS in Drake.

Both feet held (``contactRF``, ``contactLF``: gain 10, ``keep()``), the centre of mass held (gain
10, desired = initial CoM), pushed in that order; at t = 1 s the right hand (``right-wrist`` moved
by ``opmodif`` (0.1, 0, 0)) is pushed with ``gotoNd(taskRH, (0.5, -0.2, 1.0), '111',
(4.9, 0.9, 0.01, 0.9))``. Kinematic simulation at 1 kHz with the basic ``SOT`` solver.

    python diagrams/talos_appli.py --duration 8 --out out/appli

writes ``recording.html`` (Meshcat), ``trace.npz``, ``plots.png``, ``control_graph.svg`` and
``summary.json`` in the output directory. Live, steered from another terminal::

    python diagrams/talos_appli.py --live --no-push     # then: sotdrake-shell "sot.push('taskrh')"

runs at real-time rate until Ctrl-C, then writes the same files (no recording: Meshcat is live).
With the ``ros2`` extra, ``--ros`` runs live with the seed's ``RosPublish`` and its ``run_command`` and
``start_dynamic_graph`` services (drive it with ``diagrams/ros_test.py``); ``--bag`` also writes
``run/run.mcap`` (rosbag2; not with ``--live`` alone). ``--port``, ``--meshcat-port`` and ``--rate``
are options of ``--live`` and ``--ros``: a run that is not live refuses them.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import Meshcat
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem

from sotdrake import (
    MAX_DURATION,
    SOT,
    TALOS_GRIPPERS,
    MetaTaskKine6d,
    MetaTaskKineCom,
    Robot,
    Tracer,
    add_sot,
    attime,
    desired_position,
    gotoNd,
    options_given,
    save_figure,
    script_arguments,
    start,
    talos,
    write_run,
)
from sotdrake import simulate as run_simulation
from sotdrake.live import add_live_arguments, live_meshcat, run_live
from sotdrake.scenarios.common import HAND_OFFSET, gripping_hand, keep_feet_and_com, point_on, support_drift

TARGET = (0.5, -0.2, 1.0)


@dataclass
class Appli:
    """Handles on the diagram's entities, named as in the seed."""

    diagram: Diagram
    robot: Robot
    sot: SOT
    taskRH: MetaTaskKine6d
    taskCom: MetaTaskKineCom
    contactLF: MetaTaskKine6d
    contactRF: MetaTaskKine6d
    tracer: Tracer
    target: np.ndarray
    visualizer: object = None


class TargetTranslation(LeafSystem):
    """A pose's translation as a vector (to trace a task's target).

    Inputs: ``pose`` (``RigidTransform``). Outputs: ``translation`` (3, m), computed anew only
    when the input changes."""

    def __init__(self, name: str = "target_rh_translation"):
        LeafSystem.__init__(self)
        self.set_name(name)
        pose = self.DeclareAbstractInputPort("pose", AbstractValue.Make(RigidTransform()))
        self.DeclareVectorOutputPort("translation", 3, lambda c, out: out.SetFromVector(pose.Eval(c).translation()),
                                     prerequisites_of_calc={self.input_port_ticket(pose.get_index())})


def build_diagram(
    meshcat: Meshcat | None = None,
    target=TARGET,
    push_time: float | None = 1.0,
    dt: float = 1e-3,
    variant: str = "reduced",
    solver: str = "cascade",
    ros: bool = False,
) -> Appli:
    """The tutorial's control graph; with ``meshcat``, TALOS and the target are drawn there.
    ``solver``: ``'cascade'`` (sot-core ``SOT``) or ``'hqp'`` (``SolverKine``, joint limits hard).
    ``push_time=None``: the hand task is not pushed (push it live: ``sot.push('taskrh')``).
    ``ros``: the seed's ``RosPublish`` (``/sot_control/state``, ``/joint_states``, every 100 ticks),
    and the hand's target traced at every tick (``target_rh``: ``run_command`` may move it; the
    bag's ``/sot/target/rh`` is the target in force at each of its samples)."""
    builder = DiagramBuilder()
    robot = talos(builder, variant, dt)

    # --- the right hand: MetaTaskKine6d at 'right-wrist' moved by handMgrip = (0.1, 0, 0)
    taskRH = gripping_hand(robot, "rh", HAND_OFFSET)

    # --- static CoM (seed: taskCom.featureDes.errorIN.value = robot.dynamic.com.value) and contacts
    contactLF, contactRF, taskCom = keep_feet_and_com(robot, gain=10.0)

    # --- the solver and the stack
    sot = add_sot(robot, "sot", solver=solver)
    # The grippers are not the SoT's to move (on TALOS they have their own controllers); left
    # free, the CoM task would use their mass and push them past their upper limit, where both
    # start.
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS))
    sot.push(contactRF.task.name)
    sot.push(contactLF.task.name)
    sot.push(taskCom.task.name)

    # --- the hand: target set now, task pushed at push_time (the tutorial's "moving the hand")
    gotoNd(taskRH, target, "111", (4.9, 0.9, 0.01, 0.9))
    if push_time is not None:
        attime(push_time, lambda: sot.push(taskRH.task.name), "push taskrh: move the right hand")

    # --- tracer: q at every tick, the task errors
    tracer = Tracer(builder, dt)
    tracer.add(robot.device.GetOutputPort("state"), "q")
    tracer.add(sot.GetOutputPort("velocity_scale"), "velocity_scale")
    for meta in (contactRF, contactLF, taskCom, taskRH):
        tracer.add(meta.task.GetOutputPort("error_norm"), f"error_{meta.task.name}")

    visualizer = None
    if meshcat is not None:
        from sotdrake import add_robot_visualizer, add_target_marker

        visualizer = add_robot_visualizer(robot, meshcat)
        add_target_marker(meshcat, "/target", taskRH)  # follows every gotoNd (timed, live)
        meshcat.SetCameraPose(camera_in_world=[1.35, -1.45, 1.35], target_in_world=[0.15, -0.12, 0.72])
    if ros:  # the optional ros2 extra, imported only here
        import sotdrake.ros

        sotdrake.ros.add_ros_publisher(robot)
        translation = builder.AddSystem(TargetTranslation())
        builder.Connect(taskRH.featureDes.GetOutputPort("position"), translation.get_input_port())
        tracer.add(translation.get_output_port(), "target_rh")
    diagram = builder.Build()
    diagram.set_name("talos_appli")
    return Appli(diagram, robot, sot, taskRH, taskCom, contactLF, contactRF, tracer,
                 np.asarray(target, dtype=float), visualizer)


def simulate(appli: Appli, duration: float, progress: bool = True) -> tuple[Simulator, float]:
    """Run for ``duration`` seconds of simulated time; returns the simulator and the wall time."""
    return run_simulation(appli.diagram, duration, appli.visualizer, progress)


def summarize(appli: Appli, simulator: Simulator, duration: float, wall: float) -> tuple[dict, dict]:
    """The summary numbers and the trace (with the hand, feet and CoM along the run)."""
    context = simulator.get_context()
    trace = appli.tracer.data(context)
    robot, q0 = appli.robot, appli.robot.device.initial_position
    qs = np.vstack([q0, trace["q"]])
    path = robot.dynamic.trajectory(["rh", "LF", "RF"], qs)
    hand = point_on(path["rh"], HAND_OFFSET)
    target = desired_position(appli.taskRH, context)  # the last gotoNd's, not the build-time one
    hand_error = np.linalg.norm(hand - target, axis=1)
    limits = robot.model.joint_limits()
    lower, upper = limits["position_lower"], limits["position_upper"]
    finite = np.isfinite(lower) & np.isfinite(upper)
    margin = np.minimum(qs[:, finite] - lower[finite], upper[finite] - qs[:, finite]).min()
    reached = np.flatnonzero(hand_error[1:] < 5e-3)
    ticks = len(trace["time"])
    summary = {
        "hand_error_m": float(hand_error[-1]),
        "hand_initial_error_m": float(hand_error[0]),
        "hand_within_5mm_at_s": float(trace["time"][reached[0]]) if reached.size else None,
        **support_drift(path),
        "min_joint_limit_margin_rad": float(margin),
        # The command scaled into the velocity limits (1: never): the smallest factor, and how often.
        "min_velocity_scale": float(trace["velocity_scale"].min()),
        "scaled_ticks": int(np.count_nonzero(trace["velocity_scale"] < 1.0)),
        "solver": type(appli.sot).__name__,
        "final_stack": appli.sot.stack(context),
        "final_level_residuals": appli.sot.GetOutputPort("residuals").Eval(appli.sot.GetMyContextFromRoot(context)).tolist(),
        "target_m": target.tolist(),
        "duration_s": duration,
        "dt_s": robot.dt,
        "ticks": ticks,
        "wall_s": wall,
        "realtime_factor": duration / wall,
        "tick_us_mean": 1e6 * wall / ticks,
    }
    trace.update(target_position=target, hand_position=hand[1:], com_position=path["com"][1:],
                 left_ankle_position=path["LF"][1:, :3, 3], right_ankle_position=path["RF"][1:, :3, 3])
    return summary, trace


def plot(trace: dict, target: np.ndarray, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    target = trace.get("target_position", target)  # the last target, when the summary has it
    t = trace["time"]
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    axes[0].semilogy(t, np.linalg.norm(trace["hand_position"] - target, axis=1), label="hand to target")
    for name in sorted(k for k in trace if k.startswith("error_")):
        axes[0].semilogy(t, np.maximum(trace[name][:, 0], 1e-16), "--", label=f"‖e‖ {name[6:]}")
    axes[0].axhline(5e-3, color="grey", lw=0.8, ls=":")
    axes[0].set_ylabel("error (m or m+rad)")
    axes[0].legend(fontsize=8)
    axes[0].set_title("TALOS appli: task errors (hand pushed at t = 1 s)")
    for i, axis in enumerate("xyz"):
        axes[1].plot(t, trace["hand_position"][:, i], label=f"hand {axis}")
        axes[1].axhline(target[i], color=f"C{i}", lw=0.8, ls=":")
    axes[1].set_ylabel("hand position (m)")
    axes[1].legend(fontsize=8)
    for name in ("left_ankle_position", "right_ankle_position", "com_position"):
        drift = np.linalg.norm(trace[name] - trace[name][0], axis=1)
        axes[2].semilogy(t, np.maximum(drift, 1e-16), label=name.replace("_position", " drift"))
    axes[2].set_ylabel("drift (m)")
    axes[2].set_xlabel("time (s)")
    axes[2].legend(fontsize=8)
    return save_figure(fig, path, dpi=110)


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/appli", solver="cascade", bag=False)  # its --bag: below, with the ROS 2 flags
    parser.add_argument("--no-push", action="store_true", help="do not push the hand task at t = 1 s")
    add_live_arguments(parser)
    group = parser.add_argument_group("ROS 2 (pip install \".[ros2]\")")
    group.add_argument("--ros", action="store_true", help="live, with RosPublish and the run_command and "
                       "start_dynamic_graph services; the graph holds until started; no push at t = 1 s")
    group.add_argument("--bag", action="store_true", help="also write the run as a rosbag2 (run/run.mcap)")
    args = parser.parse_args(argv)
    live_only = options_given(parser, args, ("port", "meshcat_port", "rate"))  # (read by a live run only)
    if live_only and not (args.live or args.ros):
        parser.error(f"{', '.join(live_only)}: options of --live or --ros (this run is not live)")
    if args.meshcat_port is not None and args.no_meshcat:
        parser.error("--meshcat-port: an option of a live run with Meshcat (this run is --no-meshcat)")
    if args.bag and args.live and not args.ros:
        parser.error("--bag: a --live run writes no bag (a run without --live, or --ros, writes it)")
    push_time = None if args.no_push else 1.0
    if args.duration is not None and not 0 < args.duration <= MAX_DURATION:  # (before a live run waits for its start)
        parser.error(f"--duration must be a number in (0, {MAX_DURATION:g}] s, got {args.duration}")
    if args.ros:
        return main_ros(args)
    if args.live:
        return main_live(args, push_time)
    args.duration = 8.0 if args.duration is None else args.duration
    meshcat = start(args)
    args.out.mkdir(parents=True, exist_ok=True)
    appli = build_diagram(meshcat, push_time=push_time, solver=args.solver)
    simulator, wall = simulate(appli, args.duration, progress=not args.quiet)
    summary, trace = summarize(appli, simulator, args.duration, wall)

    plot(trace, appli.target, args.out / "plots.png")
    if args.bag:
        write_bag(appli, args.out, summary, trace)
    write_run(args.out, appli.diagram, summary, trace, meshcat, appli.visualizer)
    return summary


def main_live(args, push_time: float | None) -> dict:
    """``--live``: real-time rate until Ctrl-C (or ``--duration``), then the trace, plots, graph
    and summary (no recording: Meshcat is live)."""
    logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s")
    meshcat = None if args.no_meshcat else live_meshcat(args.meshcat_port)
    appli = build_diagram(meshcat, push_time=push_time, solver=args.solver)

    def write(out: Path, summary: dict, trace: dict) -> None:
        plot(trace, appli.target, out / "plots.png")
        write_run(out, appli.diagram, summary, trace)

    return run_live(appli, args.out, meshcat, args.duration, args.port, args.rate, summarize, write)


def main_ros(args) -> dict:
    """``--ros``: as ``--live``, with the seed's ``RosPublish`` and its services (the graph holds
    still until ``start_dynamic_graph``; the hand waits for ``run_command``, see ros_test.py)."""
    import sotdrake.ros

    logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s")
    meshcat = None if args.no_meshcat else live_meshcat(args.meshcat_port)
    appli = build_diagram(meshcat, push_time=None, solver=args.solver, ros=True)

    def write(out: Path, summary: dict, trace: dict) -> None:
        plot(trace, appli.target, out / "plots.png")
        write_run(out, appli.diagram, summary, trace)

    return sotdrake.ros.run_ros(appli, args.out, meshcat, args.duration, args.port, args.rate, summarize, write,
                   on_stop=(lambda out, summary, trace: write_bag(appli, out, summary, trace)) if args.bag else None)


def write_bag(appli: Appli, out: Path, summary: dict, trace: dict, every: int = 10) -> Path:
    """``--bag``: the trace every ``every`` ticks as ``out/run/run.mcap`` (needs the ros2 extra).
    ``/sot/target/rh`` is the target in force at each sample: the traced ``target_rh`` (``--ros``,
    where ``run_command`` may move it), else the one the run ended with (no command moved it)."""
    import sotdrake.ros

    trace = dict(trace)
    target = trace.pop("target_rh", None)  # (on /sot/target/rh, not also as an array)
    if target is None:
        target = trace.get("target_position", appli.target)
    path = sotdrake.ros.write_trace_bag(out / "run", trace, sotdrake.ros.joint_coordinates(appli.robot.model.plant),
                                        {"rh": target}, every)
    summary["bag"] = str(path)
    return path

