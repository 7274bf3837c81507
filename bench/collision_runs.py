#!/usr/bin/env python3
"""Randomized collision runs on TALOS under SolverKine (or SolverDyn): the collision level always holds.

    python bench/collision_runs.py                       # 300 runs of 0.3 s, every tick checked
    python bench/collision_runs.py --runs 20 --duration 0.3
    python bench/collision_runs.py --dynamic --runs 300  # SolverDyn, the acceleration-level rows
    python bench/collision_runs.py --dynamic --only 89 96  # chosen runs of the same draw

One diagram (``sotdrake.collision.reach``: feet and CoM held, the collision level, the right hand,
a table top); each run takes a fresh context from the reference posture and drives the hand to a
random target inside the torso, across the body, inside the table top or under it
(``sotdrake.collision.targets``). Every tick is checked with Drake's query on a collision world of
its own: the smallest signed distance of every checked pair (≥ d_s − 1e-4 m), the ankles' drift
(≤ 1e-4 m), the joint limits, NaN, solver failures. Prints a summary and writes it as JSON.
``--dynamic``: the same with the dynamic SoT (``build_dyn_collision_reach``: both soles in contact,
the CoM, the collision level at the acceleration level, the hand, the posture), counting the ticks
on which ``SolverDyn`` reported a failure.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from sotdrake.collision.reach import build_collision_reach, build_dyn_collision_reach, run_collision_reach, run_dyn_collision_reach
from sotdrake.collision.targets import random_targets
from sotdrake.collision.task import SAFETY_DISTANCE

TOLERANCE = 1e-4  # m


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=300)
    parser.add_argument("--duration", type=float, default=0.3, help="simulated seconds per run")
    parser.add_argument("--gain", type=float, default=10.0, help="the hand's constant gain (1/s)")
    parser.add_argument("--seed", type=int, default=20261126)
    parser.add_argument("--dynamic", action="store_true", help="SolverDyn (the acceleration-level rows)")
    parser.add_argument("--no-collision", action="store_true", help="the same runs without the collision level (a baseline)")
    parser.add_argument("--only", type=int, nargs="+", default=None, help="run only these run indices (of the --runs drawn)")
    parser.add_argument("--out", type=Path, default=None, help="the JSON summary (default bench/results/collision_runs[_dyn].json)")
    args = parser.parse_args(argv)
    out = args.out or HERE / "results" / f"collision_runs{'_dyn' if args.dynamic else ''}.json"
    if args.dynamic:
        from sotdrake import load_talos

        dyn = build_dyn_collision_reach(load_talos("reduced"), collision=not args.no_collision, table=True)
    else:
        reach = build_collision_reach(collision=not args.no_collision, table=True)
    failed_ticks = 0
    rng = np.random.default_rng(args.seed)
    started = time.perf_counter()
    worst: dict[str, float] = {"min_distance": np.inf, "feet_drift": 0.0, "limit_excess": 0.0}
    bad: list[dict] = []
    by_family: dict[str, dict] = {}
    for i, (family, target) in enumerate(random_targets(args.runs, rng)):
        if args.only is not None and i not in args.only:
            continue
        if args.dynamic:
            report = run_dyn_collision_reach(dyn, target, args.duration)
        else:
            report = run_collision_reach(reach, target, args.duration, gain=args.gain)
        failed_ticks += len(report.failures)
        worst["min_distance"] = min(worst["min_distance"], report.min_distance)
        worst["feet_drift"] = max(worst["feet_drift"], report.feet_drift)
        worst["limit_excess"] = max(worst["limit_excess"], report.limit_excess)
        stats = by_family.setdefault(family, {"runs": 0, "min_distance": np.inf, "reached": 0})
        stats["runs"] += 1
        stats["min_distance"] = min(stats["min_distance"], report.min_distance)
        stats["reached"] += int(report.hand_error < 0.01)
        ok = (report.min_distance >= SAFETY_DISTANCE - TOLERANCE and report.feet_drift <= TOLERANCE
              and report.limit_excess <= 1e-9 and not report.nan and not report.failures)
        if not ok:
            bad.append({"run": i, "family": family, "target": target.tolist(), **report.__dict__})
        print(f"run {i:3d} {family:11s} min d {report.min_distance * 1e3:7.3f} mm  hand error {report.hand_error:.3f} m"
              f"{'' if ok else '  FAILED'}{f' ({len(report.failures)} solver failures)' if report.failures else ''}", flush=True)
    summary = {
        "solver": "SolverDyn" if args.dynamic else "SolverKine", "collision_level": not args.no_collision,
        "solver_failure_ticks": failed_ticks,
        "runs": args.runs, "duration_s": args.duration, "hand_gain": args.gain, "seed": args.seed, "safety_m": SAFETY_DISTANCE,
        "worst_min_distance_m": worst["min_distance"], "worst_feet_drift_m": worst["feet_drift"],
        "worst_limit_excess": worst["limit_excess"], "failed_runs": bad, "by_family": by_family,
        "wall_s": time.perf_counter() - started,
    }
    print(json.dumps({k: v for k, v in summary.items() if k != "failed_runs"} | {"failed": len(bad)}, indent=1))
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(summary, indent=1, default=float))
    return summary


if __name__ == "__main__":
    summary = main()
    sys.exit(1 if summary["failed_runs"] else 0)
