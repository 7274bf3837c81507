#!/usr/bin/env python3
"""The dynamic SoT against a peer on the same scenarios: sway and lift_leg.

sotdrake: ``sotdrake.scenarios.talos_dynamics`` (``diagrams/talos_dynamics.py``) on ``RobotDynSimu`` (the solver
integrates its own ``q̈``, as the peer does), ticks timed one by one around ``Simulator.AdvanceTo`` (Drake's
framework and the Python entities included), by the wall clock and by the thread's CPU time (``time.thread_time``: on
a loaded machine the wall clock also counts the waits for a core). Peer: placo's ``DynamicsSolver`` (C++ core over Pinocchio; weighted QP
with "hard" and "soft" tasks, no strict priorities among soft ones), on the same URDF, the same
CoM and foot references (the same Drake trajectories, sampled), the same gains (CoM K_p = 100,
K_v = 20; foot 400, 40; posture 25, 10), planar sole contacts with μ = 0.7, joint, velocity and
torque limits on. TSID is not used: its wheel needs a source build of libtsid here. The floor: the same
diagram with callbacks that do no maths (``bench/twin.py``), its ticks interleaved with the scenario's.

    python bench/dynamics.py            # --quick: shorter runs

Prints a table and writes ``--out`` (default ``bench/results/dynamics.json``, ignored by git);
``--save`` also writes the committed ``bench/reference/dynamics.json`` the docs show.
"""

from __future__ import annotations

import argparse
import importlib.util
import logging
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from host import Steal
from output import add_output_arguments, write_json
from scenario import DT, load_compiled_paths, pinocchio_half_sitting, urdf_file
from twin import twin

from sotdrake.dynamics.station import sole_rectangle
from sotdrake.dynamics.trajectories import hold_move_hold
from sotdrake.scenarios import talos_dynamics as td


def _tick_numbers(wall: list[float], cpu: list[float]) -> dict:
    """Medians and p95 of the ticks after the first 10 (µs): wall clock and the thread's CPU time."""
    wall_a, cpu_a = np.array(wall[10:]), np.array(cpu[10:])
    return {"tick_us_median": float(np.median(wall_a) * 1e6), "tick_us_p95": float(np.percentile(wall_a, 95) * 1e6),
            "tick_cpu_us_median": float(np.median(cpu_a) * 1e6), "tick_cpu_us_p95": float(np.percentile(cpu_a, 95) * 1e6)}


def run_sotdrake(scenario: str, duration: float) -> dict:
    """The scenario's ticks and, interleaved with them in blocks of 100 ticks, its floor's: the same
    diagram with callbacks that do no maths (``twin.py``)."""
    from pydrake.systems.analysis import Simulator

    run = td.build_diagram(scenario, "dynsimu")
    simulator = Simulator(run.diagram)
    simulator.Initialize()
    floor = Simulator(twin(run.diagram, simulator.get_context()))
    floor.Initialize()
    wall, cpu, floor_wall, floor_cpu = [], [], [], []
    ticks = round(duration / DT)
    for block in range(0, ticks, 100):
        for sim, w, c in ((simulator, wall, cpu), (floor, floor_wall, floor_cpu)):
            for k in range(block, min(block + 100, ticks)):
                start, start_cpu = time.perf_counter(), time.thread_time()
                sim.AdvanceTo((k + 1) * DT)
                c.append(time.thread_time() - start_cpu)
                w.append(time.perf_counter() - start)
    summary, _ = td.summarize(run, simulator, np.array(wall), duration)
    numbers = _tick_numbers(wall, cpu)
    floor_numbers = {f"floor_{k}": v for k, v in _tick_numbers(floor_wall, floor_cpu).items()}
    return {**numbers, **floor_numbers,
            "ratio_to_floor_cpu_median": numbers["tick_cpu_us_median"] / floor_numbers["floor_tick_cpu_us_median"],
            "com_rms_error_m": summary.get("com_rms_error_m"),
            "foot_rms_error_m": summary.get("foot_rms_error_m"), "max_torque_ratio": summary["max_torque_ratio"],
            "max_friction_ratio": summary["max_friction_ratio"], "fell": summary["fell"]}


def _com_reference(scenario: str, com0: np.ndarray, left_xy: np.ndarray, t: float):
    if scenario == "sway":
        y, dy, ddy = td.sway_reference(t)
        e = np.array([0.0, 1.0, 0.0])
        return com0 + y * e, dy * e, ddy * e
    traj = td._com_trajectory("lift_leg", com0, left_xy)
    return traj.value(t)[:, 0], traj.derivative(1).value(t)[:, 0], traj.derivative(2).value(t)[:, 0]


