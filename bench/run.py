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
import math
import os
import platform
import pstats
import sys
import time
from collections import defaultdict
from collections.abc import Generator
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # a control loop's small matrices: one thread, for every peer alike

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from host import Steal
from peers import finish
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from scenario import DT, GAIN_COM, GAIN_FEET, GAIN_HAND, TARGET, load_compiled_paths

from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom, MetaTaskKinePosture, gotoNd
from sotdrake.robot import Robot, add_sot
from sotdrake.robots import TALOS_GRIPPERS, load_talos

GRIPPERS = TALOS_GRIPPERS
ACTIVE_TARGET = np.array([-0.45, -0.35, 1.0])  # the hand behind the back: joint limits active

# --- the sotdrake stacks ---------------------------------------------------------------------


#: The tasks of the benchmark stacks, by name (``build_stack``'s ``names``), in the order of the
#: ten-task stack: the feet, the CoM, the hand, then 6D tasks and the posture.
TASK_MAKERS = {
    "contactRF": lambda robot: MetaTaskKine6d("contactRF", robot, "RF", "right-ankle"),
    "contactLF": lambda robot: MetaTaskKine6d("contactLF", robot, "LF", "left-ankle"),
    "com": lambda robot: MetaTaskKineCom(robot),
    "rh": lambda robot: MetaTaskKine6d("rh", robot, "rh", "right-wrist"),
    "lh": lambda robot: MetaTaskKine6d("lh", robot, "lh", "left-wrist"),
    "chest": lambda robot: MetaTaskKine6d("chest", robot, "chest", "chest"),
    "head": lambda robot: MetaTaskKine6d("head", robot, "head", "gaze"),
    "relbow": lambda robot: MetaTaskKine6d("relbow", robot, "relbow", "arm_right_4_joint"),
    "lelbow": lambda robot: MetaTaskKine6d("lelbow", robot, "lelbow", "arm_left_4_joint"),
    "posture": lambda robot: MetaTaskKinePosture(robot),
}


def build_stack(solver: str = "cascade", variant: str = "reduced", tasks: int = 4, target=TARGET,
                names: list[str] | None = None, full_6d: bool = False):
    """The scenario's stack (feet, CoM, hand), or the first ``tasks`` of a longer list (one: the
    hand alone), or the tasks ``names`` of :data:`TASK_MAKERS` in that order. ``full_6d``: the
    extra 6D tasks (``lh``, ``chest``, ``head``, the elbows) keep their six rows (by default the
    hand and elbows keep the position, the chest and head the orientation)."""
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
    if names is None:
        names = ["rh"] if tasks == 1 else list(TASK_MAKERS)[:tasks]
    for key in names:
        meta = TASK_MAKERS[key](robot)
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
            if not full_6d:
                meta.feature.selec("111")
            meta.gain.setConstant(1.0)
        elif name in ("taskchest", "taskhead"):
            if not full_6d:
                meta.feature.selec("111000")  # orientation only
            meta.gain.setConstant(1.0)
        sot.push(name)
    return robot, sot, hand, builder.Build()


def tick_times(diagram, ticks: int, warmup: int, sample=None,
               gen2: list[int] | None = None) -> Generator[None, None, tuple[np.ndarray, Simulator, np.ndarray]]:
    """Wall time and CPU time (this thread's) of each tick (AdvanceTo one tick at a time), one tick
    per ``next`` (see :func:`interleave`); ``sample(context)`` runs every 10 ticks outside the timed
    region. Returns ``(wall, simulator, cpu)``, in seconds. As ``simulate`` does, the garbage
    collector is collected and frozen after the build (:func:`sotdrake.simulation.frozen_gc`);
    ``gen2`` gets the number of full (generation 2) collections that ran inside the timed ticks
    (target 0)."""
    from sotdrake.simulation import frozen_gc, gen2_collections

    simulator = Simulator(diagram)
    simulator.Initialize()
    times, cpu = np.empty(warmup + ticks), np.empty(warmup + ticks)
    full = 0
    with frozen_gc():
        for k in range(warmup + ticks):
            t = (k + 1) * DT - 0.5 * DT  # the tick at k·dt runs inside this call
            before = gen2_collections()
            start, start_cpu = time.perf_counter(), time.thread_time()
            simulator.AdvanceTo(t)
            times[k], cpu[k] = time.perf_counter() - start, time.thread_time() - start_cpu
            full += gen2_collections() - before
            if sample is not None and k % 10 == 0:
                sample(simulator.get_context())
            yield
    if gen2 is not None:
        gen2.append(full)
    return times[warmup:], simulator, cpu[warmup:]


