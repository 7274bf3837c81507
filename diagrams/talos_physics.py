#!/usr/bin/env python3
"""The SoT drives a physically simulated TALOS standing on the ground.

The tutorial's control graph (feet, CoM, and for ``--scenario reach`` the right hand pushed at 1 s
towards (0.5, -0.2, 1.0)) integrates its velocity command into joint references at 1 kHz; the
plant's PD-controlled actuators track them on a discrete ``MultibodyPlant`` (1 ms) with gravity and
ground contact (see :mod:`sotdrake.physics`). ``--loop open`` (default, as sot-talos on the robot) or
``closed`` (the SoT reads the simulated joints, and the base pose estimated by leg odometry: see
``KinematicBaseEstimator``). ``--push F`` pushes the torso
with F newtons along +x for 0.1 s at t = 2 s.

    python diagrams/talos_physics.py --scenario reach --duration 8 --out out/physics

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.talos_physics`.
"""

from sotdrake import report
from sotdrake.scenarios.talos_physics import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    report(main())
