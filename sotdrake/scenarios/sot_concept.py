#!/usr/bin/env python3
"""The seed's sot-concept experiment (sot-dyninv ``python/ros/sot-concept.py``) on TALOS: the right
hand grasps a ball; each configuration adds tasks to a stack whose first task is the hand, as the
original's ``config(0..7)`` did (``SolverKine``, 5 ms ticks; the original ran on Romeo).

The original's ``sot.addContact`` is sot-dyninv's kinematic one, ``keep()`` then ``push``: the feet
go *below* the hand (``addContact(..., priority="bottom")``), which is what "balance is lost" shows.

==========  ========================================================================================
config      the original's commands after ``push(taskRH)`` (stack highest first), and the lesson
==========  ========================================================================================
seed0       nothing: hand only, ball (0.5, −0.2, 1.0); the whole body, free flyer included, follows
seed1       + contacts (RF, LF at the bottom); same ball: no CoM task, balance kept incidentally
seed2       + contacts; ball behind and above (−0.15, −0.2, 1.3): the hand pulls, balance is lost
seed3       + contacts + CoM equality; ball (0.15, 0.1, 1.0): the CoM is held below the hand
seed4       + joint limits (torso yaw's upper limit set to 0) + contacts + CoM; same ball: the
            torso stops at its artificial limit
seed5       + contacts + "COM<": the CoM xy kept in the support box (−0.08..0.11, −0.15..0.15) by an
            inequality; ball (0.15, −0.2, 1.3)
seed6       + contacts + CoM; ball (0.15, −0.2, 1.3) moved +0.1 m in x four times (the original's
            ``i`` key, here at 1.0, 1.5, 2.0 and 2.5 s): the singular approach (``--steps``:
            TALOS, taller than Romeo, still reaches the ball after 4; 12 take its arm to the singularity)
seed7       seed6, then ``down(RH)`` twice (the feet above the hand) and damping 0.1 (the last level)
==========  ========================================================================================

The project's own configurations are kept as ``extra_*`` (feet first, then the CoM, then the hand;
1 ms ticks): ``extra_under_constrained``, ``extra_balance_held``, ``extra_balance_broken``,
``extra_singular_undamped``, ``extra_singular_damped``, ``extra_singular_floor`` (the undamped
one with the right arm's manipulability kept above 0.01 by an inequality above the hand,
``MetaTaskKineManipulability``), ``extra_joint_limits`` and ``extra_joint_limits_cascade`` (the
basic ``SOT``).

``--robot romeo`` runs the seed configurations on the original's robot (sot-romeo's ``small``
model, the original's grip (0.07, −0.02, 0); seed4 limits the right shoulder yaw, which the reach
turns past 0).

    python diagrams/sot_concept.py --config seed --out out/concept     # or all, extra, or one name; --robot romeo

writes ``DIR/summary.json`` (one entry per configuration), ``DIR/plots.png``,
``DIR/control_graph.svg`` and ``DIR/<config>/recording.html`` + ``trace.npz``.
"""

from __future__ import annotations

import functools
import json
import sys
from dataclasses import dataclass, replace

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import Diagram, DiagramBuilder

from sotdrake import (
    SOT,
    TALOS_GRIPPERS,
    GaitParameters,
    MetaTaskKine6d,
    MetaTaskKineCom,
    MetaTaskKineJointLimits,
    MetaTaskKineManipulability,
    Robot,
    Tracer,
    add_sot,
    attime,
    gotoNd,
    json_safe,
    manipulability,
    polygon_margin,
    script_arguments,
    simulate,
    start,
    support_polygon,
    write_control_graph,
    write_run,
)
from sotdrake import robot as make_robot
from sotdrake.configuration import velocity_names
from sotdrake.exceptions import SotError
from sotdrake.scenarios.figures import concept_figure

SEED_GAIN = (4.9, 0.9, 0.01, 0.9)
SEED_JOINT_LIMIT_GAIN = 10.0  # sot-dyninv's TaskJointLimits: the bound's rate is 1/(dt·gain)
SUPPORT_BOX = ((-0.08, -0.15), (0.11, 0.15))  # the original's taskSupport: x, y lower; x, y upper (m)
STEP_TIMES = (1.0, 1.5, 2.0, 2.5)  # seed6/seed7: the ball moves +0.1 m in x (the original: 4 times)


