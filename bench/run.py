#!/usr/bin/env python3
"""sotdrake benchmarks: tick time, real-time factors, and the peers measured in the same run.

    python bench/run.py                  # ~4-6 min; writes bench/results/ (ignored by git)
    python bench/run.py --quick          # ~2 min
    python bench/run.py --out DIR        # another output folder
    python bench/run.py --save           # also overwrite the committed reference, bench/reference.json
    python bench/run.py --table FILE     # print the README's tables from a saved run (e.g. bench/reference.json)

Writes ``latest.json`` (every number), ``table.md`` (the README's tables, from that JSON) and
``profile.txt`` (a cProfile summary of the basic stack's tick) into the output folder; it never
writes over tracked files, except ``bench/reference.json`` with ``--save``: the one committed
reference run, from which the README's benchmark tables are regenerated
(``python bench/run.py --table bench/reference.json``). The peers (pink with daqp, placo) come with
``pip install .[bench]``; a missing peer is reported as such, not silently skipped.

Per-tick times are measured around ``Simulator.AdvanceTo`` one tick at a time (median = p50, p95,
p99, max over ≥ 3000 ticks after a warm-up), so they include Drake's framework. The long runs
(the basic stack, ``SolverKine``, ``SolverKine`` with active limits, pink, placo) are interleaved:
each advances a fortieth of its ticks in turn (:func:`interleave`), so that all of them see the same
seconds of a shared host, whose speed swings within seconds, and the ratios of their medians compare
like with like. The basic tick's target ratio to pink is the median over 7 back-to-back pairs of
short runs (sotdrake, then pink); the ratios of the long runs' medians are printed too. The marginal
cost of a task is the least-squares slope of the median tick against the number of tasks (2 to 10
tasks, each one more 6D, CoM or posture task), the ten stacks timed in turns of 50 ticks. The
breakdown comes from a separate instrumented run (exclusive time per category).

Every tick is timed twice: wall clock, and this thread's CPU time (``time.thread_time``). On a
shared, loaded machine the wall clock also counts the time the process waits for a core, which can
multiply medians and tails; the CPU time does not, so the targets are judged on it, and both are
reported. OpenBLAS runs one thread (small matrices; the same for every peer).
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import os
import platform
import pstats
import sys
import time
from collections import defaultdict
from collections.abc import Generator
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # a control loop's small matrices: one thread, for every peer alike

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from host import Steal
from peers import finish
from pydrake.systems.analysis import Simulator
from report import TARGETS, check_targets, markdown, print_table
from scenario import DT, TARGET, load_compiled_paths
from stacks import GRIPPERS, TASK_MAKERS, build_stack, interleave, interleaved_medians, stats, tick_times, time_ticks

ACTIVE_TARGET = np.array([-0.45, -0.35, 1.0])  # the hand behind the back: joint limits active

__all__ = ["ACTIVE_TARGET", "GRIPPERS", "TARGETS", "TASK_MAKERS", "build_stack", "check_targets", "interleave",
           "interleaved_medians", "markdown", "print_table", "stats", "tick_times", "time_ticks"]

# --- the sotdrake stacks ---------------------------------------------------------------------


def sotdrake_run(solver: str, ticks: int, warmup: int, target=TARGET) -> dict:
    return finish(sotdrake_ticks(solver, ticks, warmup, target))


def sotdrake_ticks(solver: str, ticks: int, warmup: int, target=TARGET) -> Generator[None, None, dict]:
    """The scenario's stack with ``solver``, one tick per ``next``: the per-tick times and the
    accuracy (hand error, feet and CoM drift, joint-limit margin)."""
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
                                               for f, f0 in zip(("left-sole", "right-sole"), feet0, strict=False)))
        drift["com"] = max(drift["com"], np.linalg.norm(robot.dynamic.com_at(q) - com0))
        finite = np.isfinite(limits["position_lower"])
        margin[0] = min(margin[0], np.min(np.minimum(q - limits["position_lower"], limits["position_upper"] - q)[finite]))
        if solver == "hqp":  # the solver's own share of the tick it just ran
            solver_times.append(sot.GetOutputPort("diagnostics").Eval(sot.GetMyContextFromRoot(context)).solve_time_s)

    gen2: list[int] = []
    times, simulator, cpu = yield from tick_times(diagram, ticks, warmup, sample, gen2)
    context = simulator.get_context()
    return {
        "gen2_collections_in_ticks": gen2[0],
        "times_s": times,
        "solver_times_s": np.array(solver_times),
        "cpu_s": cpu,
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
    plain lexicographic reference (bench/lexicographic_reference.py: one quadprog QP per level over
    the null space of the equality rows above) on the same stacks, call by call. ``ratio_median``:
    the median over the stacks of the HQP's CPU time over the reference's. DAQP's hierarchical mode
    (bench/hierarchical_peer.py) too, timed the same way, and how often its answer is
    lexicographically worse or better than the HQP's."""
    from lexicographic_reference import plain_lexicographic

    from sotdrake.hqp.solve import HierarchicalQP
    from tests.hqp_stacks import random_stack

    solvers, times, cpu, reference_cpu, ratios = {}, [], [], [], []
    reference_failures = 0
    daqp_cpu, daqp_ratios, daqp_outcomes = [], [], {"worse": 0, "equal": 0, "better": 0, "better_with_looser_level_above": 0,
                                                    "outside_bounds": 0, "failed": 0}
    for seed in range(count):
        n, levels, x_lower, x_upper = random_stack(np.random.default_rng(seed))
        hqp = solvers.setdefault(n, HierarchicalQP(n))
        hqp.forget_warm_starts()  # cold: random stacks share no active sets
        start_cpu = time.process_time()
        result = hqp.solve(levels, x_lower, x_upper)
        cpu.append(time.process_time() - start_cpu)
        times.append(result.solve_time_s)
        _daqp_peer(n, levels, x_lower, x_upper, result.x, cpu[-1], daqp_cpu, daqp_ratios, daqp_outcomes)
        start_cpu = time.process_time()
        try:
            plain_lexicographic(n, levels, x_lower, x_upper)
        except ValueError:  # quadprog calls a badly scaled level "inconsistent": not timed
            reference_failures += 1
            continue
        reference_cpu.append(time.process_time() - start_cpu)
        ratios.append(cpu[-1] / max(reference_cpu[-1], 1e-9))
    ms = 1e3 * np.array(times)
    out = {"count": count, "median": float(np.median(ms)), "p99": float(np.percentile(ms, 99)), "max": float(ms.max()),
           "cpu_ms_median": float(1e3 * np.median(cpu))}  # CPU time: less sensitive to a loaded machine
    if reference_cpu:
        out["plain_reference_cpu_ms_median"] = float(1e3 * np.median(reference_cpu))
        out["plain_reference_failures"] = reference_failures  # stacks it could not solve (not timed)
        out["ratio_median"] = float(np.median(ratios))
    out["daqp_hierarchical"] = {"cpu_ms_median": float(1e3 * np.median(daqp_cpu)), "ratio_median": float(np.median(daqp_ratios)),
                                "answers": daqp_outcomes}
    return out


