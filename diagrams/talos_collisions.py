#!/usr/bin/env python3
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

Writes ``summary.json`` and, unless ``--no-meshcat``, one Meshcat recording per run with the
constraint (``recording_<target>.html``, the table drawn).

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.talos_collisions`.
"""

from sotdrake import report
from sotdrake.scenarios.talos_collisions import main

__all__ = ["main"]

if __name__ == "__main__":
    report(main())
