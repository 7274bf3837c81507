#!/usr/bin/env python3
"""The seed's basic dynamic example (``ros-dynromeo.py``) on Romeo.

    python diagrams/dynromeo.py --scenario lift_leg_no_com --duration 4 --out out/dynromeo_no_com

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.dynromeo`.
"""

from sotdrake import run_script
from sotdrake.scenarios.dynromeo import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    run_script(main)
