#!/usr/bin/env python3
"""What the collision level costs: the tutorial stack with TALOS' self-collision rows and a table
top, against the same stack without them, in one run (ratios, not absolute times).

    python bench/collisions.py                 # 2000 ticks each, interleaved in blocks of 100
    python bench/collisions.py --ticks 500

Both diagrams (``sotdrake.collision.reach``) drive the right hand point to the tutorial's target
(0.5, -0.2, 1.0) under SolverKine; they are advanced in alternating blocks so that both see the
same load on the host. Per tick: the wall and CPU time of ``AdvanceTo`` (median, p90), and for the
collision stack the number of pairs in range and the time of the distance query alone. placo's
self-collision constraint is not run here: placo is not installed in this environment (the
package list has it; it is not a dependency of sotdrake). Writes ``bench/results/collisions.json``.
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

from pydrake.systems.analysis import Simulator

from sotdrake.collision import CollisionWorld
from sotdrake.collision.distance import pair_distances
from sotdrake.collision.reach import build_collision_reach
from sotdrake.meta_tasks import gotoNd
from sotdrake.robots import load_talos

TARGET = np.array([0.5, -0.2, 1.0])
BLOCK = 100


def arm_pairs() -> list[tuple[str, str]]:
    """The pairs a user would pick for this reach: the right forearm, wrist and gripper against the
    torso, the pelvis, the head, the thighs and the table (those the SRDF leaves)."""
    world = CollisionWorld(load_talos("reduced"))
    arm = [link for link in world.links if link.startswith(("arm_right_5", "arm_right_6", "arm_right_7", "wrist_right", "gripper_right"))]
    body = ["torso_1_link", "torso_2_link", "base_link", "head_2_link", "leg_left_1_link", "leg_left_2_link",
            "leg_left_3_link", "leg_right_1_link", "leg_right_2_link", "leg_right_3_link"]
    pairs = [(a, b) for a in arm for b in body if frozenset((a, b)) not in world.disabled | world.adjacent]
    return pairs + [(a, "table") for a in arm]


def _simulator(reach) -> tuple[Simulator, object]:
    simulator = Simulator(reach.diagram)
    context = simulator.get_mutable_context()
    gotoNd(reach.hand, TARGET, "111", (4.9, 0.9, 0.01, 0.9), context=context)
    simulator.Initialize()
    return simulator, context


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--ticks", type=int, default=2000)
    parser.add_argument("--out", type=Path, default=HERE / "results" / "collisions.json")
    args = parser.parse_args(argv)
    stacks = {"without": build_collision_reach(collision=False, table=False),
              "with": build_collision_reach(collision=True, table=True),
              "with_arm_pairs": build_collision_reach(collision=True, table=True, pairs=arm_pairs())}
    sims = {name: _simulator(reach) for name, reach in stacks.items()}
    times: dict[str, list[float]] = {name: [] for name in stacks}
    cpu: dict[str, list[float]] = {name: [] for name in stacks}
    pairs_in_range: list[int] = []
    query_s: list[float] = []
    dt = stacks["with"].robot.dt
    for start in range(0, args.ticks, BLOCK):
        for name, (simulator, _context) in sims.items():
            for k in range(start + 1, min(start + BLOCK, args.ticks) + 1):
                began, began_cpu = time.perf_counter(), time.thread_time()
                simulator.AdvanceTo(k * dt)
                times[name].append(time.perf_counter() - began)
                cpu[name].append(time.thread_time() - began_cpu)
        task = stacks["with"].collision.task  # type: ignore[union-attr]
        world_context = task.world.new_context()
        q = stacks["with"].robot.device.GetOutputPort("state").Eval(stacks["with"].robot.device.GetMyContextFromRoot(sims["with"][1]))
        task.world.plant.SetPositions(task.world.plant_context(world_context), q)
        began = time.perf_counter()
        distances = pair_distances(task.world, world_context, task.settings().influence)
        query_s.append(time.perf_counter() - began)
        pairs_in_range.append(len(distances.names))
    median = {name: float(np.median(t)) for name, t in times.items()}
    median_cpu = {name: float(np.median(t)) for name, t in cpu.items()}
    summary = {
        "ticks": args.ticks,
        "tick_us_median": {name: value * 1e6 for name, value in median.items()},
        "tick_us_p90": {name: float(np.percentile(t, 90)) * 1e6 for name, t in times.items()},
        "tick_cpu_us_median": {name: value * 1e6 for name, value in median_cpu.items()},
        "ratio_median": median["with"] / median["without"],
        "ratio_cpu_median": median_cpu["with"] / median_cpu["without"],
        "ratio_median_arm_pairs": median["with_arm_pairs"] / median["without"],
        "ratio_cpu_median_arm_pairs": median_cpu["with_arm_pairs"] / median_cpu["without"],
        "arm_pairs_checked": len(arm_pairs()),
        "distance_query_us_median": float(np.median(query_s)) * 1e6,
        "pairs_in_range_median": float(np.median(pairs_in_range)),
        "self_pairs_checked": len(stacks["with"].collision.world.self_pairs()),  # type: ignore[union-attr]
        "placo": "not installed in this environment",
    }
    print(json.dumps(summary, indent=1))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(summary, indent=1))
    return summary


if __name__ == "__main__":
    main()
