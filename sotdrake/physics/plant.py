"""The simulated TALOS' plant: a discrete ``MultibodyPlant`` on a ground half-space, with soles and
whole-body collision boxes.

* A discrete ``MultibodyPlant`` (``time_step``: 1 ms by default, the station's
  :data:`~.station.PLANT_STEP`) on a ground half-space (drawn as a flat 6 m plate), gravity on.
  ``contact_solver`` (one of ``CONTACT_SOLVERS``): ``"sap"`` (the default), Drake's SAP solver in
  its lagged approximation, which treats the PD actuators implicitly (stable with stiff servos and
  a 2 ms step) and converges through any fall; ``"tamsi"``, Drake's TAMSI solver, for a plant
  without PD actuators (torque control: :func:`sotdrake.dynamics.station.add_torque_driven_talos`).
  Torque-driven, the two give the same motions (standing, swaying, lifting a leg, pushed,
  squatting and walking: the outcome figures agree to two or three digits, the soles slip less
  under TAMSI), and TAMSI steps in 0.55 to 0.65 of SAP's CPU time (the torques of a stand replayed
  to each, in one process). But TAMSI may not converge in a hard fall, and the step then stops the
  simulation with an error; with the PD actuators, it treats them explicitly, and a stiff servo at
  a 2 ms step diverges.
* Soles, ``SOLE_BOX`` (0.211 × 0.124 m, the footprint of TALOS' foot collision mesh, bottom at the
  sole frame), in one of two contact models (``contact``), friction ``μ = 0.9`` (static), ``0.8``
  (dynamic) against the rigid ground:

  - ``"point"`` (the default of :func:`~.station.add_talos_station`): four spheres of radius ``CORNER_RADIUS`` at the bottom corners of the
    box, their lowest points on the sole plane, point contact of stiffness ``CORNER_STIFFNESS``
    N/m each and Hunt-Crossley dissipation ``CORNER_DISSIPATION`` s/m. The plant alone steps 1.3 to
    1.6 times as fast as with the hydroelastic soles; standing, reaching and pushed, the feet slip by
    micrometres. Walking on position servos, a sole landing or rolling on its corners
    rocks heel to toe: the walks keep the hydroelastic soles.
  - ``"hydroelastic"`` (the default of this function): one compliant-hydroelastic box per sole (``SOLE_MODULUS`` Pa, a 2 cm thick
    layer, dissipation ``SOLE_DISSIPATION`` s/m): a distributed pressure, the centre of pressure
    anywhere under the sole, at a higher cost.

* Every other link: the box bounding its collision meshes (:mod:`.body_collision`), point contact
  with the ground only (self-collisions filtered), so a fall lands on the ground.
* Every actuator PD-controlled by the plant (:mod:`.actuators`).
* ``sampled_outputs`` (Drake's sampled output ports, on by default): the plant's step is then an
  *unrestricted* update, applied before the diagram's discrete updates of the same instant, and its
  contact results are those the step computed. Off, the step is a discrete update computed from the
  same context as the controller's; the contact results are computed from the current state when
  read. The torque-driven plant (:func:`sotdrake.dynamics.station.add_torque_driven_talos`) turns
  them off: ``SolverDyn``'s torque is read by the plant's step, and its per-tick record (the contact
  loads, the held bounds, a task's previous Jacobian) must come from that same solve. With sampled
  outputs, the record would see the state after the step, and the whole stack would be solved a
  second time at every tick. Unsampled contact results depend on the actuation input: a controller
  that reads them back (a stabilizer on the measured CoP, as the position-servoed walk has) closes
  an algebraic loop, which ``DiagramBuilder.Build`` refuses; such a diagram keeps them sampled.
* ``obstacles``: fixed shapes ``(name, shape, X_WO)`` (those of the controller's collision world,
  :func:`sotdrake.collision.obstacle_geometries`), anchored in the world as collision (point contact,
  the links' friction) and visual geometry at the same pose: the simulated robot touches them.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
from pydrake.geometry import (
    AddCompliantHydroelasticProperties,
    AddContactMaterial,
    AddRigidHydroelasticProperties,
    Box,
    CollisionFilterDeclaration,
    GeometrySet,
    HalfSpace,
    ProximityProperties,
    SceneGraph,
    Shape,
    Sphere,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import (
    AddMultibodyPlantSceneGraph,
    CoulombFriction,
    DiscreteContactApproximation,
    MultibodyPlant,
)
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import DiagramBuilder

from ..atomic import all_or_nothing
from ..drake_logging import drop_drake_message
from ..exceptions import InvalidInput, VariantNotFound, check_flag, finite_number
from ..robots.talos import VARIANTS as TALOS_VARIANTS
from ..robots.talos import add_talos, talos_urdf_path
from .actuators import check_pd_gain_values, set_pd_gains
from .body_collision import fit_link_boxes

#: Sole box in the sole frame: size (m) and centre (the bottom face lies on the sole plane).
SOLE_BOX = (np.array([0.211, 0.124, 0.02]), np.array([-0.0054, 0.0, 0.01]))
FRICTION = CoulombFriction(0.9, 0.8)
SOLE_MODULUS = 5e6  # Pa
SOLE_DISSIPATION = 50.0  # s/m
#: The ground's drawing: a plate (m) and its colour (RGBA).
GROUND_PLATE = (6.0, 6.0, 0.01)
GROUND_COLOR = np.array([0.62, 0.64, 0.60, 1.0])
#: The longest plant step (s) :func:`add_physical_talos` takes.
MAX_TIME_STEP = 0.01
#: The soles' contact models of :func:`add_physical_talos` (``contact``).
CONTACT_MODELS = ("hydroelastic", "point")
#: The contact solvers of :func:`add_physical_talos` (``contact_solver``), Drake's approximations.
CONTACT_SOLVERS = {"sap": DiscreteContactApproximation.kLagged, "tamsi": DiscreteContactApproximation.kTamsi}
#: Point-contact soles: the corner spheres' radius (m), stiffness (N/m each), dissipation (s/m).
CORNER_RADIUS = 0.002
CORNER_STIFFNESS = 1e6
CORNER_DISSIPATION = 50.0


def _add_sole(plant: MultibodyPlant, sole, side: str, contact: str) -> list:
    """Register ``side``'s sole geometry on ``sole``'s body (``contact``: see the module docstring);
    returns the geometry ids."""
    size, centre = SOLE_BOX
    X_BS = sole.GetFixedPoseInBodyFrame()
    material = ProximityProperties()
    if contact == "hydroelastic":
        AddCompliantHydroelasticProperties(resolution_hint=0.02, hydroelastic_modulus=SOLE_MODULUS, properties=material)
        AddContactMaterial(dissipation=SOLE_DISSIPATION, friction=FRICTION, properties=material)
        return [plant.RegisterCollisionGeometry(
            sole.body(), X_BS.multiply(RigidTransform(centre)), Box(*size), f"{side}_sole", material)]
    AddContactMaterial(dissipation=CORNER_DISSIPATION, point_stiffness=CORNER_STIFFNESS, friction=FRICTION,
                       properties=material)
    ids = []
    for k, (sx, sy) in enumerate(((-1, -1), (-1, 1), (1, -1), (1, 1))):
        p_SC = centre + size * np.array([sx, sy, 0.0]) / 2 - np.array([0.0, 0.0, size[2] / 2 - CORNER_RADIUS])
        ids.append(plant.RegisterCollisionGeometry(
            sole.body(), X_BS.multiply(RigidTransform(p_SC)), Sphere(CORNER_RADIUS), f"{side}_sole_{k}", material))
    return ids


@dataclass
class PhysicalTalos:
    plant: MultibodyPlant
    scene_graph: SceneGraph
    instance: ModelInstanceIndex
    actuated_q: np.ndarray  # q index of each actuator's joint, in actuator order
    actuated_v: np.ndarray
    sole_frames: dict[str, object]
    body_boxes: tuple[str, ...] = ()  # the links that got a collision box


def add_physical_talos(
    builder: DiagramBuilder,
    variant: str = "reduced",
    time_step: float = 1e-3,
    stiffness: float = 30.0,
    damping: float = 0.05,
    body_collision: bool = True,
    pd_gains: bool = True,
    obstacles: Sequence[tuple[str, Shape, RigidTransform]] = (),
    contact: str = "hydroelastic",
    sampled_outputs: bool = True,
    contact_solver: str = "sap",
) -> PhysicalTalos:
    """Add the simulated TALOS (plant + SceneGraph, visual meshes, soles, link boxes unless
    ``body_collision=False``, ground, PD actuators; ``pd_gains=False`` leaves the actuators without PD
    controllers, driven by the actuation input alone: torque control; ``obstacles``: see the module
    docstring). ``contact``: the soles' contact model, ``"hydroelastic"`` (default) or ``"point"`` (see
    the module docstring; the station of :func:`~.station.add_talos_station` takes ``"point"``).
    ``sampled_outputs``: see the module docstring (False for a controller that reads the plant's state
    inside its own discrete updates). ``contact_solver``: ``"sap"`` or ``"tamsi"`` (see the module
    docstring). ``variant``: a TALOS variant with legs (``"reduced"``, ``"full_v2"``).

    Refused with :class:`InvalidInput` naming the argument, before anything is added: a ``builder``
    that is not a ``DiagramBuilder``, is built, or already holds a simulated TALOS (its systems
    ``talos_plant`` and ``scene_graph``: Drake would end the process at ``Build()``); a ``variant``
    without soles (``"left_arm"``) or not a string (an unknown name: :class:`VariantNotFound`); a flag
    that is not a bool; a bad time step, gain, contact option or obstacle."""
    check_physics_builder("add_physical_talos", builder, PLANT_SYSTEMS)
    variant = check_legged_variant("add_physical_talos", variant)
    obstacles = _checked_obstacles(obstacles)
    if not (finite_number(time_step) and 0 < time_step <= MAX_TIME_STEP):
        raise InvalidInput(f"the physics needs a discrete plant: time_step in (0, {MAX_TIME_STEP:g}] s, got {time_step!r}")
    check_contact_options(contact, contact_solver)
    body_collision, pd_gains, sampled_outputs = (check_flag(f"add_physical_talos: {name}", value) for name, value in (
        ("body_collision", body_collision), ("pd_gains", pd_gains), ("sampled_outputs", sampled_outputs)))
    if pd_gains:
        check_pd_gain_values(stiffness, damping)
    with all_or_nothing(builder):  # (a refusal found once the plant is in, e.g. a bad gain, leaves the builder as it was)
        return _build_physical_talos(builder, variant, time_step, stiffness, damping, body_collision, pd_gains, obstacles,
                                     contact, sampled_outputs, contact_solver)


def _build_physical_talos(builder: DiagramBuilder, variant: str, time_step: float, stiffness: float, damping: float,
                          body_collision: bool, pd_gains: bool, obstacles: list, contact: str, sampled_outputs: bool,
                          contact_solver: str) -> PhysicalTalos:
    """:func:`add_physical_talos` once its arguments are checked."""
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step)
    plant.set_discrete_contact_approximation(CONTACT_SOLVERS[contact_solver])
    plant.SetUseSampledOutputPorts(bool(sampled_outputs))
    plant.set_name("talos_plant")
    instance = add_talos(plant, variant, meshes=True, collision=False)
    ground = ProximityProperties()
    AddRigidHydroelasticProperties(ground)
    AddContactMaterial(friction=FRICTION, properties=ground)
    # Each new context would make Drake warn that a rigid half-space gives no contact data with
    # *deformable* bodies. There are none here (the soles are compliant-hydroelastic boxes, which
    # the half-space does touch), so that warning is dropped.
    drop_drake_message("Rigid (non-deformable) half spaces are not currently supported for deformable contact")
    plant.RegisterCollisionGeometry(plant.world_body(), RigidTransform(), HalfSpace(), "ground", ground)
    # Drawn as a flat plate (the half-space itself has no illustration), its top 1 mm under z = 0.
    plant.RegisterVisualGeometry(plant.world_body(), RigidTransform([0.0, 0.0, -GROUND_PLATE[2] / 2 - 1e-3]),
                                 Box(*GROUND_PLATE), "ground_visual", GROUND_COLOR)
    soles = {}
    robot_geometries = []
    for side in ("left", "right"):
        sole = plant.GetFrameByName(f"{side}_sole_link")
        robot_geometries += _add_sole(plant, sole, side, contact)
        soles[side] = sole
    boxed = []
    if body_collision:
        # The feet: each sole's body and the links welded to it keep the sole box alone.
        sole_bodies = {body.name() for frame in soles.values() for body in plant.GetBodiesWeldedTo(frame.body())}
        link_material = ProximityProperties()
        AddContactMaterial(friction=FRICTION, properties=link_material)
        for name, (box_size, box_centre) in fit_link_boxes(variant).items():
            if name in sole_bodies or not plant.HasBodyNamed(name, instance):
                continue
            body = plant.GetBodyByName(name, instance)
            robot_geometries.append(plant.RegisterCollisionGeometry(
                body, RigidTransform(box_centre), Box(*box_size), f"{name}_box", link_material))
            boxed.append(name)
    _add_obstacles(plant, obstacles)
    plant.Finalize()
    # The robot collides with the ground only (see body_collision's docstring).
    scene_graph.collision_filter_manager().Apply(
        CollisionFilterDeclaration().ExcludeWithin(GeometrySet(robot_geometries)))
    if pd_gains:
        set_pd_gains(plant, stiffness, damping)
    actuators = [plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices()]
    return PhysicalTalos(
        plant, scene_graph, instance,
        np.array([a.joint().position_start() for a in actuators]),
        np.array([a.joint().velocity_start() for a in actuators]),
        soles, tuple(boxed),
    )


#: The systems :func:`add_physical_talos` adds, by name: one simulated TALOS per ``DiagramBuilder``.
PLANT_SYSTEMS = ("talos_plant", "scene_graph")
#: The links a variant needs to stand in the physics: its soles.
SOLE_LINKS = ("left_sole_link", "right_sole_link")


def check_physics_builder(what: str, builder: object, names: Sequence[str]) -> DiagramBuilder:
    """``builder`` if it is a ``DiagramBuilder``, not built, without a system named as one of
    ``names`` (the systems ``what`` adds), else :class:`InvalidInput` naming ``what``'s builder."""
    if not isinstance(builder, DiagramBuilder):
        raise InvalidInput(f"{what}: builder: expected a DiagramBuilder, got {type(builder).__name__}")
    if builder.already_built():
        raise InvalidInput(f"{what}: builder is already built (add the physics before builder.Build())")
    taken = sorted(set(names) & {system.get_name() for system in builder.GetSystems()})
    if taken:
        raise InvalidInput(f"{what}: builder already holds systems named {taken} (a simulated TALOS, a station or a "
                           "visualizer): one simulated TALOS per DiagramBuilder")
    return builder


