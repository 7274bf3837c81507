#!/usr/bin/env python3
"""Reachability map of TALOS's right hand: N targets on a grid around the robot, one short
``SolverKine`` run each, the feet, the CoM and the joint limits held.

Each case is the tutorial's stack with the hierarchical QP: ``contactRF``, ``contactLF`` (gain 10,
``keep()``), ``taskCom`` (gain 10, initial CoM), then from t = 0 the hand (``right-wrist`` moved by
``opmodif`` (0.1, 0, 0)) with ``gotoNd(taskRH, target, '111', 8)`` (constant gain 8 /s, damping
1e-2 on the hand's level so that an out-of-reach target stretches the arm smoothly); joint
positions and velocities are hard limits above all tasks (position margin 1e-3 rad). A case lasts
``--duration`` seconds (default 1 s) at ``--dt`` (default 0.02 s: 50 ticks): with gain 8 a
reachable target's error is divided by ~10⁴ in that time. The map asks where the hand can go, not
how precisely the feet hold at this coarse period: it lifts the solver's step limit
(``setStepLimit(inf)``, which at 20 ms would cap the joints at 0.35 rad/s), and the feet then stay
within about 1 mm (``max_foot_drift_m``) instead of 0.1 mm. A case's summary: the final hand error
(m), the smallest joint-limit margin over the run and over the controlled joints (rad; the
grippers, not controlled, start on their limit and are left out) with the joint that has it, and
the largest foot and CoM drifts (m).

Collisions: each case's path is checked with Drake's signed-distance query on a collision world of
its own (every self-collision pair the SRDF and adjacency leave, and every link–obstacle pair), at
every tick: ``min_signed_distance_m`` is the smallest over the run (+inf when no pair came within
5 cm), and a target whose path collides (a distance < 0) is counted as *not* reached, however
close the hand ended. ``--obstacles table`` puts the table top of ``sotdrake.collision.reach``
in front of the robot (``--obstacles path/to/scene.sdf`` any URDF/SDF scene, loaded by
``add_scene``); ``--collision`` adds the collision level (``d_s`` = 1 cm, ``d_i`` = 5 cm, ``ξ`` =
0.5 m/s) between the CoM and the hand, so that the hand stops short instead of going through;
its default period is then 5 ms (``COLLISION_DT``: the level's rows model one tick to first order,
which the unlimited 20 ms steps of the arm break, by up to 7 cm on the grid's far corners).

Targets: ``--targets N`` with ``--sampling grid`` (N a cube, k × k × k evenly spaced in the box
x ∈ [-0.4, 0.9], y ∈ [-1.1, 0.5], z ∈ [0.2, 1.8] m, world frame, the robot's base above the
origin facing +x) or ``--sampling random`` (N uniform in the box, ``--seed``).

    python diagrams/reach_map.py --targets 1000 --engine ray --out out/reach_map
    python diagrams/reach_map.py --targets 125 --obstacles table --collision --out out/reach_map_table

writes ``reach_map.csv`` (and ``.parquet`` with pyarrow: one row per target), ``reach_map.json``
(engine, wall time, host load), ``plots.png`` (slices of the workspace: hand error and joint-limit
margin), ``control_graph.svg`` and ``summary.json`` in the output directory.

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.reach_map`.
"""

from sotdrake import report
from sotdrake.scenarios.reach_map import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    report(main())
