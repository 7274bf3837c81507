"""Before/after speed of the hierarchical QP, measured in the same process (a paired A/B).

On a shared, loaded machine wall times of separate runs are not comparable; this script solves the
*same* problems with this tree's :class:`~sotdrake.hqp.HierarchicalQP` and with the one of a
git revision (``--base``, extracted with ``git archive`` into a temporary package), interleaved call
by call, and keeps the best of ``--repeat`` CPU times (``time.thread_time``) of each call:

* the random stacks of ``tests/hqp_stacks.py`` (seeds 0..N-1, each solved cold), with the sequential
  ``quadprog`` reference of ``tests/test_hqp.py`` on a quarter of them;
* the TALOS active-limits scenario of ``bench/run.py`` (a hand target behind the back): the stacks
  its ``SolverKine`` solves are recorded from one run, then replayed tick by tick through both
  solvers (each keeps its own warm starts, as in the robot's loop);
* with ``--tick N``, that scenario's whole tick (``Simulator.AdvanceTo`` one tick at a time, CPU
  time): this tree's diagram and the revision's (built from its own package), in turns of 50 ticks,
  with pink's tick on the same scenario run between the turns (100 ticks every fifth turn), so that
  both ratios to pink see the same load.

Ratios are per call (new / base), their median is reported. Usage::

    python bench/hqp_ab.py --base main [--stacks 300] [--ticks 150] [--tick 1000] [--out results/hqp_ab.json]
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from io import BytesIO
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as bench/run.py: a control loop's small matrices, one thread

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path[:0] = [str(ROOT), str(HERE)]

ACTIVE_TARGET = np.array([-0.45, -0.35, 1.0])


def base_package(revision: str, folder: Path):
    """The hierarchical QP's module of ``revision`` (``sotdrake/hqp/solve.py``, or
    ``sotdrake/solvers/hqp.py`` before it moved), imported from ``sotdrake_base``."""
    archive = subprocess.run(["git", "archive", revision, "sotdrake"], cwd=ROOT, check=True, capture_output=True).stdout
    with tarfile.open(fileobj=BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    (folder / "sotdrake").rename(folder / "sotdrake_base")
    sys.path.insert(0, str(folder))
    try:
        return importlib.import_module("sotdrake_base.hqp.solve")
    except ModuleNotFoundError:
        return importlib.import_module("sotdrake_base.solvers.hqp")


def best_times(solve_pair, count: int, repeat: int) -> tuple[np.ndarray, np.ndarray]:
    """CPU times (best of ``repeat``) of ``solve_pair(i, which)`` for which in (new, base), interleaved."""
    new, base = np.full(count, np.inf), np.full(count, np.inf)
    for i in range(count):
        for _ in range(repeat):
            for which, out in ((0, new), (1, base)):
                start = time.thread_time()
                solve_pair(i, which)
                out[i] = min(out[i], time.thread_time() - start)
    return new, base


def summary(new: np.ndarray, base: np.ndarray, unit: float) -> dict:
    return {"new_median": float(unit * np.median(new)), "base_median": float(unit * np.median(base)),
            "new_p99": float(unit * np.percentile(new, 99)), "base_p99": float(unit * np.percentile(base, 99)),
            "ratio_median": float(np.median(new / base))}


def random_stacks(modules, count: int, repeat: int) -> dict:
    from tests.hqp_stacks import random_stack
    from tests.test_hqp import reference_slack_norms

    stacks = [random_stack(np.random.default_rng(seed)) for seed in range(count)]
    rows = [[[module.LevelRows(level.A, level.lower, level.upper) for level in levels] for module in modules]
            for _, levels, _, _ in stacks]
    solvers = [{}, {}]

    def solve(i, which):
        n, _, lower, upper = stacks[i]
        hqp = solvers[which].setdefault(n, modules[which].HierarchicalQP(n))
        forget = getattr(hqp, "forget_warm_starts", None)  # cold, as bench/run.py's hqp_random (a base may lack it)
        forget() if forget is not None else hqp._working_sets.clear()
        hqp.solve(rows[i][which], lower, upper)

    new, base = best_times(solve, count, repeat)
    reference, reference_failures = [], 0
    for n, levels, lower, upper in stacks[: count // 4]:
        start = time.thread_time()
        try:
            reference_slack_norms(n, levels, lower, upper)
        except ValueError:  # quadprog's regularised QP on a badly scaled stack: "inconsistent" (as in bench/run.py)
            reference_failures += 1
            continue
        reference.append(time.thread_time() - start)
    return {**summary(new, base, 1e3), "unit": "ms CPU", "count": count,
            "quadprog_reference_median": float(1e3 * np.median(reference)), "quadprog_reference_failures": reference_failures}


def talos_ticks(modules, ticks: int, repeat: int) -> dict:
    import run as bench_run

    recorded = []
    solve = modules[0].HierarchicalQP.solve

    def record(self, levels, x_lower, x_upper, damping=0.0, solver=None, **options):
        recorded.append((self.n, [(lv.A.copy(), lv.lower.copy(), lv.upper.copy()) for lv in levels],
                         np.array(x_lower), np.array(x_upper), damping))
        return solve(self, levels, x_lower, x_upper, damping, solver, **options)

    # (SolverKine tries solve_equalities first: switched off while recording, so that every stack
    # goes through solve; both trees then replay it through solve)
    equalities = getattr(modules[0].HierarchicalQP, "solve_equalities", None)
    modules[0].HierarchicalQP.solve = record
    if equalities is not None:
        modules[0].HierarchicalQP.solve_equalities = lambda self, *args, **kwargs: None
    try:
        bench_run.sotdrake_run("hqp", ticks, 50, target=ACTIVE_TARGET)
    finally:
        modules[0].HierarchicalQP.solve = solve
        if equalities is not None:
            modules[0].HierarchicalQP.solve_equalities = equalities
    recorded = recorded[-ticks:]
    solvers = [module.HierarchicalQP(recorded[0][0]) for module in modules]
    rows = [[[module.LevelRows(*level) for level in call[1]] for module in modules] for call in recorded]

    def replay(i, which):
        _, _, lower, upper, damping = recorded[i]
        solvers[which].solve(rows[i][which], lower, upper, damping)

    new, base = best_times(replay, len(recorded), repeat)
    return {**summary(new, base, 1e6), "unit": "µs CPU", "ticks": len(recorded)}


def active_limits_diagram(package: str):
    """``bench/run.py``'s active-limits stack (feet, CoM, hand behind the back; ``SolverKine``) built
    from ``package`` (``sotdrake``, or the revision's ``sotdrake_base``)."""
    from pydrake.systems.framework import DiagramBuilder
    from scenario import DT, GAIN_COM, GAIN_FEET, GAIN_HAND

    meta = importlib.import_module(f"{package}.meta_tasks")
    robots = importlib.import_module(f"{package}.robots")
    robot_module = importlib.import_module(f"{package}.robot")
    builder = DiagramBuilder()
    model = robots.load_talos("reduced")
    robot = robot_module.Robot(builder, model, DT)
    sot = robot_module.add_sot(robot, solver="hqp")
    sot.setControlSelection(robot.velocity_selection(excluding=[g for g in robots.TALOS_GRIPPERS if model.plant.HasJointNamed(g)]))
    tasks = [meta.MetaTaskKine6d("contactRF", robot, "RF", "right-ankle"), meta.MetaTaskKine6d("contactLF", robot, "LF", "left-ankle"),
             meta.MetaTaskKineCom(robot), meta.MetaTaskKine6d("rh", robot, "rh", "right-wrist")]
    for task, gain in zip(tasks[:3], (GAIN_FEET, GAIN_FEET, GAIN_COM), strict=True):
        task.gain.setConstant(gain)
    tasks[3].opmodif = np.array([[1, 0, 0, 0.1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    meta.gotoNd(tasks[3], ACTIVE_TARGET, "111", GAIN_HAND)
    for task in tasks:
        sot.push(task.task.name)
    return builder.Build()


def talos_tick(ticks: int, warmup: int = 200, chunk: int = 50) -> dict:
    """The whole active-limits tick, this tree's and the base revision's, with pink's (see the module
    docstring); CPU time (``time.thread_time``), µs."""
    import logging

    import peers
    from pydrake.systems.analysis import Simulator
    from scenario import DT

    logging.disable(logging.WARNING)  # pink warns about the grippers starting on their limits
    simulators = {}
    for key, package in (("new", "sotdrake"), ("base", "sotdrake_base")):
        simulators[key] = Simulator(active_limits_diagram(package))
        simulators[key].Initialize()
        simulators[key].AdvanceTo((warmup - 0.5) * DT)
    cpu: dict[str, list[float]] = {"new": [], "base": [], "pink": []}
    for turn in range(max(1, ticks // chunk)):
        for key, simulator in simulators.items():
            t0 = simulator.get_context().get_time()
            for k in range(chunk):
                start = time.thread_time()
                simulator.AdvanceTo(t0 + (k + 1) * DT)
                cpu[key].append(time.thread_time() - start)
        if turn % 5 == 0:
            cpu["pink"] += list(peers.run_pink(2 * chunk, 20)["cpu_s"])
    median = {key: float(1e6 * np.median(values)) for key, values in cpu.items()}
    return {"new_median": median["new"], "base_median": median["base"], "pink_median": median["pink"],
            "new_ratio_vs_pink": median["new"] / median["pink"], "base_ratio_vs_pink": median["base"] / median["pink"],
            "ratio_median": float(np.median(np.array(cpu["new"]) / np.array(cpu["base"]))), "unit": "µs CPU", "ticks": len(cpu["new"])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--base", required=True, help="git revision to compare with (e.g. main)")
    parser.add_argument("--stacks", type=int, default=300)
    parser.add_argument("--ticks", type=int, default=150)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--tick", type=int, default=0, help="also time the whole active-limits tick, this many ticks each")
    parser.add_argument("--out", type=Path, help="write the results as JSON")
    args = parser.parse_args()
    from sotdrake.hqp import solve as hqp

    with tempfile.TemporaryDirectory() as folder:
        modules = (hqp, base_package(args.base, Path(folder)))
        results = {"base": args.base,
                   "random_stacks": random_stacks(modules, args.stacks, args.repeat),
                   "talos_active_limits_solve": talos_ticks(modules, args.ticks, args.repeat)}
        if args.tick:
            results["talos_active_limits_tick"] = tick = talos_tick(args.tick)
            print(f"talos_active_limits_tick: median {tick['new_median']:.0f} µs CPU (base {tick['base_median']:.0f}), "
                  f"pink {tick['pink_median']:.0f}: ratio to pink {tick['new_ratio_vs_pink']:.2f} (base {tick['base_ratio_vs_pink']:.2f}), "
                  f"per-tick ratio median {tick['ratio_median']:.2f}")
    for name in ("random_stacks", "talos_active_limits_solve"):
        r = results[name]
        print(f"{name}: median {r['new_median']:.3g} {r['unit']} (base {r['base_median']:.3g}), "
              f"p99 {r['new_p99']:.3g} (base {r['base_p99']:.3g}), per-call ratio median {r['ratio_median']:.2f}"
              + (f"; quadprog reference median {r['quadprog_reference_median']:.3g}" if "quadprog_reference_median" in r else ""))
    if args.out:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
