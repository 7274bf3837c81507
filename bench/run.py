#!/usr/bin/env python3
"""sotdrake benchmarks: tick time, real-time factor, and the peers measured in the same run.

    python bench/run.py            # ~3-5 min
    python bench/run.py --quick    # ~1-2 min

Prints a table and writes ``bench/results/latest.json`` and ``bench/results/profile.txt`` (a
cProfile summary of the basic stack's tick). The peers (pink with daqp, placo) come with
``pip install .[bench]``; a missing peer is reported as such, not silently skipped.

Per-tick times are measured around ``Simulator.AdvanceTo`` one tick at a time (median, p95, max over
≥ 3000 ticks after a warm-up), so they include Drake's framework. The breakdown comes from a
separate instrumented run (exclusive time per category, scaled to the clean median).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import platform
import pstats
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE.parent / "diagrams"))

from pydrake.systems.analysis import Simulator  # noqa: E402
from pydrake.systems.framework import DiagramBuilder  # noqa: E402

from scenario import DT, GAIN_COM, GAIN_FEET, GAIN_HAND, TARGET  # noqa: E402
from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom, MetaTaskKinePosture, gotoNd  # noqa: E402
from sotdrake.robot import Robot, add_sot  # noqa: E402
from sotdrake.robots import load_talos  # noqa: E402

GRIPPERS = ["gripper_left_joint", "gripper_right_joint"]

# --- the sotdrake stacks ---------------------------------------------------------------------


def build_stack(solver: str = "cascade", variant: str = "reduced", tasks: int = 4, target=TARGET):
    """The scenario's stack (feet, CoM, hand), or the first ``tasks`` of a longer list."""
    builder = DiagramBuilder()
    model = load_talos(variant)
    robot = Robot(builder, model, DT)
    sot = add_sot(robot, solver=solver)
    excluded = [g for g in GRIPPERS if model.plant.HasJointNamed(g)]
    sot.setControlSelection(robot.velocity_selection(excluding=excluded))
    hand = None
    if variant == "left_arm":
        hand = MetaTaskKine6d("lh", robot, "lh", "left-wrist")
        gotoNd(hand, hand.current_pose().translation() + [0.05, 0.05, 0.1], "111", GAIN_HAND)
        sot.push(hand.task.name)
        return robot, sot, hand, builder.Build()
    makers = [
        lambda: MetaTaskKine6d("contactRF", robot, "RF", "right-ankle"),
        lambda: MetaTaskKine6d("contactLF", robot, "LF", "left-ankle"),
        lambda: MetaTaskKineCom(robot),
        lambda: MetaTaskKine6d("rh", robot, "rh", "right-wrist"),
        lambda: MetaTaskKine6d("lh", robot, "lh", "left-wrist"),
        lambda: MetaTaskKine6d("chest", robot, "chest", "chest"),
        lambda: MetaTaskKine6d("head", robot, "head", "gaze"),
        lambda: MetaTaskKine6d("relbow", robot, "relbow", "arm_right_4_joint"),
        lambda: MetaTaskKine6d("lelbow", robot, "lelbow", "arm_left_4_joint"),
        lambda: MetaTaskKinePosture(robot),
    ]
    order = [3] if tasks == 1 else list(range(tasks))  # one task: the hand alone
    for index in order:
        meta = makers[index]()
        name = meta.task.name
        if name in ("taskcontactRF", "taskcontactLF"):
            meta.gain.setConstant(GAIN_FEET)
        elif name == "taskcom":
            meta.gain.setConstant(GAIN_COM)
        elif name == "taskrh":
            hand = meta
            meta.opmodif = np.array([[1, 0, 0, 0.1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
            gotoNd(meta, target, "111", GAIN_HAND)
        elif name in ("tasklh", "taskrelbow", "tasklelbow"):
            meta.feature.selec("111")
            meta.gain.setConstant(1.0)
        elif name in ("taskchest", "taskhead"):
            meta.feature.selec("111000")  # orientation only
            meta.gain.setConstant(1.0)
        sot.push(name)
    return robot, sot, hand, builder.Build()


def time_ticks(diagram, ticks: int, warmup: int, sample=None) -> tuple[np.ndarray, Simulator]:
    """Wall time of each tick (AdvanceTo one tick at a time); ``sample(context)`` runs every 10
    ticks outside the timed region."""
    simulator = Simulator(diagram)
    simulator.Initialize()
    times = np.empty(warmup + ticks)
    for k in range(warmup + ticks):
        t = (k + 1) * DT - 0.5 * DT  # the tick at k·dt runs inside this call
        start = time.perf_counter()
        simulator.AdvanceTo(t)
        times[k] = time.perf_counter() - start
        if sample is not None and k % 10 == 0:
            sample(simulator.get_context())
    return times[warmup:], simulator


def stats(times_s: np.ndarray) -> dict:
    us = 1e6 * np.asarray(times_s)
    return {"median": float(np.median(us)), "p95": float(np.percentile(us, 95)), "max": float(us.max()), "n": int(us.size)}


def sotdrake_run(solver: str, ticks: int, warmup: int, target=TARGET) -> dict:
    robot, sot, hand, diagram = build_stack(solver, target=target)
    solver_times = []
    q0 = robot.device.initial_position
    feet0 = [robot.dynamic.pose_at(f, q0).translation() for f in ("left-sole", "right-sole")]
    com0 = robot.dynamic.com_at(q0)
    drift = {"feet": 0.0, "com": 0.0}
    limits = robot.model.joint_limits()
    margin = [np.inf]

    def sample(context):
        q = robot.device.position(context)
        drift["feet"] = max(drift["feet"], max(np.linalg.norm(robot.dynamic.pose_at(f, q).translation() - f0)
                                               for f, f0 in zip(("left-sole", "right-sole"), feet0)))
        drift["com"] = max(drift["com"], np.linalg.norm(robot.dynamic.com_at(q) - com0))
        finite = np.isfinite(limits["position_lower"])
        margin[0] = min(margin[0], np.min(np.minimum(q - limits["position_lower"], limits["position_upper"] - q)[finite]))
        if solver == "hqp":  # the solver's own share of the tick it just ran
            solver_times.append(sot.GetOutputPort("diagnostics").Eval(sot.GetMyContextFromRoot(context)).solve_time_s)

    times, simulator = time_ticks(diagram, ticks, warmup, sample)
    context = simulator.get_context()
    return {
        "times_s": times,
        "solver_times_s": np.array(solver_times),
        "accuracy": {
            "hand_error_m": float(np.linalg.norm(hand.current_pose(context).translation() - target)),
            "max_foot_drift_m": float(drift["feet"]),
            "max_com_drift_m": float(drift["com"]),
            "min_joint_limit_margin_rad": float(margin[0]),
        },
    }


# --- the hierarchical QP on random stacks ---------------------------------------------------------


def hqp_random(count: int) -> dict:
    """Solve time of the default HQP path on ``count`` random stacks (tests/hqp_stacks.py: n 5-40,
    1-5 levels, conflicts, inequalities, scaled rows), each solved cold (no warm start), and of the
    sequential quadprog reference of tests/test_hqp.py on the same stacks."""
    from sotdrake.solvers.hqp import HierarchicalQP
    from tests.hqp_stacks import random_stack

    solvers, times, cpu, reference, reference_cpu = {}, [], [], [], []
    try:
        from tests.test_hqp import reference_slack_norms
    except ImportError:  # the reference needs the test extras (pytest, quadprog)
        reference_slack_norms = None
    for seed in range(count):
        n, levels, x_lower, x_upper = random_stack(np.random.default_rng(seed))
        hqp = solvers.setdefault(n, HierarchicalQP(n))
        hqp._working_sets.clear()  # cold: random stacks share no active sets
        start_cpu = time.process_time()
        times.append(hqp.solve(levels, x_lower, x_upper).solve_time_s)
        cpu.append(time.process_time() - start_cpu)
        if reference_slack_norms is not None and seed < count // 4:
            start, start_cpu = time.perf_counter(), time.process_time()
            reference_slack_norms(n, levels, x_lower, x_upper)
            reference.append(time.perf_counter() - start)
            reference_cpu.append(time.process_time() - start_cpu)
    ms = 1e3 * np.array(times)
    out = {"count": count, "median": float(np.median(ms)), "p99": float(np.percentile(ms, 99)), "max": float(ms.max()),
           "cpu_ms_median": float(1e3 * np.median(cpu))}  # CPU time: less sensitive to a loaded machine
    if reference:
        out["quadprog_reference_ms_median"] = float(1e3 * np.median(reference))
        out["quadprog_reference_cpu_ms_median"] = float(1e3 * np.median(reference_cpu))
    return out


# --- the breakdown ----------------------------------------------------------------------------


def breakdown(ticks: int, calls: dict | None = None) -> dict:
    """Exclusive time per category, from wrapped calc functions (a separate, slower run), as
    fractions of the run's wall time. ``calls``, if given, receives the number of calls of each
    wrapped function (``'<module>.<class>.<function>'``)."""
    from sotdrake import device, kinematics, task
    from sotdrake.features import base, feature6d
    from sotdrake.solvers import sot as sot_module

    totals: dict[str, float] = defaultdict(float)
    stack: list[list[float]] = []

    counts: dict[str, int] = defaultdict(int)

    def timed(function, category):
        key = f"{function.__module__.rsplit('.', 1)[-1]}.{function.__qualname__}"

        def wrapper(*args, **kwargs):
            counts[key] += 1
            stack.append([time.perf_counter(), 0.0])
            try:
                return function(*args, **kwargs)
            finally:
                start, children = stack.pop()
                elapsed = time.perf_counter() - start
                totals[category] += elapsed - children
                if stack:
                    stack[-1][1] += elapsed
        return wrapper

    patches = [
        (kinematics.Dynamic, "_calc_plant_context", "kinematics"), (kinematics.Dynamic, "_pose", "kinematics"),
        (kinematics.Dynamic, "_jacobian", "kinematics"), (kinematics.Dynamic, "_calc_com", "kinematics"),
        (kinematics.Dynamic, "_calc_com_jacobian", "kinematics"),
        (base.Feature, "_calc", "features/tasks"), (task._TaskBase, "_calc", "features/tasks"),
        (feature6d.Feature6dDesired, "_position", "features/tasks"), (feature6d.Feature6dDesired, "_velocity", "features/tasks"),
        (sot_module.SOT, "_calc", "solver"), (device.Device, "_update", "device"),
    ]
    originals = [(cls, name, getattr(cls, name)) for cls, name, _ in patches]
    try:
        for cls, name, category in patches:
            setattr(cls, name, timed(getattr(cls, name), category))
        robot, sot, hand, diagram = build_stack("cascade")
        simulator = Simulator(diagram)
        simulator.Initialize()
        simulator.AdvanceTo(0.2)
        totals.clear()
        counts.clear()
        start = time.perf_counter()
        simulator.AdvanceTo(0.2 + ticks * DT)
        total = time.perf_counter() - start
    finally:
        for cls, name, original in originals:
            setattr(cls, name, original)
    if calls is not None:
        calls.update(counts)
    measured = sum(totals.values())
    result = {category: value / total for category, value in totals.items()}
    result["framework overhead"] = (total - measured) / total
    return result


def profile(path: Path, ticks: int) -> None:
    robot, sot, hand, diagram = build_stack("cascade")
    simulator = Simulator(diagram)
    simulator.Initialize()
    simulator.AdvanceTo(0.2)
    profiler = cProfile.Profile()
    profiler.enable()
    simulator.AdvanceTo(0.2 + ticks * DT)
    profiler.disable()
    text = io.StringIO()
    text.write(f"cProfile of {ticks} ticks of the basic stack (sotdrake, TALOS reduced, 4 tasks)\n\n")
    pstats.Stats(profiler, stream=text).sort_stats("tottime").print_stats(30)
    path.write_text(text.getvalue())


# --- scaling, physics, peers ----------------------------------------------------------------------


def scaling(ticks: int, warmup: int) -> dict:
    by_tasks = {}
    for n in range(1, 11):
        _, _, _, diagram = build_stack("cascade", tasks=n)
        by_tasks[n] = stats(time_ticks(diagram, ticks, warmup)[0])["median"]
    by_dof = {}
    for variant in ("left_arm", "reduced", "full_v2"):
        robot, _, _, diagram = build_stack("cascade", variant=variant, tasks=1)
        by_dof[f"{variant} (nv {robot.dimension})"] = stats(time_ticks(diagram, ticks, warmup)[0])["median"]
    return {"tick_us_median_by_tasks": by_tasks, "tick_us_median_by_dof": by_dof}


def physics_rtf(duration: float) -> dict:
    import talos_physics

    run = talos_physics.build_diagram("reach")
    simulator = Simulator(run.diagram)
    simulator.Initialize()
    start = time.perf_counter()
    simulator.AdvanceTo(duration)
    wall = time.perf_counter() - start
    return {"realtime_factor": duration / wall, "duration_s": duration}


def kinematic_rtf(duration: float) -> float:
    _, _, _, diagram = build_stack("cascade")
    simulator = Simulator(diagram)
    simulator.Initialize()
    start = time.perf_counter()
    simulator.AdvanceTo(duration)
    return duration / (time.perf_counter() - start)


def peer(name: str, ticks: int, warmup: int) -> dict:
    import peers

    try:
        run = peers.run_pink(ticks, warmup) if name == "pink" else peers.run_placo(ticks, warmup)
    except ImportError as error:
        return {"available": False, "reason": f"not installed ({error}); pip install .[bench]"}
    times = run.pop("times_s")
    return {"available": True, "tick_us": stats(times), **run}


# --- main ---------------------------------------------------------------------------------------


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--quick", action="store_true",
                        help="fewer ticks (still ≥ 3000 for the headline numbers); the runs are shorter, so the "
                             "hand errors are read after 3.3 s instead of 6.5 s and are larger")
    parser.add_argument("--out", type=Path, default=HERE / "results", help="where latest.json and profile.txt go")
    args = parser.parse_args(argv)
    import logging

    logging.disable(logging.WARNING)  # the peers warn about the grippers starting on their limits
    ticks, warmup = (3000, 300) if args.quick else (6000, 500)
    small = 500 if args.quick else 1500
    args.out.mkdir(parents=True, exist_ok=True)
    log = lambda message: print(message, file=sys.stderr, flush=True)  # noqa: E731

    log("sotdrake, basic SOT …")
    basic = sotdrake_run("cascade", ticks, warmup)
    log("sotdrake, SolverKine (HQP, joint limits) …")
    hqp = sotdrake_run("hqp", ticks, warmup)
    log("sotdrake, SolverKine with active joint limits (a target behind the back) …")
    hqp_active = sotdrake_run("hqp", max(small, 1000), 200, target=np.array([-0.45, -0.35, 1.0]))
    log("hierarchical QP on random stacks …")
    random_hqp = hqp_random(300 if args.quick else 1000)
    log("pink …")
    pink = peer("pink", ticks, warmup)
    log("placo …")
    placo = peer("placo", ticks, warmup)
    log("breakdown, profile …")
    parts = breakdown(small)
    profile(args.out / "profile.txt", small)
    log("real-time factors …")
    rtf_kinematic = kinematic_rtf(3.0 if args.quick else 8.0)
    rtf_physics = physics_rtf(2.0 if args.quick else 5.0)
    log("scaling …")
    scale = scaling(300 if args.quick else 1000, 100)

    tick = stats(basic["times_s"])
    tick_hqp = stats(hqp["times_s"])
    results = {
        "machine": {"python": platform.python_version(), "processor": platform.processor() or platform.machine(), "cpus": __import__("os").cpu_count()},
        "scenario": "TALOS reduced, feet + CoM held, right hand to (0.5, -0.2, 1.0), joint limits, dt = 1 ms",
        "accuracy_after_s": (warmup + ticks) * DT,
        "realtime_factors_include_recording": False,
        "tick_us_median": tick["median"],
        "tick_us": tick,
        "hqp_tick_us_median": tick_hqp["median"],
        "hqp_tick_us": tick_hqp,
        "hqp_active_limits_tick_us": stats(hqp_active["times_s"]),
        "hqp_active_tick_us_median": stats(hqp_active["times_s"])["median"],
        "hqp_active_solver_us_median": float(1e6 * np.median(hqp_active["solver_times_s"])),
        "hqp_random_solve_ms_median": random_hqp["median"],
        "hqp_random_solve_ms_p99": random_hqp["p99"],
        "hqp_random": random_hqp,
        "realtime_factor_kinematic": rtf_kinematic,
        "realtime_factor_physics": rtf_physics["realtime_factor"],
        "breakdown_fraction": parts,
        "accuracy": {"sotdrake": basic["accuracy"], "sotdrake_hqp": hqp["accuracy"], "sotdrake_hqp_active_limits": hqp_active["accuracy"]},
        "pink": pink,
        "placo": placo,
        **scale,
    }
    if pink.get("available"):
        results["pink_tick_us_median"] = pink["tick_us"]["median"]
        results["ratio_vs_pink"] = tick["median"] / pink["tick_us"]["median"]
        results["hqp_ratio_vs_pink"] = tick_hqp["median"] / pink["tick_us"]["median"]
        results["hqp_active_ratio_vs_pink"] = results["hqp_active_tick_us_median"] / pink["tick_us"]["median"]
        results["accuracy"]["pink"] = pink["accuracy"]
    if placo.get("available"):
        results["placo_tick_us_median"] = placo["tick_us"]["median"]
        results["ratio_vs_placo"] = tick["median"] / placo["tick_us"]["median"]
        results["accuracy"]["placo"] = placo["accuracy"]
    results["targets"] = {
        "tick <= 0.5 x pink": results.get("ratio_vs_pink", float("nan")) <= 0.5,
        "realtime_factor_kinematic >= 2": rtf_kinematic >= 2.0,
        "hqp tick <= 1.0 x pink": results.get("hqp_ratio_vs_pink", float("nan")) <= 1.0,
        "realtime_factor_physics >= 1": rtf_physics["realtime_factor"] >= 1.0,
        "hqp random stacks median <= 1 ms": random_hqp["median"] <= 1.0,
        "hqp active-limits tick <= 2 x pink": results.get("hqp_active_ratio_vs_pink", float("nan")) <= 2.0,
    }
    (args.out / "latest.json").write_text(json.dumps(results, indent=2, default=float) + "\n")
    print_table(results)
    return results


def print_table(r: dict) -> None:
    def row(name, t, acc):
        return (f"{name:28s} {t['median']:9.1f} {t['p95']:9.1f} {t['max']:9.1f}   "
                f"{acc['hand_error_m']:10.2e} {acc['max_foot_drift_m']:10.2e} {acc['max_com_drift_m']:10.2e}")

    print(f"\nhand error and drifts after {r['accuracy_after_s']:.1f} s of the run; real-time factors without Meshcat")
    print(f"{'tick (µs), accuracy (m)':28s} {'median':>9s} {'p95':>9s} {'max':>9s}   {'hand err':>10s} {'foot drift':>10s} {'CoM drift':>10s}")
    print(row("sotdrake SOT (cascade)", r["tick_us"], r["accuracy"]["sotdrake"]))
    print(row("sotdrake SolverKine (HQP)", r["hqp_tick_us"], r["accuracy"]["sotdrake_hqp"]))
    print(row("  … limits active", r["hqp_active_limits_tick_us"], r["accuracy"]["sotdrake_hqp_active_limits"]))
    for name in ("pink", "placo"):
        if r[name].get("available"):
            print(row(f"{name} {r[name].get('version', '')}", r[name]["tick_us"], r[name]["accuracy"]))
        else:
            print(f"{name:28s} {r[name]['reason']}")
    print()
    for key in ("ratio_vs_pink", "hqp_ratio_vs_pink", "hqp_active_ratio_vs_pink", "ratio_vs_placo",
                "realtime_factor_kinematic", "realtime_factor_physics"):
        if key in r:
            print(f"{key:28s} {r[key]:.2f}")
    h = r["hqp_random"]
    print(f"\nHQP on {h['count']} random stacks (ms): median {h['median']:.3f}, p99 {h['p99']:.3f}, max {h['max']:.3f}"
          + (f"; quadprog sequential reference median {h['quadprog_reference_ms_median']:.3f}" if "quadprog_reference_ms_median" in h else "")
          + f"; CPU time median {h['cpu_ms_median']:.3f}"
          + (f" (reference {h['quadprog_reference_cpu_ms_median']:.3f})" if "quadprog_reference_cpu_ms_median" in h else ""))
    print(f"HQP solver's own share of the active-limits tick: median {r['hqp_active_solver_us_median']:.0f} µs"
          f" of {r['hqp_active_tick_us_median']:.0f} µs")
    print("\nbreakdown of the basic tick: " + ", ".join(f"{k} {100 * v:.0f}%" for k, v in sorted(r["breakdown_fraction"].items(), key=lambda x: -x[1])))
    print("tick (µs) by number of tasks: " + ", ".join(f"{n}: {v:.0f}" for n, v in r["tick_us_median_by_tasks"].items()))
    print("tick (µs) by DoF (one hand task): " + ", ".join(f"{n}: {v:.0f}" for n, v in r["tick_us_median_by_dof"].items()))
    print("targets: " + ", ".join(f"{k}: {'met' if v else 'NOT met'}" for k, v in r["targets"].items()))


if __name__ == "__main__":
    main()
