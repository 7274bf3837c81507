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
``SolverDyn``, :mod:`sotdrake.scenarios.planche_dyn`): on Romeo's model it falls as the right leg goes back, and its
summary says when, by which criterion, in which step and with which joints at their torque limits.

    python diagrams/planche.py --out out/planche          # --variant reduced; --solver dyn

writes ``recording.html``, ``trace.npz``, ``plots.png``, ``control_graph.svg`` and ``summary.json``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace

import numpy as np
from pydrake.geometry import Meshcat, Rgba
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder

from sotdrake import (
    SOT,
    MetaTaskKine6d,
    MetaTaskKineCom,
    MetaTaskKinePosture,
    Robot,
    Tracer,
    add_robot_visualizer,
    add_sot,
    add_target_marker,
    attime,
    gotoNd,
    options_given,
    script_arguments,
    simulate,
    start,
    write_run,
)
from sotdrake import robot as make_robot
from sotdrake.scenarios.figures import planche_figure

DT = 5e-3  # the seed's dt (s)
DEG = np.pi / 180
CHEST = 80 * DEG  # the chest's forward lean (rad)
MAX_EXT = 5 * DEG  # the right knee, extended (rad)
#: The seed's shrunken support of the left foot, around the ankle: (x_min, x_max, y_min, y_max) (m).
SHRUNKEN_SUPPORT = (-0.03, 0.03, -0.015, 0.015)
#: The sequence (s) of the reduced variant (the seed's WITH_FULL_EXTENTION = False): the seed's
#: iterations × 5 ms, from the lift on 0.8 s later.
REDUCED = {"lift": 1.5, "extend": 3.3, "chest": 4.8, "body": 5.8, "fold": 8.3, "back": 9.8, "above": 11.8, "ground": 12.8,
           "contact": 14.0}
#: The full variant (the seed's default, WITH_FULL_EXTENTION = True): the arms out at iteration 1250,
#: the foot extended and the head pitched at 2080, every later step 1000 iterations (5 s) later.
FULL = {**{k: t + (5.0 if t >= REDUCED["fold"] else 0.0) for k, t in REDUCED.items()}, "arms": 6.25 + 0.8, "foot": 10.4 + 0.8}
TIMES = {"full": FULL, "reduced": REDUCED}
T = FULL  # the default variant's
ARMS_OUT = np.pi / 2  # the shoulders' yaw in the full variant: right −π/2, left +π/2 (rad)
FOOT_EXTENSION = 0.73  # the right ankle's pitch in the full variant (rad)
HEAD_PITCH = -np.pi / 4  # the neck's pitch in the full variant (rad)
UP = (0.0, 0.0, 0.65)  # the right ankle up: Y, Z (m)
EXTEND = (-0.55, 0.0, 0.7)  # the right leg back: X, Z (m)
BACK = (-0.1, -0.1, 0.25)  # the right ankle on its way back (m)
#: Joints the SoT leaves alone: hands and fingers.
NOT_CONTROLLED = re.compile(r"hand|finger|thumb|gripper", re.I)
CHAINS = {"chest": ["TrunkYaw"], "head": ["NeckYaw", "NeckPitch", "HeadPitch", "HeadRoll"],
          "rleg": ["RHipYaw", "RHipRoll", "RHipPitch", "RKneePitch", "RAnklePitch", "RAnkleRoll"],
          "rarm": ["RShoulderPitch", "RShoulderYaw", "RElbowRoll", "RElbowYaw", "RWristRoll", "RWristYaw", "RWristPitch"],
          "larm": ["LShoulderPitch", "LShoulderYaw", "LElbowRoll", "LElbowYaw", "LWristRoll", "LWristYaw", "LWristPitch"]}


@dataclass
class Planche:
    """Handles on the diagram's entities, named as in the seed."""

    diagram: Diagram
    robot: Robot
    sot: SOT
    contactLF: MetaTaskKine6d
    contactRF: MetaTaskKine6d
    taskCom: MetaTaskKineCom
    taskrf: MetaTaskKine6d
    taskChest: MetaTaskKine6d
    taskPosture: MetaTaskKinePosture
    taskRest: MetaTaskKinePosture
    tracer: Tracer
    support_centre: np.ndarray  # the left ankle's (x, y) (m): the shrunken rectangle is around it
    times: dict  # the variant's sequence (s)
    visualizer: object = None


