"""Before/after speed of the hierarchical QP, measured in the same process (a paired A/B).

On a shared, loaded machine wall times of separate runs are not comparable; this script solves the
*same* problems with this tree's :class:`~sotdrake.solvers.hqp.HierarchicalQP` and with the one of a
git revision (``--base``, extracted with ``git archive`` into a temporary package), interleaved call
by call, and keeps the best of ``--repeat`` CPU times (``time.thread_time``) of each call:

* the random stacks of ``tests/hqp_stacks.py`` (seeds 0..N-1, each solved cold), with the sequential
  ``quadprog`` reference of ``tests/test_hqp.py`` on a quarter of them;
* the TALOS active-limits scenario of ``bench/run.py`` (a hand target behind the back): the stacks
  its ``SolverKine`` solves are recorded from one run, then replayed tick by tick through both
  solvers (each keeps its own warm starts, as in the robot's loop).

Ratios are per call (new / base), their median is reported. Usage::

    python bench/hqp_ab.py --base main [--stacks 300] [--ticks 150] [--out results/hqp_ab.json]
"""

from __future__ import annotations

import argparse
import importlib
import json
import subprocess
import sys
import tarfile
import tempfile
import time
from io import BytesIO
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path[:0] = [str(ROOT), str(HERE)]

ACTIVE_TARGET = np.array([-0.45, -0.35, 1.0])


def base_package(revision: str, folder: Path):
    """``sotdrake/solvers/hqp.py`` of ``revision``, imported as ``sotdrake_base.solvers.hqp``."""
    archive = subprocess.run(["git", "archive", revision, "sotdrake"], cwd=ROOT, check=True, capture_output=True).stdout
    with tarfile.open(fileobj=BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    (folder / "sotdrake").rename(folder / "sotdrake_base")
    sys.path.insert(0, str(folder))
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
        hqp._working_sets.clear()  # cold, as bench/run.py's hqp_random
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

    def record(self, levels, x_lower, x_upper, damping=0.0, solver=None):
        recorded.append((self.n, [(lv.A.copy(), lv.lower.copy(), lv.upper.copy()) for lv in levels],
                         np.array(x_lower), np.array(x_upper), damping))
        return solve(self, levels, x_lower, x_upper, damping, solver)

    modules[0].HierarchicalQP.solve = record
    try:
        bench_run.sotdrake_run("hqp", ticks, 50, target=ACTIVE_TARGET)
    finally:
        modules[0].HierarchicalQP.solve = solve
    recorded = recorded[-ticks:]
    solvers = [module.HierarchicalQP(recorded[0][0]) for module in modules]
    rows = [[[module.LevelRows(*level) for level in call[1]] for module in modules] for call in recorded]

    def replay(i, which):
        _, _, lower, upper, damping = recorded[i]
        solvers[which].solve(rows[i][which], lower, upper, damping)

    new, base = best_times(replay, len(recorded), repeat)
    return {**summary(new, base, 1e6), "unit": "µs CPU", "ticks": len(recorded)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--base", required=True, help="git revision to compare with (e.g. main)")
    parser.add_argument("--stacks", type=int, default=300)
    parser.add_argument("--ticks", type=int, default=150)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--out", type=Path, help="write the results as JSON")
    args = parser.parse_args()
    from sotdrake.solvers import hqp

    with tempfile.TemporaryDirectory() as folder:
        modules = (hqp, base_package(args.base, Path(folder)))
        results = {"base": args.base,
                   "random_stacks": random_stacks(modules, args.stacks, args.repeat),
                   "talos_active_limits_solve": talos_ticks(modules, args.ticks, args.repeat)}
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
