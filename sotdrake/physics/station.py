"""The TALOS station: the physics side of every physics script, built once.

``add_talos_station(builder, ...)`` adds the simulated robot (:mod:`.plant`), its PD references
(:class:`~.actuators.DesiredState`, zero feed-forward torque), the contact monitor and, optionally, a
push, and returns :class:`TalosStation`, the handles of its ports:

* inputs: ``position`` (the device's ``q``) and ``velocity`` (the solver's ``v``) of ``desired_state``;
* outputs: ``plant_state`` (``(q, v)`` of the simulated robot), ``feet`` and ``other_contact``
  (:class:`~.contact_monitor.ContactMonitor`), ``contact_results``.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import DiagramBuilder, InputPort, OutputPort
from pydrake.systems.primitives import ConstantVectorSource

from ..atomic import all_or_nothing
from ..configuration import Layout, check_base_quaternion
from ..exceptions import InvalidInput, check_finite, close_matches
from ..ranges import MAX_JOINT_TARGET
from .actuators import DesiredState
from .contact_monitor import ContactMonitor
from .plant import PLANT_SYSTEMS, PhysicalTalos, add_physical_talos, check_physics_builder
from .push import Push

#: The station plant's default step (s): twice the SoT's 1 ms tick. The PD references are held for
#: 2 ms; measured (``bench/physics.py``), standing, reaching and pushed keep the figures of a 1 ms
#: step (hand error, base drift and CoP margin within 0.3 mm in the open loop, 1.6 mm in the closed
#: one; slips in micrometres) and the loop runs 1.4 to 1.9 times as fast. (The torque-driven device
#: of ``talos_dynamics.py`` steps at the control rate: its torques held 2 ms would multiply the CoM
#: tracking error of ``sway`` by 3.7.)
PLANT_STEP = 2e-3


@dataclass
class TalosStation:
    physical: PhysicalTalos
    desired: DesiredState
    monitor: ContactMonitor
    push: Push | None

    @property
    def position(self) -> InputPort:
        return self.desired.GetInputPort("position")

    @property
    def velocity(self) -> InputPort:
        return self.desired.GetInputPort("velocity")

    @property
    def plant_state(self) -> OutputPort:
        return self.physical.plant.get_state_output_port()

    @property
    def feet(self) -> OutputPort:
        return self.monitor.GetOutputPort("feet")

    @property
    def other_contact(self) -> OutputPort:
        return self.monitor.GetOutputPort("other_contact")


def add_talos_station(
    builder: DiagramBuilder,
    q0: np.ndarray,
    time_step: float = PLANT_STEP,
    push_force=None,
    push_body: str = "torso_2_link",
    push_start: float = 2.0,
    push_duration: float = 0.1,
    contact: str = "point",
    **plant_options,
) -> TalosStation:
    """The station (see the module docstring); the plant starts at ``q0`` and steps every
    ``time_step`` seconds (:data:`PLANT_STEP` by default). ``push_force`` (N, world)
    adds a :class:`~.push.Push` on ``push_body`` during ``[push_start, push_start + push_duration)``.
    ``contact``: the soles' contact model of :func:`~.plant.add_physical_talos`, point contact at
    their corners by default (the plant 1.3 to 1.6 times as fast as with ``"hydroelastic"``, the same
    standing, reaching and pushed figures). ``plant_options``: the other options of
    :func:`~.plant.add_physical_talos` (``variant``, ``stiffness``, ``damping``, ``obstacles`` …).

    Refused with :class:`InvalidInput` naming the argument, the builder left as it was: what
    :func:`~.plant.add_physical_talos` refuses (a second station or simulated TALOS in the builder
    among them); a ``q0`` that is not the plant's positions, finite, within ``|q| ≤``
    :data:`~sotdrake.ranges.MAX_JOINT_TARGET`, its base quaternion of norm 1 ± 1e-3 (the device's
    checks); an option ``add_physical_talos`` does not have; a bad push."""
    check_physics_builder("add_talos_station", builder, (*PLANT_SYSTEMS, *STATION_SYSTEMS,
                                                         *(("push",) if push_force is not None else ())))
    q0 = check_finite("add_talos_station: q0 (rad, m)", q0, bound=MAX_JOINT_TARGET)
    unknown = sorted(set(plant_options) - set(_PLANT_OPTIONS))
    if unknown:
        close = close_matches(unknown[0], _PLANT_OPTIONS)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise InvalidInput(f"add_talos_station: unknown option {unknown[0]!r}{hint}; the plant's options are {list(_PLANT_OPTIONS)}")
    Push.check_arguments(push_force, push_start, push_duration)
    with all_or_nothing(builder):
        return _add_station(builder, q0, time_step, push_force, push_body, push_start, push_duration, contact, plant_options)


#: The systems :func:`add_talos_station` adds besides the plant's (and ``push`` with a push), by name.
STATION_SYSTEMS = ("desired_state", "feedforward_torque", "contact_monitor")
#: The options of :func:`~.plant.add_physical_talos` a station passes on (``plant_options``).
_PLANT_OPTIONS = tuple(name for name in inspect.signature(add_physical_talos).parameters
                       if name not in ("builder", "time_step", "contact"))


def _add_station(builder: DiagramBuilder, q0: np.ndarray, time_step: float, push_force, push_body: str, push_start: float,
                 push_duration: float, contact: str, plant_options: dict) -> TalosStation:
    physical = add_physical_talos(builder, time_step=time_step, contact=contact, **plant_options)
    plant = physical.plant
    if q0.shape != (plant.num_positions(),):
        raise InvalidInput(f"add_talos_station: q0 must be the plant's {plant.num_positions()} positions, got {q0.shape}")
    check_base_quaternion("add_talos_station: q0", q0, Layout.of(plant))
    plant.SetDefaultPositions(q0)
    desired = builder.AddNamedSystem("desired_state", DesiredState(physical))
    builder.Connect(desired.get_output_port(), plant.get_desired_state_input_port(physical.instance))
    feedforward = builder.AddNamedSystem(
        "feedforward_torque", ConstantVectorSource(np.zeros(plant.num_actuated_dofs(physical.instance))))
    builder.Connect(feedforward.get_output_port(), plant.get_actuation_input_port(physical.instance))
    monitor = builder.AddNamedSystem("contact_monitor", ContactMonitor(physical))
    builder.Connect(plant.get_contact_results_output_port(), monitor.get_input_port())
    push = None
    if push_force is not None:
        push = builder.AddNamedSystem("push", Push(plant, push_body, push_force, push_start, push_duration))
        builder.Connect(push.get_output_port(), plant.get_applied_spatial_force_input_port())
    return TalosStation(physical, desired, monitor, push)