def step_times(count: int) -> tuple[float, ...]:
    """``count`` steps of the ball, from 1 s, every 0.5 s."""
    return tuple(1.0 + 0.5 * k for k in range(count))
SEED_CONTACTS = ("addContact RF", "addContact LF")


@dataclass(frozen=True)
class RobotProfile:
    """What changes with the robot: its model variant, the grip point in the right wrist's frame
    (``opmodif``, m), the joint whose upper limit seed4 sets to 0, the right arm's joints (for the
    manipulability) and the joints the SoT leaves alone."""

    variant: str
    hand_offset: tuple[float, float, float]
    limited_joint: str
    right_arm: tuple[str, ...]
    excluded: tuple[str, ...] = ()


ROBOTS = {
    "talos": RobotProfile("reduced", (0.1, 0.0, 0.0), "torso_1_joint",
                          tuple(f"arm_right_{i}_joint" for i in range(1, 8)), tuple(TALOS_GRIPPERS)),
    # the original's robot: sot-romeo's 31-joint model, the original's grip (0.07, -0.02, 0); the
    # limited joint is the right shoulder yaw, which the reach of seed3 turns past 0 (see the tutorial)
    "romeo": RobotProfile("small", (0.07, -0.02, 0.0), "RShoulderYaw",
                          ("RShoulderPitch", "RShoulderYaw", "RElbowRoll", "RElbowYaw", "RWristRoll", "RWristYaw",
                           "RWristPitch")),
}


@dataclass(frozen=True)
class Configuration:
    """``commands``, in order: ``push X`` / ``addContact X`` (at the bottom: keep then push) / ``down
    X`` with X among rh, RF, LF, com, support, jl."""

    description: str
    ball: tuple[float, float, float]
    commands: tuple[str, ...]
    solver: str = "hqp"
    damping: float = 0.0
    duration: float = 4.0
    dt: float = 5e-3
    steps: tuple[float, ...] = ()
    seed: bool = True  # the original's tasks (frames 'desired', the support box and the joint limits)
    manipulability_floor: float = 0.0  # > 0: the task "floor" keeps the right arm's manipulability above it


def _seed(description: str, ball, *commands: str, **options) -> Configuration:
    return Configuration(description, ball, ("push rh", *commands), **options)


def _extra(description: str, ball, support: tuple[str, ...] = ("RF", "LF", "com"), **options) -> Configuration:
    return Configuration(description, ball, (*(f"push {t}" for t in support), "push rh"), dt=1e-3, seed=False, **options)


