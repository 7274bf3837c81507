"""The seed's basic dynamic example (``ros-dynromeo.py``) on Romeo: change the contacts, lift the
right leg, with and without the CoM task ("what happens?").

The seed's dynamic robot, ``Robot('romeo', device=RobotDynSimu('romeo'))`` with ``SolverDyn``:
``RobotDyn(builder, load_robot("romeo", "small"), device="dynsimu")``. The device integrates the
solver's ``q̈`` (``v ← v + q̈ dt``, ``q ← q ⊕ v dt``, no physics engine): whatever the solver plans
happens. Both soles are contacts (``contactLF``, ``contactRF`` on ``left-sole``/``right-sole``,
sot-dyninv's Romeo supports as CoP rectangles), under the CoM task (``kp`` 100) and the posture.

* ``lift_leg``: the CoM moves over the centre of the left sole and 2.5 cm up (t = 0.5 → 1.5 s,
  minimum jerk; straighter knees, as the seed's CoM target: Romeo's support knee would reach its
  38 N·m limit when the other leg lifts), then ``sot.rmContact(contactRF)`` at 1.7 s (its force
  ramped to 0 over 0.3 s) with the foot task ``taskRF`` pushed above the posture, and the right
  sole rises 10 cm (2.0 → 3.5 s);
* ``lift_leg_no_com``: the same stack without the CoM task: the seed's "what happens?".

The summary says whether Romeo falls (``fell``, ``fell_at_s``, ``fall_reason``, ``what_happens``):
by the criterion every script shares (:mod:`sotdrake.fall`) or, with no physics engine, by the
held sole leaving its place (``sole moved``), which is the solver failing to hold its own contact:
with the CoM outside the left sole, no contact force inside the sole can balance gravity, so the
"held" left sole tips over its edge. The run stops once the CoM has dropped 0.3 m (there is no ground under ``RobotDynSimu``).

    python diagrams/dynromeo.py --scenario lift_leg_no_com --duration 4 --out out/dynromeo_no_com

writes ``recording.html``, ``trace.npz``, ``plots.png``, ``control_graph.svg`` and ``summary.json``.
"""

from __future__ import annotations

import logging
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, Multiplexer

from sotdrake import (
    Tracer,
    add_robot_visualizer,
    attime,
    load_robot,
    save_figure,
    script_arguments,
    start,
    write_run,
)
from sotdrake.dynamics.contact import Contact6d
from sotdrake.dynamics.meta_tasks_dyn import MetaTaskDyn6d, MetaTaskDynCom, MetaTaskDynPosture
from sotdrake.dynamics.robot_dyn import RobotDyn
from sotdrake.dynamics.trajectories import hold_move_hold, trajectory_ports
from sotdrake.scenarios.common import floating_base_fall, translation_drift

SCENARIOS = ("lift_leg", "lift_leg_no_com")
DT = 5e-3  # the seed's dt (s)
COM_SHIFT = (0.5, 1.5)  # the CoM moves over the left sole in this window (s)
RELEASE = (1.7, 0.3)  # rmContact RF: time (s), force ramp (s)
LIFT = (2.0, 3.5, 0.10)  # the right sole rises 10 cm in this window (s)
#: How much the CoM rises as it moves over the left sole (m): straighter knees, as the seed's CoM
#: target does (Romeo's support knee reaches its 38 N·m limit otherwise, when the other leg lifts).
COM_RISE = 0.025
#: A fall: the held left sole moved or tilted this much (m, rad), or the CoM dropped this much (m).
FALL_SOLE_M, FALL_SOLE_RAD, FALL_COM_DROP_M = 0.01, 0.1, 0.1
#: The run stops once the CoM has dropped this much (m): there is no ground under RobotDynSimu.
STOP_COM_DROP_M = 0.3


@dataclass
class DynRomeo:
    """Handles on the diagram's entities, named as in the seed."""

    diagram: Diagram
    robot: RobotDyn
    tracer: Tracer
    scenario: str
    contactLF: Contact6d
    contactRF: Contact6d
    taskCom: MetaTaskDynCom | None
    taskRF: MetaTaskDyn6d
    taskPosture: MetaTaskDynPosture
    com0: np.ndarray
    visualizer: Any = None


