#!/usr/bin/env python3
"""Randomized collision runs on TALOS under SolverKine (or SolverDyn): the collision level always holds.

    python bench/collision_runs.py                       # 300 runs of 0.3 s, every tick checked
    python bench/collision_runs.py --runs 20 --duration 0.3
    python bench/collision_runs.py --dynamic --runs 300  # SolverDyn, the acceleration-level rows
    python bench/collision_runs.py --dynamic --only 89 96  # chosen runs of the same draw
    python bench/collision_runs.py --dynamic --jobs 2 --save  # two processes; the committed copy too

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
import multiprocessing
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")  # as bench/run.py; the spawned workers inherit it (see docs/benchmarks.md)

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from output import REFERENCE, RESULTS, add_output_arguments, write_json

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
    parser.add_argument("--jobs", type=int, default=1, help="worker processes (each its own diagram; the runs dealt in turn)")
    add_output_arguments(parser, "collision_runs.json")  # (collision_runs_dyn.json with --dynamic)
    args = parser.parse_args(argv)
    if args.jobs < 1:
        parser.error("--jobs must be at least 1")
    out = args.out.with_name("collision_runs_dyn.json") if args.dynamic and args.out == RESULTS / "collision_runs.json" else args.out
    save = args.save and (REFERENCE / "collision_runs_dyn.json" if args.dynamic else args.save)  # (each solver's own reference)
    chosen = [i for i in range(args.runs) if args.only is None or i in args.only]
    started = time.perf_counter()
    shares = [chosen[w::args.jobs] for w in range(args.jobs)]
    if args.jobs == 1:
        reports = run_share(vars(args), shares[0])
    else:
        context = multiprocessing.get_context("spawn")  # (a fresh interpreter per worker: Drake's objects are not fork-safe)
        with context.Pool(args.jobs) as pool:
            reports = [r for share in pool.starmap(run_share, [(vars(args), share) for share in shares]) for r in share]
    command = "python bench/collision_runs.py " + " ".join(sys.argv[1:] if argv is None else argv)
    summary = summarize(args, sorted(reports, key=lambda r: r["run"]), time.perf_counter() - started, command)
    print(json.dumps({k: v for k, v in summary.items() if k != "failed_runs"} | {"failed": len(summary["failed_runs"])}, indent=1))
    write_json(summary, out, save=save, indent=1)
    return summary


def run_share(options: dict, indices: list[int]) -> list[dict]:
    """The runs ``indices`` of the draw (``options``: the parsed arguments), each as a dict with its
    family, target, report and whether it holds every check; printed as they end."""
    if options["dynamic"]:
        from sotdrake import load_talos

        dyn = build_dyn_collision_reach(load_talos("reduced"), collision=not options["no_collision"], table=True)
    else:
        reach = build_collision_reach(collision=not options["no_collision"], table=True)
    wanted, out = set(indices), []
    for i, (family, target) in enumerate(random_targets(options["runs"], np.random.default_rng(options["seed"]))):
        if i not in wanted:
            continue
        if options["dynamic"]:
            report = run_dyn_collision_reach(dyn, target, options["duration"])
        else:
            report = run_collision_reach(reach, target, options["duration"], gain=options["gain"])
        ok = (report.min_distance >= SAFETY_DISTANCE - TOLERANCE and report.feet_drift <= TOLERANCE
              and report.limit_excess <= 1e-9 and not report.nan and not report.failures)
        print(f"run {i:3d} {family:11s} min d {report.min_distance * 1e3:7.3f} mm  hand error {report.hand_error:.3f} m"
              f"{'' if ok else '  FAILED'}{f' ({len(report.failures)} solver failures)' if report.failures else ''}", flush=True)
        out.append({"run": i, "family": family, "target": target.tolist(), "ok": ok, **report.__dict__})
    return out


def summarize(args: argparse.Namespace, reports: list[dict], wall: float, command: str) -> dict:
    """The JSON summary of the runs' ``reports`` (:func:`run_share`'s)."""
    by_family: dict[str, dict] = {}
    for r in reports:
        stats = by_family.setdefault(r["family"], {"runs": 0, "min_distance": np.inf, "reached": 0})
        stats["runs"] += 1
        stats["min_distance"] = min(stats["min_distance"], r["min_distance"])
        stats["reached"] += int(r["hand_error"] < 0.01)
    return {
        "command": command,
        "solver": "SolverDyn" if args.dynamic else "SolverKine", "collision_level": not args.no_collision,
        "solver_failure_ticks": sum(len(r["failures"]) for r in reports),
        "runs": args.runs, "checked_runs": len(reports), "duration_s": args.duration, "hand_gain": args.gain,
        "seed": args.seed, "safety_m": SAFETY_DISTANCE,
        "worst_min_distance_m": min((r["min_distance"] for r in reports), default=np.inf),
        "worst_feet_drift_m": max((r["feet_drift"] for r in reports), default=0.0),
        "worst_limit_excess": max((r["limit_excess"] for r in reports), default=0.0),
        "failed_runs": [{k: v for k, v in r.items() if k != "ok"} for r in reports if not r["ok"]],
        "by_family": by_family, "jobs": args.jobs, "wall_s": wall,
    }


if __name__ == "__main__":
    summary = main()
    sys.exit(1 if summary["failed_runs"] else 0)
