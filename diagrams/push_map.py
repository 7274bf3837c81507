#!/usr/bin/env python3
"""Push-recovery map: TALOS standing on a discrete ``MultibodyPlant`` with ground contact, pushed
on the torso over a grid of magnitude × direction × duration, under either controller:

* ``--controller kinematic`` (default): the physics stand scenario (``diagrams/talos_physics.py
  --scenario stand``: the SoT holds feet and CoM, PD actuators track its references, open loop);
* ``--controller dynamic``: ``SolverDyn``'s torques (``diagrams/talos_dynamics.py --scenario push``
  with the case's push instead of the scenario's two).

Each case: the push (``torso_2_link``'s origin, horizontal, N) starts at ``--push-start``
(default 0.3 s) and lasts the case's duration; the run lasts ``--duration`` seconds (default 3 s,
1 ms steps: a push that tips TALOS may take more than 2 s to floor it). Direction 0° pushes along
+x (forward), 90° along +y (to the robot's left). A case *falls* by the criterion every script
shares (:mod:`sotdrake.fall`: the base tilted more than 30° or dropped more than 0.25 m, a held
sole slid more than 5 cm, another body on the ground); its base displacement is the largest
horizontal distance of the base from its start (m). Every link collides with the ground (a box
per link), so a fallen TALOS lands on it.

    python diagrams/push_map.py --magnitudes 150,300,600 --directions 4 --push-durations 0.1,0.3 \\
        --engine ray --out out/push_map

writes ``push_map.csv`` (and ``.parquet`` with pyarrow), ``push_map.json``, ``plots.png`` (one
polar map per push duration: direction × magnitude, fall or not, base displacement),
``control_graph.svg`` and ``summary.json`` in the output directory.

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.push_map`.
"""

from sotdrake import report
from sotdrake.scenarios.push_map import main

__all__ = ["main"]

if __name__ == "__main__":
    report(main())
