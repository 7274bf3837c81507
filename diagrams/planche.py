#!/usr/bin/env python3
"""The seed's hand-made sequencer example (``ros-planche.py``) on Romeo: standing on its left foot,
Romeo lifts its right leg far back and leans its chest far forward (the planche), then comes back,
a sequence of tasks driven by ``attime``.

``--variant full`` (the default) is the seed's ``WITH_FULL_EXTENTION = True``: during the planche
the arms go out (shoulder yaws ∓π/2, at the seed's iteration 1250), then the right foot extends
(ankle pitch 0.73) and the head pitches (−π/4) (iteration 2080), and every later step comes 5 s
later; ``--variant reduced`` leaves these out (the seed's other setting).

The seed runs it on the dynamic solver with the left sole's support shrunk to 6 × 3 cm. Here it
is the kinematic SoT (``SolverKine``, joint position and velocity limits hard) with the
quasi-static counterpart of that support: the CoM (X, Y) as an *inequality* task inside the same
shrunken rectangle, right below the contacts, so every other task moves the body only as far as
the CoM stays over it. At the bottom of the stack, always, the rest posture (half-sitting, gain
1): the seed's solver holds its own ``sot.posture`` there. In between, in the seed's order and at
the seed's times (its iterations of 5 ms, the CoM given 0.8 s more to reach the rectangle before
the right foot leaves), each task pushed just above the rest posture:

==========  ===============================================================================
t (s)       ``attime`` command
==========  ===============================================================================
0           both ankles are contacts (``sot.addContact``); the CoM inequality is pushed: the
            CoM goes into the shrunken rectangle over the left ankle
1.5         ``sot.rmContact(contactRF)``, push ``taskrf``: the right ankle goes up (Y, Z to
            (0, 0.65) m, ``'000110'``)
3.3         the right leg extends back (X, Z to (−0.55, 0.7) m, ``'000101'``)
4.8         push ``taskChest``: the chest's orientation to 80° forward (``'111000'``)
5.8         remove ``taskrf``, push the posture: chest, right leg (knee at 5°) and head
            straight (``gotoq``: only those joints selected)
7.05        (full) the posture adds the arms, out to the sides
11.2        (full) the posture adds the right foot extended and the head pitched down
8.3         remove the chest task; the posture folds the arms, leg and head back to half-sitting
            (13.3 in the full variant, as every step below: +5 s)
9.8         remove the posture, push ``taskrf``: the right ankle to (−0.1, −0.1, 0.25) m
11.8, 12.8  the right ankle 7 cm above its initial pose, then on it (6D)
14.0        ``sot.addContact(contactRF)``, remove ``taskrf``, the CoM bounds widened to the
            double support; the rest posture brings the robot back to half-sitting
==========  ===============================================================================

``--solver dyn`` runs the same sequence on the dynamic SoT as the seed did (``RobotDynSimu`` +
``SolverDyn``, ``planche_dyn.py``): on Romeo's model it falls as the right leg goes back, and its
summary says when, by which criterion, in which step and with which joints at their torque limits.

    python diagrams/planche.py --out out/planche          # --variant reduced; --solver dyn

writes ``recording.html``, ``trace.npz``, ``plots.png``, ``control_graph.svg`` and ``summary.json``.

The scenario (its diagram, run and summary) is :mod:`sotdrake.scenarios.planche`.
"""

from sotdrake import report
from sotdrake.scenarios.planche import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    report(main())
