#!/usr/bin/env python3
"""The marginal cost of one more task, by kind and by solver, against the framework's floor.

For each kinematic solver (the basic ``SOT``, ``SolverKine``) the base stack (both soles held,
the right hand driven to the scenario's target: ``bench/scenario.py``) is timed beside the same
stack with one more task of each kind at the bottom:

* ``6D``: the left wrist held (six rows);
* ``CoM``: the centre of mass held (three rows);
* ``posture``: the half-sitting posture (one row per joint: more than the levels above leave free).

A kind's marginal cost is the difference of the two medians of the tick's CPU time; the floor's
slope is the least-squares slope of ``bench/floor.py``'s graph (the same topology, callbacks
without maths) from 2 to 6 tasks. Every stack is timed in the same turns of 50 ticks
(``run.interleaved_medians``), so that a change of the machine's load falls on all of them alike,
and the whole measurement is repeated ``--repeat`` times: the figures are the medians over the
repeats. The target (``marginal task ≤ 2×`` the floor's slope) is judged per solver and kind.

    python bench/marginal.py                 # bench/results/marginal.json (ignored by git)
    python bench/marginal.py --save          # and bench/reference/marginal.json (the docs' table)
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as bench/run.py: one thread for small matrices

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path[:0] = [str(HERE.parent), str(HERE)]

import floor
from output import add_output_arguments, write_json
from run import build_stack, interleaved_medians

SOLVERS = {"SOT": "cascade", "SolverKine": "hqp"}
BASE = ["contactRF", "contactLF", "rh"]
KINDS = {"6D": "lh", "CoM": "com", "posture": "posture"}
FLOOR_TASKS = range(2, 7)
TARGET = 2.0  # marginal task ≤ 2× the floor's slope


def stacks() -> dict:
    """The diagrams timed: per solver the base stack and one with each kind added, and the floor's."""
    diagrams = {}
    for solver, key in SOLVERS.items():
        diagrams[(solver, None)] = build_stack(key, names=BASE)[3]
        for kind, name in KINDS.items():
            diagrams[(solver, kind)] = build_stack(key, names=[*BASE, name], full_6d=True)[3]
    diagrams.update({("floor", n): floor.build(n) for n in FLOOR_TASKS})
    return diagrams


def summarize(rounds: list[dict]) -> dict:
    """The medians over the rounds (each ``{diagram key: median tick CPU µs}``) of the floor's slope,
    and per solver of the base tick and of each kind's tick, marginal cost and ratio to the slope."""
    slopes = [float(np.polyfit(list(FLOOR_TASKS), [r[("floor", n)] for n in FLOOR_TASKS], 1)[0]) for r in rounds]
    slope = float(np.median(slopes))
    out: dict = {"floor_slope_cpu_us": slope, "floor_slopes_cpu_us": slopes, "solvers": {}}
    for solver in SOLVERS:
        kinds = {}
        for kind in KINDS:
            marginal = float(np.median([r[(solver, kind)] - r[(solver, None)] for r in rounds]))
            kinds[kind] = {"tick_cpu_us": float(np.median([r[(solver, kind)] for r in rounds])),
                           "marginal_cpu_us": marginal, "ratio_to_floor_slope": marginal / slope,
                           "target_met": marginal <= TARGET * slope}
        out["solvers"][solver] = {"base_tick_cpu_us": float(np.median([r[(solver, None)] for r in rounds])), "kinds": kinds}
    return out


def table(result: dict) -> str:
    lines = [f"floor's slope: {result['floor_slope_cpu_us']:.1f} µs CPU per task (target: a task ≤ {TARGET:g}× it)",
             f"{'solver':<11} {'kind':<8} {'base µs':>8} {'with µs':>8} {'marginal µs':>12} {'ratio':>6}"]
    for solver, r in result["solvers"].items():
        for kind, k in r["kinds"].items():
            lines.append(f"{solver:<11} {kind:<8} {r['base_tick_cpu_us']:8.0f} {k['tick_cpu_us']:8.0f} "
                         f"{k['marginal_cpu_us']:12.1f} {k['ratio_to_floor_slope']:6.2f}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ticks", type=int, default=2000, help="timed ticks per stack and repeat")
    parser.add_argument("--warmup", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=3, help="whole measurements; the figures are their medians")
    add_output_arguments(parser, "marginal.json")
    args = parser.parse_args(argv)
    if args.ticks < 1 or args.repeat < 1 or args.warmup < 0:
        parser.error("--ticks and --repeat must be ≥ 1, --warmup ≥ 0")
    diagrams, rounds = stacks(), []
    for k in range(args.repeat):  # (each round simulates every diagram anew, from its default context)
        _, cpu = interleaved_medians(diagrams, args.ticks, args.warmup)
        rounds.append(cpu)
        print(f"repeat {k + 1}/{args.repeat} done", file=sys.stderr, flush=True)
    result = {"command": "python bench/marginal.py" + (" --save" if args.save else ""),
              "clock": "time.thread_time (this thread's CPU time), median tick",
              "ticks": args.ticks, "repeat": args.repeat, "base": BASE, "kinds": KINDS,
              "machine": {"cpus": os.cpu_count(), "python": platform.python_version()}, **summarize(rounds)}
    print(table(result))
    write_json(result, args.out, args.save)
    return result


if __name__ == "__main__":
    main()
