#!/usr/bin/env python3
"""The sot-talos tutorial (``appli.py``) on TALOS in Drake.

Both feet held (``contactRF``, ``contactLF``: gain 10, ``keep()``), the centre of mass held (gain
10, desired = initial CoM), pushed in that order; at t = 1 s the right hand (``right-wrist`` moved
by ``opmodif`` (0.1, 0, 0)) is pushed with ``gotoNd(taskRH, (0.5, -0.2, 1.0), '111',
(4.9, 0.9, 0.01, 0.9))``. Kinematic simulation at 1 kHz with the basic ``SOT`` solver.

    python diagrams/talos_appli.py --duration 8 --out out/appli

writes ``recording.html`` (Meshcat), ``trace.npz``, ``plots.png``, ``control_graph.svg`` and
``summary.json`` in the output directory. Live, steered from another terminal::

    python diagrams/talos_appli.py --live --no-push     # then: sotdrake-shell "sot.push('taskrh')"

runs at real-time rate until Ctrl-C, then writes the same files (no recording: Meshcat is live).
With the ``ros2`` extra, ``--ros`` runs live with the seed's ``RosPublish`` and its ``run_command`` and
``start_dynamic_graph`` services (drive it with ``diagrams/ros_test.py``); ``--bag`` also writes
``run/run.mcap`` (rosbag2).

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.talos_appli`.
"""

from sotdrake import report
from sotdrake.scenarios.talos_appli import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    report(main())
