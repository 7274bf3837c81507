"""The collision scenario the tests, the script and the bench share: TALOS' right hand to a target,
feet and CoM held, with or without the collision level, every tick checked independently.

:func:`build_collision_reach` makes the tutorial's stack under ``SolverKine`` (contacts, CoM, then the
collision level when ``collision``, then the hand: the hand point is ``right-wrist`` moved by
(0.1, 0, 0), the seed's ``opmodif``), with a table top (:data:`TABLE`) when ``table``. The grippers'
joints are left out of the control selection, as in the dynamic reach: TALOS' gripper links rest
10.19 mm apart, inside ``d_s`` + 1 mm, and two pairs that the solver could only open at a few
millimetres per radian would ask a recovery it cannot give at every tick.
:func:`run_collision_reach` drives the hand to a target and checks, at every tick, with Drake's own query on
a collision world of its own (not the task's numbers): the smallest signed distance over the pairs
the task checks, the drift of both ankles (contacts), the joint limits, NaN, and the solver's
failures. Targets may be inside the body or inside the table: the hand then stops short.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder

from ..exceptions import InvalidInput, finite_number
from ..meta_tasks import MetaTaskKine6d, gotoNd, hold_feet_and_com
from ..robot import Robot, add_sot, talos
from ..robots import TALOS_GRIPPERS, RobotModel
from ..solvers import SolverKine
from .distance import minimum_distance
from .meta_task import MetaTaskKineCollision
from .obstacles import add_obstacle, draw_obstacles
from .task import DAMPER_SPEED, INFLUENCE_DISTANCE, SAFETY_DISTANCE
from .world import CollisionWorld

if TYPE_CHECKING:
    from ..dynamics.meta_tasks_dyn import MetaTaskDyn6d
    from ..dynamics.robot_dyn import RobotDyn
    from .meta_task import MetaTaskDynCollision

#: The table top: full size (m) and centre (m, world), in front of TALOS at hip height, under its right hand.
TABLE = ((0.5, 0.8, 0.04), (0.55, -0.25, 0.80))
#: The hand point in the ``right-wrist`` frame (m).
HAND_OFFSET = (0.1, 0.0, 0.0)


@dataclass
class Reach:
    diagram: Diagram
    robot: Robot
    sot: SolverKine
    hand: MetaTaskKine6d
    feet: tuple[MetaTaskKine6d, MetaTaskKine6d]
    collision: MetaTaskKineCollision | None
    #: an independent collision world (same pairs and obstacles as the task's), for the checks
    checker: CollisionWorld
    #: the Meshcat visualizer, when built with one (each run is recorded)
    visualizer: MeshcatVisualizer | None = None


@dataclass
class ReachReport:
    """What one run did: ``min_distance`` (m, smallest signed distance of any checked pair at any
    tick, by Drake's query; +inf if none came within :data:`CHECK_DISTANCE`), ``feet_drift`` (m,
    largest displacement of an ankle), ``limit_excess`` (rad, largest excursion past a joint limit, 0
    inside), ``nan`` (a NaN in ``q``), ``failures`` (solver failure messages), ``hand_error`` (m,
    final distance of the hand point to its target), ``ticks`` (ticks run)."""

    min_distance: float
    feet_drift: float
    limit_excess: float
    nan: bool
    failures: list[str]
    hand_error: float
    ticks: int


def build_collision_reach(collision: bool = True, table: bool = True, dt: float = 1e-3,
                obstacles: Sequence[tuple[object, RigidTransform, str]] = (), safety: float = SAFETY_DISTANCE,
                influence: float = INFLUENCE_DISTANCE, xi: float = DAMPER_SPEED, meshcat: Meshcat | None = None,
                pairs: Sequence[tuple[str, str]] | None = None) -> Reach:
    """The stack (see the module docstring); ``obstacles``: more ``(shape, X_WO, name)`` (as
    :func:`~.obstacles.add_obstacle` takes them); ``safety``, ``influence``, ``xi``: the margins;
    ``meshcat``: draw the robot and the obstacles there; ``pairs``: the collision level's pairs (None:
    every pair)."""
    builder = DiagramBuilder()
    robot = talos(builder, dt=dt)
    sot = add_sot(robot, solver="hqp")
    assert isinstance(sot, SolverKine)
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS))  # (before the collision level reads it)
    feet = hold_feet_and_com(robot, sot)
    checker = CollisionWorld(robot.model)
    if table:
        size, centre = TABLE
        obstacles = [(("box", size), RigidTransform(list(centre)), "table"), *obstacles]
    for shape, X_WO, name in obstacles:
        for world in (robot, checker):
            add_obstacle(world, shape, X_WO, name)
    meta = None
    if collision:
        meta = MetaTaskKineCollision(robot, pairs=pairs, safety=safety, influence=influence, xi=xi)
        sot.push(meta)
    hand = MetaTaskKine6d("rh", robot, "rh", "right-wrist")
    hand.opmodif = RigidTransform(list(HAND_OFFSET))
    sot.push(hand)
    visualizer = None
    if meshcat is not None:
        from ..visualization import add_robot_visualizer

        visualizer = add_robot_visualizer(robot, meshcat)
        draw_obstacles(meshcat, checker)
    return Reach(builder.Build(), robot, sot, hand, (feet[0], feet[1]), meta, checker, visualizer)


#: Pairs farther apart than this (m) are not measured by the checks (``min_distance`` is +inf when
#: every pair stays farther): far above the safety distances used, and much cheaper than all pairs.
CHECK_DISTANCE = 0.05

#: The tutorial's hand gain (``gotoNd``'s four numbers: λ(0) = 4.9 /s, λ(∞) = 0.9 /s).
TUTORIAL_GAIN = (4.9, 0.9, 0.01, 0.9)


def run_collision_reach(reach: Reach, target: np.ndarray, duration: float = 1.0, check_every: int = 1,
              gain: float | tuple[float, ...] = TUTORIAL_GAIN) -> ReachReport:
    """Drive the hand to ``target`` (m, world) for ``duration`` s from the reference posture, with
    ``gain`` (as ``gotoNd`` takes it), checking every ``check_every`` ticks (see the module docstring)."""
    simulator = Simulator(reach.diagram)
    context = simulator.get_mutable_context()
    gotoNd(reach.hand, np.asarray(target, dtype=float), "111", gain, context=context)
    if reach.visualizer is not None:
        reach.visualizer.StartRecording(False)
    simulator.Initialize()
    device, plant = reach.robot.device, reach.robot.model.plant
    device_context = device.GetMyContextFromRoot(context)
    sot_context = reach.sot.GetMyContextFromRoot(context)
    checker_context = reach.checker.new_context()
    feet0 = [foot.current_pose(context).translation() for foot in reach.feet]
    lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
    report = ReachReport(np.inf, 0.0, 0.0, False, [], np.nan, 0)
    dt = device.dt
    ticks = ticks_of(duration, dt)
    for k in range(1, ticks + 1):
        simulator.AdvanceTo(k * dt)
        if k % check_every and k != ticks:
            continue
        q = device.GetOutputPort("state").Eval(device_context)
        if not np.all(np.isfinite(q)):
            report.nan = True
            break
        report.min_distance = min(report.min_distance, minimum_distance(reach.checker, checker_context, q, CHECK_DISTANCE))
        report.feet_drift = max(report.feet_drift, *(float(np.linalg.norm(foot.current_pose(context).translation() - p0))
                                                    for foot, p0 in zip(reach.feet, feet0, strict=True)))
        with np.errstate(invalid="ignore"):
            excess = np.nan_to_num(np.maximum(q - upper, lower - q), nan=0.0, neginf=0.0)
        report.limit_excess = max(report.limit_excess, float(excess.max()))
        failure = reach.sot.GetOutputPort("diagnostics").Eval(sot_context).failure
        if failure:
            report.failures.append(failure)
    report.ticks = k
    report.hand_error = float(np.linalg.norm(reach.hand.current_pose(context).translation() - target))
    return report


#: The dynamic hand's gain (1/s²). At 100 /s² a target 0.3–0.5 m away asks 30–50 m/s² of the
#: hand from the first tick: against the torque and friction bounds, SolverDyn's active set then
#: gives up on some ticks (2–22 of 300 in a run), with or without the collision level; at 25 /s²
#: it does not.
DYN_HAND_KP = 25.0

#: The soles' damping (1/s, ``Contact6d.setVelocityGain``) and return to their pose at the
#: reference posture (1/s², ``setPositionGain``), critically damped (K_p = K_v²/4). With the
#: default K_v = 30 /s and no K_p, only the soles' velocity is corrected, and the integration's
#: second-order error under a fast whole-body swing moved them by up to 0.157 mm in 0.3 s; with
#: (30, 225) by 0.114 mm, (60, 900) 0.083 mm, (100, 2500) 0.058 mm (the worst run, measured).
CONTACT_KV, CONTACT_KP = 100.0, 2500.0


@dataclass
class DynReach:
    """The dynamic scenario (:func:`build_dyn_collision_reach`): its diagram, the ``RobotDyn``, the
    hand (``MetaTaskDyn6d``, position only), the collision meta task and the independent checker."""

    diagram: Diagram
    robot: RobotDyn
    hand: MetaTaskDyn6d
    collision: MetaTaskDynCollision | None
    checker: CollisionWorld


def build_dyn_collision_reach(model: RobotModel, collision: bool = True, table: bool = True, dt: float = 1e-3,
                              obstacles: Sequence[tuple[object, RigidTransform, str]] = (), hand_kp: float = DYN_HAND_KP,
                              safety: float = SAFETY_DISTANCE, influence: float = INFLUENCE_DISTANCE,
                              xi: float = DAMPER_SPEED) -> DynReach:
    """The dynamic SoT on TALOS (``model``, a :class:`~sotdrake.robots.RobotModel`): ``SolverDyn``
    with its joints' torque braking (``setTorqueBraking``), both soles in contact (kept where they
    are at the reference posture, :data:`CONTACT_KP`), the CoM, the collision level at the
    acceleration level (when ``collision``), the hand point (``right-wrist`` + :data:`HAND_OFFSET`, position, gain ``hand_kp``
    1/s², :data:`DYN_HAND_KP`), the posture; the table (:data:`TABLE`) when ``table`` and ``obstacles`` as
    :func:`build_collision_reach` takes them."""
    from ..dynamics.meta_tasks_dyn import MetaTaskDyn6d, MetaTaskDynCom, MetaTaskDynPosture
    from ..dynamics.robot_dyn import RobotDyn
    from .meta_task import MetaTaskDynCollision

    builder = DiagramBuilder()
    robot = RobotDyn(builder, model, "dynsimu", dt)
    sot = robot.sot
    sot.setControlSelection(robot.velocity_selection(excluding=TALOS_GRIPPERS))
    sot.setTorqueBraking(True)  # (a weak joint braked by more than its torque: the legs take the rest, the thighs close)
    for name, op in (("contactLF", "left-sole"), ("contactRF", "right-sole")):
        contact = robot.add_contact(name, op)
        contact.setVelocityGain(CONTACT_KV)
        contact.setPositionGain(CONTACT_KP)
        sot.addContact(contact)
    sot.push(MetaTaskDynCom(robot).task.name)
    checker = CollisionWorld(model)
    if table:
        size, centre = TABLE
        obstacles = [(("box", size), RigidTransform(list(centre)), "table"), *obstacles]
    for shape, X_WO, name in obstacles:
        for world in (robot, checker):
            add_obstacle(world, shape, X_WO, name)
    meta = None
    if collision:
        meta = MetaTaskDynCollision(robot, safety=safety, influence=influence, xi=xi)
        sot.push(meta.task.name)
    hand = MetaTaskDyn6d("rh", robot, "right-wrist", kp=hand_kp)
    hand.feature.setOpmodif(RigidTransform(list(HAND_OFFSET)))
    hand.feature.selec("000111")
    sot.push(hand.task.name)
    sot.push(MetaTaskDynPosture(robot, kp=25.0).task.name)
    return DynReach(builder.Build(), robot, hand, meta, checker)


def run_dyn_collision_reach(reach: DynReach, target: np.ndarray, duration: float = 0.3) -> ReachReport:
    """Drive the dynamic hand to ``target`` (m, world) for ``duration`` s from the reference posture,
    every tick checked as :func:`run_collision_reach` does (distances by Drake's query, soles' drift,
    joint limits, NaN, ``SolverDyn``'s failures)."""
    simulator = Simulator(reach.diagram)
    context = simulator.get_mutable_context()
    reach.hand.featureDes.setPosition(RigidTransform(np.asarray(target, dtype=float)), context=context)
    failures: list[str] = []  # every failure the solver logs (its diagnostics port shows the last solve only)
    handler = _Collect(failures)
    logging.getLogger("sotdrake.solver_dyn").addHandler(handler)
    try:
        return _run_dyn(reach, simulator, target, duration, failures)
    finally:
        logging.getLogger("sotdrake.solver_dyn").removeHandler(handler)


class _Collect(logging.Handler):
    def __init__(self, into: list[str]):
        super().__init__(logging.WARNING)
        self.into = into

    def emit(self, record: logging.LogRecord) -> None:
        self.into.append(record.getMessage())


def _run_dyn(reach: DynReach, simulator: Simulator, target: np.ndarray, duration: float, failures: list[str]) -> ReachReport:
    context = simulator.get_mutable_context()
    robot = reach.robot
    simulator.Initialize()
    model = robot.model
    plant, nq = model.plant, model.nq
    plant_context = plant.CreateDefaultContext()
    device_context = robot.device.GetMyContextFromRoot(context)
    checker_context = reach.checker.new_context()
    soles = [model.frame(name) for name in ("left-sole", "right-sole")]

    def sole_positions(q: np.ndarray) -> list[np.ndarray]:
        plant.SetPositions(plant_context, q)
        return [plant.CalcRelativeTransform(plant_context, plant.world_frame(), f).translation() for f in soles]

    feet0 = sole_positions(model.half_sitting)
    lower, upper = plant.GetPositionLowerLimits(), plant.GetPositionUpperLimits()
    report = ReachReport(np.inf, 0.0, 0.0, False, [], np.nan, 0)
    dt = robot.dt
    ticks = ticks_of(duration, dt)
    q = model.half_sitting
    for k in range(1, ticks + 1):
        simulator.AdvanceTo(k * dt)
        x = robot.device.GetOutputPort("state").Eval(device_context)
        if not np.all(np.isfinite(x)):
            report.nan = True
            break
        q = x[:nq]
        report.min_distance = min(report.min_distance, minimum_distance(reach.checker, checker_context, q, CHECK_DISTANCE))
        report.feet_drift = max(report.feet_drift, *(float(np.linalg.norm(p - p0)) for p, p0 in zip(sole_positions(q), feet0, strict=True)))
        with np.errstate(invalid="ignore"):
            excess = np.nan_to_num(np.maximum(q - upper, lower - q), nan=0.0, neginf=0.0)
        report.limit_excess = max(report.limit_excess, float(excess.max()))
    report.failures = failures
    report.ticks = k
    plant.SetPositions(plant_context, q)
    p_hand = plant.CalcRelativeTransform(plant_context, plant.world_frame(), model.frame("right-wrist")) @ np.array(HAND_OFFSET)
    report.hand_error = float(np.linalg.norm(p_hand - target))
    return report


def ticks_of(duration: float, dt: float) -> int:
    """The number of ticks of a run of ``duration`` s (at least one, else :class:`InvalidInput`)."""
    if not (finite_number(duration) and duration >= dt):
        raise InvalidInput(f"duration: expected at least one tick ({dt:g} s), got {duration!r:.40} s")
    return round(duration / dt)