def gotoq(robot: Robot, q: np.ndarray, **chains: tuple[float, ...]) -> tuple[np.ndarray, str]:
    """sot-dyninv's ``taskPosture.gotoq(chest=..., rleg=...)``: ``q`` with the named chains'
    joints set (in :data:`CHAINS` order), and the posture selection of those joints only."""
    plant = robot.model.plant
    q = q.copy()
    selected = np.zeros(robot.dimension, dtype=bool)
    for chain, values in chains.items():
        for name, value in zip(CHAINS[chain], values, strict=True):
            joint = plant.GetJointByName(name)
            q[joint.position_start()] = value
            selected[joint.velocity_start()] = True
    return q, "".join("1" if s else "0" for s in reversed(selected))


def build_diagram(meshcat: Meshcat | None = None, dt: float = DT, variant: str = "full") -> Planche:
    """``variant``: ``"full"`` (the seed's default: the arms and the foot extended during the
    planche) or ``"reduced"`` (without them, 5 s shorter)."""
    if variant not in TIMES:
        raise ValueError(f"variant must be one of {sorted(TIMES)}, got {variant!r}")
    T = TIMES[variant]
    builder = DiagramBuilder()
    robot = make_robot(builder, "romeo", "small", dt)
    sot = add_sot(robot, "sot", solver="hqp")
    # The seed's motion as it ran it: without the step limit (1.4 rad/s per joint at 5 ms), whose box
    # would spread the chest's and legs' motion over the arms; the support foot stays within 0.021 mm.
    sot.setStepLimit(np.inf)
    plant = robot.model.plant
    excluded = [plant.get_joint(j).name() for j in plant.GetJointIndices()
                if plant.get_joint(j).num_velocities() == 1 and NOT_CONTROLLED.search(plant.get_joint(j).name())]
    sot.setControlSelection(robot.velocity_selection(excluding=excluded))

    # --- the contacts
    contacts = {}
    for name, op in (("LF", "left-ankle"), ("RF", "right-ankle")):
        contact = MetaTaskKine6d("contact" + name, robot, name.lower(), robot.OperationalPointsMap[op])
        contact.feature.frame("desired")
        contact.gain.setConstant(10)
        contacts[name] = contact
        sot.addContact(contact)
    contactLF, contactRF = contacts["LF"], contacts["RF"]

    # --- the CoM (X, Y) inside the shrunken support, over the left ankle
    support_centre = contactLF.current_pose().translation()[:2]
    taskCom = MetaTaskKineCom(robot, inequality=True)
    taskCom.featureDes.setReference([*support_centre, 0.0])
    taskCom.feature.selec("011")
    x_min, x_max, y_min, y_max = SHRUNKEN_SUPPORT
    taskCom.task.setBounds([x_min, y_min], [x_max, y_max])
    taskCom.gain.setConstant(10)
    sot.push(taskCom.task.name)

    # --- the operational tasks
    taskrf = MetaTaskKine6d("rf", robot, "rf", robot.OperationalPointsMap["right-ankle"])
    taskrf.feature.frame("desired")
    taskrf.gain.setByPoint(4, 1, 0.01, 0.9)
    rf0 = taskrf.current_pose().GetAsMatrix4()
    taskChest = MetaTaskKine6d("chest", robot, "chest", robot.OperationalPointsMap["chest"])
    taskChest.gain.setByPoint(2, 0.5, DEG, 0.9)
    taskPosture = MetaTaskKinePosture(robot)
    taskPosture.gain.setConstant(2)
    # The seed's solver holds its own posture below every task (``sot.posture``): here the rest
    # posture, half-sitting, always at the bottom of the stack.
    taskRest = MetaTaskKinePosture(robot, "rest")
    taskRest.gain.setConstant(1)
    sot.push(taskRest.task.name)

    _schedule(robot, sot, T, variant, contactRF, taskCom, taskrf, taskChest, taskPosture, support_centre, rf0)

    tracer = Tracer(builder, dt)
    tracer.add(robot.device.GetOutputPort("state"), "q")
    for meta in (contactLF, contactRF, taskCom, taskrf, taskChest, taskPosture, taskRest):
        tracer.add(meta.task.GetOutputPort("error_norm"), f"error_{meta.task.name}")

    visualizer = None
    if meshcat is not None:
        visualizer = add_robot_visualizer(robot, meshcat)
        add_target_marker(meshcat, "/support_centre", [*support_centre, 0.0], radius=0.015, rgba=Rgba(0.1, 0.6, 0.1, 0.8))
        meshcat.SetCameraPose(camera_in_world=[0.4, -1.9, 0.9], target_in_world=[0.0, 0.0, 0.5])
    diagram = builder.Build()
    diagram.set_name("planche")
    return Planche(diagram, robot, sot, contactLF, contactRF, taskCom, taskrf, taskChest, taskPosture, taskRest, tracer,
                   np.asarray(support_centre), T, visualizer)


