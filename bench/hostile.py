#!/usr/bin/env python3
"""The hostile user, in full: the table of bad inputs and ≥ 1000 randomized runs (see
``tests/hostile.py``) at several control periods under both kinematic solvers, each attempt in a
worker process whose exit or hang is recorded (a worker is replaced every 100 attempts, which bounds
its memory).

    python bench/hostile.py                          # ~15 min of CPU on each of 2 cores
    python bench/hostile.py --runs 80 --periods 5    # a quick look at one period

Run ``s`` uses ``SolverKine`` when ``s`` is odd, the basic ``SOT`` when it is even, and the period
``periods[(s // 2) % len(periods)]``; it lasts ``--ticks`` control ticks. Prints the summary and
writes ``--out`` (default ``bench/results/hostile.json``, ignored by git; ``--save``: also the
committed ``bench/reference/hostile.json``). Expected: 0 process exits, 0 hangs, 0 NaN, 0 frozen ticks,
every contact within 1e-4 m under both solvers at every period, 0 limit violations under
SolverKine (the basic SOT does not bound positions), and every bad input a SotError with the state
unchanged.
"""

from __future__ import annotations

import argparse
import json
import sys
import threading
import time
from collections import Counter
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

sys.path.insert(0, str(HERE))

from output import add_output_arguments, write_json

from tests.hostile import CONTACT_TOLERANCE, bad_input_solver, bad_inputs, run_attempts


def run_of(seed: int, periods: list[float]) -> tuple[str, float]:
    """The solver and the control period (s) of run ``seed``."""
    return ("hqp" if seed % 2 else "cascade"), periods[(seed // 2) % len(periods)]


def milliseconds(text: str) -> list[float]:
    try:
        values = [float(v) * 1e-3 for v in text.split(",") if v.strip()]
    except ValueError as error:
        raise SystemExit(f"--periods: expected comma-separated milliseconds, got {text!r}") from error
    if not values or not all(0 < v <= 0.02 for v in values):
        raise SystemExit(f"--periods: expected periods in (0, 20] ms, got {text!r}")
    return values


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=1000, help="randomized runs")
    parser.add_argument("--ticks", type=int, default=60, help="control ticks of a run")
    parser.add_argument("--periods", type=milliseconds, default=[1e-3, 2e-3, 5e-3, 10e-3],
                        help="control periods (ms), comma-separated")
    add_output_arguments(parser, "hostile.json")
    args = parser.parse_args(argv)
    start = time.perf_counter()

    table = bad_inputs()
    jobs: dict[tuple, list[int]] = {
        ("bad", "cascade", 1e-3): [i for i, (label, _) in enumerate(table) if bad_input_solver(label) == "cascade"],
        ("bad", "hqp", 1e-3): [i for i, (label, _) in enumerate(table) if bad_input_solver(label) == "hqp"],
    }
    for seed in range(args.runs):
        solver, dt = run_of(seed, args.periods)
        jobs.setdefault(("random", solver, dt), []).append(seed)
    results: dict = {}
    progress = args.out.with_suffix(".progress.jsonl")  # each result as it comes
    progress.parent.mkdir(parents=True, exist_ok=True)
    progress.write_text("")

    def stream(keys):  # one worker process at a time per stream: two streams, two cores
        for key in keys:
            kind, solver, dt = key
            results[key] = run_attempts(kind, solver, jobs[key], args.ticks * dt, log=progress, dt=dt)

    hqp = [key for key in jobs if key[0] == "random" and key[1] == "hqp"]
    threads = [threading.Thread(target=stream, args=(hqp,)),
               threading.Thread(target=stream, args=([key for key in jobs if key not in hqp],))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()

    bad = {**results[("bad", "cascade", 1e-3)], **results[("bad", "hqp", 1e-3)]}
    bad_failures = [{"label": table[i][0], **r} for i, r in sorted(bad.items())
                    if r.get("status") != "sot_error" or not r.get("unchanged")]
    summary: dict = {
        "bad_inputs": len(bad),
        "bad_input_status": dict(Counter(r.get("status") for r in bad.values())),
        "bad_input_state_changed": sum(1 for r in bad.values() if r.get("unchanged") is False),
        "bad_input_failures": bad_failures,
        "runs": {},
        "ticks_per_run": args.ticks,
        "contact_tolerance_m": CONTACT_TOLERANCE,
    }
    for (kind, solver, dt), runs in sorted(results.items()):
        if kind != "random":
            continue
        done = [r for r in runs.values() if "seed" in r]
        drift = [r["contact_drift_m"] for r in done]
        summary["runs"][f"{solver} {dt * 1e3:g} ms"] = {
            "runs": len(runs),
            "process_exits": sum(1 for r in runs.values() if r.get("status") == "process_exit"),
            "hangs": sum(1 for r in runs.values() if r.get("status") == "hang"),
            "worker_failures": sum(1 for r in runs.values() if r.get("status") == "worker_failed"),
            "nan": sum(1 for r in done if not r["finite"]),
            "errors": sorted({r["error"] for r in done if r.get("error")}),
            "frozen_ticks": sum(r["frozen_ticks"] for r in done),
            "failures": sorted({r["failure"] for r in done if r.get("failure")})[:5],
            "max_contact_drift_m": max(drift) if drift else None,
            "contacts_beyond_tolerance": sum(1 for d in drift if d > CONTACT_TOLERANCE),
            "runs_with_limit_violation": sum(1 for r in done if r["limit_violation"] > 1e-9),
            "max_limit_violation": max((r["limit_violation"] for r in done), default=None),
            "runs_scaled": sum(1 for r in done if r["min_velocity_scale"] < 1.0),
            "min_velocity_scale": min((r["min_velocity_scale"] for r in done), default=None),
            "worst_seeds": [r["seed"] for r in sorted(done, key=lambda r: -r["contact_drift_m"])[:5]],
            "max_worker_rss_mb": max((r.get("worker_max_rss_mb", 0.0) for r in done), default=None),
        }
    summary["wall_s"] = time.perf_counter() - start
    write_json(summary, args.out, args.save)
    print(json.dumps(summary, indent=2, default=repr))
    return summary


if __name__ == "__main__":
    main()