NEAR, BEHIND, CLOSE, HIGH = (0.5, -0.2, 1.0), (-0.15, -0.2, 1.3), (0.15, 0.1, 1.0), (0.15, -0.2, 1.3)
CONFIGURATIONS: dict[str, Configuration] = {
    "seed0": _seed("Only the task RH", NEAR),
    "seed1": _seed("Task RH + foot constraint, balance is kept", NEAR, *SEED_CONTACTS),
    "seed2": _seed("Task RH + foot constraint, balance is lost", BEHIND, *SEED_CONTACTS),
    "seed3": _seed("Task RH + foot constraint + COM=", CLOSE, *SEED_CONTACTS, "push com"),
    "seed4": _seed("Task RH + foot constraint + COM= + JL", CLOSE, "push jl", *SEED_CONTACTS, "push com"),
    "seed5": _seed("Task RH + foot constraint + COM<", HIGH, *SEED_CONTACTS, "push support"),
    "seed6": _seed("Task RH + foot constraint + COM= + SINGULARITE", HIGH, *SEED_CONTACTS, "push com", steps=STEP_TIMES),
    "seed7": _seed("Task RH + foot constraint + COM= + SINGULARITE + DAMPING", HIGH, *SEED_CONTACTS, "push com",
                   "down rh", "down rh", damping=0.1, steps=STEP_TIMES),
    "extra_under_constrained": _extra("hand only: the free flyer and every joint follow the hand", (0.65, -0.45, 1.15), ()),
    "extra_balance_held": _extra("ball out of reach, CoM held: the hand stops short, balance kept", (1.05, -0.35, 0.75),
                                 damping=1e-2),
    "extra_balance_broken": _extra("same ball, CoM free: the hand gets closer, the CoM leaves the support",
                                   (1.05, -0.35, 0.75), ("RF", "LF"), damping=1e-2),
    "extra_singular_undamped": _extra("ball beyond reach along the arm: a stretched, singular arm", (-0.03, -1.25, 1.37)),
    "extra_singular_damped": _extra("the same with damping 1e-2 on the hand's level", (-0.03, -1.25, 1.37), damping=1e-2),
    "extra_singular_floor": _extra("the same, undamped, with the right arm's manipulability kept above 0.01 (above the hand)",
                                   (-0.03, -1.25, 1.37), ("RF", "LF", "com", "floor"), manipulability_floor=0.01),
    "extra_joint_limits": _extra("ball behind the back: joints stop at their limits (HQP)", (-0.45, -0.35, 1.0)),
    "extra_joint_limits_cascade": _extra("the same with the basic SOT: limits are crossed", (-0.45, -0.35, 1.0),
                                         solver="cascade"),
}
GROUPS = {"seed": [n for n in CONFIGURATIONS if n.startswith("seed")],
          "extra": [n for n in CONFIGURATIONS if n.startswith("extra")]}
GROUPS["all"] = GROUPS["seed"] + GROUPS["extra"]


@dataclass
class Concept:
    diagram: Diagram
    robot: Robot
    sot: SOT
    taskRH: MetaTaskKine6d
    tracer: Tracer
    config: Configuration
    balls: list[tuple[float, np.ndarray]]  # (time, ball) from each gotoNd
    profile: RobotProfile = ROBOTS["talos"]
    visualizer: object = None


ConceptTask = MetaTaskKine6d | MetaTaskKineCom | MetaTaskKineJointLimits | MetaTaskKineManipulability
"""The kinds of task the configurations push."""


def _tasks(robot: Robot, seed: bool, profile: RobotProfile) -> dict[str, ConceptTask]:
    """The original's tasks: the hand (+ opmodif), the contacts, the CoM held (gain 10), the CoM
    support inequality and the joint limits (sot-dyninv's gain 10: 1/(10·dt), 20 /s at 5 ms) with the
    limited joint's upper limit at 0."""
    rh = MetaTaskKine6d("rh", robot, "rh", robot.OperationalPointsMap["right-wrist"])
    grip = np.eye(4)
    grip[0:3, 3] = profile.hand_offset
    rh.opmodif = grip
    tasks: dict[str, ConceptTask] = {"rh": rh}
    for name, op in (("RF", "right-ankle"), ("LF", "left-ankle")):
        contact = MetaTaskKine6d("contact" + name, robot, name, robot.OperationalPointsMap[op])
        if seed:
            contact.feature.frame("desired")
        contact.gain.setConstant(10)
        tasks[name] = contact
    com = tasks["com"] = MetaTaskKineCom(robot)
    com.gain.setConstant(10)
    if seed:
        rh.feature.frame("desired")
        support = MetaTaskKineCom(robot, "support", inequality=True)
        support.featureDes.setReference(np.zeros(3))  # e = the CoM itself: the box is in the world frame
        support.feature.selec("011")
        support.task.setBounds(*SUPPORT_BOX)
        # sot-dyninv's TaskInequality: (bound − e)·gain/dt with gain 1, the bound in one tick; 0.9 tick here
        # (λ·dt = 1 is the edge where an equality would overshoot, and the gain check warns there).
        support.gain.setConstant(0.9 / robot.dt)
        tasks["support"] = support
        # sot-dyninv's TaskJointLimits bounds v by (limit − q)/(dt·gain), gain 10: a rate of 1/(dt·10).
        jl = MetaTaskKineJointLimits(robot, "JL", margin=0.0, gain=1.0 / (robot.dt * SEED_JOINT_LIMIT_GAIN))
        row = jl.joint_names.index(profile.limited_joint)
        joint = robot.model.plant.GetJointByName(profile.limited_joint)
        lower, upper = joint.position_lower_limits()[0], joint.position_upper_limits()[0]
        bounds = np.ones(len(jl.joint_names))
        sup = bounds.copy()
        sup[row] = 2.0 * (0.0 - lower) / (upper - lower) - 1.0  # e of q = 0
        jl.task.setBounds(-bounds, sup)
        tasks["jl"] = jl
    return tasks


