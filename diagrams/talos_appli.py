#!/usr/bin/env python3
"""The sot-talos tutorial (``appli.py``) on TALOS in Drake.

    python diagrams/talos_appli.py --duration 8 --out out/appli
    python diagrams/talos_appli.py --live --no-push     # then: sotdrake-shell "sot.push('taskrh')"

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.talos_appli`.
"""

from sotdrake import run_script
from sotdrake.scenarios.talos_appli import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    run_script(main)
