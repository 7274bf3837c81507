#!/usr/bin/env python3
"""The SoT drives a physically simulated TALOS standing on the ground.

    python diagrams/talos_physics.py --scenario reach --duration 8 --out out/physics

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.talos_physics`.
"""

from sotdrake import run_script
from sotdrake.scenarios.talos_physics import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    run_script(main)
