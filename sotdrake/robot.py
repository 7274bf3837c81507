"""The SoT ``robot`` object: a robot's ``dynamic`` and ``device`` in a ``DiagramBuilder``.

As in sot-talos (``robot = Robot('robot')``), creating it adds and plugs the kinematics entity
(``robot.dynamic``) and the kinematic device (``robot.device``: ``device.state → dynamic.position``).
It also keeps the build-time pool of the diagram's tasks and solvers, so that every task is
connected to every solver whichever is created first: ``sot.push(name)`` then only changes the
stack order, a run-time setting held in the Context.
"""

from __future__ import annotations

import weakref
from collections.abc import Sequence
from os import PathLike
from typing import Any, TypeVar

import numpy as np
from pydrake.lcm import DrakeLcm
from pydrake.systems.framework import DiagramBuilder, OutputPort, System

from .atomic import all_or_nothing, check_new_names
from .configuration import warn_beyond_limits
from .device import Device
from .exceptions import InvalidInput, NotFound, SotError, check_name, check_type
from .joint_limitator import JointLimitator
from .kinematics import Dynamic
from .robots import RobotModel, load_robot
from .solvers import SOT, SolverKine
from .solvers.base_velocity import velocity_limit_vector
from .solvers.kinematic import KinematicSolver
from .task import Task

SystemT = TypeVar("SystemT", bound=System)

#: The builder each system was added to through a robot (a system belongs to one diagram).
_BUILDER_OF: weakref.WeakKeyDictionary[System, weakref.ref[DiagramBuilder]] = weakref.WeakKeyDictionary()


def check_not_elsewhere(builder: DiagramBuilder, system: System, what: str) -> None:
    """:class:`InvalidInput` if ``system`` was added, through a robot, to another builder than
    ``builder`` (Drake would refuse the second diagram's ``Build()``)."""
    owner = _BUILDER_OF.get(system)
    if owner is not None and owner() is not None and owner() is not builder:
        raise InvalidInput(f"{what}: {system.get_name()!r} belongs to another robot's DiagramBuilder (a system is in "
                           "one diagram: make one of its own for this robot)")


def velocity_selection(plant, excluding: Sequence[str] = ()) -> np.ndarray:
    """``plant``'s nv booleans, False on the velocities of the joints named in ``excluding`` (a list
    of names: a string alone is refused, not read as its characters); :class:`NotFound` for a name
    the plant does not have."""
    mask = np.ones(plant.num_velocities(), dtype=bool)
    if isinstance(excluding, str):  # (one joint's name, not its characters)
        raise InvalidInput(f"velocity_selection: excluding is a list of joint names, got the string {excluding!r:.60}: "
                           f"give [{excluding!r:.60}]")
    for name in excluding:
        if not isinstance(name, str) or not plant.HasJointNamed(name):
            joints = [plant.get_joint(j).name() for j in plant.GetJointIndices()]
            raise NotFound(str(name), joints).but("velocity_selection: excluding")
        joint = plant.GetJointByName(name)
        mask[joint.velocity_start() : joint.velocity_start() + joint.num_velocities()] = False
    return mask


