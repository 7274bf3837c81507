#!/usr/bin/env python3
"""Where the tick's CPU time goes, per entity kind, beside the framework's floor measured in the same run.

    python bench/profile_entities.py                # ~1 min; writes bench/results/entity_profile.json
    python bench/profile_entities.py --save         # also the committed bench/reference/entity_profile.json
    python bench/profile_entities.py --ticks 50     # a smoke test of the harness (not a measurement)

Stacks: ``bench/run.py``'s ten-task stack (feet, CoM, both hands, chest, head, both elbows, posture:
TALOS reduced) under the basic ``SOT`` and under ``SolverKine``, and ``bench/floor.py``'s graph with
ten tasks (callbacks that do no maths). Every callback a sotdrake (or floor) ``LeafSystem`` declares
(every method taking ``(self, context, …)``) is wrapped in a timer of this thread's CPU time
(``time.thread_time``); a callback's time is *exclusive*: the time of the callbacks it triggers by
evaluating its input ports is charged to those. Each kind's total is divided by its number of
instances (µs per entity per tick) after subtracting the timer's own cost per call. A callback's
time includes Drake's evaluation of its input ports when their values are cached (a cache look-up);
the rest of the tick (scheduling, the simulator's step, the discrete update's bookkeeping) is
outside every callback.

The timer's own cost per call is measured in the same run (a wrapped no-op against the bare no-op,
best of three) and the same diagrams are also timed without the wrappers, in alternating chunks of
ticks, so that the plain tick stands beside the instrumented one. CPU times on a shared machine are
noisy (other processes' cache pressure): compare ratios within one run, not across runs.
"""

from __future__ import annotations

import argparse
import inspect
import os
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path
from typing import Any

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import floor
from output import add_output_arguments, write_json
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import LeafSystem
from run import build_stack
from scenario import DT, load_compiled_paths

import sotdrake  # noqa: F401  (every entity class is defined before the patching)

TASKS = 10


class Timers:
    """Exclusive CPU time per entity kind (class name) and per callback, and call counts."""

    def __init__(self) -> None:
        self.by_kind: dict[str, float] = defaultdict(float)
        self.by_callback: dict[str, float] = defaultdict(float)
        self.calls: dict[str, int] = defaultdict(int)
        self._stack: list[list[float]] = []
        self._patches: list[tuple[type, str, Callable, Callable]] = []

    def reset(self) -> None:
        self.by_kind.clear()
        self.by_callback.clear()
        self.calls.clear()

    def wrap(self, function: Callable, name: str) -> Callable:
        stack, clock = self._stack, time.thread_time

        def timed(system, *args: Any, **kwargs: Any) -> Any:
            stack.append([clock(), 0.0])
            try:
                return function(system, *args, **kwargs)
            finally:
                start, children = stack.pop()
                elapsed = clock() - start
                kind = type(system).__name__
                self.by_kind[kind] += elapsed - children
                self.by_callback[f"{kind}.{name}"] += elapsed - children
                self.calls[kind] += 1
                if stack:
                    stack[-1][1] += elapsed
        return timed

    def prepare(self) -> None:
        """Find every callback of every sotdrake and floor LeafSystem (wrapped by :meth:`install`)."""
        classes, todo = [], list(LeafSystem.__subclasses__())
        while todo:
            cls = todo.pop()
            todo.extend(cls.__subclasses__())
            if cls.__module__.startswith(("sotdrake", "floor")):
                classes.append(cls)
        for cls in set(classes):
            for name, value in list(vars(cls).items()):
                if inspect.isfunction(value) and list(inspect.signature(value).parameters)[1:2] == ["context"]:
                    self._patches.append((cls, name, value, self.wrap(value, name)))

    def install(self) -> None:
        for cls, name, _, wrapped in self._patches:
            setattr(cls, name, wrapped)

    def remove(self) -> None:
        for cls, name, original, _ in self._patches:
            setattr(cls, name, original)


def _instances(diagram) -> dict[str, int]:
    counts: dict[str, int] = defaultdict(int)
    for system in diagram.GetSystems():
        counts[type(system).__name__] += 1
    return dict(counts)


def _simulator(diagram, warmup: int) -> Simulator:
    simulator = Simulator(diagram)
    simulator.Initialize()
    simulator.AdvanceTo(warmup * DT)
    return simulator


def _chunk(simulator: Simulator, ticks: int) -> list[float]:
    cpu, t0 = [], simulator.get_context().get_time()
    for k in range(ticks):
        start = time.thread_time()
        simulator.AdvanceTo(t0 + (k + 1) * DT)
        cpu.append(time.thread_time() - start)
    return cpu


def timer_cost_us(calls: int = 200_000) -> float:
    """The timer's own cost per call (µs of CPU): a wrapped no-op against the bare no-op."""
    class _Probe:
        def noop(self, context: object) -> None:
            return None

    timers, probe = Timers(), _Probe()
    wrapped = timers.wrap(_Probe.noop, "noop")
    costs = []
    for function in (_Probe.noop, wrapped) * 3:
        start = time.thread_time()
        for _ in range(calls):
            function(probe, None)
        costs.append(time.thread_time() - start)
    bare, timed = min(costs[0::2]), min(costs[1::2])
    return (timed - bare) / calls * 1e6


FLOOR_KIND = {"_Feature": "feature", "_Task": "task", "_Gain": "gain", "_Kinematics": "kinematics",
              "_Solver": "solver", "_Device": "device"}


def floor_kind(kind: str) -> str:
    """The floor's counterpart of a sotdrake entity kind."""
    if kind.startswith("Feature"):
        return "feature"
    if kind.startswith(("Task", "MetaTask")):
        return "task"
    if kind.startswith("Gain"):
        return "gain"
    return {"Dynamic": "kinematics", "SOT": "solver", "SolverKine": "solver", "Device": "device"}.get(kind, "")