def run_placo(scenario: str, duration: float) -> dict:
    import placo

    robot = placo.RobotWrapper(str(urdf_file()), placo.Flags.ignore_collisions)
    robot.state.q = pinocchio_half_sitting(robot.model)
    robot.update_kinematics()
    solver = placo.DynamicsSolver(robot)
    solver.dt = DT
    solver.enable_joint_limits(True)
    solver.enable_velocity_limits(True)
    solver.enable_torque_limits(True)
    x_min, x_max, y_min, y_max = sole_rectangle()
    feet, contacts = {}, {}
    for side in ("left", "right"):
        frame = f"{side}_sole_link"
        task = solver.add_frame_task(frame, robot.get_T_world_frame(frame))
        task.configure(frame, "hard", 1.0, 1.0)
        contact = solver.add_planar_contact(task)
        contact.length, contact.width, contact.mu = x_max - x_min, y_max - y_min, 0.7
        feet[side], contacts[side] = task, contact
    com0 = robot.com_world().copy()
    left_xy = robot.get_T_world_frame("left_sole_link")[:2, 3] + np.array([(x_min + x_max) / 2, 0.0])
    com = solver.add_com_task(com0)
    com.configure("com", "soft", 1e3)  # weighted far above the posture, as TSID setups do
    com.kp, com.kd = 100.0, 20.0
    posture = solver.add_joints_task()
    posture.set_joints({name: robot.get_joint(name) for name in robot.joint_names()})
    posture.configure("posture", "soft", 1e-2)
    posture.kp, posture.kd = 25.0, 10.0
    foot_p0 = robot.get_T_world_frame("right_sole_link")[:3, 3].copy()
    foot_traj = hold_move_hold(td.LIFT[0], td.LIFT[1], foot_p0, foot_p0 + [0, 0, td.LIFT[2]])
    position = feet["right"].position()
    position.kp, position.kd = 400.0, 40.0
    times, cpu, com_err, foot_err = [], [], [], []
    released = False
    for k in range(round(duration / DT)):
        t = k * DT
        start, start_cpu = time.perf_counter(), time.thread_time()
        target, velocity, acceleration = _com_reference(scenario, com0, left_xy, t)
        com.target_world, com.dtarget_world, com.ddtarget_world = target, velocity, acceleration
        if scenario == "lift_leg":
            if t >= td.RELEASE[0] and not released:
                contacts["right"].active = False  # no ramp in the peer: the contact is dropped
                released = True
            position.target_world = foot_traj.value(t)[:, 0]
            position.dtarget_world = foot_traj.derivative(1).value(t)[:, 0]
            position.ddtarget_world = foot_traj.derivative(2).value(t)[:, 0]
        robot.update_kinematics()
        solver.solve(True)
        cpu.append(time.thread_time() - start_cpu)
        times.append(time.perf_counter() - start)
        robot.update_kinematics()
        com_err.append(np.linalg.norm(robot.com_world() - _com_reference(scenario, com0, left_xy, t + DT)[0]))
        if scenario == "lift_leg" and t + DT >= td.LIFT[0]:
            foot_err.append(np.linalg.norm(robot.get_T_world_frame("right_sole_link")[:3, 3] - foot_traj.value(t + DT)[:, 0]))
    return {**_tick_numbers(times, cpu),
            "com_rms_error_m": float(np.sqrt(np.mean(np.square(com_err)))),
            "foot_rms_error_m": float(np.sqrt(np.mean(np.square(foot_err)))) if foot_err else None,
            "version": getattr(placo, "__version__", "0.10.2")}


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true")
    add_output_arguments(parser, "dynamics.json")
    args = parser.parse_args(argv)
    logging.disable(logging.WARNING)
    durations = {"sway": 1.0 if args.quick else 4.0, "lift_leg": 3.0 if args.quick else 4.0}
    load_compiled_paths()
    has_placo = importlib.util.find_spec("placo") is not None
    if not has_placo:
        print("placo is not installed (pip install placo): sotdrake against its floor only")
    results = {}
    for scenario, duration in durations.items():
        steal = Steal()  # (the host's share of the cores: it inflates both peers' times)
        peer = run_placo(scenario, duration) if has_placo else None
        results[scenario] = {"duration_s": duration, **({"placo": peer} if peer else {}),
                             "sotdrake": run_sotdrake(scenario, duration), "host_steal_fraction": steal.fraction()}
    write_json(results, args.out, args.save)
    print(f"{'scenario':10} {'peer':10} {'CPU p50 (µs)':>13} {'CPU p95':>8} {'wall p50 (µs)':>14} {'wall p95':>9} "
          f"{'CoM RMS (m)':>12} {'foot RMS (m)':>13}")
    for scenario, r in results.items():
        for peer in ("sotdrake", "placo")[: 2 if "placo" in r else 1]:
            row = r[peer]
            foot = "-" if row["foot_rms_error_m"] is None else f"{row['foot_rms_error_m']:.2e}"
            print(f"{scenario:10} {peer:10} {row['tick_cpu_us_median']:13.0f} {row['tick_cpu_us_p95']:8.0f} "
                  f"{row['tick_us_median']:14.0f} {row['tick_us_p95']:9.0f} {row['com_rms_error_m']:12.2e} {foot:>13}")
        ours = r["sotdrake"]
        versus = (f"; sotdrake / placo: {ours['tick_cpu_us_median'] / r['placo']['tick_cpu_us_median']:.2f} (CPU p50, "
                  "target ≤ 2.5)") if "placo" in r else ""
        print(f"{'':10} {Steal.describe(r['host_steal_fraction'])}{versus}; sotdrake / its floor "
              f"({ours['floor_tick_cpu_us_median']:.0f} µs): {ours['ratio_to_floor_cpu_median']:.2f} (CPU p50, target ≤ 2)")
    return results


if __name__ == "__main__":
    main()