def sole_centre(robot: RobotDyn, contact: str, sole: str) -> np.ndarray:
    """World ``(x, y)`` of the centre of ``sole``'s contact rectangle at the initial configuration."""
    x_min, x_max, y_min, y_max = robot.sole_rectangle(sole)
    X = robot.dynamic.pose_at(contact, robot.q0)
    return (X.translation() + X.rotation().matrix() @ np.array([(x_min + x_max) / 2, (y_min + y_max) / 2, 0.0]))[:2]


def build_diagram(scenario: str = "lift_leg", meshcat: Meshcat | None = None, dt: float = DT) -> DynRomeo:
    if scenario not in SCENARIOS:
        raise ValueError(f"unknown scenario {scenario!r}; available: {SCENARIOS}")
    builder = DiagramBuilder()
    # --- the robot: Robot('romeo', device=RobotDynSimu('romeo')), its dynamic entity and SolverDyn
    robot = RobotDyn(builder, load_robot("romeo", "small"), "dynsimu", dt)
    sot, connect = robot.sot, builder.Connect

    # --- the contacts: both soles
    contactLF = robot.add_contact("contactLF", "left-sole")
    contactRF = robot.add_contact("contactRF", "right-sole")
    sot.addContact(contactLF)
    sot.addContact(contactRF)

    # --- the CoM over the left sole (lift_leg only), the posture
    com0 = robot.dynamic.com_at(robot.q0)
    taskCom = None
    if scenario == "lift_leg":
        taskCom = MetaTaskDynCom(robot, kp=100.0)
        target = com0.copy()
        target[:2] = sole_centre(robot, "contactLF", "left-sole")
        target[2] += COM_RISE
        ports = trajectory_ports(robot, hold_move_hold(*COM_SHIFT, com0, target), "com_trajectory")
        connect(ports[0], taskCom.featureDes.GetInputPort("value_in"))
        connect(ports[1], taskCom.featureDes.GetInputPort("velocity_in"))
        connect(ports[2], taskCom.task.GetInputPort("reference_acceleration"))
        sot.push(taskCom.task.name)
    taskPosture = MetaTaskDynPosture(robot, kp=25.0)
    sot.push(taskPosture.task.name)

    # --- the right foot: kept, then lifted 10 cm once its contact is removed
    taskRF = MetaTaskDyn6d("RF", robot, "right-foot", "right-sole", kp=400.0)
    p0 = taskRF.initial_pose().translation()
    t0, t1, height = LIFT
    value, velocity, acceleration = trajectory_ports(
        robot, hold_move_hold(t0, t1, p0, p0 + [0, 0, height]), "foot_trajectory")
    connect(value, taskRF.featureDes.GetInputPort("translation_in"))
    connect(velocity, taskRF.featureDes.GetInputPort("translation_velocity_in"))
    zeros = robot.add(ConstantVectorSource(np.zeros(3)), "foot_zero_angular")
    foot_acc = robot.add(Multiplexer([3, 3]), "foot_reference_acceleration")
    connect(acceleration, foot_acc.get_input_port(0))
    connect(zeros.get_output_port(), foot_acc.get_input_port(1))
    connect(foot_acc.get_output_port(), taskRF.task.GetInputPort("reference_acceleration"))
    release_time, ramp = RELEASE
    attime(release_time, lambda: (sot.push(taskRF.task.name), sot.up(taskRF.task.name), sot.rmContact(contactRF, ramp)),
           "sot.rmContact('RF') (its force ramped to 0), push the foot task above the posture")

    tracer = Tracer(builder, dt)
    tracer.add(robot.state_port, "x")
    tracer.add(robot.dynamic.GetOutputPort("com"), "com")
    tracer.add(sot.GetOutputPort("torque"), "torque")
    tracer.add(sot.GetOutputPort("wrenches"), "wrenches")
    tracer.add(value, "foot_reference")
    if taskCom is not None:
        tracer.add(taskCom.featureDes.GetOutputPort("errorIN"), "com_reference")

    visualizer = None
    if meshcat is not None:
        visualizer = add_robot_visualizer(robot, meshcat)
        meshcat.SetCameraPose(camera_in_world=[1.3, -1.6, 1.0], target_in_world=[0.0, 0.0, 0.45])
    diagram = builder.Build()
    diagram.set_name("dynromeo")
    return DynRomeo(diagram, robot, tracer, scenario, contactLF, contactRF, taskCom, taskRF, taskPosture, com0, visualizer)


