"""The planche on the dynamic SoT (``planche.py --solver dyn``), as the seed ran it: Romeo on
``RobotDynSimu`` (the solver's ``q̈`` integrated, no physics engine: whatever the solver plans
happens) with ``SolverDyn`` (contact forces, torque limits hard), 5 ms ticks.

The same sequence as the kinematic run (:mod:`sotdrake.scenarios.planche`), its tasks as acceleration tasks
(``TaskDynPD``, ``q̈``-level PD: ``J q̈ = −k_p e − k_v ė + s̈* − J̇ v``):

* the contacts: both soles (``Contact6d``), the left one's rectangle shrunk to the seed's 6 × 3 cm
  around the ankle (``shrink=False``: the whole sole);
* ``taskCom``: the CoM over the left ankle before the right foot leaves (minimum jerk, 0.2 s to
  ``lift`` − 0.2 s), back over both feet once the right foot is a contact again;
* ``taskrf`` (the right ankle's translation, the seed's rows): Y, Z up to (0, 0.65), then X, Z back
  to (−0.55, 0.7), later X, Y, Z to (−0.1, −0.1, 0.25), 7 cm above its start and onto it, each a
  minimum-jerk move;
* ``taskChest`` (orientation only): 80° forward, a step for the PD (gain ``chest_kp``);
* ``taskBody`` (a posture on the selected joints, ``gotoq``): the body straight, the arms out and
  the foot extended in the full variant, folded back;
* ``taskRest``: the whole posture at half-sitting, always last (the seed's solver's ``sot.posture``).

A fall is the support failing: the held left sole leaving its place (1 cm or 0.1 rad), the CoM
dropping 10 cm, or a non-finite state; the run stops once the CoM has dropped 0.3 m. The shared
criterion (:func:`sotdrake.fall_report`) is reported beside it (``fall_report``), but its 30° of
base tilt is part of a planche (the pelvis leans forward with the chest). The summary names the
step of the sequence the fall happened in.
"""

from __future__ import annotations

import logging
import sys
import time
from dataclasses import dataclass, field

import numpy as np
from pydrake.geometry import MeshcatVisualizer
from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.tree import JointActuatorIndex
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder

from sotdrake import Tracer, attime, fall_report, load_robot, tilt_of_quaternions
from sotdrake.dynamics.contact import Contact6d
from sotdrake.dynamics.meta_tasks_dyn import MetaTaskDyn6d, MetaTaskDynCom, MetaTaskDynPosture
from sotdrake.dynamics.robot_dyn import RobotDyn
from sotdrake.dynamics.trajectories import minimum_jerk_moves, trajectory_ports
from sotdrake.exceptions import SotError
from sotdrake.scenarios.common import translation_drift

FALL_SOLE_M, FALL_SOLE_RAD, FALL_COM_DROP_M = 0.01, 0.1, 0.1  # the held sole moved/tilted, the CoM dropped (m, rad)
STOP_COM_DROP_M = 0.3  # the run stops there (no ground under RobotDynSimu)
RELEASE_RAMP = 0.3  # rmContact RF: the force ramped to 0 over this (s)


@dataclass(frozen=True)
class DynOptions:
    """The remedies one may try: gains (``k_p``, 1/s²), the CoM's rise, the support, the phases'
    speed, and (a diagnostic) the torque limits. The defaults are the best measured (the longest on
    one foot at the seed's pace); the seed's own: ``DynOptions(com_rise=0, shrink=True)``."""

    com_kp: float = 100.0
    rf_kp: float = 100.0
    chest_kp: float = 25.0
    body_kp: float = 25.0
    rest_kp: float = 25.0
    com_rise: float = 0.02  # the CoM also rises this much (m) as it moves over the left foot: straighter knees
    shrink: bool = False  # True: the left sole's support shrunk to the seed's 6 × 3 cm around the ankle
    slow: float = 1.0  # every time of the sequence × slow (> 1: slower phases)
    effort: float = 1.0  # a diagnostic: the model's torque limits × effort (the seed's solver had none)
    seed_masks: bool = True  # the foot task's rows as the seed's gotoNd: Y, Z up, then X, Z back (False: X, Y, Z)


@dataclass
class PlancheDyn:
    diagram: Diagram
    robot: RobotDyn
    tracer: Tracer
    contactLF: Contact6d
    contactRF: Contact6d
    support: tuple[float, float, float, float]  # the left contact's rectangle (m, left-sole frame)
    times: dict
    options: DynOptions
    com0: np.ndarray
    visualizer: MeshcatVisualizer | None = None
    extras: dict = field(default_factory=dict)


