"""The walking controller of ``diagrams/walk.py``: the seed's walkromeo stack fed by the
:class:`~sotdrake.walking.pattern_generator.PatternGenerator`, assembled for one of three modes
(:data:`MODES`).

``build_diagram(robot, velocity | steps, mode, ...)`` returns a :class:`Walk` (the diagram, its
robot, pattern generator, solver, tasks and tracer). The stack, in priority order: the waist's
height, roll and pitch (``'011100'``), both soles in 6D, the CoM in x, y (``'011'``, the planned
CoM velocity fed forward), then the head's pitch and yaw following the right foot, the waist's yaw
and the arms (a posture task at half-sitting, or with ``arms='inequality'`` both wrists kept from
moving backward relative to the waist). Every moving target comes with its velocity.

- ``'kinematic'``: the SoT integrates its velocity at 1 kHz (no dynamics).
- ``'physics'``: the same graph drives the physically simulated TALOS through position servos
  (:class:`Servos`: PD gains, static feed-forward, the CoM/ZMP stabiliser), the CoM planned with
  the legs' momentum by default (:mod:`sotdrake.walking.multibody_zmp`).
- ``'dynamic'``: ``SolverDyn`` drives the torque-controlled TALOS (:mod:`.dynamic_controller`).

Adding a robot is adding an entry to :data:`ROBOTS`.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

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
    load_robot,
    load_talos,
)
from sotdrake.exceptions import InvalidInput, check_finite
from sotdrake.robots import RobotModel

from .gait import MAX_STEPS, GaitParameters
from .gravity_feedforward import GravityFeedforward
from .measured_com import MeasuredCom
from .multibody_zmp import leg_masses
from .pattern_generator import PatternGenerator, start_of
from .plan import MAX_TIME
from .stabilizer import ComStabilizer


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
#: The velocity command (m/s, m/s, rad/s) of a walk given neither a velocity nor steps.
VELOCITY = (0.1, 0.0, 0.0)
#: Task gains (1/s): the tracked references (waist, soles, CoM), and the lower-priority orientations
#: (head, waist yaw, arms). walkromeo's were 40 (soles, waist yaw) and 5 (waist, head): with every
#: target's velocity fed forward the gain only corrects drift, and ``--gains 40 5`` tracks as well
#: (see the walk tutorial); 100/10 are kept so that the published runs stand.
TRACKING_GAIN = 100.0
POSTURE_GAIN = 10.0
SEED_GAINS = (40.0, 5.0)
#: How far (m) a wrist may move back, relative to the waist, from where it started.
ARM_BACKWARD_MARGIN = 0.01
#: What keeps the arms (``--arms``): ``posture`` (the default), walkromeo's ``taskPosition``, the arm
#: joints held at half-sitting by a posture task at the bottom of the stack (both solvers);
#: ``inequality``, the wrists kept from moving backward relative to the waist (``SolverKine`` only).
ARMS = ("posture", "inequality")
#: The arm joints (TALOS', Romeo's) of the ``posture`` arms.
ARM_JOINTS = re.compile(r"^arm_(left|right)_[1-7]_joint$|^[LR](Shoulder|Elbow|Wrist)")
#: walkromeo's gain of its arm posture (1/s): ``gainPosition.set(0.1, 0.1, 125e3)`` then
#: ``gainPosition.gain.value = 5``, which makes the gain's output the constant 5.
ARM_POSTURE_GAIN = 5.0
#: Dynamic mode's swing profile: ``'quintic'`` (zero acceleration at the lift-off and touch-down).
#: With the cubic the swing foot's forward acceleration jumps to 6 Δ/T² (4.9 m/s²) at the lift-off:
#: in that tick the stance sole's CoP jumps 5 cm forward, onto its toe, and the sole turns by about
#: 2 mrad (0.15 mm at its origin; the quintic: 0.15 mrad, 0.01 mm).
DYNAMIC_SWING_PROFILE = "quintic"


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
    robot: Any  # Robot; RobotDyn in dynamic mode
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


def _walking_robot(robot: str, mode: str, arms: str) -> WalkingRobot:
    """The entry of :data:`ROBOTS` for ``robot``, once ``mode`` and ``arms`` are checked."""
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
    return spec


def build_diagram(robot: str = "talos", velocity=None, then: tuple | None = None,
                  steps: tuple[int, float] | None = None, mode: str = "kinematic", solver: str = "hqp",
                  dt: float = 1e-3, gait: GaitParameters | None = None, meshcat: Meshcat | None = None,
                  servos: Servos | None = None, multibody_zmp: bool | None = None, arms: str = "posture",
                  gains: tuple[float, float] = (TRACKING_GAIN, POSTURE_GAIN)) -> Walk:
    """The walk's diagram. ``velocity``: the command from t = 0 (None: :data:`VELOCITY`); ``then``:
    ``(T, x, y, θ)``, a new command at T (at most 10⁶ s, the plans' end); ``steps``: ``(n, length)``
    instead of a velocity (both: :class:`InvalidInput`); ``solver``: ``'hqp'``
    (``SolverKine``) or ``'cascade'`` (walkromeo's ``Solver(robot)``: the basic ``SOT`` through a
    ``JointLimitator``; it takes no inequality: ``arms='inequality'`` is then left out);
    ``servos``: the physics mode's servo options (:class:`Servos`); ``multibody_zmp``: the CoM is
    planned with the legs' momentum (:func:`~sotdrake.walking.multibody_zmp.leg_masses`), kinematic
    and physics modes (None: in physics mode only); ``arms``: one of :data:`ARMS` (kinematic and
    physics modes); ``gains``: the tracking and the orientation gains (1/s), kinematic and physics modes.
    In dynamic mode (``SolverDyn``, a list of steps) ``then``, ``solver`` other than ``'hqp'``,
    ``multibody_zmp``, ``arms`` other than ``'posture'`` and ``gains`` other than the defaults are
    refused (:class:`InvalidInput` naming them), before anything is built, not ignored."""
    _check_commands(velocity, then, steps, gains)
    spec = _walking_robot(robot, mode, arms)
    if mode == "dynamic":
        _check_dynamic_options(then, solver, multibody_zmp, arms, gains)
        from .dynamic_controller import build_dynamic

        return build_dynamic(robot, spec, steps, dt, gait or dataclasses.replace(spec.gait, swing_profile=DYNAMIC_SWING_PROFILE), meshcat)
    builder = DiagramBuilder()
    model = spec.load()
    servos = servos or Servos()
    physical = None
    if mode == "physics":
        assert spec.add_physical is not None  # (checked above: physics mode needs a physical model)
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
        pg.setVelocity(*(VELOCITY if velocity is None else velocity))
    commands = []
    if then is not None:
        commands.append(attime(then[0], lambda: pg.setVelocity(*then[1:]), f"pg.setVelocity{tuple(then[1:])}"))

    # walkromeo's ``solver = Solver(robot)``: the basic SOT through a JointLimitator; the HQP holds the limits itself.
    sot = Solver(bot, "cascade", name="sot").sot if solver == "cascade" else add_sot(bot, "sot", solver=solver)
    sot.setControlSelection(bot.velocity_selection(excluding=list(spec.excluded)))
    tasks, stabilizer = _add_stack(bot, pg, sot, spec, arms, solver, gains,
                                   servos if physical is not None else None, legs is not None)

    tracer = Tracer(builder, dt)
    tracer.add(bot.device.GetOutputPort("state"), "q_device")
    for port in ("com", "com_velocity", "com_acceleration", "zmp_reference", "feet", "support_phase", "velocity_command"):
        tracer.add(pg.GetOutputPort(port), f"pg_{port}")
    visualizer = None
    if physical is not None:
        visualizer = _connect_physics(bot, sot, pg, spec, physical, servos, stabilizer, tracer, meshcat)
    elif meshcat is not None:
        from sotdrake.visualization import add_robot_visualizer

        visualizer = add_robot_visualizer(bot, meshcat)
    if meshcat is not None:
        meshcat.SetCameraPose(camera_in_world=[1.5, -2.5, 1.4], target_in_world=[0.6, 0.0, 0.7])
    diagram = builder.Build()
    diagram.set_name("walk")
    return Walk(diagram, bot, pg, sot, tasks, tracer, mode, spec, robot, physical, commands, visualizer,
                servos if physical is not None else None)


def _check_dynamic_options(then: tuple | None, solver: str, multibody_zmp: bool | None, arms: str,
                           gains: tuple[float, float]) -> None:
    """:class:`InvalidInput` naming the options of :func:`build_diagram` that the dynamic mode does
    not read (it walks a list of steps under ``SolverDyn``, its own stack)."""
    unread = [name for name, given in (("then (--then)", then is not None), ("solver (--solver)", solver != "hqp"),
                                       ("multibody_zmp (--zmp-model)", multibody_zmp is not None),
                                       ("arms (--arms)", arms != "posture"),
                                       ("gains (--gains)", tuple(gains) != (TRACKING_GAIN, POSTURE_GAIN))) if given]
    if unread:
        raise InvalidInput(f"build_diagram: {', '.join(unread)}: options of the kinematic and physics modes, not read by "
                           "mode='dynamic' (SolverDyn walks a list of steps with its own stack)")


def _check_commands(velocity, then: tuple | None, steps: tuple[int, float] | None, gains: tuple[float, float]) -> None:
    """The shapes of :func:`build_diagram`'s commands (their values are checked where they go)."""
    if velocity is not None and steps is not None:
        raise InvalidInput(f"build_diagram: velocity and steps: give one or the other (a walk at a velocity or a list of "
                           f"steps), got velocity={velocity!r:.60} and steps={steps!r:.60}")
    if velocity is not None:
        check_finite("build_diagram: velocity (x, y, θ)", velocity, (3,))
    check_finite("build_diagram: gains (tracking, orientation)", gains, (2,))
    if then is not None:
        check_finite("build_diagram: then (T, x, y, θ)", then, (4,))
    if steps is not None:
        check_finite("build_diagram: steps (n, length)", steps, (2,))
    if then is not None and not 0 <= then[0] <= MAX_TIME:
        raise InvalidInput(f"build_diagram: then's T must be in [0, {MAX_TIME:g}] s, got {then[0]!r}")
    if steps is not None and not (float(steps[0]).is_integer() and 1 <= steps[0] <= MAX_STEPS):
        raise InvalidInput(f"build_diagram: steps' n must be a whole number in [1, {MAX_STEPS}], got {steps[0]!r}")


def _add_stack(bot: Robot, pg: PatternGenerator, sot: SOT, spec: WalkingRobot, arms: str, solver: str,
               gains: tuple[float, float], servos: Servos | None, multibody: bool) -> tuple[dict, ComStabilizer | None]:
    """walkromeo's stack, pushed in priority order, its desired values read from ``pg``: the waist's
    height, roll and pitch, the soles, the CoM in x, y (through the CoM/ZMP stabiliser with the
    physics mode's ``servos``, when its CoM gain is not 0; ``multibody``: the stabiliser's ZMP
    reference is the plan's), the head, the waist's yaw and the arms. Returns the meta tasks by task
    name and the stabiliser (None without)."""
    connect = bot.builder.Connect
    tracking_gain, posture_gain = gains
    tasks: dict = {}

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
    if servos is not None and servos.com_gain:
        stabilizer = bot.add(ComStabilizer(pg.start.com[2], bot.dt, servos.com_gain, servos.zmp_gain))
        for port in ("com", "com_velocity", "com_acceleration"):
            connect(pg.GetOutputPort(port), stabilizer.GetInputPort(f"{port}_reference"))
        if multibody:  # the pendulum's ZMP of a multibody plan is off the reference, the CoP belongs on it
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
        plant = bot.model.plant
        selected = np.zeros(bot.dimension, dtype=bool)
        for j in plant.GetJointIndices():
            joint = plant.get_joint(j)
            if joint.num_velocities() == 1 and ARM_JOINTS.search(joint.name()):
                selected[joint.velocity_start()] = True
        posture.feature.selec("".join("1" if b else "0" for b in reversed(selected)))
        posture.gain.setConstant(ARM_POSTURE_GAIN)
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
    return tasks, stabilizer


def _connect_physics(bot: Robot, sot: SOT, pg: PatternGenerator, spec: WalkingRobot, physical, servos: Servos,
                     stabilizer: ComStabilizer | None, tracer: Tracer, meshcat: Meshcat | None):
    """The physics mode's plumbing: the device's ``q`` and the SoT's velocity (held one tick) as the
    servos' desired state, the feed-forward torque (:class:`Servos`), the contact monitor, the
    stabiliser's measured CoM and CoP, their traces; returns the Meshcat visualizer of the plant (None
    without ``meshcat``)."""
    from sotdrake.physics import ContactMonitor, DesiredState, hold_one_tick

    connect, model, plant = bot.builder.Connect, bot.model, physical.plant
    desired = bot.add(DesiredState(physical))
    connect(bot.device.GetOutputPort("state"), desired.GetInputPort("position"))
    control = bot.limitator if bot.limitator is not None else sot  # the command the device integrates
    # The plan is updated with the plant's step, before the device's update: the servos take the
    # command the device integrated at the last tick, held (one solve per tick).
    connect(hold_one_tick(bot.builder, control.GetOutputPort("control"), "held_velocity", bot.dt),
            desired.GetInputPort("velocity"))
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

        return MeshcatVisualizer.AddToBuilder(bot.builder, physical.scene_graph, meshcat,
                                              MeshcatVisualizerParams(publish_period=1 / 60))
    return None