def simulate(run: DynRomeo, duration: float, progress: bool = True) -> tuple[Simulator, np.ndarray]:
    """Advance tick by tick (recording if there is a visualizer) until ``duration`` or until the CoM
    has dropped :data:`STOP_COM_DROP_M`; returns the simulator and the wall time of each tick (s)."""
    from tqdm import tqdm

    simulator = Simulator(run.diagram)
    simulator.Initialize()
    if run.visualizer is not None:
        run.visualizer.StartRecording(False)
    dt, com = run.robot.dt, run.robot.dynamic.GetOutputPort("com")
    com_context = run.robot.dynamic.GetMyContextFromRoot(simulator.get_context())
    times = []
    for k in tqdm(range(round(duration / dt)), disable=not progress, file=sys.stderr, desc=run.scenario):
        start = time.perf_counter()
        simulator.AdvanceTo((k + 1) * dt)
        times.append(time.perf_counter() - start)
        if run.com0[2] - com.Eval(com_context)[2] > STOP_COM_DROP_M:
            break
    return simulator, np.array(times)


def _cop(wrench: np.ndarray, origin: np.ndarray) -> np.ndarray:
    """World ``(x, y)`` of the CoP of a world wrench ``(n, f)`` about a point ``origin`` on the ground."""
    n, f = wrench[:3], wrench[3:]
    if f[2] <= 1e-6:
        return np.full(2, np.nan)
    return origin[:2] + np.array([-n[1], n[0]]) / f[2]


def summarize(run: DynRomeo, simulator: Simulator, times: np.ndarray, duration: float) -> tuple[dict, dict]:
    trace = run.tracer.data(simulator.get_context())
    robot = run.robot
    nq = robot.model.nq
    t, x, com = trace["time"], trace["x"], trace["com"]
    finite = np.all(np.isfinite(x), axis=1)
    q = np.nan_to_num(x[:, :nq])
    path = robot.dynamic.trajectory(["contactLF", "contactRF"], q)
    left, right = path["contactLF"], path["contactRF"]
    left_move = translation_drift(left)
    left_tilt = np.arccos(np.clip(left[:, 2, 2], -1.0, 1.0))  # angle between the sole's z and the world's
    com_drop = com[0, 2] - com[:, 2]
    # The shared criterion (sotdrake.fall), and, without a ground under the dynamic device, the held
    # sole leaving its place (1 cm, or 0.1 rad of tilt) or the CoM dropping 10 cm.
    fall = floating_base_fall(t, x, left_move)
    own = np.flatnonzero(~finite | (left_move > FALL_SOLE_M) | (left_tilt > FALL_SOLE_RAD) | (com_drop > FALL_COM_DROP_M))
    if own.size and (not fall["fell"] or t[own[0]] < fall["fell_at_s"]):
        fall.update(fell=True, fell_at_s=float(t[own[0]]), fall_reason="non-finite" if not finite[own[0]] else "sole moved")
    fell = fall["fell"]
    fell_at = np.flatnonzero(t >= fall["fell_at_s"]) if fell else np.zeros(0, dtype=int)
    wrenches = trace["wrenches"]
    released = t >= RELEASE[0] + RELEASE[1]
    standing = released & (t < (t[fell_at[0]] if fell else np.inf)) & (wrenches[:, 5] > 10.0)  # on the left sole, before any fall
    support_cop = np.array([_cop(w, p) for w, p in zip(wrenches[:, :6], left[:, :3, 3], strict=True)])
    x_min, x_max, y_min, y_max = robot.sole_rectangle("left-sole")
    local = np.einsum("kji,kj->ki", left[:, :2, :2], support_cop - left[:, :2, 3])  # in the sole frame
    cop_margin = np.minimum.reduce([local[:, 0] - x_min, x_max - local[:, 0], local[:, 1] - y_min, y_max - local[:, 1]])
    com_local = np.einsum("kji,kj->ki", left[:, :2, :2], com[:, :2] - left[:, :2, 3])
    com_margin = np.minimum.reduce([com_local[:, 0] - x_min, x_max - com_local[:, 0], com_local[:, 1] - y_min, y_max - com_local[:, 1]])
    release, liftoff = _index(t, RELEASE[0]), _index(t, RELEASE[0] + RELEASE[1] - robot.dt)  # the ramp's first and last ticks
    summary: dict = {
        "robot": robot.model.name, "variant": robot.model.variant, "scenario": run.scenario, "device": "RobotDynSimu",
        "com_task": run.taskCom is not None, "duration_s": duration, "dt_s": robot.dt, "ticks": len(times),
        **fall,
        "max_left_sole_move_m": float(left_move.max()), "max_left_sole_tilt_rad": float(left_tilt.max()),
        "com_drop_m": float(com_drop.max()),
        "com_shift_at_end_m": (com[-1] - com[0]).tolist(),
        "com_margin_in_left_sole_at_release_m": None if release is None else float(com_margin[release]),
        "min_com_margin_in_left_sole_after_release_m": float(com_margin[released].min()) if released.any() else None,
        "min_cop_margin_in_left_sole_after_release_m": float(np.nanmin(cop_margin[standing])) if standing.any() else None,
        "right_force_at_release_n": None if release is None else float(wrenches[release, 11]),
        "right_force_at_liftoff_n": None if liftoff is None else float(wrenches[liftoff, 11]),
        "foot_height_final_m": float(right[-1, 2, 3] - right[0, 2, 3]),
        "max_torque_ratio": float(np.nanmax(np.abs(trace["torque"]) / robot.sot.effort)),
    }
    lifted = t >= LIFT[0]
    if lifted.any():
        error = np.linalg.norm(right[:, :3, 3] - trace["foot_reference"], axis=1)
        summary["foot_rms_error_m"] = float(np.sqrt(np.mean(error[lifted] ** 2)))
    if "com_reference" in trace:
        error = np.linalg.norm(com - trace["com_reference"], axis=1)
        summary["com_rms_error_m"] = float(np.sqrt(np.mean(error**2)))
    summary["tick_ms_median"] = float(np.median(times) * 1e3)
    summary["realtime_factor"] = float(duration / times.sum())
    summary["what_happens"] = _answer(summary)
    trace.update(tick_s=times, left_sole_cop=support_cop, left_sole_tilt=left_tilt, right_sole_height=right[:, 2, 3] - right[0, 2, 3])
    return summary, trace


