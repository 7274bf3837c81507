"""A target switch with and without joint acceleration limits (``SolverKine.setAccelerationLimit``).

TALOS (reduced) stands on both feet with its CoM held and reaches with its right hand for a point;
halfway through the run the target jumps to another point. The task's reference velocity jumps
with it (and at the start, from rest), so without acceleration limits the joint velocities jump in
one tick. The same scenario runs twice in one invocation: without a limit, then with
``a_max`` on every joint; the summary gives each run's peak joint acceleration (``|Δv|/dt`` over
the joints and ticks), at the start and at the switch, and the hand's final error::

    python diagrams/target_switch.py --a-max 20 --out out/target_switch

writes ``DIR/summary.json``, ``DIR/plots.png`` (the right elbow's velocity in both runs) and each run's
``trace.npz``. ``--duration`` is at least 10 ms (ticks of 1 ms before and after the switch).
"""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import Diagram, DiagramBuilder

from sotdrake import (
    TALOS_GRIPPERS,
    MetaTaskKine6d,
    Robot,
    SolverKine,
    Tracer,
    add_sot,
    attime,
    gotoNd,
    hold_feet_and_com,
    json_safe,
    save_figure,
    script_arguments,
    simulate,
    start,
    talos,
    write_run,
)

FIRST, SECOND = (0.45, -0.25, 0.95), (0.40, -0.45, 1.15)  # the hand's targets (m, world)
GAIN = 4.0  # the hand's gain (1/s)
DT = 1e-3  # the control period (s)
#: The shortest run (s): each half (before and after the switch) has ticks to measure.
MIN_DURATION = 10 * DT


@dataclass
class TargetSwitch:
    diagram: Diagram
    robot: Robot
    sot: SolverKine
    hand: MetaTaskKine6d
    tracer: Tracer


def build_diagram(a_max: float | None, switch_time: float, dt: float = DT) -> TargetSwitch:
    """The stand-and-reach stack, the target switched at ``switch_time`` (s); ``a_max`` (rad/s²)
    on every joint, or None for no acceleration limit."""
    builder = DiagramBuilder()
    robot = talos(builder, "reduced", dt)
    sot = add_sot(robot, solver="hqp")
    sot.setControlSelection(robot.velocity_selection(TALOS_GRIPPERS))
    if a_max is not None:
        sot.setAccelerationLimit(a_max)
    hold_feet_and_com(robot, sot)
    hand = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    gotoNd(hand, FIRST, "111", GAIN)
    sot.push(hand.task)
    attime(switch_time, lambda: gotoNd(hand, SECOND, "111", GAIN), "the hand's target jumps")
    tracer = Tracer(builder, dt)
    tracer.add(sot.GetOutputPort("control"), "control")
    tracer.add(robot.device.GetOutputPort("state"), "q")
    tracer.add(hand.task.GetOutputPort("error_norm"), "error_taskrh")
    return TargetSwitch(builder.Build(), robot, sot, hand, tracer)


def peak_accelerations(time: np.ndarray, q: np.ndarray, joints_q: np.ndarray, dt: float,
                       switch_time: float) -> dict[str, float]:
    """Peak joint acceleration (rad/s²) of the motion the device made: the velocities applied,
    ``v_k = (q_{k+1} − q_k)/dt`` (from rest, ``v_{−1} = 0``), their largest ``|v_k − v_{k−1}|/dt``
    over the joints, in the first half of the run and from the switch on. (The device's positions,
    not the traced command: a logger samples the command before a timed event of its tick.)"""
    v = np.diff(q[:, joints_q], axis=0) / dt
    rate = np.abs(np.diff(np.vstack([np.zeros((1, len(joints_q))), v]), axis=0)).max(axis=1) / dt
    after = time[:-1] >= switch_time - 1e-9
    return {"start": float(rate[~after].max()), "switch": float(rate[after].max())}


def run(case: TargetSwitch, a_max: float | None, duration: float, progress: bool) -> tuple[dict, dict]:
    """The summary and the trace of ``case`` (:func:`build_diagram` with ``a_max`` and its switch at
    ``duration / 2``) run for ``duration`` s."""
    switch_time = duration / 2
    simulator, wall = simulate(case.diagram, duration, None, progress)
    context = simulator.get_context()
    trace = case.tracer.data(context)
    layout = case.sot.layout
    assert layout is not None  # (built)
    peaks = peak_accelerations(trace["time"], trace["q"], layout.joints_q, case.robot.dt, switch_time)
    error = float(np.linalg.norm(case.hand.current_pose(context).translation() - np.array(SECOND)))
    summary = {"a_max_rad_s2": a_max, "peak_joint_acceleration_rad_s2": peaks, "hand_final_error_m": error,
               "wall_s": wall}
    return summary, trace


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/target_switch", duration=2.0, bag=False, meshcat=False)
    parser.add_argument("--a-max", type=float, default=20.0, help="the acceleration limit of every joint (rad/s²)")
    args = parser.parse_args(argv)
    if not args.duration >= MIN_DURATION:  # (both halves of the run need ticks)
        raise SystemExit(f"--duration must be at least {MIN_DURATION:g} s (ticks before and after the switch at half of it), "
                         f"got {args.duration}")
    start(args)  # (no recording: two runs compared in numbers and a plot)
    limits = {"without": None, "with": args.a_max}
    # Both built before either runs: a refused --a-max stops the script with nothing written.
    cases = {label: build_diagram(a_max, args.duration / 2) for label, a_max in limits.items()}
    runs, traces = {}, {}
    for label, case in cases.items():
        runs[label], traces[label] = run(case, limits[label], args.duration, not args.quiet)
        write_run(args.out / label, case.diagram, dict(runs[label]), traces[label], graph=False)
    summary = {"duration_s": args.duration, "switch_time_s": args.duration / 2, **runs}
    args.out.mkdir(parents=True, exist_ok=True)
    _plot(traces, cases["with"], args.out / "plots.png")
    (args.out / "summary.json").write_text(json.dumps(json_safe(summary), indent=2) + "\n")
    return summary


def _plot(traces: dict, case: TargetSwitch, path) -> None:
    import matplotlib.pyplot as plt

    joint = case.robot.model.plant.GetJointByName("arm_right_4_joint").position_start()
    figure, axis = plt.subplots(figsize=(8, 3.5))
    for label, trace in traces.items():  # the velocity the device applied, (q_{k+1} − q_k)/dt
        applied = np.diff(trace["q"][:, joint]) / case.robot.dt
        axis.plot(trace["time"][:-1], applied, label=f"{label} acceleration limit")
    axis.set_xlabel("time (s)")
    axis.set_ylabel("arm_right_4 velocity (rad/s)")
    axis.set_title("a target switch: the right elbow's velocity")
    axis.legend()
    save_figure(figure, path)

