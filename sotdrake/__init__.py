"""sotdrake: the Stack of Tasks (prioritised whole-body control) as Drake systems.

The names a SoT user reaches for, in the seed's vocabulary::

    from sotdrake import robot, talos, add_sot, MetaTaskKine6d, MetaTaskKineCom, gotoNd, attime
"""

from .exceptions import FrameNotFound, InvalidInput, RobotNotFound, SolverError, SotError, StackError, TaskNotFound
from .meta_tasks import MetaTaskKine6d, MetaTaskKineCom, gotoNd
from .robot import Robot, add_sot, robot, talos
from .robots import load_robot
from .sequencer import attime
from .solvers import SOT
from .tracing import Tracer

__all__ = [
    "SOT",
    "FrameNotFound",
    "InvalidInput",
    "MetaTaskKine6d",
    "MetaTaskKineCom",
    "Robot",
    "RobotNotFound",
    "SolverError",
    "SotError",
    "StackError",
    "TaskNotFound",
    "Tracer",
    "add_sot",
    "attime",
    "gotoNd",
    "load_robot",
    "robot",
    "talos",
]