def _shrunken(robot: RobotDyn, half: tuple[float, float, float, float]) -> tuple[float, float, float, float]:
    """The seed's shrunken rectangle around the left ankle, in the left sole's frame."""
    sole = robot.dynamic.pose_at("left-sole", robot.q0)
    ankle = robot.dynamic.pose_at("left-ankle", robot.q0).translation()
    x, y, _ = sole.inverse() @ ankle
    x_min, x_max, y_min, y_max = half
    return (x + x_min, x + x_max, y + y_min, y + y_max)


def _foot_task(robot: RobotDyn, T: dict, consts: dict, options: DynOptions):
    """``taskrf`` on the right ankle's translation, fed by minimum-jerk moves through the seed's
    targets (m, world); returns the task and its reference's output port."""
    taskrf = MetaTaskDyn6d("rf", robot, "rf", robot.OperationalPointsMap["right-ankle"], kp=options.rf_kp)
    taskrf.feature.selec("000111")
    p0 = taskrf.initial_pose().translation()
    up = np.array([p0[0], consts["UP"][1], consts["UP"][2]])
    extend = np.array([consts["EXTEND"][0], up[1], consts["EXTEND"][2]])
    above = p0 + [0.0, 0.0, 0.07]
    move = 1.0 * options.slow
    rf_path = minimum_jerk_moves(p0, [(T["lift"] + RELEASE_RAMP, T["extend"], up), (T["extend"], T["extend"] + 1.2 * options.slow, extend),
                                      (T["back"], T["above"] - 0.5 * options.slow, np.asarray(consts["BACK"], dtype=float)),
                                      (T["above"], T["above"] + move, above), (T["ground"], T["ground"] + move, p0)])
    rf_ports = trajectory_ports(robot, rf_path, "rf_trajectory")
    connect = robot.builder.Connect
    connect(rf_ports[0], taskrf.featureDes.GetInputPort("translation_in"))
    connect(rf_ports[1], taskrf.featureDes.GetInputPort("translation_velocity_in"))
    return taskrf, rf_ports[0]


def _com_task(robot: RobotDyn, T: dict, com0: np.ndarray, over_left: np.ndarray, options: DynOptions) -> MetaTaskDynCom:
    """The CoM over the left ankle before the lift, back to its start once both feet are down."""
    connect = robot.builder.Connect
    taskCom = MetaTaskDynCom(robot, kp=options.com_kp)
    ramp = 1.5 * options.slow
    com_path = minimum_jerk_moves(com0, [(0.2, T["lift"] - 0.2, over_left), (T["contact"], T["contact"] + ramp, com0)])
    ports = trajectory_ports(robot, com_path, "com_trajectory")
    connect(ports[0], taskCom.featureDes.GetInputPort("value_in"))
    connect(ports[1], taskCom.featureDes.GetInputPort("velocity_in"))
    connect(ports[2], taskCom.task.GetInputPort("reference_acceleration"))
    return taskCom


def _record(robot: RobotDyn, dt: float, rf_reference, meshcat) -> tuple[Tracer, object]:
    """The tracer (state, CoM, torques, contact wrenches, the foot's reference) and the viewer."""
    builder, sot = robot.builder, robot.sot
    tracer = Tracer(builder, dt)
    tracer.add(robot.state_port, "x")
    tracer.add(robot.dynamic.GetOutputPort("com"), "com")
    tracer.add(sot.GetOutputPort("torque"), "torque")
    tracer.add(sot.GetOutputPort("wrenches"), "wrenches")
    tracer.add(rf_reference, "rf_reference")
    visualizer = None
    if meshcat is not None:
        from sotdrake import add_robot_visualizer

        visualizer = add_robot_visualizer(robot, meshcat)
        meshcat.SetCameraPose(camera_in_world=[0.4, -1.9, 0.9], target_in_world=[0.0, 0.0, 0.5])
    return tracer, visualizer


