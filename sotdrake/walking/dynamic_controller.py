"""The walking controller's ``'dynamic'`` mode: ``SolverDyn`` drives the torque-controlled TALOS,
the soles' contacts released and added back at each step at the plan's times (see
:func:`build_dynamic`)."""

from __future__ import annotations

from functools import partial

from pydrake.geometry import Meshcat
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Demultiplexer, Multiplexer

from sotdrake import Tracer, attime
from sotdrake.exceptions import InvalidInput

from .controller import SIDES, Walk, WalkingRobot
from .gait import GaitParameters
from .pattern_generator import PatternGenerator, start_of

#: Dynamic mode: gains (1/s²) of the CoM, the feet and the posture (``TaskDynPD``, ``K_v = 2√K_p``).
DYNAMIC_GAINS = {"com": 100.0, "feet": 400.0, "waist": 100.0, "posture": 25.0}
#: Dynamic mode: the contacts' friction coefficient, below the plant's (0.8): the solver keeps the
#: soles' yaw torque (bounded by μ · r · f_z) and tangential forces away from what makes them slip.
DYNAMIC_FRICTION = 0.3


def build_dynamic(robot: str, spec: WalkingRobot, steps: tuple[int, float] | None, dt: float, gait: GaitParameters,
                   meshcat: Meshcat | None) -> Walk:
    """``--mode dynamic``: ``SolverDyn`` drives the torque-controlled TALOS (no PD, closed loop on
    the plant's state). Both soles start as contacts (``addContact``); each step releases its foot's
    contact over the double support before the lift-off (``rmContact(contact, T_ds − dt)``) and adds it
    back at the touch-down (``addContact``), at the times of the plan (``attime``). Stack: the soles
    (6D, planned pose, velocity and acceleration), the CoM (planned position, velocity and
    acceleration), the waist's orientation (the plan's), the posture. ``gait``: its ``swing_profile``
    is the caller's (:func:`~sotdrake.walking.controller.build_diagram` without a gait: :data:`DYNAMIC_SWING_PROFILE`)."""
    from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams

    from sotdrake.dynamics.robot_dyn import RobotDyn
    from sotdrake.physics import ContactMonitor

    from .plan import WalkCommand, initial_plan, replan

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
    tasks = _dynamic_stack(bot, pg, spec)
    # The contact switches, at the plan's times (the plan the pattern generator makes at t = 0).
    plan = replan(initial_plan(start, gait, pg.input_cost), WalkCommand(steps=pg.settings().command.steps), 0.0, gait, pg.input_cost)
    commands = []
    # The release starts a tick after the other foot's touch-down (commands at one time all see
    # the contact set before them) and ends at the lift-off.
    ramp = gait.double_support - dt
    for step in plan.steps:
        contact = contacts[step.side]
        commands.append(attime(step.liftoff - ramp, partial(sot.rmContact, contact, ramp), f"rmContact {contact.name}"))
        commands.append(attime(step.touchdown, partial(sot.addContact, contact), f"addContact {contact.name}"))
    physical = bot.physical
    assert physical is not None  # (built on the physics device)
    monitor = bot.add(ContactMonitor(physical))
    connect(physical.plant.get_contact_results_output_port(), monitor.get_input_port())
    tracer = Tracer(builder, dt)
    tracer.add(bot.state_port, "x_plant")
    tracer.add(monitor.GetOutputPort("feet"), "contact")
    tracer.add(sot.GetOutputPort("torque"), "torque")
    for port in ("com", "com_velocity", "com_acceleration", "zmp_reference", "feet", "support_phase", "velocity_command"):
        tracer.add(pg.GetOutputPort(port), f"pg_{port}")
    visualizer = None
    if meshcat is not None:
        visualizer = MeshcatVisualizer.AddToBuilder(builder, physical.scene_graph, meshcat,
                                                    MeshcatVisualizerParams(publish_period=1 / 60))
        meshcat.SetCameraPose(camera_in_world=[1.5, -2.5, 1.4], target_in_world=[0.6, 0.0, 0.7])
    diagram = builder.Build()
    diagram.set_name("walk")
    return Walk(diagram, bot, pg, sot, tasks, tracer, "dynamic", spec, robot, bot.physical, commands, visualizer)


def _dynamic_stack(bot, pg: PatternGenerator, spec: WalkingRobot) -> dict:
    """The dynamic walk's stack, pushed in priority order, its references read from ``pg``: the
    soles (6D: planned pose, velocity and acceleration), the CoM (planned position, velocity and
    acceleration), the waist's orientation, the posture. Returns the meta tasks by task name."""
    from sotdrake.dynamics.meta_tasks_dyn import MetaTaskDyn6d, MetaTaskDynCom, MetaTaskDynPosture

    sot, connect = bot.sot, bot.builder.Connect
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
    return tasks
