"""TALOS' right hand to targets across its torso and under a table top, with and without the
collision level: the summary gives the smallest signed distance each way.

The tutorial's stack under SolverKine (both ankles and the CoM held, the hand point at
``right-wrist`` + (0.1, 0, 0)), a table top in front of the robot at hip height; with the constraint,
the collision level (every self-collision pair the SRDF and adjacency leave, and every link–table
pair; ``d_s`` = 1 cm, ``d_i`` = 5 cm, ``ξ`` = 0.5 m/s) sits between the contacts and the hand. Every
tick is checked with Drake's own distance query on a collision world of its own (not the task's
numbers): the smallest signed distance of any checked pair, the ankles' drift::

    python diagrams/talos_collisions.py --out out/talos_collisions
    python diagrams/talos_collisions.py --no-meshcat --duration 1

Writes ``summary.json`` (a smallest distance of no pair in range, +inf, as ``null``) and, unless
``--no-meshcat``, one Meshcat recording per run with the constraint (``recording_<target>.html``,
the table drawn).
"""

from __future__ import annotations

import numpy as np

from sotdrake import build_collision_reach, run_collision_reach, save_recording, script_arguments, start, write_run

#: The targets of the hand point (m, world), TALOS in half-sitting facing +x.
TARGETS = {
    "across_torso": np.array([0.15, 0.30, 1.05]),  # in front of the left side of the chest
    "into_torso": np.array([-0.10, 0.0, 1.30]),  # deep in the chest
    "under_table": np.array([0.50, -0.30, 0.70]),  # under the table top, reached through it
}
HAND_GAIN = 10.0  # 1/s, constant


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/talos_collisions", duration=1.5, bag=False)
    args = parser.parse_args(argv)
    if args.duration < 1e-3:
        raise SystemExit(f"--duration must be at least one tick (0.001 s), got {args.duration}")
    meshcat = start(args)
    args.out.mkdir(parents=True, exist_ok=True)
    with_constraint = build_collision_reach(collision=True, table=True, meshcat=meshcat)
    without = build_collision_reach(collision=False, table=True)
    summary: dict = {"duration_s": args.duration, "hand_gain_per_s": HAND_GAIN, "safety_m": 0.01, "runs": {}}
    for name, target in TARGETS.items():
        runs: dict[str, dict] = {}
        for label, reach in (("without", without), ("with", with_constraint)):
            report = run_collision_reach(reach, target, args.duration, gain=HAND_GAIN)
            runs[label] = {"min_signed_distance_m": report.min_distance, "hand_error_m": report.hand_error,
                           "feet_drift_m": report.feet_drift, "solver_failures": len(report.failures)}
            if not args.quiet:
                print(f"{name:13s} {label:7s} min signed distance {report.min_distance * 1e3:8.2f} mm, "
                      f"hand {report.hand_error * 1e3:6.1f} mm from its target")
            if label == "with" and reach.visualizer is not None and meshcat is not None:
                runs[label]["recording"] = str(save_recording(reach.visualizer, meshcat, args.out / f"recording_{name}.html"))
        summary["runs"][name] = {"target_m": target.tolist(), **runs}
    write_run(args.out, with_constraint.diagram, summary, graph=False)  # (summary.json: inf, no pair in range, as null)
    return summary
