#!/usr/bin/env python3
"""TALOS' right hand to targets across its torso and under a table top, with and without the collision
level.

    python diagrams/talos_collisions.py --out out/talos_collisions
    python diagrams/talos_collisions.py --no-meshcat --duration 1

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.talos_collisions`.
"""

from sotdrake import run_script
from sotdrake.scenarios.talos_collisions import main

__all__ = ["main"]

if __name__ == "__main__":
    run_script(main)
