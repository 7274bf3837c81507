#!/usr/bin/env python3
"""The seed's minimal example (``ros-kineromeo.py``) on Romeo: choose the robot, the solver, the
tasks, the viewer, and run.

* the robot: ``robot(builder, "romeo")`` (sot-romeo's ``robot = Robot('robot')``): Romeo (the
  ``small`` model, sot-romeo's 31 joints) in half-sitting, with ``dynamic`` and ``device`` plugged;
  ``--robot`` takes any humanoid of the catalog (talos, icub, g1), whose op points carry the same names;
* the solver: the seed's ``solver = Solver(robot)``: the basic ``SOT`` (SVD threshold 1e-6) with a
  ``JointLimitator`` between its control and the device's, which stops a joint whose next position
  would leave its limits (``--solver hqp``: ``SolverKine``, joint limits also hard in the QP;
  ``--no-limitator``: the bare solver plugged into the device);
* the tasks: both ankles held (``contactRF``, ``contactLF``: gain 10, ``keep()``), the CoM held in
  X and Y (``selec = '011'``, gain 10), the right hand (``right-wrist`` moved by ``opmodif``
  (0.1, 0, 0)) sent by ``gotoNd(taskRH, (0.5, -0.2, 0.8), '111', (4.9, 0.9, 0.01, 0.9))``, pushed
  in that order;
* the viewer: Meshcat (``--no-meshcat`` for none); the run: 5 ms ticks, as in the seed.

    python diagrams/kineromeo.py --duration 5 --out out/kineromeo

writes ``recording.html``, ``trace.npz``, ``plots.png``, ``control_graph.svg`` and ``summary.json``.

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.kineromeo`.
"""

from sotdrake import report
from sotdrake.scenarios.kineromeo import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    report(main())