class Robot:
    """A robot's ``dynamic`` (:class:`~sotdrake.kinematics.Dynamic`) and ``device``
    (:class:`~sotdrake.device.Device`) in ``builder``, plugged ``device.state → dynamic.position``;
    ``Robot(builder, load_robot("arm.urdf"))`` for your own robot. Tasks and the solver are added
    through it (:meth:`add_task`, :meth:`add_solver`), so that each task reaches the solver."""

    def __init__(
        self,
        builder: DiagramBuilder,
        model: RobotModel,
        dt: float = 1e-3,
        q0: np.ndarray | None = None,
        measured_position: OutputPort | None = None,
    ):
        """``measured_position``: where the kinematics reads ``q`` (closed loop, e.g. a simulated
        robot's joints and estimated base); by default the device's own ``q`` (open loop)."""
        if not isinstance(builder, DiagramBuilder):
            raise InvalidInput(f"Robot: expected a DiagramBuilder, got {type(builder).__name__}")
        if builder.already_built():
            raise SotError("cannot add a robot: the diagram is already built (create the robot before builder.Build())")
        check_type("Robot: model", model, RobotModel, "a RobotModel (load_robot('arm.urdf'); for a robot by its name, "
                   "sotdrake.robot(builder, 'talos'))")
        if measured_position is not None:
            check_type("Robot: measured_position", measured_position, OutputPort, "an output port holding q (or None)")
        taken = {system.get_name() for system in builder.GetSystems()} & {"dynamic", "device"}
        if taken:
            raise InvalidInput(f"this builder already holds systems named {sorted(taken)} (another robot?): one robot per "
                               "DiagramBuilder (build each robot's graph in its own builder, or nest their diagrams)")
        self.builder = builder
        self.model = model
        self.OperationalPointsMap = model.OperationalPointsMap
        self.tasks: dict[str, Task] = {}
        self.solver: KinematicSolver | None = None
        self.limitator: JointLimitator | None = None  # between the solver and the device (Solver(robot))
        self._names: set[str] = set()
        self.lcm: DrakeLcm | None = None  # the publishers' LCM instance (sotdrake.publishing), made by the first of them
        device = Device(model.plant, dt, model.half_sitting if q0 is None else q0, "device")  # (checks dt and q0 first)
        if q0 is not None:
            warn_beyond_limits(model.plant, device.initial_position, "q0")
        with all_or_nothing(builder):  # (a measured_position that cannot be connected: the builder as it was)
            self.dynamic = self.add(Dynamic(model, "dynamic"))
            self.device = self.add(device)
            builder.Connect(measured_position or self.device.GetOutputPort("state"), self.dynamic.GetInputPort("position"))

    @property
    def dimension(self) -> int:
        """Size of the solver's variable (nv), sot-core's ``robot.dynamic.getDimension()``."""
        return self.model.nv

    @property
    def dt(self) -> float:
        return self.device.dt

    def velocity_selection(self, excluding: Sequence[str] = ()) -> np.ndarray:
        """nv booleans, False on the velocities of the joints named in ``excluding``."""
        return velocity_selection(self.model.plant, excluding)

    def check_new_names(self, names: list[str]) -> None:
        """:class:`InvalidInput` if an entity of one of ``names`` exists already, :class:`SotError`
        if the diagram is built (what :meth:`add` checks, for a caller that adds several entities
        and must refuse before adding any)."""
        check_new_names(self.builder, names, self._names)

    def add(self, system: SystemT, name: str | None = None) -> SystemT:
        """Add ``system`` to the builder under ``name`` (default: its own), which must be new; a
        system already in another robot's builder is refused."""
        check_type("add: system", system, System, "a Drake system (an entity, a LeafSystem)")
        if name is not None:
            check_name("add: name", name)
        check_not_elsewhere(self.builder, system, "add")
        name = system.get_name() if name is None else name
        if not name:
            raise InvalidInput(f"a {type(system).__name__} needs a name to be added")
        self.check_new_names([name])
        system.set_name(name)
        self._names.add(name)
        _BUILDER_OF[system] = weakref.ref(self.builder)
        return self.builder.AddNamedSystem(name, system)

    def add_task(self, task: Task) -> Task:
        """Add a task and connect it to the solver (now, or when the solver is created); refused
        (nothing added) when the solver could not take it."""
        if self.solver is not None:
            self.solver.check_task_input(task)
        self.add(task)
        self.tasks[task.name] = task
        if self.solver is not None:
            self._connect(task, self.solver)
        return task

    def _connect(self, task: Task, solver: KinematicSolver) -> None:
        """``task.task → solver``, and the solver's step bound to a task that reads it (the
        collision level: which pairs one tick can bring within reach)."""
        self.builder.Connect(task.GetOutputPort("task"), solver.declare_task_input(task))
        if task.HasInputPort("step_bound") and solver.HasOutputPort("step_bound"):
            self.builder.Connect(solver.GetOutputPort("step_bound"), task.GetInputPort("step_bound"))

    def add_solver(self, solver: KinematicSolver, limitator: JointLimitator | None = None) -> KinematicSolver:
        """Add the solver, plug ``solver.control → device.control`` and connect every task.

        With a ``limitator`` (:class:`~sotdrake.joint_limitator.JointLimitator`, added here too):
        ``solver.control → limitator.control_in``, ``limitator.control → device.control`` and
        ``device.state → limitator.position``, as sot-core's ``Solver`` wrapper plugs it."""
        if self.solver is not None:
            raise InvalidInput(f"{self.solver.name} already drives the device")
        if limitator is not None and limitator.layout.nv != self.dimension:
            raise InvalidInput(f"limitator {limitator.name!r} is for nv = {limitator.layout.nv}, the robot has nv = {self.dimension}")
        names = [solver.get_name()] + ([] if limitator is None else [limitator.get_name()])
        if len(set(names)) < len(names):
            raise InvalidInput(f"the solver and its limitator need two names, got {names[0]!r} for both")
        self.check_new_names(names)  # (everything refused before anything is added)
        for task in self.tasks.values():
            solver.check_task_input(task)
        self.add(solver)
        self.solver = solver
        if limitator is None:
            self.builder.Connect(solver.GetOutputPort("control"), self.device.GetInputPort("control"))
        else:
            self.add(limitator)
            self.limitator = limitator
            self.builder.Connect(solver.GetOutputPort("control"), limitator.GetInputPort("control_in"))
            self.builder.Connect(limitator.GetOutputPort("control"), self.device.GetInputPort("control"))
            self.builder.Connect(self.device.GetOutputPort("state"), limitator.GetInputPort("position"))
        if solver.HasInputPort("position"):  # the HQP reads q for the joint limits
            self.builder.Connect(self.device.GetOutputPort("state"), solver.GetInputPort("position"))
        for task in self.tasks.values():
            self._connect(task, solver)
        return solver


