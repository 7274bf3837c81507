#!/usr/bin/env python3
"""A target switch with and without joint acceleration limits (``SolverKine.setAccelerationLimit``).

TALOS (reduced) stands on both feet with its CoM held and reaches with its right hand for a point;
halfway through the run the target jumps to another point. The task's reference velocity jumps
with it (and at the start, from rest), so without acceleration limits the joint velocities jump in
one tick. The same scenario runs twice in one invocation: without a limit, then with
``a_max`` on every joint; the summary gives each run's peak joint acceleration (``|Δv|/dt`` over
the joints and ticks), at the start and at the switch, and the hand's final error::

    python diagrams/target_switch.py --a-max 20 --out out/target_switch

writes ``DIR/summary.json``, ``DIR/plots.png`` (the right elbow's velocity in both runs) and each run's
``trace.npz``.

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.target_switch`.
"""

from sotdrake import report
from sotdrake.scenarios.target_switch import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    report(main())