def time_ticks(diagram, ticks: int, warmup: int, sample=None) -> tuple[np.ndarray, Simulator, np.ndarray]:
    """:func:`tick_times` run to its end."""
    return finish(tick_times(diagram, ticks, warmup, sample))


def interleave(runs: dict[str, tuple[Generator[None, None, Any], int]], turns: int = 40) -> dict[str, Any]:
    """Run tick generators (``name: (generator, its number of ticks)``) in ``turns`` turns, each run
    advancing ``ceil(ticks / turns)`` ticks per turn so that they all end in the last turn: every
    run sees the same seconds of a shared host, whose speed swings within seconds, and the ratio of
    two runs' medians compares like with like. Returns each run's result."""
    results: dict[str, Any] = {}
    steps = {name: math.ceil(count / turns) for name, (_, count) in runs.items()}
    while len(results) < len(runs):
        for name, (run, _) in runs.items():
            if name in results:
                continue
            for _ in range(steps[name]):
                try:
                    next(run)
                except StopIteration as done:
                    results[name] = done.value
                    break
    return results


def stats(times_s: np.ndarray) -> dict:
    us = 1e6 * np.asarray(times_s)
    return {"median": float(np.median(us)), "p95": float(np.percentile(us, 95)), "p99": float(np.percentile(us, 99)),
            "max": float(us.max()), "n": int(us.size)}


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
    the median over the stacks of the HQP's CPU time over the reference's."""
    from lexicographic_reference import plain_lexicographic

    from sotdrake.hqp.solve import HierarchicalQP
    from tests.hqp_stacks import random_stack

    solvers, times, cpu, reference_cpu, ratios = {}, [], [], [], []
    reference_failures = 0
    for seed in range(count):
        n, levels, x_lower, x_upper = random_stack(np.random.default_rng(seed))
        hqp = solvers.setdefault(n, HierarchicalQP(n))
        hqp.forget_warm_starts()  # cold: random stacks share no active sets
        start_cpu = time.process_time()
        times.append(hqp.solve(levels, x_lower, x_upper).solve_time_s)
        cpu.append(time.process_time() - start_cpu)
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
    return out


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


def interleaved_medians(diagrams: dict, ticks: int, warmup: int, chunk: int = 50) -> tuple[dict, dict]:
    """Median tick (µs), wall and CPU, of each diagram, timed in turns of ``chunk`` ticks (round
    robin), so that a change of the machine's load falls on all of them alike."""
    simulators = {}
    for key, diagram in diagrams.items():
        simulators[key] = Simulator(diagram)
        simulators[key].Initialize()
        simulators[key].AdvanceTo((warmup - 0.5) * DT)
    times = {key: [] for key in diagrams}
    cpu = {key: [] for key in diagrams}
    for _ in range(max(1, ticks // chunk)):
        for key, simulator in simulators.items():
            t0 = simulator.get_context().get_time()
            for k in range(chunk):
                start, start_cpu = time.perf_counter(), time.thread_time()
                simulator.AdvanceTo(t0 + (k + 1) * DT)
                times[key].append(time.perf_counter() - start)
                cpu[key].append(time.thread_time() - start_cpu)
    return ({key: float(np.median(v)) * 1e6 for key, v in times.items()},
            {key: float(np.median(v)) * 1e6 for key, v in cpu.items()})


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

#: The targets of the basic ``SOT`` tick (issue "a control tick that holds 1 kHz"): key of the
#: verdict (CPU time: a shared machine's other jobs do not inflate it by descheduling), key of the
#: same quantity in wall-clock time, sense, bound, label.
TARGETS = {
    "ratio_vs_pink": ("ratio_vs_pink_cpu_paired", "ratio_vs_pink_paired", "<=", 1.0, "basic SOT tick / pink's median (paired runs)"),
    "ratio_vs_pink_stretch": ("ratio_vs_pink_cpu_paired", "ratio_vs_pink_paired", "<=", 0.5, "the same, stretch target"),
    "tick_p99": ("tick_cpu_us_p99", "tick_us_p99", "<=", 1000.0, "basic SOT tick p99 (µs)"),
    "marginal_task": ("marginal_task_cpu_us", "marginal_task_us", "<=", 40.0, "marginal cost of one more task (µs)"),
    "realtime_factor_kinematic": ("realtime_factor_kinematic_cpu", "realtime_factor_kinematic", ">=", 3.0,
                                  "real-time factor, kinematic tutorial"),
    "realtime_factor_physics": ("realtime_factor_physics_cpu", "realtime_factor_physics", ">=", 1.0,
                                "real-time factor, physics (talos_physics reach)"),
    "hqp_random_median": ("hqp_random_solve_cpu_ms_median", "hqp_random_solve_ms_median", "<=", 1.0,
                          "HQP on random stacks, median solve (ms)"),
    "hqp_vs_plain_reference": ("hqp_random_ratio_vs_plain", "hqp_random_ratio_vs_plain", "<=", 0.5,
                               "HQP on random stacks / a plain lexicographic reference (per-stack median, CPU)"),
    "hqp_active_ratio": ("hqp_active_ratio_vs_pink", "hqp_active_ratio_vs_pink", "<=", 2.0,
                         "`SolverKine` tick with active limits / pink's median"),
}


def _values(r: dict) -> dict:
    return dict(r, tick_cpu_us_p99=r.get("tick_cpu_us", {}).get("p99"), tick_us_p99=r["tick_us"].get("p99"))


def check_targets(results: dict) -> dict:
    """``{target: True/False}`` for each target whose number (CPU time) was measured."""
    values = _values(results)
    met = {}
    for key, (cpu_key, _, sense, bound, _) in TARGETS.items():
        if values.get(cpu_key) is not None:
            met[key] = values[cpu_key] <= bound if sense == "<=" else values[cpu_key] >= bound
    return met


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


def _fmt(value, spec: str) -> str:
    return "n/a" if value is None else format(value, spec)


def markdown(r: dict) -> str:
    """The README's benchmark tables, from a run's JSON."""
    def row(name, t, acc, cpu=None):
        cpu_text = "" if cpu is None else f"{cpu['median']:.0f} / {cpu['p99']:.0f}"
        return (f"| {name} | {cpu_text} | {t['median']:.0f} | {t['p95']:.0f} | {_fmt(t.get('p99'), '.0f')} | "
                f"{acc['hand_error_m']:.1e} | {acc['max_foot_drift_m']:.1e} | {acc['max_com_drift_m']:.1e} |")

    lines = ["| peer (same scenario, same run) | CPU median / p99 (µs) | wall median (µs) | wall p95 (µs) | wall p99 (µs) "
             "| hand error (m) | max foot drift (m) | max CoM drift (m) |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |",
             row("sotdrake `SOT` (strict cascade)", r["tick_us"], r["accuracy"]["sotdrake"], r.get("tick_cpu_us")),
             row("sotdrake `SolverKine` (HQP, limits hard)", r["hqp_tick_us"], r["accuracy"]["sotdrake_hqp"]),
             row("… with joint limits active (target behind the back)", r["hqp_active_limits_tick_us"],
                 r["accuracy"]["sotdrake_hqp_active_limits"])]
    for name, label in (("pink", "pink {} (weighted QP, daqp)"), ("placo", "placo {} (C++ core; feet hard, CoM and hand soft)")):
        peer_run = r.get(name, {})
        if peer_run.get("available"):
            lines.append(row(label.format(peer_run.get("version", "")), peer_run["tick_us"], peer_run["accuracy"],
                             peer_run.get("tick_cpu_us")))
        else:
            lines.append(f"| {name} | {peer_run.get('reason', 'not run')} | | | | | | |")
    met = r.get("targets", {})
    values = _values(r)
    lines += ["", "| quantity | CPU time | wall clock | target (on CPU time) |", "| --- | --- | --- | --- |"]
    for key, (cpu_key, wall_key, sense, bound, label) in TARGETS.items():
        verdict = "" if key not in met else (" (met)" if met[key] else " (**not met**)")
        lines.append(f"| {label} | {_fmt(values.get(cpu_key), '.2f')} | {_fmt(values.get(wall_key), '.2f')} | "
                     f"{sense.replace('<=', '≤').replace('>=', '≥')} {bound:g}{verdict} |")
    for key, label in (("ratio_vs_pink_cpu", "basic SOT tick / pink's, the long runs above (CPU time)"),
                       ("ratio_vs_pink", "basic SOT tick / pink's, the long runs above (wall clock)"),
                       ("hqp_ratio_vs_pink", "`SolverKine` tick / pink's (wall clock)"),
                       ("hqp_active_ratio_vs_pink_cpu_paired", "`SolverKine` tick with active limits / pink's (paired runs, CPU time)"),
                       ("hqp_active_ratio_vs_pink_paired", "`SolverKine` tick with active limits / pink's (paired runs, wall clock)"),
                       ("ratio_vs_placo", "basic SOT tick / placo's (wall clock)")):
        if key in r:
            lines.append(f"| {label} | {r[key]:.2f} | | |")
    lines += ["", "Median tick, CPU time (µs), by number of tasks: "
              + ", ".join(f"{n}: {v:.0f}" for n, v in r.get("tick_cpu_us_median_by_tasks", {}).items())
              + "; by DoF, one hand task: "
              + ", ".join(f"{n}: {v:.0f}" for n, v in r.get("tick_cpu_us_median_by_dof", {}).items()) + ".",
              "Median tick, wall clock (µs), by number of tasks: "
              + ", ".join(f"{n}: {v:.0f}" for n, v in r["tick_us_median_by_tasks"].items())
              + "; by DoF, one hand task: " + ", ".join(f"{n}: {v:.0f}" for n, v in r["tick_us_median_by_dof"].items()) + ".",
              *([f"Framework floor (`bench/floor.py`: the same graph, callbacks without maths), CPU time: "
                 f"{r['framework_floor_cpu_us_per_task']:.1f} µs per task."] if "framework_floor_cpu_us_per_task" in r else []),
              "Breakdown of the basic tick (exclusive time): "
              + ", ".join(f"{k} {100 * v:.0f}%" for k, v in sorted(r["breakdown_fraction"].items(), key=lambda x: -x[1])) + "."]
    if "machine" in r:
        m = r["machine"]
        lines.append(f"Measured {r.get('date', '')} on {m.get('cpus')} CPUs, "
                     f"load average {', '.join(f'{x:.1f}' for x in m.get('load_average', []))}"
                     + (f", {Steal.describe(m['host_steal_fraction'])}" if "host_steal_fraction" in m else "") + ".")
    return "\n".join(lines)


def print_table(r: dict) -> None:
    def row(name, t, acc):
        return (f"{name:28s} {t['median']:9.1f} {t['p95']:9.1f} {t['p99']:9.1f} {t['max']:9.1f}   "
                f"{acc['hand_error_m']:10.2e} {acc['max_foot_drift_m']:10.2e} {acc['max_com_drift_m']:10.2e}")

    print(f"\nhand error and drifts after {r['accuracy_after_s']:.1f} s of the run; real-time factors without Meshcat")
    print(f"\n{'tick (µs), accuracy (m)':28s} {'p50':>9s} {'p95':>9s} {'p99':>9s} {'max':>9s}   "
          f"{'hand err':>10s} {'foot drift':>10s} {'CoM drift':>10s}")
    print(row("sotdrake SOT (cascade)", r["tick_us"], r["accuracy"]["sotdrake"]))
    print(row("  … its CPU time", r["tick_cpu_us"], r["accuracy"]["sotdrake"]))
    print(row("sotdrake SolverKine (HQP)", r["hqp_tick_us"], r["accuracy"]["sotdrake_hqp"]))
    print(row("  … limits active", r["hqp_active_limits_tick_us"], r["accuracy"]["sotdrake_hqp_active_limits"]))
    for name in ("pink", "placo"):
        if r[name].get("available"):
            print(row(f"{name} {r[name].get('version', '')}", r[name]["tick_us"], r[name]["accuracy"]))
        else:
            print(f"{name:28s} {r[name]['reason']}")
    print()
    for key in ("ratio_vs_pink_cpu_paired", "ratio_vs_pink_paired", "ratio_vs_pink_cpu", "ratio_vs_pink", "hqp_ratio_vs_pink",
                "hqp_active_ratio_vs_pink", "hqp_active_ratio_vs_pink_cpu_paired", "hqp_active_ratio_vs_pink_paired",
                "ratio_vs_placo", "marginal_task_cpu_us", "marginal_task_us", "realtime_factor_kinematic_cpu",
                "realtime_factor_kinematic", "realtime_factor_physics_cpu", "realtime_factor_physics"):
        if key in r:
            print(f"{key:36s} {r[key]:.2f}")
    if "gen2_collections_in_ticks" in r:
        print(f"{'full GC collections in the ticks':36s} {r['gen2_collections_in_ticks']} (target 0)")
    h = r["hqp_random"]
    print(f"\nHQP on {h['count']} random stacks (ms): median {h['median']:.3f}, p99 {h['p99']:.3f}, max {h['max']:.3f}"
          + f"; CPU time median {h['cpu_ms_median']:.3f}"
          + (f" (plain lexicographic reference {h['plain_reference_cpu_ms_median']:.3f}; per-stack ratio median "
             f"{h['ratio_median']:.2f}, target ≤ 0.5)" if "ratio_median" in h else ""))
    print(f"HQP solver's own share of the active-limits tick: median {r['hqp_active_solver_us_median']:.0f} µs"
          f" of {r['hqp_active_tick_us_median']:.0f} µs")
    print("\nbreakdown of the basic tick: "
          + ", ".join(f"{k} {100 * v:.0f}%" for k, v in sorted(r["breakdown_fraction"].items(), key=lambda x: -x[1])))
    print("tick (µs) by number of tasks: " + ", ".join(f"{n}: {v:.0f}" for n, v in r["tick_us_median_by_tasks"].items()))
    print(f"marginal cost of one more task: {r['marginal_task_cpu_us']:.1f} µs CPU, {r['marginal_task_us']:.1f} µs wall clock")
    if "framework_floor_cpu_us_per_task" in r:
        print("framework floor (bench/floor.py: the same graph, callbacks without maths): "
              f"{r['framework_floor_cpu_us_per_task']:.1f} µs CPU per task; "
              + ", ".join(f"{n}: {v:.0f}" for n, v in r["framework_floor_cpu_us_by_tasks"].items()))
    print("tick (µs) by DoF (one hand task): " + ", ".join(f"{n}: {v:.0f}" for n, v in r["tick_us_median_by_dof"].items()))
    print("targets (CPU time): " + ", ".join(f"{TARGETS[k][4]}: {'met' if v else 'NOT met'}" for k, v in r["targets"].items()))


if __name__ == "__main__":
    main()
