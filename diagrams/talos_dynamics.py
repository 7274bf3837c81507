#!/usr/bin/env python3
"""The dynamic SoT: TALOS under torque control (SolverDyn), standing, swaying, lifting a leg.

The seed's dynamic level: ``SolverDyn`` computes ``(q̈, f, τ)`` in strict priority (dynamics,
contacts with friction/CoP/torque/joint limits, then the stack, then damping). ``--device physics``
sends ``τ`` to the actuation input of a simulated TALOS (no PD, 1 kHz, closed loop on the plant's
state); ``--device dynsimu`` integrates ``q̈`` (``RobotDynSimu``, no physics). Scenarios:

* ``stand``: both soles held, CoM and posture held;
* ``sway``: the CoM follows ``y = y0 + e(t) · 5 cm · sin(2π · 0.5 t)`` (velocity and acceleration
  feed-forward), the amplitude faded in by a minimum-jerk envelope ``e`` over the first 2 s (a
  sine started at full amplitude asks a step of 16 cm/s at t = 0);
* ``lift_leg`` (the seed's dynromeo): the CoM moves over the left sole (t = 0.5 → 2 s), the right
  contact is released at 2.2 s (its force ramps to 0 over 0.3 s), then the right sole rises 10 cm
  (2.5 → 3.5 s) and stays up;
* ``lift_leg_no_com``: the same without the CoM task (the seed's "what happens?");
* ``squat``: the CoM goes 15 cm down (0.5 → 1.5 s) and back up (2 → 3 s);
* ``push``: standing, 500 N × 2 ms at t = 1 s and 100 N × 0.1 s at t = 2 s on the torso (+x);
  the CoM task is softer (``PUSH_COM_KP``): after the long push (10 N·s, the CoM at 0.11 m/s) a
  stiff one asks a deceleration no CoP inside the soles can give; ``--momentum-damping KV`` adds an
  angular-momentum damping task under the CoM task (``diagrams/push_momentum.py`` compares pushes).

    python diagrams/talos_dynamics.py --scenario lift_leg --device physics --duration 5 --out out/dyn_lift

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.talos_dynamics`.
"""

from sotdrake import report
from sotdrake.scenarios.talos_dynamics import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    report(main())
