#!/usr/bin/env python3
"""The seed's sot-concept experiment (sot-dyninv ``python/ros/sot-concept.py``) on TALOS: the right
hand grasps a ball; each configuration adds tasks to a stack whose first task is the hand, as the
original's ``config(0..7)`` did (``SolverKine``, 5 ms ticks; the original ran on Romeo).

The original's ``sot.addContact`` is sot-dyninv's kinematic one, ``keep()`` then ``push``: the feet
go *below* the hand (``addContact(..., priority="bottom")``), which is what "balance is lost" shows.

==========  ========================================================================================
config      the original's commands after ``push(taskRH)`` (stack highest first), and the lesson
==========  ========================================================================================
seed0       nothing: hand only, ball (0.5, −0.2, 1.0); the whole body, free flyer included, follows
seed1       + contacts (RF, LF at the bottom); same ball: no CoM task, balance kept incidentally
seed2       + contacts; ball behind and above (−0.15, −0.2, 1.3): the hand pulls, balance is lost
seed3       + contacts + CoM equality; ball (0.15, 0.1, 1.0): the CoM is held below the hand
seed4       + joint limits (torso yaw's upper limit set to 0) + contacts + CoM; same ball: the
            torso stops at its artificial limit
seed5       + contacts + "COM<": the CoM xy kept in the support box (−0.08..0.11, −0.15..0.15) by an
            inequality; ball (0.15, −0.2, 1.3)
seed6       + contacts + CoM; ball (0.15, −0.2, 1.3) moved +0.1 m in x four times (the original's
            ``i`` key, here at 1.0, 1.5, 2.0 and 2.5 s): the singular approach (``--steps``:
            TALOS, taller than Romeo, still reaches the ball after 4; 12 take its arm to the singularity)
seed7       seed6, then ``down(RH)`` twice (the feet above the hand) and damping 0.1 (the last level)
==========  ========================================================================================

The project's own configurations are kept as ``extra_*`` (feet first, then the CoM, then the hand;
1 ms ticks): ``extra_under_constrained``, ``extra_balance_held``, ``extra_balance_broken``,
``extra_singular_undamped``, ``extra_singular_damped``, ``extra_singular_floor`` (the undamped
one with the right arm's manipulability kept above 0.01 by an inequality above the hand,
``MetaTaskKineManipulability``), ``extra_joint_limits`` and ``extra_joint_limits_cascade`` (the
basic ``SOT``).

``--robot romeo`` runs the seed configurations on the original's robot (sot-romeo's ``small``
model, the original's grip (0.07, −0.02, 0); seed4 limits the right shoulder yaw, which the reach
turns past 0).

    python diagrams/sot_concept.py --config seed --out out/concept     # or all, extra, or one name; --robot romeo

writes ``DIR/summary.json`` (one entry per configuration), ``DIR/plots.png``,
``DIR/control_graph.svg`` and ``DIR/<config>/recording.html`` + ``trace.npz``.

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.sot_concept`.
"""

from sotdrake import report  # noqa: F401  (the summary is printed by main's table)
from sotdrake.scenarios.sot_concept import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    main()
