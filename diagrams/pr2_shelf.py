#!/usr/bin/env python3
"""PR2 reaches into the compartments of a shelf with its right arm, with and without the collision
level.

    python diagrams/pr2_shelf.py --out out/pr2_shelf --duration 4

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.pr2_shelf`.
"""

from sotdrake import run_script
from sotdrake.scenarios.pr2_shelf import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    run_script(main)