def build(variant: str, times: dict, gotoq, consts: dict, options: DynOptions = DynOptions(), meshcat=None,
          dt: float = 5e-3) -> PlancheDyn:
    """The dynamic diagram. ``times`` is the kinematic variant's sequence (s, scaled by
    ``options.slow``), ``gotoq`` the posture helper and ``consts`` its constants (planche.py's)."""
    if options.slow <= 0:
        raise SotError(f"slow must be > 0, got {options.slow!r}")
    if not options.effort > 0:
        raise SotError(f"effort must be > 0, got {options.effort!r}")
    T = {k: v * options.slow for k, v in times.items()}
    builder = DiagramBuilder()
    model = load_robot("romeo", "small")
    for i in range(model.plant.num_actuators()):  # a stronger (or weaker) Romeo, as a diagnostic
        actuator = model.plant.get_joint_actuator(JointActuatorIndex(i))
        actuator.set_effort_limit(actuator.effort_limit() * options.effort)
    robot = RobotDyn(builder, model, "dynsimu", dt)
    sot, q0 = robot.sot, robot.q0
    support = _shrunken(robot, consts["SHRUNKEN_SUPPORT"]) if options.shrink else robot.sole_rectangle("left-sole")
    contactLF = robot.add_contact("contactLF", "left-sole", rectangle=support)
    contactRF = robot.add_contact("contactRF", "right-sole")
    sot.addContact(contactLF)
    sot.addContact(contactRF)

    # --- the CoM: over the left ankle before the lift, over both feet once back
    com0 = robot.dynamic.com_at(q0)
    left = robot.dynamic.pose_at("left-ankle", q0).translation()
    right = robot.dynamic.pose_at("right-ankle", q0).translation()
    over_left = np.array([left[0], left[1], com0[2] + options.com_rise])
    taskCom = _com_task(robot, T, com0, over_left, options)
    sot.push(taskCom.task.name)
    taskRest = MetaTaskDynPosture(robot, "rest", kp=options.rest_kp)
    sot.push(taskRest.task.name)

    # --- the right foot (translation only), the chest (orientation only), the body posture
    taskrf, rf_reference = _foot_task(robot, T, consts, options)
    taskChest = MetaTaskDyn6d("chest", robot, "chest", robot.OperationalPointsMap["chest"], kp=options.chest_kp)
    taskChest.feature.selec("111000")
    chest0 = taskChest.initial_pose()
    lean = RigidTransform(RollPitchYaw(0.0, consts["CHEST"], 0.0), chest0.translation())
    taskBody = MetaTaskDynPosture(robot, "body", kp=options.body_kp)

    def push(meta) -> tuple:  # above the rest posture
        return sot.push(meta.task.name), sot.up(meta.task.name)

    def posture(q, mask) -> tuple:
        return taskBody.feature.setPosture(q), taskBody.feature.selec(mask)

    masks = ("000110", "000101") if options.seed_masks else ("000111", "000111")
    attime(T["lift"], lambda: (sot.rmContact(contactRF, RELEASE_RAMP), taskrf.feature.selec(masks[0]), push(taskrf)),
           "rmContact RF, push rf: up (Y, Z)")
    attime(T["extend"], lambda: taskrf.feature.selec(masks[1]), "rf back (X, Z)")
    attime(T["chest"], lambda: (taskChest.featureDes.setPosition(lean), push(taskChest)), "add chest (80° forward)")
    plant, MAX_EXT = robot.model.plant, consts["MAX_EXT"]
    body = gotoq(robot, q0, chest=(0,), rleg=(0, 0, 0, MAX_EXT, 0, 0), head=(0, 0, 0, 0))
    attime(T["body"], lambda: (sot.remove(taskrf.task.name), posture(*body), push(taskBody)), "remove rf, the body posture")
    if variant == "full":
        arms = {"rarm": (0, -consts["ARMS_OUT"], 0, 0, 0, 0, 0), "larm": (0, consts["ARMS_OUT"], 0, 0, 0, 0, 0)}
        extended = gotoq(robot, q0, chest=(0,), rleg=(0, 0, 0, MAX_EXT, 0, 0), head=(0, 0, 0, 0), **arms)
        attime(T["arms"], lambda: posture(*extended), "extend arm")
        foot = gotoq(robot, q0, chest=(0,), rleg=(0, 0, 0, MAX_EXT, consts["FOOT_EXTENSION"], 0),
                     head=(0, consts["HEAD_PITCH"], 0, 0), **arms)
        attime(T["foot"], lambda: posture(*foot), "extend foot")
    chains = consts["CHAINS"]
    initial = {c: tuple(q0[plant.GetJointByName(j).position_start()] for j in chains[c]) for c in ("rleg", "rarm", "larm")}
    fold = gotoq(robot, q0, chest=(0,), head=(0, 0, 0, 0), **initial)
    attime(T["fold"], lambda: (sot.remove(taskChest.task.name), posture(*fold)), "remove the chest, fold arms and leg")
    attime(T["back"], lambda: (sot.remove(taskBody.task.name), taskrf.feature.selec("000111"), push(taskrf)),
           "remove the body posture, rf back (X, Y, Z)")
    attime(T["contact"], lambda: (sot.remove(taskrf.task.name), sot.addContact(contactRF)), "RF to contact")

    tracer, visualizer = _record(robot, dt, rf_reference, meshcat)
    diagram = builder.Build()
    diagram.set_name("planche_dyn")
    return PlancheDyn(diagram, robot, tracer, contactLF, contactRF, support, T, options, com0, visualizer,
                      {"right_ankle0": right})