def _index(t: np.ndarray, when: float) -> int | None:
    """The first sample at or after ``when`` (s), None if the run ended before."""
    k = int(np.searchsorted(t, when - 1e-9))
    return k if k < len(t) else None


def _answer(s: dict) -> str:
    if s["com_margin_in_left_sole_at_release_m"] is None:
        return "the run ended before the right contact was removed"
    outside = -s["com_margin_in_left_sole_at_release_m"]
    if s["fell"]:
        why = ("without the CoM task nothing moves the CoM over the left sole" if not s["com_task"]
               else "the CoM task did not keep the CoM over the left sole")
        side = "right" if s["com_shift_at_end_m"][1] < 0 else "left"
        return (f"Romeo falls at t = {s['fell_at_s']:.2f} s: {why} (the CoM is {outside * 100:.1f} cm outside the left sole's "
                "support when the right contact is removed); once the right force is ramped away, the dynamics and the left "
                f"contact cannot both hold, and Romeo tips over towards its {side}: the left sole tilts "
                f"{np.degrees(s['max_left_sole_tilt_rad']):.0f}° and the CoM drops {s['com_drop_m'] * 100:.0f} cm "
                f"by t = {s['ticks'] * s['dt_s']:.2f} s")
    return (f"Romeo stands on its left sole: the CoM was moved over it before the right contact was removed "
            f"(margin {s['com_margin_in_left_sole_at_release_m'] * 100:.1f} cm at release), and the right foot rises "
            f"{s['foot_height_final_m'] * 100:.1f} cm")


