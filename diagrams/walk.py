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
servo options of :class:`Servos` (``--stiffness``, ``--damping``, the static feed-forward torque with
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
"""

from __future__ import annotations

import dataclasses
import json
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, Demultiplexer, Multiplexer

from sotdrake import (
    SOT,
    TALOS_GRIPPERS,
    MetaTaskKine6d,
    MetaTaskKine6dRel,
    MetaTaskKineCom,
    MetaTaskKinePosture,
    Robot,
    Solver,
    Tracer,
    add_sot,
    attime,
    fall_report,
    load_robot,
    load_talos,
    save_figure,
    script_arguments,
    simulate,
    start,
    tilt_of_rotations,
    write_run,
)
from sotdrake.exceptions import InvalidInput
from sotdrake.robots import RobotModel
from sotdrake.walking import (
    ComStabilizer,
    GaitParameters,
    GravityFeedforward,
    MeasuredCom,
    PatternGenerator,
    leg_masses,
    motion_zmp,
    start_of,
)
from sotdrake.walking.com_planner import GRAVITY
from sotdrake.walking.support import footprint, polygon_margin, support_polygon


@dataclass(frozen=True)
class WalkingRobot:
    """What the walk needs of a robot: its loader, op points (feet soles, waist, head, wrists),
    the joints the SoT leaves alone, and (for ``--mode physics``) its physical model."""

    load: Callable[[], RobotModel]
    feet: tuple[str, str] = ("left-sole", "right-sole")
    waist: str = "waist"
    head: str = "gaze"
    wrists: tuple[str, str] = ("left-wrist", "right-wrist")
    excluded: tuple[str, ...] = ()
    add_physical: Callable | None = None
    gait: GaitParameters = field(default_factory=GaitParameters)
    #: For ``--zmp-model multibody``: the name prefixes of the legs' bodies and the sole frames (left, right).
    legs: tuple[tuple[str, str], tuple[str, str]] | None = None


def _add_physical_talos(builder, dt, **options):
    from sotdrake.physics import add_physical_talos

    return add_physical_talos(builder, time_step=dt, **options)


SIDES = ("left", "right")
#: Adding a robot is adding an entry.
ROBOTS: dict[str, WalkingRobot] = {
    "talos": WalkingRobot(load=lambda: load_talos("reduced"),
                          excluded=TALOS_GRIPPERS,
                          add_physical=_add_physical_talos,
                          legs=(("leg_left_", "leg_right_"), ("left_sole_link", "right_sole_link"))),
    # Romeo (sot-romeo's 31-joint model): its foot is the bounding box of the collision mesh of
    # its ankle link, 0.244 m long from 8.9 cm behind the sole frame, 0.112 m wide (the narrower
    # half mirrored, so one footprint serves both feet). Swing apex 3 cm: at 5 cm the swinging
    # ankle needs more dorsiflexion than its limit (-0.52 rad) with the sole kept flat. No
    # physical model: the physics station is TALOS' (sole boxes, link boxes and PD gains fitted to TALOS).
    "romeo": WalkingRobot(load=lambda: load_robot("romeo", "small"),
                          gait=GaitParameters(sole_length=0.244, sole_width=0.112, sole_centre=(0.033, 0.0), swing_height=0.03)),
}
MODES = ("kinematic", "physics", "dynamic")
#: Task gains (1/s): the tracked references (waist, soles, CoM), and the lower-priority orientations
#: (head, waist yaw, arms). walkromeo's were 40 (soles, waist yaw) and 5 (waist, head): with every
#: target's velocity fed forward the gain only corrects drift, and ``--gains 40 5`` tracks as well
#: (see the walk tutorial); 100/10 are kept so that the published runs stand.
TRACKING_GAIN = 100.0
POSTURE_GAIN = 10.0
SEED_GAINS = (40.0, 5.0)
#: A sole carrying more than this (N) stands: its motion then is slip.
SLIP_LOAD_N = 100.0
#: How far (m) a wrist may move back, relative to the waist, from where it started.
ARM_BACKWARD_MARGIN = 0.01
#: What keeps the arms (``--arms``): ``posture`` (the default), walkromeo's ``taskPosition``, the arm
#: joints held at half-sitting by a posture task at the bottom of the stack (both solvers);
#: ``inequality``, the wrists kept from moving backward relative to the waist (``SolverKine`` only).
ARMS = ("posture", "inequality")
#: The arm joints (TALOS', Romeo's) of the ``posture`` arms.
ARM_JOINTS = re.compile(r"^arm_(left|right)_[1-7]_joint$|^[LR](Shoulder|Elbow|Wrist)")
#: walkromeo's gain of its arm posture: ``GainAdaptive.set(0.1, 0.1, 125e3)``, a constant 0.1 /s.
ARM_POSTURE_GAIN = (0.1, 0.1, 125e3)


@dataclass(frozen=True)
class Servos:
    """The physics mode's servos: ``stiffness`` (``kp = stiffness · effort limit``, rad⁻¹; 300, ten
    times the physics station's default: with 30 the legs' sag makes TALOS fall at 0.2 m per step),
    ``feedforward`` (the static torques of the planned posture,
    :class:`~sotdrake.walking.gravity_feedforward.GravityFeedforward`; default: none), ``com_gain`` and
    ``zmp_gain`` (1/s) of the CoM stabiliser (:class:`~sotdrake.walking.stabilizer.ComStabilizer`,
    fed by the plant's CoM and CoP; ``com_gain = 0``: none; default 8 and 2: with the multibody
    plan it keeps the CoP within millimetres of the reference; ``k_z = 0`` made the loop
    unstable), ``closed_loop`` (the SoT's kinematics reads the plant's ``q``, a perfect estimator,
    instead of the device's), ``damping`` (``kd = damping · kp``, s)."""

    stiffness: float = 300.0
    feedforward: bool = False
    com_gain: float = 8.0
    zmp_gain: float = 2.0
    closed_loop: bool = False  # the SoT's kinematics reads the plant's q (a perfect estimator), not the device's
    damping: float = 0.05  # kd = damping · kp (s), the physics station's default


@dataclass
class Walk:
    diagram: Diagram
    robot: Robot  # RobotDyn in dynamic mode
    pg: PatternGenerator
    sot: SOT  # SolverDyn in dynamic mode
    tasks: dict
    tracer: Tracer
    mode: str
    spec: WalkingRobot
    robot_name: str = "talos"
    physical: object = None
    commands: list = field(default_factory=list)
    visualizer: object = None
    servos: Servos | None = None  # physics mode


def build_diagram(robot: str = "talos", velocity=(0.1, 0.0, 0.0), then: tuple | None = None,
                  steps: tuple[int, float] | None = None, mode: str = "kinematic", solver: str = "hqp",
                  dt: float = 1e-3, gait: GaitParameters | None = None, meshcat: Meshcat | None = None,
                  servos: Servos | None = None, multibody_zmp: bool | None = None, arms: str = "posture",
                  gains: tuple[float, float] = (TRACKING_GAIN, POSTURE_GAIN)) -> Walk:
    """The walk's diagram. ``velocity``: the command from t = 0; ``then``: ``(T, x, y, θ)``, a new
    command at T; ``steps``: ``(n, length)`` instead of a velocity; ``solver``: ``'hqp'``
    (``SolverKine``) or ``'cascade'`` (walkromeo's ``Solver(robot)``: the basic ``SOT`` through a
    ``JointLimitator``; it takes no inequality: ``arms='inequality'`` is then left out);
    ``servos``: the physics mode's servo options (:class:`Servos`); ``multibody_zmp``: the CoM is
    planned with the legs' momentum (:func:`~sotdrake.walking.multibody_zmp.leg_masses`), kinematic
    and physics modes (None: in physics mode only); ``arms``: one of :data:`ARMS` (kinematic and
    physics modes); ``gains``: the tracking and the orientation gains (1/s), kinematic and physics modes."""
    tracking_gain, posture_gain = gains
    if arms not in ARMS:
        raise InvalidInput(f"arms is one of {ARMS}, got {arms!r}")
    if robot not in ROBOTS:
        from sotdrake.exceptions import NotFound

        raise NotFound(robot, list(ROBOTS))
    if mode not in MODES:
        raise InvalidInput(f"mode is one of {MODES}, got {mode!r}")
    spec = ROBOTS[robot]
    if mode != "kinematic" and spec.add_physical is None:
        raise InvalidInput(f"--mode {mode}: no physical model for {robot!r}; the physics station of sotdrake.physics is "
                           f"TALOS' (its sole and link boxes, PD gains and torque limits); {robot!r} walks in kinematic mode")
    if mode == "dynamic":
        return _build_dynamic(robot, spec, steps, dt, gait or dataclasses.replace(spec.gait, swing_profile=DYNAMIC_SWING_PROFILE), meshcat)
    builder = DiagramBuilder()
    model = spec.load()
    servos = servos or Servos()
    physical = None
    if mode == "physics":
        physical = spec.add_physical(builder, dt, stiffness=servos.stiffness, damping=servos.damping)
        physical.plant.SetDefaultPositions(model.half_sitting)
    measured_q = None
    if physical is not None and servos.closed_loop:
        state = physical.plant
        split = builder.AddNamedSystem("measured_position", Demultiplexer([state.num_positions(), state.num_velocities()]))
        builder.Connect(state.get_state_output_port(), split.get_input_port())
        measured_q = split.get_output_port(0)
    bot = Robot(builder, model, dt, measured_position=measured_q)
    dyn = bot.dynamic
    gait = gait or spec.gait
    legs = None
    if multibody_zmp or (multibody_zmp is None and mode == "physics"):
        if spec.legs is None:
            raise InvalidInput(f"--zmp-model multibody: no leg bodies known for {robot!r} (WalkingRobot.legs)")
        legs = leg_masses(model, bot.device.initial_position, soles=spec.legs[1], prefixes=spec.legs[0])
    pg = bot.add(PatternGenerator(start_of(dyn, bot.device.initial_position, spec.feet, spec.waist), dt, gait, legs=legs))
    if steps is not None:
        pg.setSteps([(steps[1], 0.0, 0.0)] * int(steps[0]))
    else:
        pg.setVelocity(*velocity)
    commands = []
    if then is not None:
        commands.append(attime(then[0], lambda: pg.setVelocity(*then[1:]), f"pg.setVelocity{tuple(then[1:])}"))

    # walkromeo's ``solver = Solver(robot)``: the basic SOT through a JointLimitator; the HQP holds the limits itself.
    sot = Solver(bot, "cascade", name="sot").sot if solver == "cascade" else add_sot(bot, "sot", solver=solver)
    sot.setControlSelection(bot.velocity_selection(excluding=list(spec.excluded)))
    connect = builder.Connect
    tasks = {}

    def six_d(name, op, frame, selection, pose, velocity, gain):
        meta = MetaTaskKine6d(name, bot, op, frame)
        meta.feature.selec(selection)
        meta.gain.setConstant(gain)
        connect(pg.GetOutputPort(pose), meta.featureDes.GetInputPort("pose_in"))
        connect(pg.GetOutputPort(velocity), meta.featureDes.GetInputPort("spatial_velocity_in"))
        tasks[meta.task.name] = meta
        return meta

    six_d("Waist", "waist", spec.waist, "011100", "waist_pose", "waist_velocity", tracking_gain)
    six_d("RF", "RF", spec.feet[1], "111111", "right_foot_pose", "right_foot_velocity", tracking_gain)
    six_d("LF", "LF", spec.feet[0], "111111", "left_foot_pose", "left_foot_velocity", tracking_gain)
    com = MetaTaskKineCom(bot)
    com.feature.selec("011")
    com.gain.setConstant(tracking_gain)
    stabilizer = None
    if physical is not None and servos.com_gain:
        stabilizer = bot.add(ComStabilizer(pg.start.com[2], dt, servos.com_gain, servos.zmp_gain))
        for port in ("com", "com_velocity", "com_acceleration"):
            connect(pg.GetOutputPort(port), stabilizer.GetInputPort(f"{port}_reference"))
        if legs is not None:  # the pendulum's ZMP of a multibody plan is off the reference, the CoP belongs on it
            connect(pg.GetOutputPort("zmp_reference"), stabilizer.GetInputPort("zmp_reference"))
        connect(stabilizer.GetOutputPort("com"), com.featureDes.GetInputPort("value_in"))
        connect(stabilizer.GetOutputPort("com_velocity"), com.featureDes.GetInputPort("velocity_in"))
    else:
        connect(pg.GetOutputPort("com"), com.featureDes.GetInputPort("value_in"))
        connect(pg.GetOutputPort("com_velocity"), com.featureDes.GetInputPort("velocity_in"))
    tasks[com.task.name] = com
    six_d("Head", "head", spec.head, "110000", "right_foot_pose", "right_foot_velocity", posture_gain)
    six_d("WaistOr", "waist", spec.waist, "100000", "waist_pose", "waist_velocity", posture_gain)
    if arms == "posture":
        # walkromeo's taskPosition: the arm joints towards half-sitting, at the bottom of the stack.
        posture = MetaTaskKinePosture(bot, "Arms")
        plant = model.plant
        selected = np.zeros(bot.dimension, dtype=bool)
        for j in plant.GetJointIndices():
            joint = plant.get_joint(j)
            if joint.num_velocities() == 1 and ARM_JOINTS.search(joint.name()):
                selected[joint.velocity_start()] = True
        posture.feature.selec("".join("1" if b else "0" for b in reversed(selected)))
        posture.gain.set(*ARM_POSTURE_GAIN)
        tasks[posture.task.name] = posture
    elif solver == "hqp":
        for name, wrist in zip(("ArmL", "ArmR"), spec.wrists, strict=False):
            arm = MetaTaskKine6dRel(name, bot, name.lower(), "waist", wrist, spec.waist, inequality=True)
            # The desired relative pose without its rotation: the error's x is then along the
            # waist's x axis, e = x_wrist - x_wrist(0) in the waist frame.
            arm.featureDes.setPosition(arm.featureDes.settings().position.translation())
            arm.feature.selec("000001")
            arm.task.setBounds([-ARM_BACKWARD_MARGIN], [np.inf])
            arm.gain.setConstant(posture_gain)
            tasks[arm.task.name] = arm
    for name in tasks:
        sot.push(name)

    tracer = Tracer(builder, dt)
    tracer.add(bot.device.GetOutputPort("state"), "q_device")
    for port in ("com", "com_velocity", "com_acceleration", "zmp_reference", "feet", "support_phase", "velocity_command"):
        tracer.add(pg.GetOutputPort(port), f"pg_{port}")
    visualizer = None
    if physical is not None:
        from sotdrake.physics import ContactMonitor, DesiredState

        plant = physical.plant
        desired = bot.add(DesiredState(physical))
        connect(bot.device.GetOutputPort("state"), desired.GetInputPort("position"))
        control = bot.limitator if bot.limitator is not None else sot  # the command the device integrates
        connect(control.GetOutputPort("control"), desired.GetInputPort("velocity"))
        connect(desired.get_output_port(), plant.get_desired_state_input_port(physical.instance))
        monitor = bot.add(ContactMonitor(physical))
        connect(plant.get_contact_results_output_port(), monitor.get_input_port())
        if servos.feedforward:
            feedforward = bot.add(GravityFeedforward(model, physical.actuated_v, spec.feet, pg.gait.sole_centre), "feedforward_torque")
            connect(bot.device.GetOutputPort("state"), feedforward.GetInputPort("position"))
            connect(pg.GetOutputPort("zmp_reference"), feedforward.GetInputPort("zmp_reference"))
            # (f_left, f_right, cop) → the normal forces (the CoP is NaN in the air: selected out, not multiplied by 0).
            split = bot.add(Demultiplexer([2, 1, 2, 1, 2]), "sole_forces")
            normal = bot.add(Multiplexer([1, 1]), "sole_normal_forces")
            connect(monitor.GetOutputPort("feet"), split.get_input_port())
            connect(split.get_output_port(1), normal.get_input_port(0))
            connect(split.get_output_port(3), normal.get_input_port(1))
            connect(normal.get_output_port(), feedforward.GetInputPort("normal_forces"))
            tracer.add(feedforward.get_output_port(), "feedforward_torque")
        else:
            feedforward = bot.add(ConstantVectorSource(np.zeros(plant.num_actuated_dofs(physical.instance))), "feedforward_torque")
        connect(feedforward.get_output_port(), plant.get_actuation_input_port(physical.instance))
        tracer.add(plant.get_state_output_port(), "x_plant")
        tracer.add(monitor.GetOutputPort("feet"), "contact")
        if stabilizer is not None:
            measured = bot.add(MeasuredCom(model))
            connect(plant.get_state_output_port(), measured.GetInputPort("state"))
            connect(measured.GetOutputPort("com"), stabilizer.GetInputPort("measured_com"))
            cop = bot.add(Demultiplexer([6, 2]), "cop")
            connect(monitor.GetOutputPort("feet"), cop.get_input_port())
            connect(cop.get_output_port(1), stabilizer.GetInputPort("measured_cop"))
            tracer.add(stabilizer.GetOutputPort("offset"), "stabilizer_offset")
        if meshcat is not None:
            from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams

            visualizer = MeshcatVisualizer.AddToBuilder(builder, physical.scene_graph, meshcat,
                                                        MeshcatVisualizerParams(publish_period=1 / 60))
    elif meshcat is not None:
        from sotdrake.visualization import add_robot_visualizer

        visualizer = add_robot_visualizer(bot, meshcat)
    if meshcat is not None:
        meshcat.SetCameraPose(camera_in_world=[1.5, -2.5, 1.4], target_in_world=[0.6, 0.0, 0.7])
    diagram = builder.Build()
    diagram.set_name("walk")
    return Walk(diagram, bot, pg, sot, tasks, tracer, mode, spec, robot, physical, commands, visualizer,
                servos if physical is not None else None)


#: Dynamic mode: gains (1/s²) of the CoM, the feet and the posture (``TaskDynPD``, ``K_v = 2√K_p``).
DYNAMIC_GAINS = {"com": 100.0, "feet": 400.0, "waist": 100.0, "posture": 25.0}
#: Dynamic mode: the contacts' friction coefficient, below the plant's (0.8): the solver keeps the
#: soles' yaw torque (bounded by μ · r · f_z) and tangential forces away from what makes them slip.
DYNAMIC_FRICTION = 0.3
#: Dynamic mode's swing profile: ``'quintic'`` (zero acceleration at the lift-off and touch-down).
#: With the cubic the swing foot's forward acceleration jumps to 6 Δ/T² (4.9 m/s²) at the lift-off:
#: in that tick the stance sole's yaw torque jumps to ~9 N·m and its CoP 5 cm forward; the sole rolls
#: onto its toe, whose patch cannot hold that torque, and spins by up to 20 mrad (1.2 mm at its origin).
DYNAMIC_SWING_PROFILE = "quintic"


def _build_dynamic(robot: str, spec: WalkingRobot, steps: tuple[int, float] | None, dt: float, gait: GaitParameters,
                   meshcat: Meshcat | None) -> Walk:
    """``--mode dynamic``: ``SolverDyn`` drives the torque-controlled TALOS (no PD, closed loop on
    the plant's state). Both soles start as contacts (``addContact``); each step releases its foot's
    contact over the double support before the lift-off (``rmContact(contact, T_ds − dt)``) and adds it
    back at the touch-down (``addContact``), at the times of the plan (``attime``). Stack: the soles
    (6D, planned pose, velocity and acceleration), the CoM (planned position, velocity and
    acceleration), the waist's orientation (the plan's), the posture. ``gait``: its ``swing_profile``
    is the caller's (:func:`build_diagram` without a gait: :data:`DYNAMIC_SWING_PROFILE`)."""
    from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams

    from sotdrake.dynamics.meta_tasks_dyn import MetaTaskDyn6d, MetaTaskDynCom, MetaTaskDynPosture
    from sotdrake.dynamics.robot_dyn import RobotDyn
    from sotdrake.physics import ContactMonitor
    from sotdrake.walking import WalkCommand, initial_plan, replan

    if steps is None:
        raise InvalidInput("--mode dynamic walks a list of steps (--steps N --step-length L): the contact switches are "
                           "scheduled from the plan at build time")
    builder = DiagramBuilder()
    model = spec.load()
    bot = RobotDyn(builder, model, "physics", dt)
    sot, connect = bot.sot, builder.Connect
    sot.setControlSelection(bot.velocity_selection(excluding=list(spec.excluded)))
    contacts = {side: bot.add_contact(f"contact{side[0].upper()}F", frame) for side, frame in zip(SIDES, spec.feet, strict=True)}
    for contact in contacts.values():
        contact.setFriction(DYNAMIC_FRICTION)
        sot.addContact(contact)
    start = start_of(bot.dynamic, bot.q0, spec.feet, spec.waist)
    pg = bot.add(PatternGenerator(start, dt, gait))
    pg.setSteps([(steps[1], 0.0, 0.0)] * int(steps[0]))
    tasks: dict = {}
    for side, frame in zip(SIDES, spec.feet, strict=True):
        name = f"{side[0].upper()}F"
        foot = MetaTaskDyn6d(name, bot, f"{side}-foot", frame, kp=DYNAMIC_GAINS["feet"])
        connect(pg.GetOutputPort(f"{side}_foot_pose"), foot.featureDes.GetInputPort("pose_in"))
        connect(pg.GetOutputPort(f"{side}_foot_velocity"), foot.featureDes.GetInputPort("spatial_velocity_in"))
        # The task's rows are (translation, rotation): the plan's (ω̇, p̈) swapped.
        split = bot.add(Demultiplexer([3, 3]), f"{side}_foot_acceleration_split")
        swap = bot.add(Multiplexer([3, 3]), f"{side}_foot_reference_acceleration")
        connect(pg.GetOutputPort(f"{side}_foot_acceleration"), split.get_input_port())
        connect(split.get_output_port(1), swap.get_input_port(0))
        connect(split.get_output_port(0), swap.get_input_port(1))
        connect(swap.get_output_port(), foot.task.GetInputPort("reference_acceleration"))
        tasks[foot.task.name] = foot
    waist = MetaTaskDyn6d("Waist", bot, "waist", spec.waist, kp=DYNAMIC_GAINS["waist"])
    waist.feature.selec("111000")  # its orientation: the plan's (level, turned with the feet)
    connect(pg.GetOutputPort("waist_pose"), waist.featureDes.GetInputPort("pose_in"))
    connect(pg.GetOutputPort("waist_velocity"), waist.featureDes.GetInputPort("spatial_velocity_in"))
    com = MetaTaskDynCom(bot, kp=DYNAMIC_GAINS["com"])
    connect(pg.GetOutputPort("com"), com.featureDes.GetInputPort("value_in"))
    connect(pg.GetOutputPort("com_velocity"), com.featureDes.GetInputPort("velocity_in"))
    connect(pg.GetOutputPort("com_acceleration"), com.task.GetInputPort("reference_acceleration"))
    tasks[com.task.name] = com
    tasks[waist.task.name] = waist
    posture = MetaTaskDynPosture(bot, kp=DYNAMIC_GAINS["posture"])
    tasks[posture.task.name] = posture
    for name in tasks:
        sot.push(name)
    # The contact switches, at the plan's times (the plan the pattern generator makes at t = 0).
    plan = replan(initial_plan(start, gait, pg.input_cost), WalkCommand(steps=pg.settings().command.steps), 0.0, gait, pg.input_cost)
    commands = []
    # The release starts a tick after the other foot's touch-down (commands at one time all see
    # the contact set before them) and ends at the lift-off.
    ramp = gait.double_support - dt
    for step in plan.steps:
        contact = contacts[step.side]
        commands.append(attime(step.liftoff - ramp, lambda c=contact: sot.rmContact(c, ramp), f"rmContact {contact.name}"))
        commands.append(attime(step.touchdown, lambda c=contact: sot.addContact(c), f"addContact {contact.name}"))
    monitor = bot.add(ContactMonitor(bot.physical))
    connect(bot.physical.plant.get_contact_results_output_port(), monitor.get_input_port())
    tracer = Tracer(builder, dt)
    tracer.add(bot.state_port, "x_plant")
    tracer.add(monitor.GetOutputPort("feet"), "contact")
    tracer.add(sot.GetOutputPort("torque"), "torque")
    for port in ("com", "com_velocity", "com_acceleration", "zmp_reference", "feet", "support_phase", "velocity_command"):
        tracer.add(pg.GetOutputPort(port), f"pg_{port}")
    visualizer = None
    if meshcat is not None:
        visualizer = MeshcatVisualizer.AddToBuilder(builder, bot.physical.scene_graph, meshcat,
                                                    MeshcatVisualizerParams(publish_period=1 / 60))
        meshcat.SetCameraPose(camera_in_world=[1.5, -2.5, 1.4], target_in_world=[0.6, 0.0, 0.7])
    diagram = builder.Build()
    diagram.set_name("walk")
    return Walk(diagram, bot, pg, sot, tasks, tracer, "dynamic", spec, robot, bot.physical, commands, visualizer)


# --- post-processing ------------------------------------------------------------------------
def _planar(poses: np.ndarray) -> np.ndarray:
    """(k, 4, 4) poses → (k, 3) ``(x, y, yaw)``."""
    return np.column_stack([poses[:, 0, 3], poses[:, 1, 3], np.unwrap(np.arctan2(poses[:, 1, 0], poses[:, 0, 0]))])


def _segment_velocity(t, base, plan, t0, t1, gait: GaitParameters) -> tuple[np.ndarray, float, float] | None:
    """Mean realised velocity ``(vx, vy, ω)`` (walking frame at the window's start) of the base
    over a whole, even number of steps inside ``[t0, t1]``: between touch-downs, from the second
    step after ``t0 + start_duration`` (a new command applies from the next step)."""
    touchdowns = [s.touchdown for s in plan.steps if t0 + gait.start_duration + 2 * gait.step_duration <= s.touchdown <= t1]
    if len(touchdowns) < 3:
        return None
    a, b = touchdowns[0], touchdowns[-1 - (len(touchdowns) - 1) % 2]
    ia, ib = np.searchsorted(t, a), np.searchsorted(t, b)
    return _mean_velocity(base[ia], base[ib], b - a), a, b


def _mean_velocity(start, end, duration: float) -> np.ndarray:
    """``(vx, vy, ω)`` from base poses ``(x, y, yaw)`` at the same phase of the gait ``duration``
    apart: the displacement in the walking frame at mid-turn, the chord of a circular arc turned
    into its length (``arc = chord · (Δθ/2) / sin(Δθ/2)``)."""
    turn = end[2] - start[2]
    heading = start[2] + turn / 2
    c, s = np.cos(heading), np.sin(heading)
    dx, dy = end[:2] - start[:2]
    chord_to_arc = 1.0 if abs(turn) < 1e-9 else (turn / 2) / np.sin(turn / 2)
    return np.array([c * dx + s * dy, -s * dx + c * dy, turn]) * np.array([chord_to_arc, chord_to_arc, 1.0]) / duration


def _stretches(flags: np.ndarray) -> list[np.ndarray]:
    """The index ranges where ``flags`` is True, each as an array of indices."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], flags.astype(int), [0]])))
    return [np.arange(a, b) for a, b in zip(edges[::2], edges[1::2], strict=False)]


def summarize(walk: Walk, simulator, duration: float, wall: float, then=None) -> tuple[dict, dict]:
    context = simulator.get_context()
    trace = walk.tracer.data(context)
    bot, spec, gait = walk.robot, walk.spec, walk.pg.gait
    nq = bot.model.nq
    physics = walk.mode in ("physics", "dynamic")
    qs = trace["x_plant"][:, :nq] if physics else trace["q_device"]
    t = trace["time"]
    path = bot.dynamic.trajectory([spec.feet[0], spec.feet[1], spec.waist], qs)
    plan = walk.pg.plan(context)
    feet_ref = trace["pg_feet"]
    # Each tick's q (logged after its update) is what the next tick's tasks see: compare q[k]
    # with the references at k + 1.
    foot_errors = np.concatenate([np.linalg.norm(path[spec.feet[i]][:-1, :3, 3] - feet_ref[1:, 4 * i : 4 * i + 3], axis=1)
                                  for i in range(2)])
    com_error = np.linalg.norm(path["com"][:-1, :2] - trace["pg_com"][1:, :2], axis=1)
    # Planned ZMP (of the planned CoM) and reference against the planned support polygons.
    zmp_planned = trace["pg_com"][:, :2] - trace["pg_com"][:, 2:3] / GRAVITY * trace["pg_com_acceleration"][:, :2]
    polygons = [plan.support_polygon(tk, gait) for tk in t]
    zmp_margin = np.array([polygon_margin(z, P) for z, P in zip(zmp_planned, polygons, strict=False)])
    ref_margin = np.array([polygon_margin(z, P) for z, P in zip(trace["pg_zmp_reference"], polygons, strict=False)])
    base = _planar(path[spec.waist])
    base_z = path[spec.waist][:, 2, 3]
    fall = fall_report(t, tilt_of_rotations(path[spec.waist]), base_z)  # (the soles move: no slip criterion)
    # The planned base: the planned CoM plus the start's base-to-CoM offset (turned with the feet).
    q0 = bot.q0 if walk.mode == "dynamic" else bot.device.initial_position
    offset0 = bot.dynamic.pose_at(spec.waist, q0).translation()[:2] - bot.dynamic.com_at(q0)[:2]
    yaw_ref = 0.5 * (feet_ref[-1, 3] + feet_ref[-1, 7]) - 0.5 * (feet_ref[0, 3] + feet_ref[0, 7])
    c, s = np.cos(yaw_ref), np.sin(yaw_ref)
    planned_base = trace["pg_com"][-1, :2] + np.array([c * offset0[0] - s * offset0[1], s * offset0[0] + c * offset0[1]])
    final_error = float(np.linalg.norm(base[-1, :2] - planned_base))
    # Slip: how far each sole moves (xy) while it stands: kinematic, over each planned stance
    # (touch-down to the next lift-off); physics, over each stretch where it carries more than
    # SLIP_LOAD_N (a sole that lands early, late or bounces moves in the air: a tracking error).
    slips = []
    for i, side in enumerate(("left", "right")):
        xy = path[spec.feet[i]][:, :2, 3]
        if physics:
            stretches = _stretches(trace["contact"][:, 2 + 3 * i] > SLIP_LOAD_N)
        else:
            landings = [0.0] + [st.touchdown for st in plan.steps if st.side == side]
            liftoffs = [st.liftoff for st in plan.steps if st.side == side] + [np.inf]
            stretches = [np.flatnonzero((t >= down) & (t <= up)) for down, up in zip(landings, liftoffs, strict=False)]
        slips += [float(np.linalg.norm(xy[k] - xy[k[0]], axis=1).max()) for k in stretches if k.size > 1]
    summary = {
        "robot": walk.robot_name,
        "mode": walk.mode,
        "solver": type(walk.sot).__name__,
        **fall,
        "max_foot_tracking_error_m": float(foot_errors.max()),
        "max_com_tracking_error_m": float(com_error.max()),
        "min_zmp_margin_m": float(zmp_margin.min()),
        "min_zmp_reference_margin_m": float(ref_margin.min()),
        "max_zmp_planned_minus_reference_m": float(np.linalg.norm(zmp_planned - trace["pg_zmp_reference"], axis=1)[1:].max()),
        "final_position_error_m": final_error,
        "max_slip_per_step_m": max(slips) if slips else 0.0,
        "steps": int(sum(1 for st in plan.steps if st.touchdown <= t[-1])),
        "input_cost": walk.pg.input_cost,
    }
    # The multibody ZMP of the motion the SoT commands (the device's q, Drake's momentum), every
    # 10 ticks from the first lift-off: how far the whole body's ZMP strays from the reference.
    liftoffs = [st.liftoff for st in plan.steps]
    walking = np.flatnonzero(t >= liftoffs[0])[::10] if liftoffs else np.array([], dtype=int)
    if walking.size >= 5 and "q_device" in trace:  # (the dynamic walk traces no device)
        device_zmp, _ = motion_zmp(bot.model.plant, t[walking], trace["q_device"][walking][:, :nq])
        error = np.linalg.norm(device_zmp - trace["pg_zmp_reference"][walking], axis=1)[2:-2]  # (one-sided differences at the ends)
        summary["max_multibody_zmp_minus_reference_m"] = float(error.max())
        summary["multibody_zmp_correction"] = walk.pg.legs is not None
    change = then[0] if then is not None else duration
    segments = [(0.0, change, trace["pg_velocity_command"][0])]
    if then is not None:
        segments.append((change, duration, np.asarray(then[1:], dtype=float)))
    ratios = []
    for t0, t1, command in segments:
        measured = _segment_velocity(t, base, plan, t0, t1, gait)
        if measured is None or not np.any(command):
            ratios.append(None)
            continue
        v, a, b = measured
        linear = np.linalg.norm(command[:2])
        ratio = float(np.linalg.norm(v[:2] - command[:2]) / linear) if linear else None
        ratios.append({"command": command.tolist(), "realised": v.tolist(), "window_s": [a, b], "linear_ratio": ratio,
                       "yaw_rate_ratio": abs(v[2] - command[2]) / abs(command[2]) if command[2] else None})
    summary["velocity_error_ratio"] = ratios[0]["linear_ratio"] if ratios[0] else None
    summary["velocity_segments"] = ratios
    if physics:
        contact = trace["contact"]
        loaded = np.column_stack([contact[:, 2] > 20.0, contact[:, 5] > 20.0])
        soles = [_planar(path[spec.feet[i]]) for i in range(2)]
        cop_margin = [polygon_margin(contact[k, 6:8], support_polygon([soles[i][k] for i in range(2) if loaded[k, i]], gait))
                      for k in range(1, len(t)) if loaded[k].any() and np.all(np.isfinite(contact[k, 6:8]))]
        summary["min_cop_margin_m"] = float(min(cop_margin)) if cop_margin else None
        summary["servos"] = dataclasses.asdict(walk.servos) if walk.servos is not None else None
        trace["cop"] = contact[:, 6:8]
    else:
        summary["min_cop_margin_m"] = None  # no contact forces without physics
    summary.update(duration_s=duration, dt_s=bot.dt, wall_s=wall, realtime_factor=duration / wall)
    trace.update(base=base, com_realised=path["com"], zmp_planned=zmp_planned, zmp_margin=zmp_margin,
                 foot_error=np.column_stack(np.split(foot_errors, 2)), com_error=com_error)
    return summary, trace


def plot(walk: Walk, simulator, trace: dict, path: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon

    gait, plan = walk.pg.gait, walk.pg.plan(simulator.get_context())
    t = trace["time"]
    fig, axes = plt.subplots(2, 2, figsize=(14, 9))
    ax = axes[0, 0]
    poses = [plan.start.foot("left"), plan.start.foot("right")] + [(s.x, s.y, s.yaw) for s in plan.steps if s.touchdown <= t[-1]]
    for k, pose in enumerate(poses):
        ax.add_patch(Polygon(footprint(pose, gait), closed=True, fill=False, color="C0" if k % 2 == 0 else "C3", lw=0.8))
    ax.plot(trace["pg_zmp_reference"][:, 0], trace["pg_zmp_reference"][:, 1], "k--", lw=0.8, label="ZMP reference")
    ax.plot(trace["zmp_planned"][:, 0], trace["zmp_planned"][:, 1], "g", lw=0.8, label="ZMP of the planned CoM")
    ax.plot(trace["pg_com"][:, 0], trace["pg_com"][:, 1], "b", lw=1.2, label="CoM planned")
    ax.plot(trace["com_realised"][:, 0], trace["com_realised"][:, 1], "m:", lw=1.2, label="CoM realised")
    if "cop" in trace:
        ax.plot(trace["cop"][:, 0], trace["cop"][:, 1], ".", color="orange", ms=0.6, label="CoP (physics)")
    ax.set_aspect("equal")
    ax.set_title("footprints, CoM and ZMP")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=7)
    ax = axes[0, 1]
    ax.plot(t, trace["zmp_margin"], label="planned ZMP margin in the support polygon")
    ax.axhline(0.02, color="grey", ls=":", lw=0.8)
    ax.set_ylabel("margin (m)")
    ax.set_xlabel("time (s)")
    ax.set_title("planned ZMP margin (dotted: the 2 cm target)")
    ax.legend(fontsize=7)
    ax = axes[1, 0]
    window = max(1, round(2 * gait.step_duration / walk.robot.dt))  # a left and a right step: the sway cancels
    base = trace["base"]
    if len(base) > window:
        rate = (base[window:] - base[:-window]) / (window * walk.robot.dt)
        yaw = base[:-window, 2]
        forward = np.cos(yaw) * rate[:, 0] + np.sin(yaw) * rate[:, 1]
        lateral = -np.sin(yaw) * rate[:, 0] + np.cos(yaw) * rate[:, 1]
        tm = t[:-window] + 0.5 * window * walk.robot.dt
        ax.plot(tm, forward, "C0", label="realised vx (mean over two steps)")
        ax.plot(tm, lateral, "C1", label="realised vy")
        ax.plot(tm, rate[:, 2], "C2", label="realised ω")
        planned = (trace["pg_com"][window:, :2] - trace["pg_com"][:-window, :2]) / (window * walk.robot.dt)
        ax.plot(tm, np.cos(yaw) * planned[:, 0] + np.sin(yaw) * planned[:, 1], "k:", lw=1.0,
                label="planned vx (the CoM plan, mean over two steps)")
    command = trace["pg_velocity_command"]
    if np.any(command):  # a velocity command (a list of footsteps has none)
        for i, name in enumerate(("vx", "vy", "ω")):
            ax.plot(t, command[:, i], f"C{i}--", lw=0.8, label=f"commanded {name}")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("m/s, rad/s")
    ax.set_title("commanded, planned and realised velocity (base frame)")
    ax.legend(fontsize=7)
    ax = axes[1, 1]
    ax.semilogy(t[1:], np.maximum(trace["foot_error"], 1e-9), label=["left sole", "right sole"])
    ax.semilogy(t[1:], np.maximum(trace["com_error"], 1e-9), label="CoM xy")
    ax.axhline(1e-3, color="grey", ls=":", lw=0.8)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("tracking error (m)")
    ax.set_title("feet and CoM tracking (dotted: 1 mm)")
    ax.legend(fontsize=7)
    fig.suptitle(f"walk: {walk.robot_name}, {walk.mode} mode, {len(poses) - 2} steps shown")
    return save_figure(fig, path)


def main(argv: list[str] | None = None) -> dict:
    parser = script_arguments(__doc__, "out/walk", duration=15.0)
    parser.add_argument("--robot", choices=sorted(ROBOTS), default="talos")
    parser.add_argument("--velocity", type=float, nargs=3, default=(0.1, 0.0, 0.0), metavar=("X", "Y", "THETA"))
    parser.add_argument("--then", type=float, nargs=4, default=None, metavar=("T", "X", "Y", "THETA"),
                        help="pg.setVelocity(X, Y, THETA) at time T")
    parser.add_argument("--steps", type=int, default=None, help="walk this many steps instead of a velocity")
    parser.add_argument("--step-length", type=float, default=0.2, help="with --steps: advance per step (m)")
    parser.add_argument("--mode", choices=MODES, default="kinematic")
    parser.add_argument("--solver", choices=["hqp", "cascade"], default="hqp")
    parser.add_argument("--gains", type=float, nargs=2, default=(TRACKING_GAIN, POSTURE_GAIN), metavar=("TRACKING", "ORIENTATION"),
                        help=f"the tracking and orientation gains (1/s; walkromeo's: {SEED_GAINS[0]:g} {SEED_GAINS[1]:g})")
    parser.add_argument("--arms", choices=ARMS, default="posture",
                        help="posture: walkromeo's, the arm joints held at half-sitting; inequality: the wrists kept from "
                             "moving backward (hqp only)")
    parser.add_argument("--step-duration", type=float, default=None, help="a step's duration (s; default 0.8, as walkromeo)")
    parser.add_argument("--single-support", type=float, default=None, help="its single support (s; default 0.7)")
    parser.add_argument("--landing-depth", type=float, default=None, help="the swing ends this far below the ground (m; default 0)")
    parser.add_argument("--swing-profile", choices=["cubic", "quintic"], default=None,
                        help="the swing's profile (default: quintic in dynamic mode, else cubic)")
    defaults = Servos()
    parser.add_argument("--stiffness", type=float, default=defaults.stiffness, help="physics: servo kp = STIFFNESS · effort limit (1/rad)")
    parser.add_argument("--damping", type=float, default=defaults.damping, help="physics: servo kd = DAMPING · kp (s)")
    parser.add_argument("--feedforward", action="store_true", help="physics: the static feed-forward torque in the servos")
    parser.add_argument("--com-gain", type=float, default=defaults.com_gain, help="physics: the stabiliser's CoM gain k_c (1/s; 0: none)")
    parser.add_argument("--zmp-gain", type=float, default=defaults.zmp_gain, help="physics: the stabiliser's ZMP gain k_z (1/s)")
    parser.add_argument("--closed-loop", action="store_true", help="physics: the SoT reads the plant's q (perfect estimation)")
    parser.add_argument("--zmp-model", choices=["lipm", "multibody"], default=None,
                        help="the CoM plan: the pendulum alone, or with the legs' momentum (default: multibody in physics mode)")
    args = parser.parse_args(argv)
    meshcat = start(args)
    steps = (args.steps, args.step_length) if args.steps else None
    servos = Servos(args.stiffness, args.feedforward, args.com_gain, args.zmp_gain, args.closed_loop, args.damping)
    gait = ROBOTS[args.robot].gait
    if args.step_duration is not None or args.single_support is not None:
        duration = args.step_duration or gait.step_duration
        gait = dataclasses.replace(gait, step_duration=duration,
                                   single_support=args.single_support or duration - gait.double_support)
    if args.landing_depth is not None:
        gait = dataclasses.replace(gait, landing_depth=args.landing_depth)
    if args.swing_profile is not None or args.mode == "dynamic":
        gait = dataclasses.replace(gait, swing_profile=args.swing_profile or DYNAMIC_SWING_PROFILE)
    walk = build_diagram(args.robot, args.velocity, args.then, steps, args.mode, args.solver, gait=gait, meshcat=meshcat,
                         servos=servos, multibody_zmp=None if args.zmp_model is None else args.zmp_model == "multibody",
                         arms=args.arms, gains=tuple(args.gains))
    simulator, wall = simulate(walk.diagram, args.duration, walk.visualizer, not args.quiet)
    summary, trace = summarize(walk, simulator, args.duration, wall, args.then)
    args.out.mkdir(parents=True, exist_ok=True)
    plot(walk, simulator, trace, args.out / "plots.png")
    write_run(args.out, walk.diagram, summary, trace, meshcat, walk.visualizer, bag=args.bag)
    print(json.dumps({k: v for k, v in summary.items() if k != "outputs"}, indent=2))
    return summary


if __name__ == "__main__":
    main()