def simulate(run: PlancheDyn, duration: float, progress: bool = True) -> tuple[Simulator, float]:
    """Tick by tick until ``duration`` or until the CoM has dropped :data:`STOP_COM_DROP_M`;
    returns the simulator and the CPU time of the loop (s)."""
    from tqdm import tqdm

    logging.getLogger("drake").setLevel(logging.WARNING)
    simulator = Simulator(run.diagram)
    simulator.Initialize()
    if run.visualizer is not None:
        run.visualizer.StartRecording(False)
    dt, com = run.robot.dt, run.robot.dynamic.GetOutputPort("com")
    com_context = run.robot.dynamic.GetMyContextFromRoot(simulator.get_context())
    start = time.process_time()
    for k in tqdm(range(round(duration / dt)), disable=not progress, file=sys.stderr, desc="planche dyn"):
        simulator.AdvanceTo((k + 1) * dt)
        if run.com0[2] - com.Eval(com_context)[2] > STOP_COM_DROP_M:
            break
    if run.visualizer is not None:
        run.visualizer.StopRecording()
        run.visualizer.PublishRecording()
    return simulator, time.process_time() - start


def phase_at(times: dict, t: float) -> str:
    """The last step of the sequence started at or before ``t`` (s): ``stand`` before the first."""
    started = [(when, name) for name, when in times.items() if when <= t + 1e-9]
    return max(started)[1] if started else "stand"


