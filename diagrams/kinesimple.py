#!/usr/bin/env python3
"""The project's smallest example: one task on TALOS' left arm (not one of the seed's scripts).

    python diagrams/kinesimple.py --duration 3 --out out/kinesimple

The scenario, its options (``--help``) and what it reports: :mod:`sotdrake.scenarios.kinesimple`.
"""

from sotdrake import run_script
from sotdrake.scenarios.kinesimple import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    result = run_script(main)  # (a summary is printed)
    if not isinstance(result, dict):  # --interactive: the seed's names at the prompt
        from sotdrake import displaySignals  # noqa: F401

        kine, runner = result
        robot, sot, taskLW = kine.robot, kine.sot, kine.taskLW
        step, go, context = runner.step, runner.go, lambda: runner.context
        next_ = runner.next
        print("sotdrake: step(n), next_(), go(seconds), displaySignals(sot, context()), sot.push(name, context())")
