"""A physically simulated TALOS driven by the SoT, as the real robot is (seed: the SoT "is not a
dynamic simulator"; the tutorial uses Gazebo and ros_control for that).

* A discrete ``MultibodyPlant`` (1 ms, Drake's SAP solver) on a ground half-space (drawn as a flat
  6 m plate), gravity on.
  Contact geometry: one box per sole, ``SOLE_BOX`` (0.211 × 0.124 m, the footprint of TALOS' foot
  collision mesh, bottom at the sole frame), compliant-hydroelastic (``SOLE_MODULUS`` Pa, a 2 cm
  thick layer, Hunt-Crossley dissipation ``SOLE_DISSIPATION`` s/m) against a rigid-hydroelastic
  ground; the links' own collision meshes are not loaded. Friction ``μ = 0.9`` (static), ``0.8``
  (dynamic). (Point contact at the box corners made the loaded feet creep by millimetres in seconds;
  the distributed hydroelastic pressure holds them.)
* Every actuator PD-controlled by the plant (as ros_control's position controllers), with
  ``kp = stiffness · effort_limit`` and ``kd = damping · kp`` (defaults 30 rad⁻¹ and 0.05 s), set
  after ``Finalize()`` and checked: a missing or non-positive gain is an error, never a silent fall.
  Torques are saturated at the URDF effort limits by the plant.
* The SoT device's ``q`` (and its velocity command) become the PD references of the actuated joints
  (``DesiredState``). The loop is *open* (the SoT's kinematics reads the device's own ``q``, as
  sot-talos does on the robot) or *closed* (it reads the simulated joints and a base pose from leg
  odometry, ``KinematicBaseEstimator``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import (
    AddCompliantHydroelasticProperties,
    AddContactMaterial,
    AddRigidHydroelasticProperties,
    Box,
    HalfSpace,
    ProximityProperties,
    SceneGraph,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import (
    AddMultibodyPlantSceneGraph,
    ContactResults,
    CoulombFriction,
    ExternallyAppliedSpatialForce,
    MultibodyPlant,
)
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.tree import ModelInstanceIndex, PdControllerGains
from pydrake.systems.framework import BasicVector, Context, DiagramBuilder, LeafSystem, ValueProducer

from .configuration import Layout, PlantContextHolder
from .drake_logging import drop_drake_message
from .exceptions import InvalidInput, SotError
from .robots.talos import add_talos

#: Sole box in the sole frame: size (m) and centre (the bottom face lies on the sole plane).
SOLE_BOX = (np.array([0.211, 0.124, 0.02]), np.array([-0.0054, 0.0, 0.01]))
FRICTION = CoulombFriction(0.9, 0.8)
SOLE_MODULUS = 5e6  # Pa
SOLE_DISSIPATION = 50.0  # s/m
#: The ground's drawing: a plate (m) and its colour (RGBA).
GROUND_PLATE = (6.0, 6.0, 0.01)
GROUND_COLOR = np.array([0.62, 0.64, 0.60, 1.0])


@dataclass
class PhysicalTalos:
    plant: MultibodyPlant
    scene_graph: SceneGraph
    instance: ModelInstanceIndex
    actuated_q: np.ndarray  # q index of each actuator's joint, in actuator order
    actuated_v: np.ndarray
    sole_frames: dict[str, object]


def add_physical_talos(
    builder: DiagramBuilder,
    variant: str = "reduced",
    time_step: float = 1e-3,
    stiffness: float = 30.0,
    damping: float = 0.05,
) -> PhysicalTalos:
    """Add the simulated TALOS (plant + SceneGraph, visual meshes, sole boxes, ground, PD actuators)."""
    if not time_step > 0:
        raise InvalidInput(f"the physics needs a discrete plant: time_step > 0, got {time_step}")
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step)
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
    set_pd_gains(plant, stiffness, damping)
    actuators = [plant.get_joint_actuator(i) for i in plant.GetJointActuatorIndices()]
    return PhysicalTalos(
        plant, scene_graph, instance,
        np.array([a.joint().position_start() for a in actuators]),
        np.array([a.joint().velocity_start() for a in actuators]),
        soles,
    )


def set_pd_gains(plant: MultibodyPlant, stiffness: float, damping: float) -> None:
    """``kp = stiffness · effort_limit``, ``kd = damping · kp`` on every actuator, then
    :func:`check_pd_gains`."""
    if not (np.isfinite(stiffness) and stiffness > 0 and np.isfinite(damping) and damping >= 0):
        raise InvalidInput(f"PD gains need stiffness > 0 and damping ≥ 0, got {stiffness}, {damping}")
    for index in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(index)
        kp = stiffness * actuator.effort_limit()
        actuator.set_controller_gains(PdControllerGains(p=kp, d=damping * kp))
    check_pd_gains(plant)


def check_pd_gains(plant: MultibodyPlant) -> None:
    """Every actuator must have a PD controller with finite ``kp > 0`` and ``kd ≥ 0`` (else the
    plant ignores its desired state for that joint and the robot falls without a word)."""
    bad = []
    for index in plant.GetJointActuatorIndices():
        actuator = plant.get_joint_actuator(index)
        if not actuator.has_controller():
            bad.append(f"{actuator.name()}: no PD controller")
            continue
        gains = actuator.get_controller_gains()
        if not (np.isfinite(gains.p) and gains.p > 0 and np.isfinite(gains.d) and gains.d >= 0):
            bad.append(f"{actuator.name()}: kp = {gains.p}, kd = {gains.d}")
    if bad:
        raise SotError("PD gains not set on every actuator: " + "; ".join(bad))


class DesiredState(LeafSystem):
    """The PD references: inputs ``position`` (the device's ``q``) and ``velocity`` (the solver's
    ``v``); output ``desired_state`` = ``(q, v)`` of the actuated joints, in actuator order."""

    def __init__(self, robot: PhysicalTalos, name: str = "desired_state"):
        LeafSystem.__init__(self)
        self.set_name(name)
        self._q, self._v = robot.actuated_q, robot.actuated_v
        self.position = self.DeclareVectorInputPort("position", robot.plant.num_positions())
        self.velocity = self.DeclareVectorInputPort("velocity", robot.plant.num_velocities())
        self.DeclareVectorOutputPort("desired_state", 2 * len(self._q), self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(np.concatenate([self.position.Eval(context)[self._q], self.velocity.Eval(context)[self._v]]))


class Push(LeafSystem):
    """A horizontal push on a body: ``force`` (N, world frame) at the body origin during
    ``[start, start + duration)``. Output ``applied_spatial_force`` for the plant."""

    def __init__(self, plant: MultibodyPlant, body_name: str, force, start: float, duration: float):
        LeafSystem.__init__(self)
        self.set_name("push")
        self.body_index = plant.GetBodyByName(body_name).index()
        self.force = np.asarray(force, dtype=float)
        if self.force.shape != (3,) or not np.all(np.isfinite(self.force)) or not duration > 0 or start < 0:
            raise InvalidInput(f"push: a finite 3D force, start ≥ 0 and duration > 0, got {force}, {start}, {duration}")
        self.start, self.end = start, start + duration
        self.DeclareAbstractOutputPort("applied_spatial_force", lambda: AbstractValue.Make([ExternallyAppliedSpatialForce()]), self._calc)

    def _calc(self, context: Context, output: AbstractValue) -> None:
        push = ExternallyAppliedSpatialForce()
        push.body_index = self.body_index
        active = self.start <= context.get_time() < self.end
        push.F_Bq_W = SpatialForce(np.zeros(3), self.force if active else np.zeros(3))
        output.set_value([push])


class ContactMonitor(LeafSystem):
    """From the plant's contact results: output ``feet`` = ``(f_left (3), f_right (3), cop (2))``,
    the total contact force on each sole (N, world) and the centre of pressure of all contacts on
    the ground (z = 0): with each contact's force ``f`` at point ``c`` and moment ``τ`` about it,
    ``cop = (Σ c_x f_z - τ_y, Σ c_y f_z + τ_x) / Σ f_z`` (m; NaN when nothing touches)."""

    def __init__(self, robot: PhysicalTalos, name: str = "contact_monitor"):
        LeafSystem.__init__(self)
        self.set_name(name)
        plant = robot.plant
        self._bodies = {side: frame.body().index() for side, frame in robot.sole_frames.items()}
        inspector = robot.scene_graph.model_inspector()
        self._geometry_bodies = {
            geometry: plant.GetBodyFromFrameId(inspector.GetFrameId(geometry)).index()
            for geometry in inspector.GetAllGeometryIds()
            if plant.GetBodyFromFrameId(inspector.GetFrameId(geometry)) is not None
        }
        self.contact_results = self.DeclareAbstractInputPort("contact_results", AbstractValue.Make(ContactResults()))
        self.DeclareVectorOutputPort("feet", 8, self._calc)

    def _calc(self, context: Context, output: BasicVector) -> None:
        results = self.contact_results.Eval(context)
        forces = {"left": np.zeros(3), "right": np.zeros(3)}
        moment, total = np.zeros(2), 0.0

        def add(body_a, body_b, force, torque, point):
            nonlocal total
            for side, body in self._bodies.items():
                sign = 1.0 if body_a == body else -1.0 if body_b == body else 0.0
                if sign:  # the force on the foot
                    f, tau = sign * force, sign * torque
                    forces[side] += f
                    moment[:] += [point[0] * f[2] - tau[1], point[1] * f[2] + tau[0]]
                    total += f[2]

        for i in range(results.num_hydroelastic_contacts()):
            info = results.hydroelastic_contact_info(i)
            surface = info.contact_surface()
            F = info.F_Ac_W()  # on the body of geometry M, at the surface's centroid
            body_m, body_n = self._geometry_bodies[surface.id_M()], self._geometry_bodies[surface.id_N()]
            add(body_m, body_n, F.translational(), F.rotational(), surface.centroid())
        for i in range(results.num_point_pair_contacts()):
            info = results.point_pair_contact_info(i)  # force on body B at the contact point
            add(info.bodyB_index(), info.bodyA_index(), info.contact_force(), np.zeros(3), info.contact_point())
        cop = moment / total if total > 1e-9 else np.full(2, np.nan)
        output.SetFromVector(np.concatenate([forces["left"], forces["right"], cop]))


class KinematicBaseEstimator(LeafSystem):
    """The closed loop's estimate of ``q``: the measured joints, and the base pose by leg odometry.

    With both soles in contact where they were at the start (``X_WS0``), each sole gives a base pose
    ``X_WB = X_WS0 · X_BS(q)⁻¹`` from the measured joints (``X_BS`` the base-to-sole kinematics); the
    estimate averages the two (translations, and the normalised sum of the quaternions). This is the
    usual humanoid estimator's kinematic part: the feet's compliance against the ground goes into the
    base estimate instead of into the contact tasks' errors, where an integrating SoT would wind up
    against it. Input ``plant_state`` (``(q, v)`` of the simulated robot); output ``position``.
    """

    def __init__(self, model, q0: np.ndarray, name: str = "estimator"):
        LeafSystem.__init__(self)
        self.set_name(name)
        self.plant = model.plant
        self.layout = Layout.of(self.plant)
        if self.layout.base_q is None:
            raise InvalidInput("the base estimator needs a floating base")
        self._base = self.plant.get_body(next(iter(self.plant.GetFloatingBaseBodies()))).body_frame()
        self._soles = [model.frame("left-sole"), model.frame("right-sole")]
        context = self.plant.CreateDefaultContext()
        self.plant.SetPositions(context, q0)
        self._X_WS0 = [self.plant.CalcRelativeTransform(context, self.plant.world_frame(), s) for s in self._soles]
        nq, nv = self.plant.num_positions(), self.plant.num_velocities()
        self.plant_state = self.DeclareVectorInputPort("plant_state", nq + nv)
        # The kinematics' plant context lives in a cache entry, as the dynamic entity's does.
        self._plant_context = self.DeclareCacheEntry(
            "plant_context",
            ValueProducer(allocate=lambda: AbstractValue.Make(PlantContextHolder(self.plant)), calc=self._set_positions),
            prerequisites_of_calc={self.input_port_ticket(self.plant_state.get_index())},
        )
        self.DeclareVectorOutputPort("position", nq, self._calc)

    def _set_positions(self, context: Context, value: AbstractValue) -> None:
        self.plant.SetPositions(value.get_mutable_value().context, self.plant_state.Eval(context)[: self.plant.num_positions()])

    def _calc(self, context: Context, output: BasicVector) -> None:
        plant_context = self._plant_context.Eval(context).context
        q = self.plant.GetPositions(plant_context)
        poses = [X_WS0.multiply(self.plant.CalcRelativeTransform(plant_context, self._base, sole).inverse())
                 for X_WS0, sole in zip(self._X_WS0, self._soles)]
        quaternions = [X.rotation().ToQuaternion().wxyz() for X in poses]
        if quaternions[0] @ quaternions[1] < 0:
            quaternions[1] = -quaternions[1]
        mean = quaternions[0] + quaternions[1]  # (w, x, y, z), as Drake's q
        iq = self.layout.base_q
        q[iq : iq + 4] = mean / np.linalg.norm(mean)
        q[iq + 4 : iq + 7] = 0.5 * (poses[0].translation() + poses[1].translation())
        output.SetFromVector(q)
