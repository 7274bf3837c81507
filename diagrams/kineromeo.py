#!/usr/bin/env python3
"""The seed's minimal example (``ros-kineromeo.py``) on Romeo.

    python diagrams/kineromeo.py --duration 5 --out out/kineromeo

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.kineromeo`.
"""

from sotdrake import run_script
from sotdrake.scenarios.kineromeo import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    run_script(main)
