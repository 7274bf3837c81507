"""The seed's minimal example (``ros-kineromeo.py``) on Romeo: choose the robot, the solver, the
tasks, the viewer, and run.

* the robot: ``robot(builder, "romeo")`` (sot-romeo's ``robot = Robot('robot')``): Romeo (the
  ``small`` model, sot-romeo's 31 joints) in half-sitting, with ``dynamic`` and ``device`` plugged;
  ``--robot`` takes any humanoid of the catalog (talos, icub, g1), whose op points carry the same names;
* the solver: the seed's ``solver = Solver(robot)``: the basic ``SOT`` (SVD threshold 1e-6) with a
  ``JointLimitator`` between its control and the device's, which stops a joint whose next position
  would leave its limits (``--solver hqp``: ``SolverKine``, joint limits also hard in the QP;
  ``--no-limitator``: the bare solver plugged into the device);
* the tasks: both ankles held (``contactRF``, ``contactLF``: gain 10, ``keep()``), the CoM held in
  X and Y (``selec = '011'``, gain 10), the right hand (``right-wrist`` moved by ``opmodif``
  (0.1, 0, 0)) sent by ``gotoNd(taskRH, (0.5, -0.2, 0.8), '111', (4.9, 0.9, 0.01, 0.9))``, pushed
  in that order;
* the viewer: Meshcat (``--no-meshcat`` for none); the run: 5 ms ticks, as in the seed.

    python diagrams/kineromeo.py --duration 5 --out out/kineromeo

writes ``recording.html``, ``trace.npz``, ``plots.png``, ``control_graph.svg`` and ``summary.json``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder

from sotdrake import (
    SOT,
    MetaTaskKine6d,
    MetaTaskKineCom,
    Robot,
    Solver,
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
from sotdrake.scenarios.common import HAND_OFFSET, gripping_hand, keep_feet_and_com, point_on, support_drift

TARGET = (0.5, -0.2, 0.8)
DT = 5e-3  # the seed's dt
#: Joints the SoT leaves alone: hands and fingers (their own controllers on the real robots).
NOT_CONTROLLED = re.compile(r"hand|finger|thumb|gripper", re.I)
#: The variant each robot runs in (``small``: sot-romeo's model, without the finger joints).
VARIANTS = {"romeo": "small", "talos": "reduced", "icub": "full", "g1": "29dof"}


@dataclass
class KineRomeo:
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


def build_diagram(
    meshcat: Meshcat | None = None,
    robot_name: str = "romeo",
    solver: str = "cascade",
    target=TARGET,
    dt: float = DT,
    limitator: bool = True,
) -> KineRomeo:
    """``limitator``: the seed's ``Solver(robot)`` (the solver named ``solver``, a ``JointLimitator``
    before the device); without it, ``add_sot`` (the bare solver, named ``sot``)."""
    builder = DiagramBuilder()
    # --- the robot
    robot = make_robot(builder, robot_name, VARIANTS.get(robot_name), dt)

    # --- the solver
    sot = Solver(robot, solver).sot if limitator else add_sot(robot, "sot", solver=solver)
    plant = robot.model.plant
    excluded = [plant.get_joint(j).name() for j in plant.GetJointIndices()
                if plant.get_joint(j).num_velocities() == 1 and NOT_CONTROLLED.search(plant.get_joint(j).name())]
    sot.setControlSelection(robot.velocity_selection(excluding=excluded))

    # --- the tasks: the grip, the static CoM (X, Y), the contacts
    taskRH = gripping_hand(robot, "right-wrist", HAND_OFFSET)
    contactLF, contactRF, taskCom = keep_feet_and_com(robot, com_selec="011", gain=10.0)
    contacts = {"LF": contactLF, "RF": contactRF}

    # --- run: the target, then the stack
    gotoNd(taskRH, target, "111", (4.9, 0.9, 0.01, 0.9))
    for task in (contacts["RF"], contacts["LF"], taskCom, taskRH):
        sot.push(task.task.name)

    tracer = Tracer(builder, dt)
    tracer.add(robot.device.GetOutputPort("state"), "q")
    for meta in (contacts["RF"], contacts["LF"], taskCom, taskRH):
        tracer.add(meta.task.GetOutputPort("error_norm"), f"error_{meta.task.name}")

    # --- the viewer
    visualizer = None
    if meshcat is not None:

        visualizer = add_robot_visualizer(robot, meshcat)
        add_target_marker(meshcat, "/target", taskRH)  # follows every gotoNd (timed, live)
        meshcat.SetCameraPose(camera_in_world=[1.3, -1.3, 1.2], target_in_world=[0.15, -0.1, 0.6])
    diagram = builder.Build()
    diagram.set_name("kineromeo")
    return KineRomeo(diagram, robot, sot, taskRH, taskCom, contacts["LF"], contacts["RF"], tracer,
                     np.asarray(target, dtype=float), visualizer)


def summarize(kine: KineRomeo, simulator: Simulator, duration: float, wall: float) -> tuple[dict, dict]:
    """The summary numbers and the trace (with the hand, ankles and CoM along the run)."""
    context = simulator.get_context()
    trace = kine.tracer.data(context)
    robot = kine.robot
    qs = np.vstack([robot.device.initial_position, trace["q"]])
    path = robot.dynamic.trajectory(["right-wrist", "LF", "RF"], qs)
    hand = point_on(path["right-wrist"], HAND_OFFSET)
    target = desired_position(kine.taskRH, context)  # the last gotoNd's, not the build-time one
    hand_error = np.linalg.norm(hand - target, axis=1)
    limits = robot.model.joint_limits()
    lower, upper = limits["position_lower"], limits["position_upper"]
    finite = np.isfinite(lower) & np.isfinite(upper)
    margin = np.minimum(qs[:, finite] - lower[finite], upper[finite] - qs[:, finite]).min()
    ticks = len(trace["time"])
    sot_context = kine.sot.GetMyContextFromRoot(context)
    summary = {
        "robot": robot.model.name,
        "variant": robot.model.variant,
        "solver": type(kine.sot).__name__,
        "joint_limitator": kine.robot.limitator is not None,
        "hand_initial_error_m": float(hand_error[0]),
        "hand_error_m": float(hand_error[-1]),
        **support_drift(path),
        "com_height_change_m": float(path["com"][-1, 2] - path["com"][0, 2]),
        "min_joint_limit_margin_rad": float(margin),
        "final_stack": kine.sot.stack(context),
        "final_level_residuals": kine.sot.GetOutputPort("residuals").Eval(sot_context).tolist(),
        "target_m": target.tolist(),
        "duration_s": duration,
        "dt_s": robot.dt,
        "ticks": ticks,
        "wall_s": wall,
        "realtime_factor": duration / wall,
    }
    trace.update(hand_position=hand[1:], com_position=path["com"][1:],
                 left_ankle_position=path["LF"][1:, :3, 3], right_ankle_position=path["RF"][1:, :3, 3])
    return summary, trace


def plot(trace: dict, target: np.ndarray, title: str, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = trace["time"]
    fig, axes = plt.subplots(3, 1, figsize=(8, 9), sharex=True)
    axes[0].semilogy(t, np.linalg.norm(trace["hand_position"] - target, axis=1), label="hand to target")
    for name in sorted(k for k in trace if k.startswith("error_")):
        axes[0].semilogy(t, np.maximum(trace[name][:, 0], 1e-16), "--", label=f"‖e‖ {name[6:]}")
    axes[0].set_ylabel("error (m or m+rad)")
    axes[0].legend(fontsize=8)
    axes[0].set_title(title)
    for i, axis in enumerate("xyz"):
        axes[1].plot(t, trace["hand_position"][:, i], label=f"hand {axis}")
        axes[1].axhline(target[i], color=f"C{i}", lw=0.8, ls=":")
    axes[1].set_ylabel("hand position (m)")
    axes[1].legend(fontsize=8)
    for name in ("left_ankle_position", "right_ankle_position"):
        drift = np.linalg.norm(trace[name] - trace[name][0], axis=1)
        axes[2].semilogy(t, np.maximum(drift, 1e-16), label=name.replace("_position", " drift"))
    com = trace["com_position"]
    axes[2].semilogy(t, np.maximum(np.linalg.norm(com[:, :2] - com[0, :2], axis=1), 1e-16), label="CoM xy drift")
    axes[2].set_ylabel("drift (m)")
    axes[2].set_xlabel("time (s)")
    axes[2].legend(fontsize=8)
    return save_figure(fig, path, dpi=110)


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/kineromeo", duration=5.0, solver="cascade")
    parser.add_argument("--robot", choices=sorted(VARIANTS), default="romeo", help="the humanoid")
    parser.add_argument("--no-limitator", dest="limitator", action="store_false",
                        help="the bare solver into the device (no JointLimitator)")
    args = parser.parse_args(argv)
    meshcat = start(args)
    kine = build_diagram(meshcat, args.robot, args.solver, limitator=args.limitator)
    simulator, wall = simulate(kine.diagram, args.duration, kine.visualizer, not args.quiet)
    summary, trace = summarize(kine, simulator, args.duration, wall)
    args.out.mkdir(parents=True, exist_ok=True)
    plot(trace, kine.target, f"kineromeo on {args.robot}: task errors ({summary['solver']})", args.out / "plots.png")
    write_run(args.out, kine.diagram, summary, trace, meshcat, kine.visualizer, bag=args.bag)
    return summary

