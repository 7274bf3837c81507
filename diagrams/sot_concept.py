#!/usr/bin/env python3
"""The seed's sot-concept experiment (sot-dyninv ``python/ros/sot-concept.py``) on TALOS.

    python diagrams/sot_concept.py --config seed --out out/concept     # or all, extra, or one name; --robot romeo

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.sot_concept`.
"""

from sotdrake import run_script
from sotdrake.scenarios.sot_concept import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    run_script(main, print_summary=False)