def _schedule(robot: Robot, sot: SOT, T: dict[str, float], variant: str, contactRF: MetaTaskKine6d,
              taskCom: MetaTaskKineCom, taskrf: MetaTaskKine6d, taskChest: MetaTaskKine6d, taskPosture: MetaTaskKinePosture,
              support_centre: np.ndarray, rf0: np.ndarray) -> None:
    """The seed's sequence of stack changes and targets, each at its time (``attime``)."""
    q0, plant = robot.device.initial_position, robot.model.plant
    x_min, x_max, y_min, y_max = SHRUNKEN_SUPPORT
    above = rf0.copy()
    above[2, 3] += 0.07

    def push(meta) -> tuple:  # sot.push, above the rest posture
        return sot.push(meta.task.name), sot.up(meta.task.name)

    attime(T["lift"], lambda: (sot.rmContact(contactRF), push(taskrf), gotoNd(taskrf, UP, "000110")),
           "remove the RF contact, add RF, up foot RF")
    attime(T["extend"], lambda: gotoNd(taskrf, EXTEND, "000101"), "extend RF")
    attime(T["chest"], lambda: (gotoNd(taskChest, (0, 0, 0, 0, CHEST, 0), "111000"), push(taskChest)), "add chest")
    body, body_mask = gotoq(robot, q0, chest=(0,), rleg=(0, 0, 0, MAX_EXT, 0, 0), head=(0, 0, 0, 0))
    attime(T["body"], lambda: (sot.remove(taskrf.task.name), taskPosture.feature.setPosture(body), taskPosture.feature.selec(body_mask),
                               push(taskPosture)),
           "remove RF, add the posture, extend the body")
    if variant == "full":
        arms = {"rarm": (0, -ARMS_OUT, 0, 0, 0, 0, 0), "larm": (0, ARMS_OUT, 0, 0, 0, 0, 0)}
        extended, extended_mask = gotoq(robot, q0, chest=(0,), rleg=(0, 0, 0, MAX_EXT, 0, 0), head=(0, 0, 0, 0), **arms)
        attime(T["arms"], lambda: (taskPosture.feature.setPosture(extended), taskPosture.feature.selec(extended_mask)),
               "extend arm")
        foot, foot_mask = gotoq(robot, q0, chest=(0,), rleg=(0, 0, 0, MAX_EXT, FOOT_EXTENSION, 0),
                                head=(0, HEAD_PITCH, 0, 0), **arms)
        attime(T["foot"], lambda: (taskPosture.feature.setPosture(foot), taskPosture.feature.selec(foot_mask)),
               "extend foot")
    fold, fold_mask = gotoq(robot, q0, chest=(0,), rleg=tuple(q0[plant.GetJointByName(j).position_start()] for j in CHAINS["rleg"]),
                            head=(0, 0, 0, 0), rarm=tuple(q0[plant.GetJointByName(j).position_start()] for j in CHAINS["rarm"]),
                            larm=tuple(q0[plant.GetJointByName(j).position_start()] for j in CHAINS["larm"]))
    attime(T["fold"], lambda: (sot.remove(taskChest.task.name), taskPosture.feature.setPosture(fold),
                               taskPosture.feature.selec(fold_mask)), "remove the chest, fold arms and leg")
    attime(T["back"], lambda: (sot.remove(taskPosture.task.name), push(taskrf), gotoNd(taskrf, BACK, "111")),
           "remove the posture, add RF, back RF")
    attime(T["above"], lambda: gotoNd(taskrf, above, "111111", (4, 1, 0.005, 0.9)), "RF to upper ground")
    attime(T["ground"], lambda: gotoNd(taskrf, rf0, "111111", (4, 1, 0.005, 0.9)), "RF to ground")
    double_centre = (support_centre + contactRF.current_pose().translation()[:2]) / 2
    half_width = abs(support_centre[1] - double_centre[1])
    attime(T["contact"], lambda: (sot.remove(taskrf.task.name), sot.addContact(contactRF),
                                  taskCom.featureDes.setReference([*double_centre, 0.0]),
                                  taskCom.task.setBounds([x_min, y_min - half_width], [x_max, y_max + half_width]),
                                  ),
           "RF to contact, the CoM over the double support (the rest posture brings the robot to its initial pose)")


