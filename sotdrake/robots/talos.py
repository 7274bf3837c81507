"""TALOS (PAL Robotics) from the example-robot-data wheel: one case of :mod:`.loader`.

``load_talos(variant)`` is ``load_robot("talos", variant)``; its URDF fix-ups are those of
:func:`~sotdrake.robots.urdf_text.prepare_urdf` (STL meshes, three-slash ``package:///`` URIs,
``<mimic>`` on fixed joints, the ``friction`` attribute, the differential transmissions of the torso,
head and wrists replaced by one actuator a joint), its reference posture is ``half_sitting`` of
``talos.srdf`` and its operational points are sot-talos' (:data:`OPERATIONAL_POINTS`).

Drake's coordinates: the floating base ``base_link`` comes first, ``q = (qw, qx, qy, qz, x, y, z, …)``
and ``v = (ω_WB, v_WB, …)``, both expressed in the world frame.
"""

from __future__ import annotations

from pathlib import Path

from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex

from .catalog import ROBOTS
from .loader import add_robot, example_robot_data_dir, load_robot, robot_urdf_text, urdf_path
from .model import RobotModel, posture_from_srdf

__all__ = [
    "OPERATIONAL_POINTS",
    "VARIANTS",
    "RobotModel",
    "add_talos",
    "example_robot_data_dir",
    "fixed_urdf_text",
    "load_talos",
    "posture_from_srdf",
    "talos_urdf_path",
]

#: URDF file of each TALOS variant, under ``robots/talos_data/robots/``.
VARIANTS: dict[str, str] = ROBOTS["talos"].variants

#: sot-talos operational points (``robot.OperationalPointsMap``): op-point name → joint name.
#: The operational point is the child frame of the joint (the URDF link frame), as in sot-dynamic.
OPERATIONAL_POINTS: dict[str, str] = ROBOTS["talos"].op_points


def talos_urdf_path(variant: str) -> Path:
    return urdf_path("talos", variant)


def fixed_urdf_text(variant: str, meshes: bool, collision: bool = True) -> str:
    """The URDF of ``variant`` with the fix-ups applied; without ``collision`` the ``<collision>``
    elements are dropped (the physics model adds its own soles)."""
    return robot_urdf_text("talos", variant, meshes, collision)


def add_talos(
    plant: MultibodyPlant,
    variant: str = "reduced",
    meshes: bool = False,
    fixed_base: bool | None = None,
    collision: bool = True,
) -> ModelInstanceIndex:
    """Add TALOS to an unfinalized ``plant`` (geometry only if ``meshes`` and the plant has a
    SceneGraph); returns its model instance. Actuators are added for every actuable joint.

    ``fixed_base`` welds the URDF root link to the world at the origin; by default only the
    ``left_arm`` variant is welded, the others have a floating base.
    """
    base = None if fixed_base is None else ("fixed" if fixed_base else "free")
    return add_robot(plant, "talos", variant, meshes, base, collision)


def load_talos(
    variant: str = "reduced",
    meshes: bool = False,
    time_step: float = 0.0,
    fixed_base: bool | None = None,
) -> RobotModel:
    """A finalized TALOS ``RobotModel``; with ``meshes`` the plant is registered with a SceneGraph
    (OBJ visual and collision meshes) and the model holds that SceneGraph."""
    base = None if fixed_base is None else ("fixed" if fixed_base else "free")
    return load_robot("talos", variant, meshes, time_step, base)