def build_diagram(config: Configuration, meshcat: Meshcat | None = None, robot_name: str = "talos") -> Concept:
    """``robot_name``: talos or romeo (the original's robot, sot-romeo's ``small`` model)."""
    if robot_name not in ROBOTS:
        raise SotError(f"robot_name must be one of {sorted(ROBOTS)}, got {robot_name!r}")
    profile = ROBOTS[robot_name]
    builder = DiagramBuilder()
    robot = make_robot(builder, robot_name, profile.variant, config.dt)
    sot = add_sot(robot, "sot", solver=config.solver, damping=config.damping)
    sot.setControlSelection(robot.velocity_selection(excluding=profile.excluded))
    tasks = _tasks(robot, config.seed, profile)
    if config.manipulability_floor > 0:
        tasks["floor"] = MetaTaskKineManipulability("rhManipulability", robot, "right-wrist", config.manipulability_floor,
                                                    joints=list(profile.right_arm))
    rh = tasks["rh"]
    assert isinstance(rh, MetaTaskKine6d)
    gotoNd(rh, config.ball, "111", SEED_GAIN)
    for command in config.commands:
        verb, name = command.split()
        task = tasks[name]
        if verb == "addContact":
            sot.addContact(task, priority="bottom")
        else:
            getattr(sot, verb)(task.task.name)
    balls = [(0.0, np.asarray(config.ball, dtype=float))]
    for k, t in enumerate(config.steps, start=1):  # the original's `i`: the ball 0.1 m further in x
        ball = np.asarray(config.ball) + (0.1 * k, 0.0, 0.0)
        attime(t, functools.partial(gotoNd, rh, tuple(ball), "111", SEED_GAIN), f"ball +{0.1 * k:.1f} m in x")
        balls.append((t, ball))

    tracer = Tracer(builder, config.dt)
    tracer.add(robot.device.GetOutputPort("state"), "q")
    tracer.add(sot.GetOutputPort("control"), "v")
    visualizer = None
    if meshcat is not None:
        from sotdrake import add_robot_visualizer, add_target_marker

        visualizer = add_robot_visualizer(robot, meshcat)
        add_target_marker(meshcat, "/ball", rh, radius=0.05)
        meshcat.SetCameraPose(camera_in_world=[1.6, -2.2, 1.6], target_in_world=[0.1, -0.2, 0.8])
    diagram = builder.Build()
    return Concept(diagram, robot, sot, rh, tracer, config, balls, profile, visualizer)


def run(concept: Concept, progress: bool = True) -> tuple[Simulator, float]:
    return simulate(concept.diagram, concept.config.duration, concept.visualizer, progress)


def _joint_names(robot: Robot) -> list[str]:
    names = velocity_names(robot.model.plant)
    return [names[i] for i in robot.device.layout.joints_v]


def _arm_velocities(robot: Robot, arm: tuple[str, ...]) -> list[int]:
    return [robot.model.plant.GetJointByName(name).velocity_start() for name in arm]


def _min_arm_manipulability(robot: Robot, qs: np.ndarray, arm: tuple[str, ...]) -> float:
    """The smallest manipulability of the right wrist's translation over the right arm's joints."""
    plant = robot.model.plant
    context, world, wrist = plant.CreateDefaultContext(), plant.world_frame(), robot.model.frame("right-wrist")
    columns = np.zeros(robot.dimension, dtype=bool)
    columns[_arm_velocities(robot, arm)] = True
    values = []
    for q in qs[::10]:
        plant.SetPositions(context, q)
        J = plant.CalcJacobianSpatialVelocity(context, JacobianWrtVariable.kV, wrist, np.zeros(3), world, world)
        values.append(manipulability(J[3:][:, columns]))
    return float(min(values))