def _q(robot: Robot, joint: str) -> int:
    return robot.model.plant.GetJointByName(joint).position_start()


def summarize(run: Planche, simulator: Simulator, duration: float, wall: float) -> tuple[dict, dict]:
    context = simulator.get_context()
    trace = run.tracer.data(context)
    robot = run.robot
    qs = np.vstack([robot.device.initial_position, trace["q"]])
    t = np.concatenate([[0.0], trace["time"]])
    path = robot.dynamic.trajectory(["lf", "rf", "chest"], qs)
    com_xy = path["com"][:, :2] - run.support_centre
    x_min, x_max, y_min, y_max = SHRUNKEN_SUPPORT
    margin = np.minimum.reduce([com_xy[:, 0] - x_min, x_max - com_xy[:, 0], com_xy[:, 1] - y_min, y_max - com_xy[:, 1]])
    T = run.times
    single = (t >= T["lift"]) & (t < T["contact"])
    chest_lean = np.arccos(np.clip(path["chest"][:, 2, 2], -1.0, 1.0))  # the chest's z from the vertical
    rf = path["rf"][:, :3, 3]
    lf_drift = np.linalg.norm(path["lf"][:, :3, 3] - path["lf"][0, :3, 3], axis=1)
    limits = robot.model.joint_limits()
    lower, upper = limits["position_lower"], limits["position_upper"]
    finite = np.isfinite(lower) & np.isfinite(upper)
    joint_margin = np.minimum(qs[:, finite] - lower[finite], upper[finite] - qs[:, finite]).min(axis=1)
    summary = {
        "robot": robot.model.name, "variant": robot.model.variant, "solver": type(run.sot).__name__,
        "planche_variant": "full" if "arms" in T else "reduced",
        "duration_s": duration, "dt_s": robot.dt, "ticks": len(trace["time"]),
        "com_in_shrunken_support_from_s": float(t[np.argmax(margin >= -1e-6)]) if (margin >= -1e-6).any() else None,
        "min_com_margin_single_support_m": float(margin[single].min()) if single.any() else None,
        "max_chest_lean_deg": float(np.degrees(chest_lean.max())),
        "max_right_ankle_height_m": float(rf[:, 2].max()),
        "min_right_ankle_x_m": float(rf[:, 0].min()),
        "max_left_ankle_drift_m": float(lf_drift.max()),
        "right_ankle_final_error_m": float(np.linalg.norm(rf[-1] - rf[0])),
        "min_joint_limit_margin_rad": float(joint_margin.min()),
        # the full variant's extensions: the arms out (shoulder yaws), the foot (ankle pitch), the head (neck pitch)
        "min_right_shoulder_yaw_rad": float(qs[:, _q(robot, "RShoulderYaw")].min()),
        "max_left_shoulder_yaw_rad": float(qs[:, _q(robot, "LShoulderYaw")].max()),
        "max_right_ankle_pitch_rad": float(qs[:, _q(robot, "RAnklePitch")].max()),
        "min_neck_pitch_rad": float(qs[:, _q(robot, "NeckPitch")].min()),
        "final_stack": run.sot.stack(context), "final_contacts": run.sot.contacts(context),
        "wall_s": wall, "realtime_factor": duration / wall,
    }
    trace.update(com_in_support=com_xy[1:], com_margin=margin[1:], chest_lean=chest_lean[1:], right_ankle=rf[1:],
                 left_ankle_drift=lf_drift[1:], joint_limit_margin=joint_margin[1:])
    return summary, trace


