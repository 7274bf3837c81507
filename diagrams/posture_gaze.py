#!/usr/bin/env python3
"""TALOS looks at a moving point while holding its feet and its CoM; a posture task below.

    python diagrams/posture_gaze.py --duration 8 --out out/posture_gaze

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.posture_gaze`.
"""

from sotdrake import run_script
from sotdrake.scenarios.posture_gaze import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    run_script(main)
