#!/usr/bin/env python3
"""The dynamic SoT: TALOS under torque control (SolverDyn), standing, swaying, lifting a leg.

    python diagrams/talos_dynamics.py --scenario lift_leg --device physics --duration 5 --out out/dyn_lift

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.talos_dynamics`.
"""

from sotdrake import run_script
from sotdrake.scenarios.talos_dynamics import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    run_script(main)
