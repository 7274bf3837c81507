#!/usr/bin/env python3
"""The project's smallest example: one task on TALOS' left arm (not one of the seed's scripts).

sot-dyninv has no one-arm example: its ``kinesimple.py`` scripts are whole-body stacks (both
contacts, the CoM, the right hand with ``opmodif`` (0, 0, −0.21) sent to (0.5, −0.2, 1.3)), and the
seed's slides name ``ros-kineromeo.py`` as the minimal example (``diagrams/kineromeo.py``). This
script is the step before: one arm, one task, and the interactive prompt.

The ``left_arm`` model (shoulder welded to the world, six arm joints and the gripper), the device
at 1 kHz, the basic ``SOT``, and one ``MetaTaskKine6d`` on the hand (``left-wrist`` moved by
``opmodif`` (0.1, 0, 0), as in the tutorial) driven by ``gotoNd`` to a point 0.245 m away, with a
constant gain. (The wrist's own origin would be a poor choice here: its position depends on three
joints only, which half-sitting aligns, a singular start.) Interactive use, as in the seed::

    python -i diagrams/kinesimple.py --interactive
    >>> step(100); go(1.0); displaySignals(sot, context())

or a whole run::

    python diagrams/kinesimple.py --duration 3 --out out/kinesimple

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.kinesimple`.
"""

from sotdrake import report
from sotdrake.scenarios.kinesimple import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    result = main()
    if isinstance(result, dict):
        report(result)
    else:  # --interactive: the seed's names at the prompt
        from sotdrake import displaySignals  # noqa: F401

        kine, runner = result
        robot, sot, taskLW = kine.robot, kine.sot, kine.taskLW
        step, go, context = runner.step, runner.go, lambda: runner.context
        next_ = runner.next
        print("sotdrake: step(n), next_(), go(seconds), displaySignals(sot, context()), sot.push(name, context())")