def summarize(concept: Concept, simulator: Simulator, wall: float) -> tuple[dict, dict]:
    """The lessons' numbers: hand to ball, the CoM's margin in the initial feet's support polygon
    (positive inside: balance kept), its distance outside the support box, foot drift, the limited
    joint's largest value, joint-limit margins, the hand's top speed and the joint velocity ratio."""
    context = simulator.get_context()
    trace = concept.tracer.data(context)
    robot, config, profile = concept.robot, concept.config, concept.profile
    qs = np.vstack([robot.device.initial_position, trace["q"]])
    path = robot.dynamic.trajectory(["rh", "LF", "RF"], qs)
    hand = path["rh"][:, :3, :3] @ np.asarray(profile.hand_offset) + path["rh"][:, :3, 3]
    t = np.concatenate([[0.0], trace["time"]])
    ball = np.array([next(b for s, b in reversed(concept.balls) if s <= time + 1e-9) for time in t])
    feet = [(p[0, 0, 3], p[0, 1, 3], np.arctan2(p[0, 1, 0], p[0, 0, 0])) for p in (path["LF"], path["RF"])]
    polygon = support_polygon(feet, GaitParameters())
    com_margin = np.array([polygon_margin(c[:2], polygon) for c in path["com"]])
    (lo_x, lo_y), (hi_x, hi_y) = SUPPORT_BOX
    com_xy = path["com"][:, :2]
    box_excess = np.maximum.reduce([lo_x - com_xy[:, 0], com_xy[:, 0] - hi_x, lo_y - com_xy[:, 1], com_xy[:, 1] - hi_y])
    foot_drift = max(np.linalg.norm(path[f][:, :3, 3] - path[f][0, :3, 3], axis=1).max() for f in ("LF", "RF"))
    limits, layout = robot.model.joint_limits(), robot.device.layout
    selection = concept.sot.settings(context).control_selection
    controlled = selection[layout.joints_v] if selection is not None else np.ones(len(layout.joints_v), dtype=bool)
    joints_q, joints_v = layout.joints_q[controlled], layout.joints_v[controlled]
    margins = np.minimum(qs[:, joints_q] - limits["position_lower"][joints_q], limits["position_upper"][joints_q] - qs[:, joints_q])
    ratio = np.abs(trace["v"][:, joints_v]) / limits["velocity_upper"][joints_v]
    names = [n for n, keep in zip(_joint_names(robot), controlled, strict=False) if keep]
    worst = np.unravel_index(np.argmin(margins), margins.shape)
    hand_speed = np.linalg.norm(np.diff(hand, axis=0), axis=1) / config.dt
    limited = robot.model.plant.GetJointByName(profile.limited_joint).position_start()
    residuals = concept.sot.GetOutputPort("residuals").Eval(concept.sot.GetMyContextFromRoot(context))
    summary = {
        "description": config.description,
        "robot": robot.model.name,
        "solver": type(concept.sot).__name__,
        "stack": concept.sot.stack(context),
        "ball_m": ball[-1].tolist(),
        "hand_error_m": float(np.linalg.norm(hand[-1] - ball[-1])),
        "hand_initial_error_m": float(np.linalg.norm(hand[0] - ball[0])),
        "com_support_margin_m": float(com_margin[-1]),
        "min_com_support_margin_m": float(com_margin.min()),
        "balance_kept": bool(com_margin.min() > 0 and foot_drift < 1e-3),
        "com_box_excess_m": float(box_excess[-1]),
        "max_com_box_excess_m": float(box_excess.max()),
        "com_error_m": float(np.linalg.norm(path["com"][-1] - path["com"][0])),
        "com_horizontal_shift_m": float(np.linalg.norm(path["com"][-1, :2] - path["com"][0, :2])),
        "max_foot_drift_m": float(foot_drift),
        "base_displacement_m": float(np.linalg.norm(qs[-1, 4:7] - qs[0, 4:7])),
        "limited_joint_max_rad": float(qs[:, limited].max()),
        "limited_joint_final_rad": float(qs[-1, limited]),
        "level_slacks": [float(x) for x in residuals],
        "min_joint_limit_margin_rad": float(margins[worst]),
        "min_margin_joint": names[worst[1]],
        "max_joint_velocity_ratio": float(ratio.max()),
        "max_velocity_joint": names[int(np.argmax(ratio.max(axis=0)))],
        "max_hand_speed_m_s": float(hand_speed.max()),
        "max_joint_speed_rad_s": float(np.abs(trace["v"][:, joints_v]).max()),
        "max_right_arm_speed_rad_s": float(np.abs(trace["v"][:, _arm_velocities(robot, profile.right_arm)]).max()),
        "min_right_arm_manipulability": _min_arm_manipulability(robot, qs, profile.right_arm),
        "duration_s": config.duration,
        "dt_s": config.dt,
        "wall_s": wall,
        "realtime_factor": config.duration / wall,
    }
    trace.update(hand_position=hand[1:], com_position=path["com"][1:], hand_error=np.linalg.norm(hand[1:] - ball[1:], axis=1),
                 velocity_ratio=ratio.max(axis=1), min_margin=margins[1:].min(axis=1), com_support_margin=com_margin[1:])
    return summary, trace


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/concept", duration=None)
    parser.add_argument("--config", default="seed", choices=[*GROUPS, *CONFIGURATIONS],
                        help="a configuration, or a group: seed (0-7, the original's), extra, all")
    parser.add_argument("--steps", type=int, default=len(STEP_TIMES),
                        help="seed6/seed7: how many times the ball moves +0.1 m in x (the original: 4; TALOS's arm "
                             "reaches the ball after 4, its singular approach needs about 12)")
    parser.add_argument("--robot", default="talos", choices=sorted(ROBOTS),
                        help="talos, or romeo (the original's robot; the seed configurations only)")
    args = parser.parse_args(argv)  # --duration, if given, overrides every configuration's
    names = GROUPS.get(args.config, [args.config])
    if args.robot != "talos" and any(not CONFIGURATIONS[n].seed for n in names):
        parser.error(f"--robot {args.robot} runs the seed configurations only (the extras' balls are TALOS's)")
    if args.steps < 0:
        parser.error(f"--steps must be ≥ 0, got {args.steps}")
    if args.steps != len(STEP_TIMES) and not any(CONFIGURATIONS[n].steps for n in names):
        parser.error(f"--steps: an option of the configurations whose ball moves (seed6, seed7); this run is {args.config}")
    meshcat = start(args)
    args.out.mkdir(parents=True, exist_ok=True)
    summary, traces = {}, {}
    for name in names:
        config = CONFIGURATIONS[name]
        if config.steps and args.steps != len(config.steps):
            times = step_times(args.steps)
            config = replace(config, steps=times, duration=max(config.duration, (times[-1] if times else 0.0) + 1.5))
        if args.duration is not None:
            config = replace(config, duration=args.duration)
        if meshcat is not None:
            meshcat.Delete()
        concept = build_diagram(config, meshcat, args.robot)
        if not args.quiet:
            print(f"{name}: {config.description}", file=sys.stderr)
        simulator, wall = run(concept, progress=not args.quiet)
        summary[name], traces[name] = summarize(concept, simulator, wall)
        write_run(args.out / name, concept.diagram, dict(summary[name]), traces[name], meshcat, concept.visualizer,
                  graph=False, bag=args.bag)
        if name == names[0]:
            write_control_graph(concept.diagram, args.out / "control_graph.svg")
    concept_figure(traces, args.out / "plots.png", args.robot)
    (args.out / "summary.json").write_text(json.dumps(json_safe(summary), indent=2) + "\n")
    keys = ("hand_error_m", "com_support_margin_m", "max_foot_drift_m", "com_box_excess_m", "limited_joint_max_rad",
            "max_hand_speed_m_s", "max_joint_velocity_ratio")
    for name, entry in summary.items():
        print(f"{name:27s} " + "  ".join(f"{k}={np.round(entry[k], 4).tolist()}" for k in keys))
    return summary
