"""The SoT ``dynamic`` entity: operational points, their Jacobians, the centre of mass.

All quantities are computed by Drake on the *control model* plant (no geometry), whose context
lives in a cache entry that depends only on the ``position`` input, so forward kinematics runs
once per configuration whatever the number of op points read.

Conventions (Drake monogram notation): the pose output of op point F is ``X_WF``
(``RigidTransform``); its Jacobian ``J_WF`` is the 6×nv spatial-velocity Jacobian with respect to
the generalized velocities ``v``, rows ``(ω_WF; v_WF)`` expressed in the world frame, ``v_WF`` the
velocity of F's origin. ``com`` is ``p_WCm`` (m) and ``Jcom`` its 3×nv Jacobian.

``Jcom`` of a floating-base robot comes from Drake's mass matrix: the base's translational
velocity ``v_WBo`` (world) is conjugate to the total linear momentum, ``∂T/∂v_WBo = Σ mᵢ ṗ_WCmᵢ =
m ṗ_WCm``, so the rows of ``M(q)`` of ``v_WBo`` are ``m·Jcom``. ``CalcMassMatrix`` costs about a
tenth of ``CalcJacobianCenterOfMassTranslationalVelocity`` on TALOS (which sums a Jacobian per
body). The identity is checked against Drake's CoM Jacobian at construction; a robot for which it
does not hold (fixed base, several free bodies) uses Drake's CoM Jacobian.
"""

from __future__ import annotations

import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import BasicVector, Context, LeafSystem, OutputPort, ValueProducer

from .atomic import in_built_diagram
from .centroidal import centroidal_momentum_matrix
from .configuration import Layout, PlantContextHolder
from .exceptions import InvalidInput, SotError, check_finite, check_name
from .lie import MIN_QUATERNION_NORM, check_base_quaternion
from .robots import RobotModel


