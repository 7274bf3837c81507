#!/usr/bin/env python3
"""Reachability map of TALOS's right hand: N targets on a grid around the robot, one short
``SolverKine`` run each, the feet, the CoM and the joint limits held.

    python diagrams/reach_map.py --targets 1000 --engine ray --out out/reach_map
    python diagrams/reach_map.py --targets 125 --obstacles table --collision --out out/reach_map_table

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.reach_map`.
"""

from sotdrake import run_script
from sotdrake.scenarios.reach_map import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    run_script(main)