def plot(run: DynRomeo, trace: dict, summary: dict, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon

    t = trace["time"]
    fig, axes = plt.subplots(2, 2, figsize=(13, 8))
    ax = axes[0, 0]
    for i, axis in enumerate("xyz"):
        ax.plot(t, trace["com"][:, i] - run.com0[i], label=f"CoM {axis}")
        if "com_reference" in trace:
            ax.plot(t, trace["com_reference"][:, i] - run.com0[i], "--", color=ax.lines[-1].get_color(), label=f"reference {axis}")
    ax.set_ylabel("CoM − initial CoM (m)")
    ax.set_title("centre of mass")
    ax.legend(fontsize=7, ncol=2)
    ax = axes[0, 1]
    ax.plot(t, trace["wrenches"][:, 5], label="left sole")
    ax.plot(t, trace["wrenches"][:, 11], label="right sole")
    ax.axvline(RELEASE[0], color="k", ls=":", lw=0.8, label="rmContact RF")
    ax.set_ylabel("normal force (N)")
    ax.set_title("contact forces (SolverDyn)")
    ax.legend(fontsize=7)
    ax = axes[1, 0]
    nq = run.robot.model.nq
    poses = run.robot.dynamic.trajectory(["contactLF", "contactRF"], trace["x"][:1, :nq])
    for side, sole, style in (("contactLF", "left-sole", "-"), ("contactRF", "right-sole", ":")):
        x_min, x_max, y_min, y_max = run.robot.sole_rectangle(sole)
        X = poses[side][0]
        square = ((x_min, y_min), (x_max, y_min), (x_max, y_max), (x_min, y_max))
        corners = np.array([X[:3, 3] + X[:3, :3] @ [cx, cy, 0.0] for cx, cy in square])
        ax.add_patch(Polygon(corners[:, :2], fill=False, ls=style, color="k", label=f"{sole} support"))
    ax.plot(trace["com"][:, 0], trace["com"][:, 1], lw=0.8, label="CoM (ground projection)")
    loaded = (trace["wrenches"][:, 5] > 10.0) & (t < (summary["fell_at_s"] or np.inf))
    ax.plot(trace["left_sole_cop"][loaded, 0], trace["left_sole_cop"][loaded, 1], ".", ms=1, label="left sole CoP (SolverDyn, > 10 N)")
    feet = np.array([poses[side][0, :2, 3] for side in ("contactLF", "contactRF")])
    ax.set_xlim(feet[:, 0].min() - 0.2, feet[:, 0].max() + 0.25)
    ax.set_ylim(feet[:, 1].min() - 0.2, feet[:, 1].max() + 0.2)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("support, CoM and CoP (world, seen from above)")
    ax.legend(fontsize=6, loc="lower right")
    ax = axes[1, 1]
    ax.plot(t, trace["right_sole_height"] * 100, label="right sole height (cm)")
    ax.plot(t, (trace["foot_reference"][:, 2] - trace["foot_reference"][0, 2]) * 100, "--", label="its reference (cm)")
    ax.plot(t, np.degrees(trace["left_sole_tilt"]), label="left sole tilt (°)")
    ax.set_ylabel("cm or °")
    ax.set_title("the lifted foot and the support sole")
    ax.legend(fontsize=7)
    for a in (axes[0, 0], axes[0, 1], axes[1, 1]):
        a.set_xlabel("time (s)")
        if summary["fell"]:
            a.axvline(summary["fell_at_s"], color="r", ls="--", lw=0.8)
    com = "with" if summary["com_task"] else "without"
    fig.suptitle(f"dynromeo: Romeo lifts its right leg {com} the CoM task (RobotDynSimu, SolverDyn): fell = {summary['fell']}")
    return save_figure(fig, path)


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/dynromeo", duration=4.0)
    parser.add_argument("--scenario", choices=SCENARIOS, default="lift_leg",
                        help="lift the right leg with the CoM task, or without it (the seed's 'what happens?')")
    args = parser.parse_args(argv)
    meshcat = start(args)
    logging.getLogger("drake").setLevel(logging.WARNING)
    run = build_diagram(args.scenario, meshcat)
    simulator, times = simulate(run, args.duration, not args.quiet)
    summary, trace = summarize(run, simulator, times, args.duration)
    args.out.mkdir(parents=True, exist_ok=True)
    plot(run, trace, summary, args.out / "plots.png")
    write_run(args.out, run.diagram, summary, trace, meshcat, run.visualizer, bag=args.bag)
    return summary

