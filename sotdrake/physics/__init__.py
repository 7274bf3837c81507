"""A physically simulated TALOS driven by the SoT, as the real robot is (seed: the SoT "is not a
dynamic simulator"; the tutorial uses Gazebo and ros_control for that).

One concept a module:

* :mod:`.plant`: the discrete plant on the ground, soles (point or hydroelastic contact), whole-body collision boxes
  (:mod:`.body_collision`);
* :mod:`.actuators`: the PD-controlled actuators and their references (``DesiredState``);
* :mod:`.estimator`: the closed loop's leg-odometry base estimate (``KinematicBaseEstimator``);
* :mod:`.contact_monitor`: sole forces, centre of pressure, other bodies on the ground;
* :mod:`.push`: an external push;
* :mod:`.station`: all of the above wired as one station (``add_talos_station``).

The loop is *open* (the SoT's kinematics reads the device's own ``q``, as sot-talos does on the
robot) or *closed* (it reads the simulated joints and a base pose from leg odometry).
"""

from .actuators import (
    DAMPING_RANGE,
    STIFFNESS_RANGE,
    DesiredState,
    check_pd_gains,
    hold_one_tick,
    set_pd_gains,
)
from .body_collision import fit_link_boxes
from .contact_monitor import ContactMonitor
from .estimator import KinematicBaseEstimator
from .plant import (
    CONTACT_MODELS,
    CONTACT_SOLVERS,
    CORNER_DISSIPATION,
    CORNER_RADIUS,
    CORNER_STIFFNESS,
    FRICTION,
    SOLE_BOX,
    SOLE_DISSIPATION,
    SOLE_MODULUS,
    PhysicalTalos,
    add_physical_talos,
)
from .push import MAX_PUSH_FORCE, Push
from .station import PLANT_STEP, TalosStation, add_talos_station

__all__ = [
    "CONTACT_MODELS",
    "CONTACT_SOLVERS",
    "CORNER_DISSIPATION",
    "CORNER_RADIUS",
    "CORNER_STIFFNESS",
    "DAMPING_RANGE",
    "FRICTION",
    "MAX_PUSH_FORCE",
    "PLANT_STEP",
    "SOLE_BOX",
    "SOLE_DISSIPATION",
    "SOLE_MODULUS",
    "STIFFNESS_RANGE",
    "ContactMonitor",
    "DesiredState",
    "KinematicBaseEstimator",
    "PhysicalTalos",
    "Push",
    "TalosStation",
    "add_physical_talos",
    "add_talos_station",
    "check_pd_gains",
    "fit_link_boxes",
    "hold_one_tick",
    "set_pd_gains",
]
