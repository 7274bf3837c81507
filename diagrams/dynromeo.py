#!/usr/bin/env python3
"""The seed's basic dynamic example (``ros-dynromeo.py``) on Romeo: change the contacts, lift the
right leg, with and without the CoM task ("what happens?").

The seed's dynamic robot, ``Robot('romeo', device=RobotDynSimu('romeo'))`` with ``SolverDyn``:
``RobotDyn(builder, load_robot("romeo", "small"), device="dynsimu")``. The device integrates the
solver's ``q̈`` (``v ← v + q̈ dt``, ``q ← q ⊕ v dt``, no physics engine): whatever the solver plans
happens. Both soles are contacts (``contactLF``, ``contactRF`` on ``left-sole``/``right-sole``,
sot-dyninv's Romeo supports as CoP rectangles), under the CoM task (``kp`` 100) and the posture.

* ``lift_leg``: the CoM moves over the centre of the left sole and 2.5 cm up (t = 0.5 → 1.5 s,
  minimum jerk; straighter knees, as the seed's CoM target: Romeo's support knee would reach its
  38 N·m limit when the other leg lifts), then ``sot.rmContact(contactRF)`` at 1.7 s (its force
  ramped to 0 over 0.3 s) with the foot task ``taskRF`` pushed above the posture, and the right
  sole rises 10 cm (2.0 → 3.5 s);
* ``lift_leg_no_com``: the same stack without the CoM task: the seed's "what happens?".

The summary says whether Romeo falls (``fell``, ``fell_at_s``, ``fall_reason``, ``what_happens``):
by the criterion every script shares (:mod:`sotdrake.fall`) or, with no physics engine, by the
held sole leaving its place (``sole moved``), which is the solver failing to hold its own contact:
with the CoM outside the left sole, no contact force inside the sole can balance gravity, so the
"held" left sole tips over its edge. The run stops once the CoM has dropped 0.3 m (there is no ground under ``RobotDynSimu``).

    python diagrams/dynromeo.py --scenario lift_leg_no_com --duration 4 --out out/dynromeo_no_com

writes ``recording.html``, ``trace.npz``, ``plots.png``, ``control_graph.svg`` and ``summary.json``.

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.dynromeo`.
"""

from sotdrake import report
from sotdrake.scenarios.dynromeo import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    report(main())
