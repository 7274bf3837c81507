#!/usr/bin/env python3
"""Resident memory and full garbage collections on long runs: a live run and a long scenario.

    python bench/memory.py                              # live 30 s + scenario 60 s (~3 min)
    python bench/memory.py --live-seconds 600           # the 10-minute live run
    python bench/memory.py --out /tmp/memory.json       # default: bench/results/memory.json (ignored)
    python bench/memory.py --live-seconds 600 --save    # also the committed bench/reference/memory.json

Each part runs in its own process on the tutorial's diagram (``diagrams/talos_appli.py``: TALOS,
feet and CoM held, right hand pushed at 1 s, traced every tick), without Meshcat:

* ``live``: :class:`sotdrake.live.runner.LiveRun` at real-time rate for ``--live-seconds``;
* ``scenario``: :func:`sotdrake.simulation.simulate` for ``--scenario-seconds`` of simulated time.

A thread samples the process' resident set size (``/proc/self/statm``) every 0.25 s of wall time.
Reported per part: RSS (MiB) at the start of the loop, 10 s into it (wall time for ``live``; the
wall time at which the loop reached 10 s of simulated time, interpolated, for ``scenario``), the
peak after that and at the end; ``growth_after_10s`` = end / at-10-s − 1 (target ≤ 0.10); and
``gen2_in_loop``, the full (generation 2) garbage collections while the loop ran (target 0).
"""

from __future__ import annotations

import argparse
import gc
import json
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))

from output import add_output_arguments, write_json


def rss_mib() -> float:
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


class Sampler(threading.Thread):
    """(wall s since start, RSS MiB) every ``period`` s until stopped."""

    def __init__(self, period: float = 0.25):
        super().__init__(daemon=True)
        self.period, self.samples, self.done = period, [], threading.Event()
        self.start_time = time.monotonic()

    def run(self) -> None:
        while not self.done.wait(self.period):
            self.samples.append((time.monotonic() - self.start_time, rss_mib()))


def count_gen2() -> list[int]:
    """A counter of the generation-2 collections made while the collector is frozen (the loops)."""
    counter = [0]

    def callback(phase: str, info: dict) -> None:
        if phase == "start" and info["generation"] == 2 and gc.get_freeze_count() > 0:
            counter[0] += 1

    gc.callbacks.append(callback)
    return counter


def part(kind: str, seconds: float) -> dict:
    from sotdrake.scenarios import talos_appli

    appli = talos_appli.build_diagram()
    gen2 = count_gen2()
    sampler = Sampler()
    start_rss = rss_mib()
    sampler.start()
    if kind == "live":
        from sotdrake.live.runner import LiveRun

        wall = LiveRun(appli.diagram, appli.robot.dt, appli).run(seconds)
        at_10 = 10.0
    else:
        from sotdrake.simulation import simulate

        _, wall = simulate(appli.diagram, seconds, progress=False)
        at_10 = (time.monotonic() - sampler.start_time - wall) + wall * 10.0 / seconds
    sampler.done.set()
    sampler.join()
    end_rss = rss_mib()
    after = [rss for t, rss in sampler.samples if t >= at_10] or [end_rss]
    rss_10 = after[0]
    return {"seconds": seconds, "wall_s": round(wall, 2), "rss_start_mib": round(start_rss, 1),
            "rss_10s_mib": round(rss_10, 1), "rss_peak_after_10s_mib": round(max(after), 1),
            "rss_end_mib": round(end_rss, 1), "growth_after_10s": round(end_rss / rss_10 - 1, 4),
            "gen2_in_loop": gen2[0], "tracer_streams": appli.tracer.path is not None}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--live-seconds", type=float, default=30.0, help="the live run's length (s)")
    parser.add_argument("--scenario-seconds", type=float, default=60.0, help="the scenario's simulated time (s)")
    add_output_arguments(parser, "memory.json")
    parser.add_argument("--part", choices=["live", "scenario"], help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    for name in ("live_seconds", "scenario_seconds"):
        if not getattr(args, name) > 10:
            raise SystemExit(f"--{name.replace('_', '-')} must be > 10 s, got {getattr(args, name)}")
    if args.part:
        print(json.dumps(part(args.part, args.live_seconds if args.part == "live" else args.scenario_seconds)))
        return {}
    result: dict = {"date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), "cpus": os.cpu_count(),
                    "command": "python bench/memory.py " + " ".join(argv if argv is not None else sys.argv[1:])}
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    for kind in ("scenario", "live"):
        command = [sys.executable, __file__, "--part", kind, "--live-seconds", str(args.live_seconds),
                   "--scenario-seconds", str(args.scenario_seconds)]
        done = subprocess.run(command, env=env, capture_output=True, text=True, check=False)
        if done.returncode:
            raise SystemExit(f"the {kind} part failed:\n{done.stderr[-2000:]}")
        result[kind] = json.loads(done.stdout.strip().splitlines()[-1])
    result["load_average"] = os.getloadavg()
    write_json(result, args.out, args.save)
    print(json.dumps(result, indent=2))
    return result


if __name__ == "__main__":
    main()
