"""sotdrake: the Stack of Tasks (prioritised whole-body control) as Drake systems.

The names a SoT user reaches for, in the seed's vocabulary (see README, "Your first stack")::

    from sotdrake import robot, talos, add_sot, MetaTaskKine6d, MetaTaskKineCom, gotoNd, attime, simulate

Everything a user composes is importable from here and listed in ``__all__``: robots
(``load_robot`` also takes the path of your own URDF), meta tasks, features and their desired
values, tasks, gains, solvers, the dynamic SoT, contacts, the tracer and publishers, the physics
and walking wings. The wings that pull in more (``dynamics``, ``physics``, ``walking``, ``sweep``,
``live``, ``publishing``, ``collision``) are imported on first use of one of their names.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .configuration import velocity_names
from .device import Device
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
    SotWarning,
    StackError,
    TaskNotFound,
)
from .fall import fall_report, fall_thresholds, tilt_of_quaternions, tilt_of_rotations
from .features import (
    Feature,
    Feature1D,
    Feature6d,
    Feature6dDesired,
    FeatureGeneric,
    FeatureGenericDesired,
    FeatureJointLimits,
    FeatureManipulability,
    FeatureMomentum,
    FeaturePosture,
    FeatureRelative6d,
    FeatureVisualPoint,
)
from .gains import GainAdaptive, GainHyperbolic
from .interactive import MAX_DURATION, Runner
from .introspection import displayAll, displaySignals, entities, entity, signal, signals_report
from .joint_limitator import JointLimitator, limit_joint_velocities
from .kinematics import Dynamic
from .manipulability import manipulability, manipulability_and_gradient
from .meta_tasks import (
    MetaTaskKine6d,
    MetaTaskKine6dRel,
    MetaTaskKineCom,
    MetaTaskKineFeature,
    MetaTaskKineJointLimits,
    MetaTaskKineManipulability,
    MetaTaskKineMomentum,
    MetaTaskKinePosture,
    MetaTaskVisualPoint,
    gotoNd,
    hold_feet_and_com,
)
from .progress import stalled_tasks
from .robot import Robot, add_sot, robot, talos
from .robots import ROBOTS, TALOS_GRIPPERS, RobotModel, available_robots, load_robot, load_talos
from .sequencer import attime
from .simulation import json_safe, options_given, report, run_script, save_figure, script_arguments, simulate, start, write_run
from .solver_wrapper import Solver
from .solvers import SOT, SolverKine
from .stack_checks import check_stack
from .target_marker import TargetMarker, desired_position
from .task import Task, TaskInequality, TaskLevel, TaskPD
from .task_weight import TaskWeight, add_task_weight, weighted_level
from .tracing import Tracer, flush_tracers, read_trace
from .visualization import (
    add_robot_visualizer,
    add_target_marker,
    save_recording,
    start_meshcat,
    write_control_graph,
)

#: Names imported on first use, by module: the wings that pull in more than the kinematic SoT, and
#: the HQP's back-end names. A script may import these from their wing too (``sotdrake.physics`` …).
_LAZY: dict[str, tuple[str, ...]] = {
    ".dynamics": ("Contact6d", "ContactRows", "DynamicEntity", "DynamicsTerms", "RobotDynSimu", "SolverDyn", "TaskDynPD"),
    ".dynamics.dyn_types": ("ContactNotFound", "DynDiagnostics"),
    ".dynamics.robot_dyn": ("RobotDyn",),
    ".dynamics.meta_tasks_dyn": ("MetaTaskDyn6d", "MetaTaskDynCom", "MetaTaskDynMomentum", "MetaTaskDynPosture"),
    ".dynamics.contact": ("friction_ratio",),
    ".dynamics.station": ("sole_rectangle",),
    ".dynamics.trajectories": ("hold_move_hold", "minimum_jerk_moves", "trajectory_ports"),
    ".physics": (
        "CONTACT_MODELS",
        "CONTACT_SOLVERS",
        "FRICTION",
        "PLANT_STEP",
        "SOLE_BOX",
        "ContactMonitor",
        "DesiredState",
        "KinematicBaseEstimator",
        "PhysicalTalos",
        "Push",
        "TalosStation",
        "add_physical_talos",
        "add_talos_station",
        "hold_one_tick",
    ),
    ".walking": (
        "GRAVITY",
        "ComStabilizer",
        "GaitParameters",
        "GravityFeedforward",
        "MeasuredCom",
        "PatternGenerator",
        "WalkCommand",
        "footprint",
        "initial_plan",
        "leg_masses",
        "motion_zmp",
        "polygon_margin",
        "replan",
        "start_of",
        "support_polygon",
    ),
    ".sweep": ("EngineUnavailable", "add_sweep_arguments", "engine_options", "grid", "per_process", "random_cases", "run_sweep"),
    ".live": ("add_live_arguments", "live_meshcat", "run_live"),
    ".publishing": ("RobotStateMessage", "add_signal_publisher", "add_state_publisher"),
    ".hqp": ("ACTIVE_SET", "SOLVERS"),
    ".collision": (
        "SHELF",
        "SHELF_COMPARTMENTS",
        "TABLE",
        "CollisionWorld",
        "MetaTaskDynCollision",
        "MetaTaskKineCollision",
        "NoCollisionGeometry",
        "TaskCollision",
        "add_obstacle",
        "add_scene",
        "build_collision_reach",
        "collision_world",
        "draw_obstacles",
        "minimum_distance",
        "obstacle_geometries",
        "pair_distances",
        "run_collision_reach",
    ),
}
_LAZY_MODULE = {name: module for module, names in _LAZY.items() for name in names}

if TYPE_CHECKING:
    from .collision import (
        SHELF,
        SHELF_COMPARTMENTS,
        TABLE,
        CollisionWorld,
        MetaTaskDynCollision,
        MetaTaskKineCollision,
        NoCollisionGeometry,
        TaskCollision,
        add_obstacle,
        add_scene,
        build_collision_reach,
        collision_world,
        draw_obstacles,
        minimum_distance,
        obstacle_geometries,
        pair_distances,
        run_collision_reach,
    )
    from .dynamics import Contact6d, ContactRows, DynamicEntity, DynamicsTerms, RobotDynSimu, SolverDyn, TaskDynPD
    from .dynamics.contact import friction_ratio
    from .dynamics.dyn_types import ContactNotFound, DynDiagnostics
    from .dynamics.meta_tasks_dyn import MetaTaskDyn6d, MetaTaskDynCom, MetaTaskDynMomentum, MetaTaskDynPosture
    from .dynamics.robot_dyn import RobotDyn
    from .dynamics.station import sole_rectangle
    from .dynamics.trajectories import hold_move_hold, minimum_jerk_moves, trajectory_ports
    from .hqp import ACTIVE_SET, SOLVERS
    from .live import add_live_arguments, live_meshcat, run_live
    from .physics import (
        CONTACT_MODELS,
        CONTACT_SOLVERS,
        FRICTION,
        PLANT_STEP,
        SOLE_BOX,
        ContactMonitor,
        DesiredState,
        KinematicBaseEstimator,
        PhysicalTalos,
        Push,
        TalosStation,
        add_physical_talos,
        add_talos_station,
        hold_one_tick,
    )
    from .publishing import RobotStateMessage, add_signal_publisher, add_state_publisher
    from .sweep import (
        EngineUnavailable,
        add_sweep_arguments,
        engine_options,
        grid,
        per_process,
        random_cases,
        run_sweep,
    )
    from .walking import (
        GRAVITY,
        ComStabilizer,
        GaitParameters,
        GravityFeedforward,
        MeasuredCom,
        PatternGenerator,
        WalkCommand,
        footprint,
        initial_plan,
        leg_masses,
        motion_zmp,
        polygon_margin,
        replan,
        start_of,
        support_polygon,
    )


def __getattr__(name: str) -> Any:
    """The names of :data:`_LAZY`, imported on first use."""
    module = _LAZY_MODULE.get(name)
    if module is None:
        raise AttributeError(f"module 'sotdrake' has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY_MODULE))


__all__ = [
    "ACTIVE_SET",
    "CONTACT_MODELS",
    "CONTACT_SOLVERS",
    "FRICTION",
    "GRAVITY",
    "MAX_DURATION",
    "PLANT_STEP",
    "ROBOTS",
    "SHELF",
    "SHELF_COMPARTMENTS",
    "SOLE_BOX",
    "SOLVERS",
    "SOT",
    "TABLE",
    "TALOS_GRIPPERS",
    "CollisionWorld",
    "ComStabilizer",
    "Contact6d",
    "ContactMonitor",
    "ContactNotFound",
    "ContactRows",
    "DesiredState",
    "Device",
    "DynDiagnostics",
    "Dynamic",
    "DynamicEntity",
    "DynamicsTerms",
    "EngineUnavailable",
    "Feature",
    "Feature1D",
    "Feature6d",
    "Feature6dDesired",
    "FeatureGeneric",
    "FeatureGenericDesired",
    "FeatureJointLimits",
    "FeatureManipulability",
    "FeatureMomentum",
    "FeaturePosture",
    "FeatureRelative6d",
    "FeatureVisualPoint",
    "FrameNotFound",
    "GainAdaptive",
    "GainHyperbolic",
    "GaitParameters",
    "GravityFeedforward",
    "InvalidInput",
    "JointLimitator",
    "KinematicBaseEstimator",
    "MeasuredCom",
    "MetaTaskDyn6d",
    "MetaTaskDynCollision",
    "MetaTaskDynCom",
    "MetaTaskDynMomentum",
    "MetaTaskDynPosture",
    "MetaTaskKine6d",
    "MetaTaskKine6dRel",
    "MetaTaskKineCollision",
    "MetaTaskKineCom",
    "MetaTaskKineFeature",
    "MetaTaskKineJointLimits",
    "MetaTaskKineManipulability",
    "MetaTaskKineMomentum",
    "MetaTaskKinePosture",
    "MetaTaskVisualPoint",
    "NoCollisionGeometry",
    "NotFound",
    "OperationalPointNotFound",
    "PackageNotFound",
    "PatternGenerator",
    "PhysicalTalos",
    "Push",
    "Robot",
    "RobotDescriptionError",
    "RobotDyn",
    "RobotDynSimu",
    "RobotFileNotFound",
    "RobotModel",
    "RobotNotFound",
    "RobotStateMessage",
    "Runner",
    "Solver",
    "SolverDyn",
    "SolverError",
    "SolverKine",
    "SotError",
    "SotWarning",
    "StackError",
    "TalosStation",
    "TargetMarker",
    "Task",
    "TaskCollision",
    "TaskDynPD",
    "TaskInequality",
    "TaskLevel",
    "TaskNotFound",
    "TaskPD",
    "TaskWeight",
    "Tracer",
    "WalkCommand",
    "add_live_arguments",
    "add_obstacle",
    "add_physical_talos",
    "add_robot_visualizer",
    "add_scene",
    "add_signal_publisher",
    "add_sot",
    "add_state_publisher",
    "add_sweep_arguments",
    "add_talos_station",
    "add_target_marker",
    "add_task_weight",
    "attime",
    "available_robots",
    "build_collision_reach",
    "check_stack",
    "collision_world",
    "desired_position",
    "displayAll",
    "displaySignals",
    "draw_obstacles",
    "engine_options",
    "entities",
    "entity",
    "fall_report",
    "fall_thresholds",
    "flush_tracers",
    "footprint",
    "friction_ratio",
    "gotoNd",
    "grid",
    "hold_feet_and_com",
    "hold_move_hold",
    "hold_one_tick",
    "initial_plan",
    "json_safe",
    "leg_masses",
    "limit_joint_velocities",
    "live_meshcat",
    "load_robot",
    "load_talos",
    "manipulability",
    "manipulability_and_gradient",
    "minimum_distance",
    "minimum_jerk_moves",
    "motion_zmp",
    "obstacle_geometries",
    "options_given",
    "pair_distances",
    "per_process",
    "polygon_margin",
    "random_cases",
    "read_trace",
    "replan",
    "report",
    "robot",
    "run_collision_reach",
    "run_live",
    "run_script",
    "run_sweep",
    "save_figure",
    "save_recording",
    "script_arguments",
    "signal",
    "signals_report",
    "simulate",
    "sole_rectangle",
    "stalled_tasks",
    "start",
    "start_meshcat",
    "start_of",
    "support_polygon",
    "talos",
    "tilt_of_quaternions",
    "tilt_of_rotations",
    "trajectory_ports",
    "velocity_names",
    "weighted_level",
    "write_control_graph",
    "write_run",
]