def measure(builders: dict[str, Callable], ticks: int, warmup: int, chunk: int = 50) -> dict:
    """Each stack timed plain and instrumented, in alternating chunks of ``chunk`` ticks."""
    timers = Timers()
    timers.prepare()
    plain = {key: _simulator(build(), warmup) for key, build in builders.items()}
    timers.install()
    try:
        timed = {key: _simulator(build(), warmup) for key, build in builders.items()}
    finally:
        timers.remove()
    plain_cpu: dict[str, list[float]] = {key: [] for key in builders}
    timed_cpu: dict[str, list[float]] = {key: [] for key in builders}
    kinds: dict[str, dict[str, float]] = {key: defaultdict(float) for key in builders}
    callbacks: dict[str, dict[str, float]] = {key: defaultdict(float) for key in builders}
    calls: dict[str, dict[str, int]] = {key: defaultdict(int) for key in builders}
    for _ in range(max(1, ticks // chunk)):
        for key in builders:
            plain_cpu[key] += _chunk(plain[key], chunk)
            timers.install()
            timers.reset()
            try:
                timed_cpu[key] += _chunk(timed[key], chunk)
            finally:
                timers.remove()
            for kind, value in timers.by_kind.items():
                kinds[key][kind] += value
            for name, value in timers.by_callback.items():
                callbacks[key][name] += value
            for kind, count in timers.calls.items():
                calls[key][kind] += count
    per_call = timer_cost_us()
    results: dict[str, Any] = {}
    for key in builders:
        n = len(timed_cpu[key])
        instances = _instances(timed[key].get_system())
        plain_us, timed_us = float(np.median(plain_cpu[key])) * 1e6, float(np.median(timed_cpu[key])) * 1e6
        calls_per_tick = sum(calls[key].values()) / n
        inside = sum(kinds[key].values()) / n * 1e6
        results[key] = {
            "tick_cpu_us_median": plain_us,
            "tick_cpu_us_median_instrumented": timed_us,
            "timed_calls_per_tick": calls_per_tick,
            "callbacks_us_per_tick_net": inside - per_call * calls_per_tick,
            "kinds": {
                kind: {"instances": instances.get(kind, 0), "calls_per_tick": calls[key][kind] / n,
                       "us_per_tick": value / n * 1e6,
                       "us_per_entity_net": (value / n * 1e6 - per_call * calls[key][kind] / n) / max(1, instances.get(kind, 0))}
                for kind, value in sorted(kinds[key].items(), key=lambda item: -item[1])
            },
            "callbacks_us_per_tick": {name: value / n * 1e6 for name, value in
                                      sorted(callbacks[key].items(), key=lambda item: -item[1])},
        }
    floor_row = {FLOOR_KIND[kind]: k["us_per_entity_net"] for key, r in results.items() if key.startswith("floor")
                 for kind, k in r["kinds"].items() if kind in FLOOR_KIND}
    for key, r in results.items():
        if key.startswith("floor"):
            continue
        for kind, k in r["kinds"].items():
            base = floor_row.get(floor_kind(kind))
            k["floor_us_per_entity"] = base
            k["ratio_to_floor"] = k["us_per_entity_net"] / base if base else None
    return {"timer_cost_us_per_call": per_call, "stacks": results}


def table(results: dict) -> str:
    """The per-entity table, each kind beside its counterpart in the floor's graph."""
    per_call, stacks = results["timer_cost_us_per_call"], results["stacks"]
    lines = [f"timer's own cost: {per_call:.2f} µs CPU per timed call (subtracted from the net figures)"]
    for key, r in stacks.items():
        lines.append(f"{key}: tick {r['tick_cpu_us_median']:.0f} µs CPU median (instrumented "
                     f"{r['tick_cpu_us_median_instrumented']:.0f}; {r['timed_calls_per_tick']:.0f} timed calls per tick; "
                     f"callbacks {r['callbacks_us_per_tick_net']:.0f} µs net)")
        lines.append(f"  {'entity kind':<22}{'instances':>10}{'calls/tick':>11}{'µs/tick':>9}{'µs/entity':>10}"
                     f"{'floor µs/entity':>16}{'ratio':>7}")
        for kind, k in r["kinds"].items():
            base = k.get("floor_us_per_entity")
            ratio = f"{k['ratio_to_floor']:7.1f}" if base else f"{'':>7}"
            lines.append(f"  {kind:<22}{k['instances']:>10}{k['calls_per_tick']:>11.1f}{k['us_per_tick']:>9.1f}"
                         f"{k['us_per_entity_net']:>10.1f}{(f'{base:.1f}' if base else ''):>16}{ratio}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ticks", type=int, default=2000, help="instrumented ticks per stack (and as many plain)")
    parser.add_argument("--warmup", type=int, default=200)
    add_output_arguments(parser, "entity_profile.json")
    args = parser.parse_args(argv)
    import logging

    logging.disable(logging.WARNING)
    load_compiled_paths()
    builders = {
        f"basic SOT, {TASKS} tasks": lambda: build_stack("cascade", tasks=TASKS)[3],
        f"SolverKine, {TASKS} tasks": lambda: build_stack("hqp", tasks=TASKS)[3],
        f"floor, {TASKS} tasks": lambda: floor.build(TASKS),
    }
    results = measure(builders, args.ticks, args.warmup)
    data = {"tasks": TASKS, "ticks": args.ticks, "clock": "time.thread_time (this thread's CPU time)",
            "command": "python bench/profile_entities.py --save", **results}
    print(table(results))
    for path in write_json(data, args.out, args.save):
        print(f"wrote {path}", file=sys.stderr)
    return data


if __name__ == "__main__":
    main()