@lru_cache(maxsize=1)
def legged_variants() -> tuple[str, ...]:
    """The TALOS variants whose URDF has both soles (:data:`SOLE_LINKS`): those the physics takes."""
    return tuple(variant for variant in TALOS_VARIANTS if set(SOLE_LINKS) <= _link_names(talos_urdf_path(variant)))


def _link_names(urdf: Path) -> set[str | None]:
    return {link.get("name") for link in ET.parse(urdf).getroot().iter("link")}


def check_legged_variant(what: str, variant: object) -> str:
    """``variant`` if it is a TALOS variant with soles; else :class:`InvalidInput` (not a string, or
    no soles) or :class:`VariantNotFound` (an unknown name), naming ``what``'s variant."""
    if not isinstance(variant, str):
        raise InvalidInput(f"{what}: variant: expected the name of a TALOS variant, got {type(variant).__name__}")
    legged = legged_variants()
    if variant not in TALOS_VARIANTS:
        raise VariantNotFound(variant, list(legged)).but(f"{what}: variant")
    if variant not in legged:
        raise InvalidInput(f"{what}: variant {variant!r} has no soles ({', '.join(SOLE_LINKS)}) to stand on the ground; "
                           f"the physics takes {list(legged)}")
    return variant


def check_contact_options(contact: object, contact_solver: object) -> None:
    """Refuse (:class:`InvalidInput`, naming the argument) a ``contact`` not in ``CONTACT_MODELS`` or a
    ``contact_solver`` not in ``CONTACT_SOLVERS``."""
    if contact not in CONTACT_MODELS:
        raise InvalidInput(f"contact is one of {CONTACT_MODELS}, got {contact!r}")
    if not (isinstance(contact_solver, str) and contact_solver in CONTACT_SOLVERS):
        raise InvalidInput(f"contact_solver is one of {sorted(CONTACT_SOLVERS)}, got {contact_solver!r:.100}")


