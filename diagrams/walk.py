#!/usr/bin/env python3
"""The seed's kinematic walk (walkromeo) on TALOS: a pattern generator commanded by velocity.

    python diagrams/walk.py --robot talos --velocity 0.1 0 0 --then 10 0.1 0 0.1 --duration 15 --out out/walk
    python diagrams/walk.py --mode physics --steps 8 --step-length 0.2 --duration 10 --out out/walk_physics
    python diagrams/walk.py --mode dynamic --steps 8 --step-length 0.2 --duration 10 --out out/walk_dynamic
    python diagrams/walk.py --robot romeo --velocity 0.1 0 0 --duration 6 --out out/walk_romeo

The controller is :mod:`sotdrake.walking.controller`; the scenario, its options (``--help``) and
what it reports: :mod:`sotdrake.scenarios.walk`.
"""

from sotdrake import run_script
from sotdrake.scenarios.walk import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    run_script(main)
