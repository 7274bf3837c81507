#!/usr/bin/env python3
"""The seed's hand-made sequencer example (``ros-planche.py``) on Romeo.

    python diagrams/planche.py --out out/planche          # --variant reduced; --solver dyn

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.planche`.
"""

from sotdrake import run_script
from sotdrake.scenarios.planche import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    run_script(main)
