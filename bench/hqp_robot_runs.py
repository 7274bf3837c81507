#!/usr/bin/env python3
"""Randomized SolverKine runs on TALOS: the hierarchical QP never fails, the limits always hold.

    python bench/hqp_robot_runs.py                 # 1000 runs of 150 ticks at 1, 2, 5 and 10 ms
    python bench/hqp_robot_runs.py --runs 40 --ticks 60 --periods 5

One diagram per control period holds every task (both feet 6D, the CoM held or kept in a ±3 cm
box, both hands, the posture); run ``i`` uses the period ``periods[i % len(periods)]``, takes a
fresh context and draws: a start configuration (half-sitting moved by a random velocity, clipped to
the limits, so that some joints start on a limit), which tasks are in the stack and in which order
(the feet first), hand targets near (≤ 15 cm) or far (up to 1 m, behind the back, unreachable),
position only or with an orientation, gains with ``λ·dt`` up to 0.5, the posture on all joints or a
random subset, the position margin, and the solver's damping. Every tick checks the solver's
diagnostics (a failure would hold the device: a *frozen tick*), the joint positions against their
limits and the velocities against theirs. Prints a summary and writes it as JSON.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

from output import add_output_arguments, write_json
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from scenario import load_compiled_paths

from sotdrake.configuration import Layout, integrate
from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom, MetaTaskKinePosture, gotoNd
from sotdrake.robot import Robot, add_sot
from sotdrake.robots import TALOS_GRIPPERS, load_talos

GRIPPERS = TALOS_GRIPPERS
DT = 1e-3


@dataclass
class Runs:
    diagram: object
    robot: Robot
    sot: object
    feet: list
    com: MetaTaskKineCom
    com_box: MetaTaskKineCom
    hands: list
    posture: MetaTaskKinePosture


def build(model=None, dt: float = DT) -> Runs:
    """The diagram with every task declared (none pushed: each run builds its own stack)."""
    builder = DiagramBuilder()
    robot = Robot(builder, model or load_talos("reduced"), dt)
    sot = add_sot(robot, solver="hqp")
    sot.setControlSelection(robot.velocity_selection(GRIPPERS))
    feet = [MetaTaskKine6d(name, robot, name[-2:], robot.OperationalPointsMap[op])
            for name, op in (("contactRF", "right-ankle"), ("contactLF", "left-ankle"))]
    com = MetaTaskKineCom(robot)
    com_box = MetaTaskKineCom(robot, name="combox", inequality=True)
    com_box.feature.selec("011")
    hands = [MetaTaskKine6d(name, robot, name, robot.OperationalPointsMap[op])
             for name, op in (("rh", "right-wrist"), ("lh", "left-wrist"))]
    posture = MetaTaskKinePosture(robot)
    return Runs(builder.Build(), robot, sot, feet, com, com_box, hands, posture)


def start_configuration(model, rng) -> np.ndarray:
    spread = rng.uniform(0.0, 0.4)
    q = integrate(model.half_sitting, rng.normal(scale=spread, size=model.nv), 1.0, Layout.of(model.plant))
    lower, upper = model.plant.GetPositionLowerLimits(), model.plant.GetPositionUpperLimits()
    return np.clip(q, lower, upper)


def one_run(runs: Runs, rng: np.random.Generator, ticks: int) -> dict:
    """One random run (see the module docstring): counts of frozen ticks and limit violations."""
    robot, sot, model = runs.robot, runs.sot, runs.robot.model
    dt = robot.dt
    top_gain = min(20.0, 0.5 / dt)  # λ·dt ≤ 0.5
    context = runs.diagram.CreateDefaultContext()
    robot.device.set_position(context, start_configuration(model, rng))
    stack = []
    if rng.random() < 0.9:
        for foot in runs.feet:
            foot.keep(context)
            foot.gain.setConstant(rng.uniform(1, top_gain), context)
            stack.append(foot.task.name)
    com_kind = rng.choice(["held", "box", "none"])
    if com_kind == "held":
        runs.com.keep(context)
        runs.com.gain.setConstant(rng.uniform(1, top_gain), context)
        stack.append(runs.com.task.name)
    elif com_kind == "box":
        runs.com_box.keep(context)
        runs.com_box.gain.setConstant(rng.uniform(1, top_gain), context)
        runs.com_box.task.setBounds([-0.03, -0.03], [0.03, 0.03], context)
        stack.append(runs.com_box.task.name)
    targets = []
    for hand in runs.hands:
        if rng.random() < 0.7:
            here = hand.current_pose(context).translation()
            if rng.random() < 0.5:
                target = here + rng.uniform(-0.15, 0.15, 3)
            else:
                target = rng.uniform([-0.8, -1.0, 0.0], [1.2, 1.0, 2.0])
            if rng.random() < 0.3:  # with an orientation (roll, pitch, yaw)
                target, selection = [*target, *rng.uniform(-np.pi, np.pi, 3)], "111111"
            else:
                selection = "111"
            gotoNd(hand, target, selection, rng.uniform(1, top_gain), context=context)
            targets.append(hand.task.name)
    order = rng.permutation(len(targets))
    stack += [targets[i] for i in order]
    if rng.random() < 0.5:
        runs.posture.gain.setConstant(rng.uniform(0.5, 5), context)
        if rng.random() < 0.5:  # a random subset of the joints
            for index in rng.choice(model.nv, size=int(rng.integers(1, model.nv)), replace=False):
                runs.posture.feature.selectDof(int(index), False, context)
        stack.append(runs.posture.task.name)
    own = sot.GetMyContextFromRoot(context)
    for name in stack:
        sot.push(name, own)
    sot.setPositionMargin(rng.choice([0.0, 1e-3, 1e-2]), own)
    sot.setDamping(rng.choice([0.0, 0.0, 1e-6, 1e-3]), own)

    limits = model.joint_limits()
    lower, upper = limits["position_lower"], limits["position_upper"]
    v_lower, v_upper = limits["velocity_lower"], limits["velocity_upper"]
    layout = robot.device.layout
    simulator = Simulator(runs.diagram, context)
    simulator.Initialize()
    frozen, position_violations, velocity_violations, solve_times, active = 0, 0, 0, [], 0
    failures, fallbacks, drake, iterations, by_active_bounds, by_sweep = [], 0, 0, 0, 0, 0
    for k in range(ticks):
        diagnostics = sot.GetOutputPort("diagnostics").Eval(own)
        v = sot.GetOutputPort("control").Eval(own)
        if diagnostics.failure:
            frozen += 1
            failures.append(diagnostics.failure)
        solve_times.append(diagnostics.solve_time_s)
        if diagnostics.fallbacks:  # a path failed on this tick before another one succeeded
            fallbacks += 1
            drake += any(how.split(" ")[0] not in ("active-set", "active-bounds") for how in diagnostics.level_solvers)
            failures.append(f"fallback: {diagnostics.fallbacks}")
        iterations = max(iterations, diagnostics.max_iterations)
        active += len(diagnostics.active_limits) > 0
        by_active_bounds += diagnostics.level_solvers[:1] == ["active-bounds"]  # the whole stack at once
        by_sweep += diagnostics.level_solvers[:1] == ["qr"]  # the whole stack by the QR sweep
        iv = layout.joints_v
        velocity_violations += int(np.any(v[iv] < v_lower[iv] - 1e-9) or np.any(v[iv] > v_upper[iv] + 1e-9))
        simulator.AdvanceTo((k + 1) * dt)
        q = robot.device.position(simulator.get_context())
        iq = layout.joints_q
        position_violations += int(np.any(q[iq] < lower[iq] - 1e-9) or np.any(q[iq] > upper[iq] + 1e-9))
    return {"dt": dt, "stack": stack, "frozen_ticks": frozen, "position_limit_violations": position_violations,
            "velocity_limit_violations": velocity_violations, "ticks_with_active_limits": active,
            "solve_times_s": solve_times, "failures": failures[:3], "ticks_with_a_fallback": fallbacks,
            "ticks_with_a_drake_fallback": drake,
            "max_iterations": iterations, "ticks_by_active_bounds": by_active_bounds, "ticks_by_qr_sweep": by_sweep}


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=1000)
    parser.add_argument("--ticks", type=int, default=150)
    parser.add_argument("--periods", default="1,2,5,10", help="control periods (ms), comma-separated")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--only", type=int, nargs="*", help="run only these run indices")
    add_output_arguments(parser, "hqp_robot_runs.json")
    args = parser.parse_args(argv)
    import logging

    logging.disable(logging.WARNING)
    periods = [float(p) * 1e-3 for p in args.periods.split(",")]
    model = load_talos("reduced")
    diagrams = {dt: build(model, dt) for dt in periods}
    load_compiled_paths()  # (their first call is not a solve time)
    start = time.perf_counter()
    indices = args.only if args.only else range(args.runs)
    results = []
    for k, i in enumerate(indices):
        results.append(one_run(diagrams[periods[i % len(periods)]], np.random.default_rng(args.seed + i), args.ticks))
        if results[-1]["frozen_ticks"]:
            print(f"run {i}: {results[-1]['failures']}", file=sys.stderr, flush=True)
        if (k + 1) % 100 == 0:
            print(f"{k + 1} runs, {sum(r['frozen_ticks'] > 0 for r in results)} with a frozen tick", file=sys.stderr, flush=True)
    wall = time.perf_counter() - start
    times = 1e3 * np.concatenate([r["solve_times_s"] for r in results])

    def counts(rows: list[dict]) -> dict:
        return {"runs": len(rows), "runs_with_a_frozen_tick": sum(r["frozen_ticks"] > 0 for r in rows),
                "frozen_ticks": sum(r["frozen_ticks"] for r in rows),
                "position_limit_violations": sum(r["position_limit_violations"] for r in rows),
                "velocity_limit_violations": sum(r["velocity_limit_violations"] for r in rows)}

    summary = {
        **counts(results), "ticks_per_run": args.ticks, "ticks": len(results) * args.ticks,
        "by_period_ms": {f"{dt * 1e3:g}": counts([r for r in results if r["dt"] == dt]) for dt in periods},
        "ticks_with_active_limits": sum(r["ticks_with_active_limits"] for r in results),
        "ticks_with_a_fallback": sum(r["ticks_with_a_fallback"] for r in results),
        "ticks_with_a_drake_fallback": sum(r["ticks_with_a_drake_fallback"] for r in results),
        "max_active_set_iterations": max(r["max_iterations"] for r in results),
        "ticks_by_active_bounds": sum(r["ticks_by_active_bounds"] for r in results),
        "ticks_by_qr_sweep": sum(r["ticks_by_qr_sweep"] for r in results),
        "solve_ms_median": float(np.median(times)), "solve_ms_p99": float(np.percentile(times, 99)),
        "solve_ms_max": float(times.max()), "wall_s": wall,
        "failures": [f for r in results for f in r["failures"]][:10],
    }
    print(json.dumps(summary, indent=1))
    write_json(summary, args.out, args.save, indent=1)
    return summary


if __name__ == "__main__":
    main()
