#!/usr/bin/env python3
"""PR2, the seed's wheeled robot: it reaches an object on a table with its right arm while its base
drives up to the table, under ``SolverKine`` (joint limits hard).

    python diagrams/pr2_reach.py --duration 6 --out out/pr2_reach

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.pr2_reach`.
"""

from sotdrake import run_script
from sotdrake.scenarios.pr2_reach import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    run_script(main)
