"""The physics plant under torque control: TALOS on the ground, its actuators driven by ``τ``.

The world of :mod:`sotdrake.physics` itself (a discrete ``MultibodyPlant`` with Drake's SAP solver
or, on request, TAMSI; gravity, a rigid-hydroelastic ground, the sole boxes ``SOLE_BOX``, a box per
link so that a fall lands on the ground), but *no PD controller* on the actuators: the actuation
input is the torque itself (actuator order, N·m), and the plant's state output is what the
controller reads back (closed loop). Every actuator is checked to have no PD controller (a PD left
on would silently add a position servo). The torque limits are the controller's hard bounds
(``SolverDyn``), and the diagrams report ``max |τ|/limit``.
"""

from __future__ import annotations

from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import DiagramBuilder

from ..exceptions import SotError
from ..physics import SOLE_BOX, PhysicalTalos, add_physical_talos


def add_torque_driven_talos(builder: DiagramBuilder, variant: str = "reduced", time_step: float = 1e-3,
                            contact: str = "hydroelastic", contact_solver: str = "sap") -> PhysicalTalos:
    """Add the simulated TALOS of :func:`sotdrake.physics.add_physical_talos` (plant + SceneGraph,
    visual meshes, ground, sole and link boxes) with its actuators torque-driven: no PD controller,
    checked (see the module docstring). Its output ports are not sampled (``sampled_outputs=False``):
    the plant's step and the controller's discrete updates read the same state, and the stack is
    solved once per tick. ``contact`` (the soles' model) and ``contact_solver`` (``"sap"`` or
    ``"tamsi"``): see :mod:`sotdrake.physics.plant`."""
    physical = add_physical_talos(builder, variant, time_step, pd_gains=False, sampled_outputs=False,
                                  contact=contact, contact_solver=contact_solver)
    check_torque_driven(physical.plant)
    return physical


def check_torque_driven(plant: MultibodyPlant) -> None:
    """No actuator may have a PD controller (the torque input must be the whole actuation)."""
    with_pd = [plant.get_joint_actuator(i).name() for i in plant.GetJointActuatorIndices()
               if plant.get_joint_actuator(i).has_controller()]
    if with_pd:
        raise SotError(f"torque control needs actuators without PD controllers; these have one: {with_pd}")


def sole_rectangle() -> tuple[float, float, float, float]:
    """The sole box's footprint in the sole frame: ``(x_min, x_max, y_min, y_max)`` (m)."""
    size, centre = SOLE_BOX
    return (centre[0] - size[0] / 2, centre[0] + size[0] / 2, centre[1] - size[1] / 2, centre[1] + size[1] / 2)