#: The obstacles' colour in the physics drawing (RGBA).
OBSTACLE_COLOR = np.array([0.85, 0.45, 0.2, 0.6])


def _checked_obstacles(obstacles: object) -> list[tuple[str, Shape, RigidTransform]]:
    """``obstacles`` as a list of ``(name, shape, X_WO)``, each checked (distinct non-empty names)."""
    if isinstance(obstacles, (str, bytes)) or not isinstance(obstacles, Sequence):
        raise InvalidInput(f"obstacles must be a list of (name, shape, X_WO), got {obstacles!r:.100}")
    names: set[str] = set()
    for item in obstacles:
        if not (isinstance(item, tuple) and len(item) == 3 and isinstance(item[0], str) and item[0].strip()
                and isinstance(item[1], Shape) and isinstance(item[2], RigidTransform)):
            raise InvalidInput(f"obstacles: each must be (name, Drake shape, RigidTransform X_WO), got {item!r:.100}")
        if not np.all(np.isfinite(item[2].GetAsMatrix4())):
            raise InvalidInput(f"obstacles: {item[0]!r} has a non-finite pose X_WO")
        if item[0] in names:
            raise InvalidInput(f"obstacles: the name {item[0]!r} is given twice")
        names.add(item[0])
    return list(obstacles)


def _add_obstacles(plant: MultibodyPlant, obstacles: list[tuple[str, Shape, RigidTransform]]) -> None:
    material = ProximityProperties()
    AddContactMaterial(friction=FRICTION, properties=material)
    for name, shape, X_WO in obstacles:
        plant.RegisterCollisionGeometry(plant.world_body(), X_WO, shape, f"obstacle/{name}", material)
        plant.RegisterVisualGeometry(plant.world_body(), X_WO, shape, f"obstacle/{name}_visual", OBSTACLE_COLOR)
