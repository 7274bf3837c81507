#!/usr/bin/env python3
"""The seed's kinematic walk (walkromeo) on TALOS: a pattern generator commanded by velocity.

``pg.setVelocity(x, y, θ)`` (the ``PatternGenerator``: footsteps, ZMP reference, CoM by Drake's
``ZmpPlanner``, swing trajectories) feeds the desired values of the seed's stack, in priority
order: the waist's height, roll and pitch (``taskWaist``, ``'011100'``), both soles in 6D
(``taskRF``, ``taskLF``), the CoM in x, y (``taskCom``, ``'011'``, with the planned CoM velocity as
feed-forward), then the head's orientation following the right foot (``taskHead``, ``'110000'``: pitch and yaw),
the waist's yaw (``taskWaistOr``, ``'100000'``) and walkromeo's arm task, the arm joints held at
half-sitting by a posture task at the bottom (``taskArms``, gain 0.1 /s; ``--arms posture``, the
default); ``--arms inequality``: instead, with ``SolverKine`` (``--solver hqp``, the default), both
wrists kept from moving backward relative to the waist (``taskArmL``, ``taskArmR``:
``TaskInequality`` on the x of ``FeatureRelative6d``). Every moving target comes with its velocity
(feed-forward).

``--mode kinematic``: the SoT integrates its velocity at 1 kHz (no dynamics). ``--mode physics``:
the same control graph drives the physically simulated TALOS through position servos (the PD
actuators of :mod:`sotdrake.physics`, open loop, as ``diagrams/talos_physics.py``), with the
servo options of :class:`~sotdrake.walking.controller.Servos` (``--stiffness``, ``--damping``, the static feed-forward torque with
``--feedforward``, the CoM/ZMP stabiliser's ``--com-gain``/``--zmp-gain``, on by default) and the gait's
``--landing-depth``; its CoM is planned with the legs' momentum (the multibody ZMP correction of
:mod:`sotdrake.walking.multibody_zmp`; ``--zmp-model lipm``: the pendulum alone, ``--zmp-model
multibody`` in kinematic mode). ``--mode dynamic``: ``SolverDyn`` drives the torque-controlled TALOS, the soles'
contacts released and added back at each step (``rmContact``/``addContact``; ``--steps`` only), the
swing quintic (``--swing-profile``; zero acceleration at the lift-off: with the cubic, the stance
sole spins when the other foot lifts off).
``--then T X Y THETA`` changes the command at time T (``attime``); ``--steps N --step-length L``
walks N steps of L metres (the walking frame's advance per step) instead of a velocity.
``--robot romeo`` walks Romeo (kinematic mode: the physics station is TALOS').

    python diagrams/walk.py --robot talos --velocity 0.1 0 0 --then 10 0.1 0 0.1 --duration 15 --out out/walk
    python diagrams/walk.py --mode physics --steps 8 --step-length 0.2 --duration 10 --out out/walk_physics
    python diagrams/walk.py --mode dynamic --steps 8 --step-length 0.2 --duration 10 --out out/walk_dynamic
    python diagrams/walk.py --robot romeo --velocity 0.1 0 0 --duration 6 --out out/walk_romeo

The controller is :mod:`sotdrake.walking.controller`; the run, its summary and plots are
:mod:`sotdrake.scenarios.walk`.
"""

from sotdrake import report
from sotdrake.scenarios.walk import build_diagram, main

__all__ = ["build_diagram", "main"]

if __name__ == "__main__":
    report(main())