def summarize(run: PlancheDyn, simulator: Simulator, duration: float, cpu: float) -> tuple[dict, dict]:
    trace = run.tracer.data(simulator.get_context())
    robot, T = run.robot, run.times
    t, x, com = trace["time"], trace["x"], trace["com"]
    nq = robot.model.nq
    finite = np.all(np.isfinite(x), axis=1)
    q = np.nan_to_num(x[:, :nq])
    path = robot.dynamic.trajectory(["contactLF", "rf", "chest"], q)
    left = path["contactLF"]
    left_move = translation_drift(left)
    left_tilt = np.arccos(np.clip(left[:, 2, 2], -1.0, 1.0))
    com_drop = com[0, 2] - com[:, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        base_tilt = np.where(finite, tilt_of_quaternions(x[:, :4]), np.nan)
        shared = fall_report(t, base_tilt, x[:, 6], left_move)
    # The planche leans the pelvis forward on purpose (the chest to 80°): the shared criterion's 30°
    # of base tilt is part of the motion, so the fall is judged by the support: the held left sole
    # leaving its place, the CoM dropping, a non-finite state. The shared report is kept beside it.
    own = np.flatnonzero(~finite | (left_move > FALL_SOLE_M) | (left_tilt > FALL_SOLE_RAD) | (com_drop > FALL_COM_DROP_M))
    fell_at: float | None = None
    reason: str | None = None
    if own.size:
        k = own[0]
        fell_at = float(t[k])
        reason = ("non-finite" if not finite[k] else "sole moved" if left_move[k] > FALL_SOLE_M
                  else "sole tilted" if left_tilt[k] > FALL_SOLE_RAD else "CoM dropped")
    fall = {"fell": fell_at is not None, "fell_at_s": fell_at, "fall_reason": reason}
    end = fell_at if fell_at is not None else np.inf
    before = t < end
    x_min, x_max, y_min, y_max = run.support
    com_local = np.einsum("kji,kj->ki", left[:, :2, :2], com[:, :2] - left[:, :2, 3])
    margin = np.minimum.reduce([com_local[:, 0] - x_min, x_max - com_local[:, 0], com_local[:, 1] - y_min, y_max - com_local[:, 1]])
    single = (t >= T["lift"] + RELEASE_RAMP) & (t < T["contact"]) & before
    chest_z = path["chest"][:, :3, 2]
    chest_lean = np.arccos(np.clip(chest_z @ chest_z[0], -1.0, 1.0))  # the chest's z axis from its initial one
    rf = path["rf"][:, :3, 3]
    tracking = np.linalg.norm(rf - trace["rf_reference"], axis=1)
    in_rf = ((t >= T["lift"] + RELEASE_RAMP) & (t < T["body"])) & before
    ratios = np.nan_to_num(np.abs(trace["torque"]) / robot.sot.effort)
    torque_ratio = ratios.max(axis=1)
    at_limit = np.flatnonzero(torque_ratio > 0.999)
    plant = robot.model.plant
    actuated = [plant.get_joint_actuator(JointActuatorIndex(i)).joint().name() for i in range(plant.num_actuators())]
    saturated = actuated[int(np.argmax(ratios[at_limit[0]]))] if at_limit.size else None
    last = before & (t >= end - 0.2) & (t >= T["lift"])  # the 0.2 s before the fall, on one foot
    limited = [actuated[j] for j in np.flatnonzero(ratios[last].max(axis=0, initial=0.0) > 0.999)] if last.any() else []
    summary = {
        "robot": robot.model.name, "variant": robot.model.variant, "solver": type(robot.sot).__name__, "device": "RobotDynSimu",
        "planche_variant": "full" if "arms" in T else "reduced", "duration_s": duration, "dt_s": robot.dt,
        "ticks": len(t), "options": vars(run.options).copy(), "support_rectangle_m": list(run.support),
        **fall, "fall_report": shared,
        "fall_phase": phase_at(T, fell_at) if fell_at is not None else None,
        "time_on_one_foot_s": float(max(0.0, min(end, t[-1]) - (T["lift"] + RELEASE_RAMP))),
        "min_com_margin_in_support_single_m": float(margin[single].min()) if single.any() else None,
        "com_margin_in_support_at_lift_m": float(margin[np.searchsorted(t, T["lift"])]) if t[-1] >= T["lift"] else None,
        "max_left_sole_move_before_fall_m": float(left_move[before].max()),
        "max_chest_rotation_before_fall_deg": float(np.degrees(chest_lean[before].max())),
        "max_right_ankle_height_before_fall_m": float(rf[before, 2].max()),
        "max_rf_tracking_error_before_fall_m": float(tracking[in_rf].max()) if in_rf.any() else None,
        "max_torque_ratio_before_fall": float(torque_ratio[before].max()),
        "first_torque_limit_s": float(t[at_limit[0]]) if at_limit.size else None,
        "first_torque_limit_joint": saturated,
        "joints_at_torque_limit_before_fall": limited,
        "max_base_tilt_before_fall_deg": float(np.nanmax(base_tilt[before])),
        "max_com_drop_before_fall_m": float(np.nanmax(com_drop[before])),
        "com_drop_m": float(np.nanmax(com_drop)),
        "cpu_s": cpu,
    }
    summary["holds"] = not fall["fell"]
    summary["what_happens"] = _answer(summary)
    trace.update(com_margin=margin, left_sole_move=left_move, chest_lean=chest_lean, right_ankle=rf, torque_ratio=torque_ratio)
    return summary, trace


def _answer(s: dict) -> str:
    shared = s["fall_report"]
    tilt = (f"; the shared criterion calls it a fall ({shared['fall_reason']}) at {shared['fell_at_s']:.2f} s"
            if shared["fell"] else "")
    if s["holds"]:
        return f"Romeo holds the planche on its left foot for the {s['duration_s']:g} s run{tilt}"
    joint = f"; at their torque limits in the 0.2 s before: {', '.join(s['joints_at_torque_limit_before_fall'])}" \
        if s["joints_at_torque_limit_before_fall"] else ""
    return (f"Romeo falls at t = {s['fell_at_s']:.2f} s ({s['fall_reason']}), in the '{s['fall_phase']}' step, "
            f"{s['time_on_one_foot_s']:.2f} s after its right foot left the ground, the right ankle "
            f"{s['max_right_ankle_height_before_fall_m']:.2f} m high at most (the seed asks 0.65 m){joint}{tilt}")
