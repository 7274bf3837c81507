"""The benchmark's sotdrake stacks and how their ticks are timed: :func:`build_stack` (the
scenario's stack, or up to ten tasks of :data:`TASK_MAKERS`), :func:`tick_times` (wall and CPU
time of each tick, one ``AdvanceTo`` per tick), :func:`interleave` and :func:`interleaved_medians`
(several runs in turns, so that they all see the same seconds of a shared host)."""

from __future__ import annotations

import math
import time
from collections.abc import Generator
from typing import Any

import numpy as np
from peers import finish
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from scenario import DT, GAIN_COM, GAIN_FEET, GAIN_HAND, TARGET

from sotdrake.meta_tasks import MetaTaskKine6d, MetaTaskKineCom, MetaTaskKinePosture, gotoNd
from sotdrake.robot import Robot, add_sot
from sotdrake.robots import TALOS_GRIPPERS, load_talos

GRIPPERS = TALOS_GRIPPERS


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
