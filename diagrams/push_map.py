#!/usr/bin/env python3
"""Push-recovery map: TALOS standing on the ground, pushed on the torso over a grid of magnitude ×
direction × duration, under the kinematic or the dynamic controller.

    python diagrams/push_map.py --magnitudes 150,300,600 --directions 4 --push-durations 0.1,0.3 \\
        --engine ray --out out/push_map

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.push_map`.
"""

from sotdrake import run_script
from sotdrake.scenarios.push_map import main

__all__ = ["main"]

if __name__ == "__main__":
    run_script(main)
