"""sotdrake: the Stack of Tasks (prioritised whole-body control) as Drake systems.

The names a SoT user reaches for, in the seed's vocabulary (see README, "Your first stack")::

    from sotdrake import robot, talos, add_sot, MetaTaskKine6d, MetaTaskKineCom, gotoNd, attime, simulate
"""

from .exceptions import (
    FrameNotFound,
    InvalidInput,
    NotFound,
    OperationalPointNotFound,
    PackageNotFound,
    RobotDescriptionError,
    RobotFileNotFound,
    RobotNotFound,
    SolverError,
    SotError,
    StackError,
    TaskNotFound,
)
from .interactive import Runner
from .introspection import displayAll, displaySignals, entities, entity, signal, signals_report
from .meta_tasks import (
    MetaTaskKine6d,
    MetaTaskKine6dRel,
    MetaTaskKineCom,
    MetaTaskKineJointLimits,
    MetaTaskKinePosture,
    MetaTaskVisualPoint,
    gotoNd,
    hold_feet_and_com,
)
from .robot import Robot, add_sot, robot, talos
from .robots import TALOS_GRIPPERS, RobotModel, load_robot, load_talos
from .sequencer import attime
from .simulation import save_figure, script_arguments, simulate, start, write_run
from .solvers import SOT, SolverKine
from .tracing import Tracer
from .visualization import (
    add_robot_visualizer,
    add_target_marker,
    save_recording,
    start_meshcat,
    write_control_graph,
)

__all__ = [
    "SOT",
    "TALOS_GRIPPERS",
    "FrameNotFound",
    "InvalidInput",
    "MetaTaskKine6d",
    "MetaTaskKine6dRel",
    "MetaTaskKineCom",
    "MetaTaskKineJointLimits",
    "MetaTaskKinePosture",
    "MetaTaskVisualPoint",
    "NotFound",
    "OperationalPointNotFound",
    "PackageNotFound",
    "RobotDescriptionError",
    "RobotFileNotFound",
    "RobotModel",
    "Robot",
    "RobotNotFound",
    "Runner",
    "SolverError",
    "SolverKine",
    "SotError",
    "StackError",
    "TaskNotFound",
    "Tracer",
    "add_robot_visualizer",
    "add_sot",
    "add_target_marker",
    "attime",
    "displayAll",
    "displaySignals",
    "entities",
    "entity",
    "gotoNd",
    "hold_feet_and_com",
    "load_robot",
    "load_talos",
    "robot",
    "save_figure",
    "save_recording",
    "script_arguments",
    "signal",
    "signals_report",
    "simulate",
    "start",
    "start_meshcat",
    "talos",
    "write_control_graph",
    "write_run",
]
