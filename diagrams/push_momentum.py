#!/usr/bin/env python3
"""The largest torso push the dynamic SoT survives, without and with angular-momentum damping.

    python diagrams/push_momentum.py --damping 10 --forces 100,900 --steps 4 --out out/push_momentum

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.push_momentum`.
"""

from sotdrake import run_script
from sotdrake.scenarios.push_momentum import main

__all__ = ["main"]

if __name__ == "__main__":
    run_script(main, leave_out=("runs",))