def robot(
    builder: DiagramBuilder,
    name: str | PathLike[str] | RobotModel = "talos",
    variant: str | None = None,
    dt: float = 1e-3,
    base: str | None = None,
    q0: np.ndarray | None = None,
    **load_options: Any,
) -> Robot:
    """The SoT ``robot`` (sot-romeo's ``from dynamic_graph.sot.romeo.romeo import *; robot =
    Robot('robot')``): its ``dynamic`` and ``device`` (period ``dt`` seconds) in ``builder``,
    starting in the robot's reference posture (or ``q0``).

    ``name``: a robot of :data:`sotdrake.robots.ROBOTS`, the path of your URDF/SDF/MJCF file, or
    a :class:`~sotdrake.robots.RobotModel` already loaded (``load_robot("arm.urdf")``).
    ``variant``, ``base`` and ``load_options`` (``floating_base``, ``srdf``, ``package_paths``,
    ``operational_points``, ``reference_posture``) as in :func:`sotdrake.robots.load_robot`."""
    if isinstance(name, RobotModel):
        if variant is not None or base is not None or load_options:
            raise InvalidInput("robot(builder, model): the model is already loaded; give variant, base and the "
                               "load options to load_robot instead")
        return Robot(builder, name, dt, q0)
    return Robot(builder, load_robot(name, variant, base=base, **load_options), dt, q0)


def talos(builder: DiagramBuilder, variant: str = "reduced", dt: float = 1e-3) -> Robot:
    """TALOS (``variant`` of :data:`sotdrake.robots.VARIANTS`) in half-sitting, at ``dt`` seconds:
    ``robot(builder, "talos", variant, dt)``."""
    return robot(builder, "talos", variant, dt)


def add_sot(
    robot: Robot,
    name: str = "sot",
    solver: str = "cascade",
    damping: float = 0.0,
    svd_threshold: float = 1e-4,
    position_margin: float = 1e-3,
    qp_solver: str = "active-set",
) -> SOT | SolverKine:
    """sot-core's ``sot = SOT('sot'); sot.setSize(...); plug(sot.control, robot.device.control)``.

    ``solver='cascade'``: the basic ``SOT`` (pseudo-inverse cascade; ``svd_threshold``, ``damping``
    on every level; the command scaled uniformly into the joints' velocity limits and the base
    bound). ``solver='hqp'``: ``SolverKine`` (hierarchical QP with inequalities and joint limits;
    ``damping`` on the last level, ``position_margin``, ``qp_solver``).
    """
    if not isinstance(robot, Robot):
        raise InvalidInput(f"add_sot takes the robot (add_sot(robot)), got {type(robot).__name__}")
    check_name("add_sot: the solver's name", name)
    if solver == "cascade":
        sot = SOT(name, robot.dimension, svd_threshold, damping, dt=robot.dt)
        sot.setVelocityLimit(velocity_limit_vector(robot.model))
        robot.add_solver(sot)
        return sot
    if solver == "hqp":
        hqp = SolverKine(name, robot.model, robot.dt, damping, position_margin, qp_solver)
        robot.add_solver(hqp)
        return hqp
    raise InvalidInput(f"unknown solver {solver!r}: 'cascade' (SOT) or 'hqp' (SolverKine)")