class Dynamic(LeafSystem):
    """Kinematics of the control model: input ``position`` (q, size nq).

    Outputs: ``com`` (3), ``Jcom`` (3×nv), ``momentum_matrix`` (the centroidal momentum matrix
    ``A_G``, 6×nv, rows ``(k_G; l)``: :mod:`sotdrake.centroidal`; a floating base only) and, for
    each op point created with :meth:`createOpPoint`, ``<name>`` (``X_WF``) and ``J<name>`` (``J_WF``).
    """

    def __init__(self, model: RobotModel, name: str = "dynamic"):
        LeafSystem.__init__(self)
        self.set_name(name)
        self.model = model
        self.plant = model.plant
        self._world = self.plant.world_frame()
        self._position = self.DeclareVectorInputPort("position", model.nq)
        self._plant_context = self.DeclareCacheEntry(
            "plant_context",
            ValueProducer(
                allocate=lambda: AbstractValue.Make(PlantContextHolder(self.plant)),
                calc=self._calc_plant_context,
            ),
            prerequisites_of_calc={self.input_port_ticket(self._position.get_index())},
        )
        self.DeclareVectorOutputPort("com", 3, self._calc_com)
        self.DeclareAbstractOutputPort(
            "Jcom", lambda: AbstractValue.Make(np.zeros((3, model.nv))), self._calc_com_jacobian
        )
        self._layout = Layout.of(self.plant)
        self.DeclareAbstractOutputPort(
            "momentum_matrix", lambda: AbstractValue.Make(np.zeros((6, model.nv))), self._calc_momentum_matrix
        )
        self._op_points: dict[str, tuple[object, RigidTransform]] = {}
        self._com_rows = _momentum_rows(self.plant)


    # --- op points -------------------------------------------------------------------------
    def createOpPoint(self, name: str, frame_name: str) -> tuple[OutputPort, OutputPort]:
        """Declare the outputs ``name`` (pose) and ``J<name>`` (Jacobian) of the frame
        ``frame_name`` (an op-point name like ``'right-wrist'``, a joint or a frame of the plant).

        Creating the same op point twice returns the existing ports; another frame under the same
        name is an error. Raises :class:`FrameNotFound` for an unknown frame, :class:`SotError` once
        this entity is in a built diagram (its contexts would not have the new ports).
        """
        frame = self.check_op_point(name, frame_name)
        if name in self._op_points:
            return self.GetOutputPort(name), self.GetOutputPort("J" + name)
        if in_built_diagram(self):
            raise SotError(f"{self.get_name()}: cannot create the op point {name!r:.60}: the diagram is already built "
                           "(create op points, and the meta tasks that make them, before builder.Build())")
        self._op_points[name] = (frame, frame_name)
        pose = self.DeclareAbstractOutputPort(
            name, lambda: AbstractValue.Make(RigidTransform()), lambda c, o: o.set_value(self._pose(c, frame))
        )
        jac = self.DeclareAbstractOutputPort(
            "J" + name,
            lambda: AbstractValue.Make(np.zeros((6, self.model.nv))),
            lambda c, o: o.set_value(self._jacobian(c, frame)),
        )
        return pose, jac

    def check_op_point(self, name: str, frame_name: str):
        """The frame of a new or existing op point ``name`` on ``frame_name``, checked as
        :meth:`createOpPoint` does (an unknown frame, another frame under that name, a name taken by
        another output or by another frame of the model), without declaring anything."""
        check_name("op point name", name)
        frame = self.model.frame(frame_name)
        if name in self._op_points:
            if self._op_points[name][0] is not frame:
                raise InvalidInput(f"op point {name!r} already exists on another frame")
            return frame
        for port_name in (name, "J" + name):
            if self.HasOutputPort(port_name):
                raise InvalidInput(f"{self.get_name()} already has an output named {port_name!r}")
        named = self.model.find_frame(name)
        if named is not None and named.index() != frame.index():  # (the op point would hide that frame)
            raise InvalidInput(f"op point {name!r} on {frame_name!r}: {name!r} already names another frame of "
                               f"{self.model.name} ({named.name()!r}); give the op point another name")
        return frame

    def hasOpPoint(self, name: str) -> bool:
        return name in self._op_points

    # --- calc ------------------------------------------------------------------------------
    def _calc_plant_context(self, context: Context, value: AbstractValue) -> None:
        q = self._position.Eval(context)
        if not math.isfinite(q.sum()):  # Drake would abort the process
            raise InvalidInput(f"{self.get_name()}: non-finite position at t = {context.get_time()}: {q}")
        self.plant.SetPositions(value.get_mutable_value().context, q)

    def _plant_ctx(self, context: Context):
        return self._plant_context.Eval(context).context

    def _pose(self, context: Context, frame) -> RigidTransform:
        return self.plant.CalcRelativeTransform(self._plant_ctx(context), self._world, frame)

    def _jacobian(self, context: Context, frame) -> np.ndarray:
        return self.plant.CalcJacobianSpatialVelocity(
            self._plant_ctx(context), JacobianWrtVariable.kV, frame, np.zeros(3), self._world, self._world
        )

    def _calc_com(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self.plant.CalcCenterOfMassPositionInWorld(self._plant_ctx(context)))

    def _calc_com_jacobian(self, context: Context, output: AbstractValue) -> None:
        plant_context = self._plant_ctx(context)
        if self._com_rows is not None:
            rows, mass = self._com_rows
            output.set_value(self.plant.CalcMassMatrix(plant_context)[rows] / mass)
            return
        output.set_value(self.plant.CalcJacobianCenterOfMassTranslationalVelocity(
            plant_context, JacobianWrtVariable.kV, self._world, self._world))

    def _calc_momentum_matrix(self, context: Context, output: AbstractValue) -> None:
        plant_context = self._plant_ctx(context)
        M = self.plant.CalcMassMatrix(plant_context)
        p_WG = self.plant.CalcCenterOfMassPositionInWorld(plant_context)
        output.set_value(centroidal_momentum_matrix(M, self.plant.GetPositions(plant_context), p_WG, self._layout))

    # --- evaluation at a given configuration (build time, tests, post-processing) ----------
    def _context_at(self, q: np.ndarray):
        q = check_finite("q", q, (self.model.nq,))
        if self._layout.base_q is not None:
            check_base_quaternion("q", q, self._layout.base_q)
        context = self.plant.CreateDefaultContext()
        self.plant.SetPositions(context, q)
        return context

    def frame(self, name: str):
        """The frame of one of this entity's op points, else :meth:`RobotModel.frame`."""
        return self._op_points[name][0] if isinstance(name, str) and name in self._op_points else self.model.frame(name)

    def pose_at(self, name: str, q: np.ndarray) -> RigidTransform:
        """``X_WF`` of an op point of this entity, or of a frame, at configuration ``q`` (nq finite
        numbers, the floating base's quaternion of norm ≥ 1e-6, normalised by Drake; else
        :class:`InvalidInput` naming ``q``)."""
        return self.plant.CalcRelativeTransform(self._context_at(q), self._world, self.frame(name))

    def trajectory(self, names: list[str], qs: np.ndarray) -> dict[str, np.ndarray]:
        """Along configurations ``qs`` (k×nq): ``X_WF`` of each named op point or frame as a
        (k, 4, 4) array, and ``'com'`` (k, 3). For post-processing traces. Each row of ``qs`` is
        checked as :meth:`pose_at` checks ``q`` (finite, the base's quaternion of norm ≥ 1e-6; else
        :class:`InvalidInput` naming the row)."""
        qs = check_finite("qs", qs)
        if qs.ndim != 2 or qs.shape[1] != self.model.nq:
            raise InvalidInput(f"qs: expected shape (k, {self.model.nq}), got {qs.shape}")
        base = self._layout.base_q
        if base is not None and len(qs):
            norms = np.linalg.norm(qs[:, base : base + 4], axis=1)
            if not norms.min() >= MIN_QUATERNION_NORM:  # (the first such row named)
                k = int(np.flatnonzero(norms < MIN_QUATERNION_NORM)[0])
                check_base_quaternion(f"qs[{k}]", qs[k], base)
        frames = {name: self.frame(name) for name in names}
        out = {name: np.empty((len(qs), 4, 4)) for name in names}
        out["com"] = np.empty((len(qs), 3))
        context = self.plant.CreateDefaultContext()
        for k, q in enumerate(qs):
            self.plant.SetPositions(context, q)
            for name, frame in frames.items():
                out[name][k] = self.plant.CalcRelativeTransform(context, self._world, frame).GetAsMatrix4()
            out["com"][k] = self.plant.CalcCenterOfMassPositionInWorld(context)
        return out

    def com_at(self, q: np.ndarray) -> np.ndarray:
        """``p_WCm`` at configuration ``q`` (checked as :meth:`pose_at` does); :class:`InvalidInput` for
        a robot of no mass, which has no centre of mass."""
        context = self._context_at(q)
        mass = self.plant.CalcTotalMass(context)
        if not mass > 0:
            raise InvalidInput(f"the robot {self.model.name!r} has a total mass of {mass:g} kg: it has no centre of mass "
                               "(give its links masses: <inertial> in a URDF)")
        return self.plant.CalcCenterOfMassPositionInWorld(context)


def _momentum_rows(plant) -> tuple[slice, float] | None:
    """``(rows, m)`` such that ``M(q)[rows] / m`` is the CoM Jacobian (see the module docstring),
    or None when the identity does not hold for this plant (checked at a random configuration)."""
    bases = list(plant.GetFloatingBaseBodies())
    if len(bases) != 1:
        return None
    start = plant.get_body(bases[0]).floating_velocities_start_in_v()
    rows = slice(start + 3, start + 6)
    context = plant.CreateDefaultContext()
    rng = np.random.default_rng(0)
    plant.SetPositions(context, plant.GetPositions(context) + 0.1 * rng.standard_normal(plant.num_positions()))
    mass = plant.CalcTotalMass(context)
    if not mass > 0:
        return None
    world = plant.world_frame()
    reference = plant.CalcJacobianCenterOfMassTranslationalVelocity(context, JacobianWrtVariable.kV, world, world)
    if not np.allclose(plant.CalcMassMatrix(context)[rows] / mass, reference, atol=1e-9, rtol=0):
        return None
    return rows, mass
