#!/usr/bin/env python3
"""A target switch with and without joint acceleration limits (``SolverKine.setAccelerationLimit``).

    python diagrams/target_switch.py --a-max 20 --out out/target_switch

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.target_switch`.
"""

from sotdrake import run_script
from sotdrake.scenarios.target_switch import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    run_script(main)