def _daqp_peer(n, levels, x_lower, x_upper, x, hqp_cpu: float, cpu: list, ratios: list, outcomes: dict) -> None:
    """DAQP's hierarchical mode on one stack: its CPU time, the HQP's over it, and its answer
    against the HQP's ``x`` (see :mod:`hierarchical_peer`)."""
    from hierarchical_peer import compare, daqp_hierarchical

    start_cpu = time.process_time()
    x_daqp, flag = daqp_hierarchical(n, levels, x_lower, x_upper)
    cpu.append(time.process_time() - start_cpu)
    ratios.append(hqp_cpu / max(cpu[-1], 1e-9))
    if flag < 0 or not np.all(np.isfinite(x_daqp)):
        outcomes["failed"] += 1
    elif np.any(x_daqp < x_lower - 1e-6) or np.any(x_daqp > x_upper + 1e-6):
        outcomes["outside_bounds"] += 1
    else:
        order, looser = compare(levels, x_daqp, x)
        outcomes[("better", "equal", "worse")[order + 1]] += 1
        outcomes["better_with_looser_level_above"] += int(order < 0 and looser)


# --- the breakdown ----------------------------------------------------------------------------


def breakdown(ticks: int, calls: dict | None = None) -> dict:
    """Exclusive time per category, from wrapped calc functions (a separate, slower run), as
    fractions of the run's wall time. ``calls``, if given, receives the number of calls of each
    wrapped function (``'<module>.<class>.<function>'``)."""
    from sotdrake import device, gains, kinematics, task
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
        (gains._Gain, "_calc_gain", "features/tasks"),
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


