#!/usr/bin/env python3
"""PR2 reaches into the compartments of a shelf with its right arm, with and without the collision
level: the summary gives the smallest signed distance each way and whether each target was reached.

* the robot: ``robot(builder, "pr2")``, arms tucked, base fixed; ``SolverKine`` over the torso lift
  and the right arm (joint position and velocity limits hard);
* the shelf: ``sotdrake/data/shelf.sdf`` (:data:`sotdrake.collision.SHELF`, 0.8 × 0.4 × 1.2 m, three
  compartments) loaded by :func:`sotdrake.collision.add_scene` at :data:`SHELF_POSE`, open towards
  the robot;
* the tasks, in priority order: with the constraint, the collision level (every right-arm link from
  the upper arm to the finger tips against every board of the shelf; ``d_s`` = 1 cm, ``d_i`` = 5 cm,
  ``ξ`` = 0.5 m/s), then the right gripper's tool frame (position) sent to a point 8 cm deep in a
  compartment by ``gotoNd`` (the tutorial's adaptive gain).

Every tick is checked with Drake's query on a collision world of its own (not the task's numbers)::

    python diagrams/pr2_shelf.py --out out/pr2_shelf --duration 4

writes ``summary.json`` and, unless ``--no-meshcat``, ``recording_<target>.html`` per run with the
constraint (the shelf drawn).

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.pr2_shelf`.
"""

from sotdrake import report
from sotdrake.scenarios.pr2_shelf import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    report(main())
