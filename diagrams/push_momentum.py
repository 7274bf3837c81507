#!/usr/bin/env python3
"""The largest torso push the dynamic SoT survives, without and with angular-momentum damping.

The ``push`` scenario of ``diagrams/talos_dynamics.py`` on the physics device (TALOS under torque
control, ``SolverDyn``: both soles held, the soft CoM task, the posture), with one push on the torso
(``torso_2_link``, +x) of ``--push-duration`` seconds starting at ``--push-start``. For each setting
(no momentum task; ``MetaTaskDynMomentum`` with ``K_v = --damping`` in its own level under the CoM
task, or with ``--weight W`` in one weighted level with the posture, posture 1 and momentum W), a
bisection on the push's force between ``--forces LOW,HIGH`` (N) finds the largest push survived to
``(HIGH − LOW)/2^steps``. A run has fallen when the base drops by more than 0.25 m or tilts by more
than 30° from upright (or the state is not finite); it stops there::

    python diagrams/push_momentum.py --damping 10 --forces 100,900 --steps 4 --out out/push_momentum

writes ``DIR/summary.json`` (each setting's largest force survived, the smallest that felled TALOS,
and every run's outcome).

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.push_momentum`.
"""

from sotdrake import report
from sotdrake.scenarios.push_momentum import main

__all__ = ["main"]

if __name__ == "__main__":
    report(main(), leave_out=("runs",))
