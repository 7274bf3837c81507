"""The dynamic SoT's ``robot`` (the seed's ``Robot('robot', device=RobotDynSimu('robot'))``).

Creating it adds and plugs, in a ``DiagramBuilder``: the dynamic entity ``dynamic``
(:class:`.dynamic_entity.DynamicEntity`), the solver ``sot`` (:class:`.solver_dyn.SolverDyn`,
``dynamic.dynamics → sot.dynamics``) and the device:

* ``device='dynsimu'``: ``RobotDynSimu`` (``sot.control`` = ``q̈`` → ``device.control``,
  ``device.state → dynamic.state``);
* ``device='physics'``: the torque-driven plant of :mod:`.station` (``sot.torque`` → the plant's
  actuation input, the plant's state → ``dynamic.state``: closed loop, no PD); ``contact`` and
  ``contact_solver`` choose its soles' contact model and its contact solver
  (:func:`sotdrake.physics.add_physical_talos`).

Tasks (:mod:`.meta_tasks_dyn`) and contacts (:meth:`add_contact`) are connected to the solver as
they are created; the stack and the contact set are the solver's settings in the Context.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydrake.systems.framework import DiagramBuilder, LeafSystem

from ..atomic import all_or_nothing, check_new_names
from ..configuration import Layout, check_base_quaternion, warn_beyond_limits
from ..exceptions import InvalidInput, check_finite, check_name, check_number, check_type
from ..hqp import ACTIVE_SET
from ..physics.plant import MAX_TIME_STEP, check_contact_options
from ..robot import velocity_selection
from ..robots import RobotModel
from .checks import MAX_DT
from .contact import Contact6d
from .device import RobotDynSimu
from .dynamic_entity import DynamicEntity
from .solver_dyn import SolverDyn
from .station import add_torque_driven_talos, sole_rectangle
from .task_dyn_pd import TaskDynPD

DEVICES = ("dynsimu", "physics")
#: TALOS' sole op points, whose rectangle is the physics plant's sole box (``station.sole_rectangle``).
TALOS_SOLES = ("left-sole", "right-sole")


class RobotDyn:
    """The dynamic SoT's robot: ``dynamic``, ``sot`` (``SolverDyn``) and the device in ``builder``
    (see the module docstring); tasks and contacts are connected to the solver as they are created."""

    def __init__(self, builder: DiagramBuilder, model: RobotModel, device: str = "dynsimu", dt: float = 1e-3,
                 q0: np.ndarray | None = None, max_contacts: int = 2, solver: str = ACTIVE_SET, effort_scale: float = 1.0,
                 contact: str = "hydroelastic", contact_solver: str = "sap"):
        check_type("RobotDyn: builder", builder, DiagramBuilder, "a DiagramBuilder")
        check_type("RobotDyn: model", model, RobotModel, "a RobotModel (load_robot('talos', 'full'), load_robot('arm.urdf'))")
        if not isinstance(device, str) or device not in DEVICES:
            raise InvalidInput(f"unknown device {device!r:.60}; available: {list(DEVICES)}")
        check_contact_options(contact, contact_solver)  # (before anything is added to the builder)
        if device == "dynsimu" and (contact, contact_solver) != ("hydroelastic", "sap"):
            raise InvalidInput("contact and contact_solver choose the physics plant's contact: device='physics'")
        if device == "physics" and not _is_talos(model):
            raise InvalidInput(f"device='physics' is TALOS' torque-driven plant (the catalog's); {model.name} runs on "
                               "device='dynsimu'")
        dt = check_number("dt (the control period" + (", the physics plant's step)" if device == "physics" else ")"), dt, 1e-6,
                          MAX_TIME_STEP if device == "physics" else MAX_DT, " s")
        # q0 checked before anything is added (Drake aborts the process on a non-finite or
        # wrongly sized default position of the physics plant).
        given = q0 is not None
        q0 = check_finite("q0", q0, (model.nq,)) if given else model.half_sitting
        check_base_quaternion("q0", q0, Layout.of(model.plant))
        if given:
            warn_beyond_limits(model.plant, q0, "q0")
        self.builder, self.model, self.dt, self.device_kind = builder, model, dt, device
        self.OperationalPointsMap = model.OperationalPointsMap
        self.q0 = np.array(q0, dtype=float)
        self.tasks: dict[str, TaskDynPD] = {}
        self.contacts: dict[str, Contact6d] = {}
        self._names: set[str] = set()
        with all_or_nothing(builder):  # (a refusal found once systems are in leaves the builder as it was)
            self.dynamic = self.add(DynamicEntity(model, "dynamic"))
            self.sot = self.add(SolverDyn("sot", model, dt, max_contacts=max_contacts, solver=solver, effort_scale=effort_scale))
            builder.Connect(self.dynamic.GetOutputPort("dynamics"), self.sot.GetInputPort("dynamics"))
            self.physical = None
            if device == "dynsimu":
                self.device = self.add(RobotDynSimu(model.plant, dt, self.q0, name="device"))
                builder.Connect(self.sot.GetOutputPort("control"), self.device.GetInputPort("control"))
                self.state_port = self.device.GetOutputPort("state")
            else:
                self.physical = add_torque_driven_talos(builder, model.variant, time_step=dt, contact=contact,
                                                        contact_solver=contact_solver)
                plant = self.physical.plant
                if plant.num_positions() != model.nq or plant.num_actuators() != model.plant.num_actuators():
                    raise InvalidInput("the physics plant and the control model differ in size")
                plant.SetDefaultPositions(self.q0)
                self.device = plant
                builder.Connect(self.sot.GetOutputPort("torque"), plant.get_actuation_input_port(self.physical.instance))
                self.state_port = plant.get_state_output_port()
            builder.Connect(self.state_port, self.dynamic.GetInputPort("state"))

    def velocity_selection(self, excluding: Sequence[str] = ()) -> np.ndarray:
        """nv booleans, False on the velocities of the joints named in ``excluding``."""
        return velocity_selection(self.model.plant, excluding)

    def sole_rectangle(self, opPoint: str) -> tuple[float, float, float, float]:
        """The contact rectangle ``(x_min, x_max, y_min, y_max)`` (m, sole frame) of a sole op point."""
        if opPoint in self.model.sole_rectangles:
            return self.model.sole_rectangles[opPoint]
        if _is_talos(self.model) and opPoint in TALOS_SOLES:
            return sole_rectangle()
        known = sorted(self.model.sole_rectangles) or (list(TALOS_SOLES) if _is_talos(self.model) else [])
        raise InvalidInput(f"no sole rectangle known for {self.model.name}'s {opPoint!r} "
                           f"(known: {known}); pass rectangle=(x_min, x_max, y_min, y_max), or None for a point contact")

    @property
    def dimension(self) -> int:
        return self.model.nv

    def check_new_names(self, names: list[str]) -> None:
        """:class:`InvalidInput` if an entity of one of ``names`` exists already (for a caller that
        adds several entities and must refuse before adding any)."""
        check_new_names(self.builder, names, self._names)

    def add(self, system: LeafSystem, name: str | None = None) -> LeafSystem:
        """Add ``system`` under ``name`` (default: its own), which must be new."""
        check_type("add: system", system, LeafSystem, "a Drake LeafSystem (an entity)")
        if name is not None:
            check_name("add: name", name)
        name = system.get_name() if name is None else name
        if not name:
            raise InvalidInput(f"an entity needs a name, got {name!r}")
        self.check_new_names([name])
        system.set_name(name)
        self._names.add(name)
        return self.builder.AddNamedSystem(name, system)

    def add_task(self, task: TaskDynPD) -> TaskDynPD:
        """Add a task, plug ``dynamic.velocity`` into it and connect it to the solver (and the solver's
        ``stack`` to it, when the task keeps a previous Jacobian). Refused first (nothing added) when
        it is not a task of this robot's size and control period (a ``TaskDynPD``'s gains were
        checked stable at its own period)."""
        if not (isinstance(task, LeafSystem) and task.HasOutputPort("task") and task.HasInputPort("velocity")
                and hasattr(task, "nv") and hasattr(task, "dt")):
            raise InvalidInput(f"add_task: a task of the dynamic level (a TaskDynPD), got {task!r:.60}")
        if task.nv != self.dimension or task.dt != self.dt:
            raise InvalidInput(f"add_task({task.name!r}): the task has nv = {task.nv} and dt = {task.dt:g} s, the robot "
                               f"nv = {self.dimension} and dt = {self.dt:g} s: build it with the robot's")
        self.sot.check_task_input(task)
        self.add(task)
        self.tasks[task.name] = task
        self.builder.Connect(self.dynamic.GetOutputPort("velocity"), task.GetInputPort("velocity"))
        self.builder.Connect(task.GetOutputPort("task"), self.sot.declare_task_input(task))
        if task.stack is not None:  # its Jacobian recorded only while it is in the stack
            self.builder.Connect(self.sot.GetOutputPort("stack"), task.stack)
        return task

    def add_contact(self, name: str, opPoint: str, rectangle: tuple[float, float, float, float] | str | None = "sole",
                    mu: float = 0.7, f_min: float = 1.0, cop_margin: float = 0.01) -> Contact6d:
        """A contact entity on op point ``opPoint`` (e.g. ``'left-sole'``), plugged to the
        dynamic entity and the solver (not yet held: ``sot.addContact``). ``rectangle='sole'``
        is the robot model's rectangle for that op point (``model.sole_rectangles``; TALOS': its
        physics sole box); None makes a point contact. The contact keeps the op point's pose at
        ``q0`` (:meth:`.contact.Contact6d.keep`, used with ``setPositionGain``)."""
        check_name("add_contact: the contact's name", name)
        self.model.frame(opPoint)  # (everything checked before anything is added)
        if isinstance(rectangle, str):
            if rectangle != "sole":
                raise InvalidInput(f"{name}: rectangle is 'sole', (x_min, x_max, y_min, y_max) or None, got {rectangle!r}")
            rectangle = self.sole_rectangle(opPoint)
        self.check_new_names([name])
        self.dynamic.check_op_point(name, opPoint)
        port = name if name.startswith("contact") else "contact" + name
        if self.sot.HasInputPort(port):
            raise InvalidInput(f"add_contact({name!r}): {self.sot.name} already has the input {port!r} of another contact")
        if len(self.sot.known_contacts) >= self.sot.max_contacts:
            raise InvalidInput(f"{name}: {self.sot.name} was built for {self.sot.max_contacts} contacts (RobotDyn's max_contacts), "
                               f"it has {self.sot.known_contacts}")
        contact = self.add(Contact6d(name, self.dimension, rectangle, mu, f_min, cop_margin, dt=self.dt,
                                     compliant=self.physical is not None))
        plant = self.model.plant
        at_q0 = plant.CreateDefaultContext()
        plant.SetPositions(at_q0, self.q0)
        contact.keep(plant.CalcRelativeTransform(at_q0, plant.world_frame(), self.model.frame(opPoint)))
        self.dynamic.createOpPoint(name, opPoint)
        connect = self.builder.Connect
        connect(self.dynamic.kinematics_port(name), contact.GetInputPort("kinematics"))
        connect(contact.GetOutputPort("contact"), self.sot.declare_contact_input(contact))
        self.contacts[name] = contact
        return contact


def _is_talos(model) -> bool:
    """Whether ``model`` is the catalog's TALOS (not a file of the user's that is named so)."""
    return model.name == "talos" and model.source_path is None

