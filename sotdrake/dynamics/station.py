"""The physics plant under torque control: TALOS on the ground, its actuators driven by ``τ``.

The same world as :mod:`sotdrake.physics` (a discrete ``MultibodyPlant`` with Drake's SAP solver,
gravity, a rigid-hydroelastic ground, the compliant-hydroelastic sole boxes ``SOLE_BOX`` with the
same modulus, dissipation and friction), but *no PD controller* on the actuators: the actuation
input is the torque itself (actuator order, N·m), and the plant's state output is what the
controller reads back (closed loop). Every actuator is checked to have no PD controller (a PD left
on would silently add a position servo). The torque limits
are the controller's hard bounds (``SolverDyn``), and the diagrams report ``max |τ|/limit``.
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import (
    AddCompliantHydroelasticProperties,
    AddContactMaterial,
    AddRigidHydroelasticProperties,
    Box,
    HalfSpace,
    ProximityProperties,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, MultibodyPlant
from pydrake.systems.framework import DiagramBuilder

from ..drake_logging import drop_drake_message
from ..exceptions import InvalidInput, SotError
from ..physics import FRICTION, SOLE_BOX, SOLE_DISSIPATION, SOLE_MODULUS, PhysicalTalos
from ..robots.talos import add_talos


def add_torque_driven_talos(builder: DiagramBuilder, variant: str = "reduced", time_step: float = 1e-3) -> PhysicalTalos:
    """Add the simulated TALOS (plant + SceneGraph, visual meshes, sole boxes, ground), its
    actuators torque-driven (see the module docstring)."""
    if not time_step > 0:
        raise InvalidInput(f"the physics needs a discrete plant: time_step > 0, got {time_step}")
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step)
    plant.set_name("talos_plant")
    instance = add_talos(plant, variant, meshes=True, collision=False)
    ground = ProximityProperties()
    AddRigidHydroelasticProperties(ground)
    AddContactMaterial(friction=FRICTION, properties=ground)
    # Drake would warn at each new context that a rigid half-space gives no contact data with
    # deformable bodies; there are none here (see sotdrake.physics.plant).
    drop_drake_message("Rigid (non-deformable) half spaces are not currently supported for deformable contact")
    plant.RegisterCollisionGeometry(plant.world_body(), RigidTransform(), HalfSpace(), "ground", ground)
    sole_material = ProximityProperties()
    AddCompliantHydroelasticProperties(resolution_hint=0.02, hydroelastic_modulus=SOLE_MODULUS, properties=sole_material)
    AddContactMaterial(dissipation=SOLE_DISSIPATION, friction=FRICTION, properties=sole_material)
    size, centre = SOLE_BOX
    soles = {}
    for side in ("left", "right"):
        sole = plant.GetFrameByName(f"{side}_sole_link")
        X_BS = sole.GetFixedPoseInBodyFrame()
        plant.RegisterCollisionGeometry(sole.body(), X_BS.multiply(RigidTransform(centre)), Box(*size), f"{side}_sole", sole_material)
        soles[side] = sole
    plant.Finalize()
    check_torque_driven(plant)
    actuators = [plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices()]
    return PhysicalTalos(
        plant, scene_graph, instance,
        np.array([a.joint().position_start() for a in actuators]),
        np.array([a.joint().velocity_start() for a in actuators]),
        soles,
    )


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