def _slope(by_tasks: dict) -> float:
    counts = np.arange(2, 11)
    return float(np.polyfit(counts, [by_tasks[n] for n in counts], 1)[0])


def scaling(ticks: int, warmup: int) -> dict:
    """The tick by number of tasks, and the framework's floor (``bench/floor.py``: the same graph with
    callbacks that do no maths) by number of tasks, all timed in the same turns."""
    import floor

    diagrams = {n: build_stack("cascade", tasks=n)[3] for n in range(1, 11)}
    diagrams.update({f"floor {n}": floor.build(n) for n in range(1, 11)})
    wall, cpu = interleaved_medians(diagrams, ticks, warmup)
    by_tasks = {n: wall[n] for n in range(1, 11)}
    by_tasks_cpu = {n: cpu[n] for n in range(1, 11)}
    framework = {n: cpu[f"floor {n}"] for n in range(1, 11)}
    stacks = {}
    for variant in ("left_arm", "reduced", "full_v2"):
        robot, _, _, diagram = build_stack("cascade", variant=variant, tasks=1)
        stacks[f"{variant} (nv {robot.dimension})"] = diagram
    by_dof, by_dof_cpu = interleaved_medians(stacks, ticks, warmup)
    return {"tick_us_median_by_tasks": by_tasks, "marginal_task_us": _slope(by_tasks),
            "tick_cpu_us_median_by_tasks": by_tasks_cpu, "marginal_task_cpu_us": _slope(by_tasks_cpu),
            "tick_us_median_by_dof": by_dof, "tick_cpu_us_median_by_dof": by_dof_cpu,
            "framework_floor_cpu_us_by_tasks": framework, "framework_floor_cpu_us_per_task": _slope(framework)}


def _rtf(diagram, duration: float) -> dict:
    """Simulated time over wall time, and over this process's CPU time."""
    simulator = Simulator(diagram)
    simulator.Initialize()
    start, start_cpu = time.perf_counter(), time.process_time()
    simulator.AdvanceTo(duration)
    return {"wall": duration / (time.perf_counter() - start), "cpu": duration / (time.process_time() - start_cpu)}


def physics_rtf(duration: float) -> dict:
    """Real-time factors of ``talos_physics --scenario reach``."""
    from sotdrake.scenarios import talos_physics

    return _rtf(talos_physics.build_diagram("reach").diagram, duration)


def kinematic_rtf(duration: float) -> dict:
    """Real-time factors of the tutorial (``sotdrake.scenarios.talos_appli``: its tracer, its ``attime``
    push of the hand task), without Meshcat."""
    from sotdrake.scenarios import talos_appli

    return _rtf(talos_appli.build_diagram(None).diagram, duration)


#: What each peer imports: a peer whose modules are missing is reported as not installed.
PEER_MODULES = {"pink": ("pinocchio", "pink"), "placo": ("placo",)}


def peer_ticks(name: str, ticks: int, warmup: int) -> Generator[None, None, dict] | str:
    """The peer's tick generator (``peers.pink_ticks`` or ``peers.placo_ticks``), or why it cannot run."""
    import importlib

    import peers

    try:
        for module in PEER_MODULES[name]:
            importlib.import_module(module)
    except ImportError as error:
        return f"not installed ({error}); pip install .[bench]"
    return peers.pink_ticks(ticks, warmup) if name == "pink" else peers.placo_ticks(ticks, warmup)


def peer_result(run: dict | str) -> dict:
    """A peer's times as statistics, or the reason it did not run (:func:`peer_ticks`)."""
    if isinstance(run, str):
        return {"available": False, "reason": run}
    times, cpu = run.pop("times_s"), run.pop("cpu_s")
    return {"available": True, "tick_us": stats(times), "tick_cpu_us": stats(cpu), **run}


