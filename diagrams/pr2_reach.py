#!/usr/bin/env python3
"""PR2, the seed's wheeled robot: it reaches an object on a table with its right arm while its base
drives up to the table, under ``SolverKine`` (joint limits hard).

* the robot: ``robot(builder, "pr2")``, its base a planar joint (``root_joint``: x, y, yaw in
  the world), arms tucked (the SRDF's ``tuck_left_arm`` and ``tuck_right_arm``);
* the solver: ``SolverKine`` over the base, the torso lift and the right arm (casters, wheels,
  head, laser, left arm and grippers are left out of the control); joint position and velocity
  limits are hard constraints above every task;
* the tasks, in priority order: the base (``waist``: X, Y and yaw, ``selec = '100011'``) driven
  to a stand-off pose in front of the table (gain 1), then the right gripper's tool frame
  (``right-gripper``, position only) sent to the object by ``gotoNd`` with the tutorial's adaptive
  gain. Both start at t = 0: the arm unfolds while the base moves.

    python diagrams/pr2_reach.py --duration 6 --out out/pr2_reach

writes ``recording.html``, ``trace.npz``, ``plots.png``, ``control_graph.svg`` and ``summary.json``.

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.pr2_reach`.
"""

from sotdrake import report
from sotdrake.scenarios.pr2_reach import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    report(main())