def dynamic():
    """The dynamic run's module (:mod:`sotdrake.scenarios.planche_dyn`)."""
    from sotdrake.scenarios import planche_dyn

    return planche_dyn


DYN_CONSTANTS = {"SHRUNKEN_SUPPORT": SHRUNKEN_SUPPORT, "UP": UP, "EXTEND": EXTEND, "BACK": BACK, "CHEST": CHEST,
                 "MAX_EXT": MAX_EXT, "ARMS_OUT": ARMS_OUT, "FOOT_EXTENSION": FOOT_EXTENSION, "HEAD_PITCH": HEAD_PITCH,
                 "CHAINS": CHAINS}


def build_dynamic(variant: str = "full", options=None, meshcat: Meshcat | None = None):
    """``--solver dyn``: the same sequence on ``RobotDynSimu`` + ``SolverDyn`` (:mod:`sotdrake.scenarios.planche_dyn`)."""
    if variant not in TIMES:
        raise ValueError(f"variant must be one of {sorted(TIMES)}, got {variant!r}")
    dyn = dynamic()
    return dyn.build(variant, TIMES[variant], gotoq, DYN_CONSTANTS, options or dyn.DynOptions(), meshcat, DT)


def main_dynamic(args) -> dict:
    dyn = dynamic()
    options = dyn.DynOptions()
    if args.support is not None:
        options = replace(options, shrink=args.support == "shrunken")
    if args.slow is not None:
        options = replace(options, slow=args.slow)
    if args.effort is not None:
        options = replace(options, effort=args.effort)
    if args.duration_given is None:
        args.duration = TIMES[args.variant]["contact"] * options.slow + 2.0
    meshcat = start(args)
    run = build_dynamic(args.variant, options, meshcat)
    simulator, cpu = dyn.simulate(run, args.duration, not args.quiet)
    summary, trace = dyn.summarize(run, simulator, args.duration, cpu)
    args.out.mkdir(parents=True, exist_ok=True)
    write_run(args.out, run.diagram, summary, trace, meshcat, run.visualizer, bag=args.bag)
    return summary


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/planche", duration=None)
    parser.add_argument("--variant", choices=sorted(TIMES), default="full",
                        help="full (the seed's: arms and foot extended, 21 s) or reduced (without them, 16 s)")
    parser.add_argument("--solver", choices=("kine", "dyn"), default="kine",
                        help="kine (SolverKine, the default) or dyn (RobotDynSimu + SolverDyn, as the seed ran it)")
    parser.add_argument("--support", choices=("sole", "shrunken"), default=None,
                        help="--solver dyn: the left contact's rectangle, the whole sole (default) or the seed's 6 × 3 cm")
    parser.add_argument("--slow", type=float, default=None,
                        help="--solver dyn: every time of the sequence × SLOW (default 1)")
    parser.add_argument("--effort", type=float, default=None,
                        help="--solver dyn, a diagnostic: Romeo's torque limits × EFFORT (default 1, the model's)")
    args = parser.parse_args(argv)
    dynamic_only = options_given(parser, args, ("support", "slow", "effort"))  # (each None by default)
    if args.solver != "dyn" and dynamic_only:
        parser.error(f"{', '.join(dynamic_only)}: options of --solver dyn (this run is --solver {args.solver})")
    for name in ("slow", "effort"):
        value = getattr(args, name)
        if value is not None and not 0 < value <= 100:
            parser.error(f"--{name} must be a number in (0, 100], got {value}")
    args.duration_given = args.duration
    if args.duration is None:
        args.duration = TIMES[args.variant]["contact"] + 2.0
    if args.solver == "dyn":
        return main_dynamic(args)
    meshcat = start(args)
    run = build_diagram(meshcat, variant=args.variant)
    simulator, wall = simulate(run.diagram, args.duration, run.visualizer, not args.quiet)
    summary, trace = summarize(run, simulator, args.duration, wall)
    args.out.mkdir(parents=True, exist_ok=True)
    planche_figure(trace, summary, args.out / "plots.png", run.times, SHRUNKEN_SUPPORT)
    write_run(args.out, run.diagram, summary, trace, meshcat, run.visualizer, bag=args.bag)
    return summary