def paired_ratio(rounds: int, ticks: int, warmup: int, solver: str = "cascade", target=TARGET) -> dict | None:
    """The basic tick (or ``solver``'s, with the hand ``target``) against pink's, in ``rounds``
    back-to-back pairs of short runs (sotdrake, then pink, each ``ticks`` ticks after ``warmup``): the
    ratios of the medians of each pair (wall and CPU time), whose two halves see the same load on a
    shared machine. None without pink."""
    import peers

    out = {"ratios": [], "cpu_ratios": []}
    for _ in range(rounds):
        _, _, _, diagram = build_stack(solver, target=target)
        wall, _, cpu = time_ticks(diagram, ticks, warmup)
        try:
            pink = peers.run_pink(ticks, warmup)
        except ImportError:
            return None
        out["ratios"].append(float(np.median(wall) / np.median(pink["times_s"])))
        out["cpu_ratios"].append(float(np.median(cpu) / np.median(pink["cpu_s"])))
    out["median"], out["cpu_median"] = float(np.median(out["ratios"])), float(np.median(out["cpu_ratios"]))
    return out


# --- main ---------------------------------------------------------------------------------------


REFERENCE = HERE / "reference.json"  # the committed reference run; only --save overwrites it

def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.ArgumentDefaultsHelpFormatter)
    parser.add_argument("--quick", action="store_true",
                        help="fewer ticks (still ≥ 3000 for the headline numbers); the runs are shorter, so the "
                             "hand errors are read after 3.3 s instead of 6.5 s and are larger")
    parser.add_argument("--out", type=Path, default=HERE / "results", help="output folder (ignored by git)")
    parser.add_argument("--save", action="store_true", help=f"also write the run to {REFERENCE.relative_to(HERE.parent)}")
    parser.add_argument("--table", type=Path, help="print the README's tables from a saved run and exit")
    parser.add_argument("--ticks", type=int, help="ticks per measurement (a smoke test of the harness; not a benchmark)")
    args = parser.parse_args(argv)
    if args.table is not None:
        text = markdown(json.loads(args.table.read_text()))
        print(text)
        return {}
    import logging

    logging.disable(logging.WARNING)  # the peers warn about the grippers starting on their limits
    ticks, warmup = (3000, 300) if args.quick else (6000, 500)
    small = 500 if args.quick else 1500
    if args.ticks is not None:
        ticks, warmup, small = args.ticks, 10, args.ticks
    args.out.mkdir(parents=True, exist_ok=True)
    log = lambda message: print(message, file=sys.stderr, flush=True)  # noqa: E731

    load_compiled_paths()
    steal = Steal()  # (the host's share of the cores over the run: it inflates every timing)
    log("sotdrake (basic SOT, SolverKine, SolverKine with active joint limits) and the peers, interleaved …")
    active_ticks, active_warmup = (max(small, 1000), 200) if args.ticks is None else (args.ticks, 10)
    runs = {
        "basic": (sotdrake_ticks("cascade", ticks, warmup), ticks + warmup),
        "hqp": (sotdrake_ticks("hqp", ticks, warmup), ticks + warmup),
        # the hand behind the back: the joint limits become active
        "hqp_active": (sotdrake_ticks("hqp", active_ticks, active_warmup, target=ACTIVE_TARGET), active_ticks + active_warmup),
    }
    peer_runs = {name: peer_ticks(name, ticks, warmup) for name in PEER_MODULES}
    runs.update({name: (run, ticks + warmup) for name, run in peer_runs.items() if not isinstance(run, str)})
    done = interleave(runs)
    basic, hqp, hqp_active = done["basic"], done["hqp"], done["hqp_active"]
    pink, placo = (peer_result(done.get(name, peer_runs[name])) for name in ("pink", "placo"))
    log("hierarchical QP on random stacks …")
    random_hqp = hqp_random((300 if args.quick else 1000) if args.ticks is None else 20)
    log("breakdown, profile …")
    parts = breakdown(small)
    profile(args.out / "profile.txt", small)
    log("real-time factors …")
    rtf_kinematic = kinematic_rtf(3.0 if args.quick else 8.0) if args.ticks is None else kinematic_rtf(0.1)
    rtf_physics = physics_rtf(2.0 if args.quick else 5.0) if args.ticks is None else physics_rtf(0.05)
    log("scaling …")
    scale = scaling(300 if args.quick else 1000, 100) if args.ticks is None else scaling(args.ticks, 10)
    log("paired runs against pink …")
    paired = paired_ratio(3 if args.quick else 7, 1000, 100) if args.ticks is None else paired_ratio(2, args.ticks, 10)
    log("paired runs against pink, SolverKine with active limits …")
    paired_active = (paired_ratio(3 if args.quick else 7, 1000, 200, "hqp", ACTIVE_TARGET) if args.ticks is None
                     else paired_ratio(2, args.ticks, 10, "hqp", ACTIVE_TARGET))

    tick = stats(basic["times_s"])
    tick_cpu = stats(basic["cpu_s"])
    tick_hqp = stats(hqp["times_s"])
    results = {
        "machine": {"python": platform.python_version(), "processor": platform.processor() or platform.machine(),
                    "cpus": __import__("os").cpu_count(), "load_average": list(__import__("os").getloadavg()),
                    "host_steal_fraction": steal.fraction()},
        "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        "scenario": "TALOS reduced, feet + CoM held, right hand to (0.5, -0.2, 1.0), joint limits, dt = 1 ms",
        "accuracy_after_s": (warmup + ticks) * DT,
        "realtime_factors_include_recording": False,
        "tick_us_median": tick["median"],
        "tick_us": tick,
        "tick_cpu_us": tick_cpu,
        "hqp_tick_us_median": tick_hqp["median"],
        "hqp_tick_us": tick_hqp,
        "hqp_active_limits_tick_us": stats(hqp_active["times_s"]),
        # full garbage collections inside the timed ticks (the collector frozen after the build): target 0
        "gen2_collections_in_ticks": {name: run["gen2_collections_in_ticks"]
                                      for name, run in (("basic", basic), ("hqp", hqp), ("hqp_active", hqp_active))},
        "hqp_active_tick_us_median": stats(hqp_active["times_s"])["median"],
        "hqp_active_solver_us_median": float(1e6 * np.median(hqp_active["solver_times_s"])),
        "hqp_random_solve_ms_median": random_hqp["median"],
        "hqp_random_solve_ms_p99": random_hqp["p99"],
        "hqp_random_solve_cpu_ms_median": random_hqp["cpu_ms_median"],
        "hqp_random": random_hqp,
        "hqp_random_ratio_vs_plain": random_hqp.get("ratio_median"),
        "realtime_factor_kinematic": rtf_kinematic["wall"],
        "realtime_factor_kinematic_cpu": rtf_kinematic["cpu"],
        "realtime_factor_physics": rtf_physics["wall"],
        "realtime_factor_physics_cpu": rtf_physics["cpu"],
        "breakdown_fraction": parts,
        "accuracy": {"sotdrake": basic["accuracy"], "sotdrake_hqp": hqp["accuracy"], "sotdrake_hqp_active_limits": hqp_active["accuracy"]},
        "pink": pink,
        "placo": placo,
        **scale,
    }
    if pink.get("available"):
        results["pink_tick_us_median"] = pink["tick_us"]["median"]
        results["ratio_vs_pink"] = tick["median"] / pink["tick_us"]["median"]
        results["ratio_vs_pink_cpu"] = tick_cpu["median"] / pink["tick_cpu_us"]["median"]
        results["hqp_ratio_vs_pink"] = tick_hqp["median"] / pink["tick_us"]["median"]
        results["hqp_active_ratio_vs_pink"] = results["hqp_active_tick_us_median"] / pink["tick_us"]["median"]
        results["accuracy"]["pink"] = pink["accuracy"]
    if paired is not None:
        results["pink_paired"] = paired
        results["ratio_vs_pink_paired"] = paired["median"]
        results["ratio_vs_pink_cpu_paired"] = paired["cpu_median"]
    if paired_active is not None:
        results["pink_paired_hqp_active"] = paired_active
        results["hqp_active_ratio_vs_pink_paired"] = paired_active["median"]
        results["hqp_active_ratio_vs_pink_cpu_paired"] = paired_active["cpu_median"]
    if placo.get("available"):
        results["placo_tick_us_median"] = placo["tick_us"]["median"]
        results["ratio_vs_placo"] = tick["median"] / placo["tick_us"]["median"]
        results["accuracy"]["placo"] = placo["accuracy"]
    results["targets"] = check_targets(results)
    text = json.dumps(results, indent=2, default=float) + "\n"
    (args.out / "latest.json").write_text(text)
    (args.out / "table.md").write_text(markdown(results) + "\n")
    if args.save:
        REFERENCE.write_text(text)
    print_table(results)
    return results


if __name__ == "__main__":
    main()
