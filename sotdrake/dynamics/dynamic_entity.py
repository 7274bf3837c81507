"""The dynamic entity (sot-dyninv ``Dynamic`` with its dynamic outputs): from the measured state
``(q, v)``, the kinematics of :class:`sotdrake.kinematics.Dynamic` plus the dynamics terms.

Input ``state`` (``(q, v)``, size nq + nv). Outputs:

* ``position`` (q), ``velocity`` (v);
* ``com`` (``p_WCm``, m), ``Jcom`` (3×nv), ``com_drift`` (``J̇_CoM v``, m/s²), the last two from
  the floating-base rows of ``M`` and ``C v`` (:func:`.terms.com_terms`);
* ``momentum`` (``h_G``, the centroidal momentum ``(k_G; l)``: kg·m²/s, kg·m/s, world),
  ``momentum_drift`` (``Ȧ_G v``), ``momentum_matrix`` (``A_G``, 6×nv) and ``momentum_terms``
  (all three), from the floating-base rows of ``M`` and ``C v`` (:mod:`sotdrake.centroidal`; a
  floating base only);
* ``dynamics``: :class:`.terms.DynamicsTerms` (``M`` from ``CalcMassMatrix``, ``C v`` from
  ``CalcBiasTerm``, ``τ_g = M[:, t] g`` from the base's translational columns of ``M``
  (:func:`.terms.gravity_columns`, checked at construction; else Drake's
  ``CalcGravityGeneralizedForces``), ``h = C v − τ_g + D v`` with ``D`` the joints' damping, ``B``
  from ``MakeActuationMatrix``);
* per op point (:meth:`createOpPoint`): ``<name>`` (``X_WF``), ``J<name>`` (``J_WF``, rows
  ``(ω; v)`` world), ``<name>_drift`` (``J̇_WF v``, the bias spatial acceleration of F's origin,
  ``CalcBiasSpatialAcceleration``, rows ``(α; a)`` world) and ``<name>_kinematics`` (all of it and
  ``J_WF v`` in one :class:`.terms.OpPointMotion`: what a contact reads, one port instead of four).

The plant context lives in one cache entry that depends on ``state`` only. Every other output is
computed by its port (Drake caches each output port's value): ``com_drift`` and ``Jcom`` read the
``dynamics`` port.
"""

from __future__ import annotations

import copy
import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import BasicVector, Context, OutputPort, ValueProducer

from ..centroidal import centroidal_momentum_terms
from ..configuration import Layout
from ..exceptions import InvalidInput, OperationalPointNotFound, check_name
from ..kinematics import Dynamic, PlantContextHolder
from ..robots import RobotModel
from .terms import DynamicsTerms, OpPointMotion, base_translation_rows, com_terms, gravity_columns


class StateContextHolder(PlantContextHolder):
    """:class:`PlantContextHolder` whose context is set from the state ``x = (q, v)``, kept with it."""

    def __init__(self, plant):
        PlantContextHolder.__init__(self, plant)
        self.x = np.zeros(plant.num_multibody_states())

    def __deepcopy__(self, memo: dict) -> StateContextHolder:
        clone = copy.copy(self)
        clone.context, clone.x = self.context.Clone(), self.x.copy()
        return clone


_ORIGIN = np.zeros(3)  # the op point is the frame's origin
_ORIGIN.flags.writeable = False


class DynamicEntity(Dynamic):
    """``dynamic`` over the measured state (see the module docstring).

    Inputs: ``state`` (``x = (q, v)``, nq + nv). Outputs: ``position`` (``q``), ``velocity``
    (``v``), ``dynamics`` (:class:`.terms.DynamicsTerms`), ``com`` (m, world), ``Jcom`` (3 × nv),
    ``com_drift`` (``J̇_com v``, m/s²), ``momentum_terms`` (``(A_G, Ȧ_G v, h_G)``),
    ``momentum_matrix`` (``A_G``, 6 × nv), ``momentum`` (``h_G``, the centroidal momentum:
    angular N·m·s, linear kg·m/s) and ``momentum_drift`` (``Ȧ_G v``); per op point,
    ``<name>_drift`` and ``<name>_kinematics`` (:meth:`createOpPoint`).
    """

    def __init__(self, model: RobotModel, name: str = "dynamic"):
        Dynamic.__init__(self, model, name)  # declares the kinematic outputs over _plant_ctx
        plant = self.plant
        self.layout = Layout.of(plant)
        self.nq, self.nv = model.nq, model.nv
        self.B = plant.MakeActuationMatrix()
        self.B.flags.writeable = False  # the same array in every DynamicsTerms (SolverDyn caches on it)
        self.mass = plant.CalcTotalMass(plant.CreateDefaultContext())
        self.damping = np.zeros(self.nv)  # the joints' viscous damping (N·m·s/rad), applied by the plant
        for index in plant.GetJointIndices():
            joint = plant.get_joint(index)
            if joint.num_velocities():
                self.damping[joint.velocity_start() : joint.velocity_start() + joint.num_velocities()] = joint.default_damping_vector()
        self.state = self.DeclareVectorInputPort("state", self.nq + self.nv)
        self._state_context = self.DeclareCacheEntry(
            "plant_state_context",
            ValueProducer(allocate=lambda: AbstractValue.Make(StateContextHolder(plant)), calc=self._calc_state_context),
            prerequisites_of_calc={self.input_port_ticket(self.state.get_index())},
        )
        self._gravity = gravity_columns(plant, self.layout)  # τ_g from M, when it holds for this plant
        self._base_rows = base_translation_rows(self.layout)  # com_terms' rows
        self.DeclareVectorOutputPort("position", self.nq, lambda c, o: o.SetFromVector(self.state.Eval(c)[: self.nq]))
        self.DeclareVectorOutputPort("velocity", self.nv, lambda c, o: o.SetFromVector(self.state.Eval(c)[self.nq :]))
        self._dynamics = self.DeclareAbstractOutputPort("dynamics", lambda: AbstractValue.Make(self._empty_terms()), self._calc_terms)
        self.DeclareVectorOutputPort("com_drift", 3, self._calc_com_drift)
        self._momentum = self.DeclareAbstractOutputPort(
            "momentum_terms", lambda: AbstractValue.Make((np.zeros((6, self.nv)), np.zeros(6), np.zeros(6))),
            self._calc_momentum_terms)
        self.DeclareVectorOutputPort("momentum", 6, lambda c, o: o.SetFromVector(self._momentum.Eval(c)[2]))
        self.DeclareVectorOutputPort("momentum_drift", 6, lambda c, o: o.SetFromVector(self._momentum.Eval(c)[1]))

    def _empty_terms(self) -> DynamicsTerms:
        nv = self.nv
        return DynamicsTerms(np.eye(nv), np.zeros(nv), np.zeros(nv), self.B, np.zeros(self.nq), np.zeros(nv), self.mass)

    # The kinematics reads the state's plant context (the position input of Dynamic is unused).
    def _plant_ctx(self, context: Context):
        return self._state_context.Eval(context).context

    def _calc_state_context(self, context: Context, value: AbstractValue) -> None:
        x = self.state.Eval(context)
        if not math.isfinite(x @ x) and not np.isfinite(x).all():  # Drake would abort the process (‖x‖² first)
            raise InvalidInput(f"{self.get_name()}: non-finite state at t = {context.get_time()}")
        holder = value.get_mutable_value()
        self.plant.SetPositionsAndVelocities(holder.context, x)
        holder.x = x

    def _calc_terms(self, context: Context, value: AbstractValue) -> None:
        plant, holder = self.plant, self._state_context.Eval(context)
        pc, x = holder.context, holder.x  # x: the state input's value (a copy of its own: q and v are views of it)
        M = np.ascontiguousarray(plant.CalcMassMatrix(pc))  # (column-major from Drake) C-ordered, as compiled code takes it
        Cv = plant.CalcBiasTerm(pc)
        v = x[self.nq :]
        if self._gravity is not None:
            columns, g = self._gravity
            h = Cv - M[:, columns] @ g
        else:
            h = Cv - plant.CalcGravityGeneralizedForces(pc)
        h += self.damping * v
        value.set_value(DynamicsTerms(M, h, Cv, self.B, x[: self.nq], v, self.mass))

    def _calc_com_jacobian(self, context: Context, output: AbstractValue) -> None:
        terms = self._dynamics.Eval(context)
        if self._base_rows is None:
            com_terms(terms.M, terms.Cv, self.mass, self.layout)  # says why it cannot
        output.set_value(terms.M[self._base_rows] / self.mass)  # com_terms' J_CoM alone

    def _calc_momentum_terms(self, context: Context, value: AbstractValue) -> None:
        """``(A_G, Ȧ_G v, h_G)`` from the dynamics terms (:mod:`sotdrake.centroidal`)."""
        terms = self._dynamics.Eval(context)
        p_WG = self.GetOutputPort("com").Eval(context)
        value.set_value(centroidal_momentum_terms(terms.M, terms.Cv, terms.q, terms.v, p_WG, self.layout))

    def _calc_momentum_matrix(self, context: Context, output: AbstractValue) -> None:
        output.set_value(self._momentum.Eval(context)[0])

    def _calc_com_drift(self, context: Context, output: BasicVector) -> None:
        terms = self._dynamics.Eval(context)
        if self._base_rows is None:
            com_terms(terms.M, terms.Cv, self.mass, self.layout)
        output.SetFromVector(terms.Cv[self._base_rows] / self.mass)  # com_terms' J̇_CoM v alone

    def createOpPoint(self, name: str, frame_name: str) -> tuple[OutputPort, OutputPort]:
        """As :meth:`Dynamic.createOpPoint`, plus the outputs ``<name>_drift`` (``J̇_WF v``) and
        ``<name>_kinematics`` (:class:`.terms.OpPointMotion`)."""
        pose, jacobian = Dynamic.createOpPoint(self, name, frame_name)
        if not self.HasOutputPort(name + "_drift"):
            frame = self._op_points[name][0]
            self.DeclareVectorOutputPort(name + "_drift", 6, lambda c, o, f=frame: o.SetFromVector(self._drift(c, f)))
            empty = OpPointMotion(RigidTransform(), np.zeros((6, self.nv)), np.zeros(6), np.zeros(6))
            self.DeclareAbstractOutputPort(name + "_kinematics", lambda: AbstractValue.Make(empty),
                                           lambda c, o, f=frame: o.set_value(self._motion(c, f)))
        return pose, jacobian

    def _drift(self, context: Context, frame) -> np.ndarray:
        A = self.plant.CalcBiasSpatialAcceleration(
            self._plant_ctx(context), JacobianWrtVariable.kV, frame, np.zeros(3), self._world, self._world
        )
        return A.get_coeffs()

    def _motion(self, context: Context, frame) -> OpPointMotion:
        plant, pc, world = self.plant, self._plant_ctx(context), self._world
        J = plant.CalcJacobianSpatialVelocity(pc, JacobianWrtVariable.kV, frame, _ORIGIN, world, world)
        drift = plant.CalcBiasSpatialAcceleration(pc, JacobianWrtVariable.kV, frame, _ORIGIN, world, world).get_coeffs()
        return OpPointMotion(plant.CalcRelativeTransform(pc, world, frame), J, drift, frame.CalcSpatialVelocityInWorld(pc).get_coeffs())

    def drift_port(self, name: str) -> OutputPort:
        """The output ``<name>_drift`` of op point ``name`` (:meth:`createOpPoint` first; else
        :class:`~sotdrake.exceptions.OperationalPointNotFound` listing the op points created)."""
        return self.GetOutputPort(self._op_point_of("drift_port", name) + "_drift")

    def kinematics_port(self, name: str) -> OutputPort:
        """The output ``<name>_kinematics`` of op point ``name`` (:meth:`createOpPoint` first; else
        :class:`~sotdrake.exceptions.OperationalPointNotFound` listing the op points created)."""
        return self.GetOutputPort(self._op_point_of("kinematics_port", name) + "_kinematics")

    def _op_point_of(self, what: str, name: str) -> str:
        """``name`` if it is an op point of this entity, else :class:`OperationalPointNotFound`."""
        check_name(f"{self.get_name()}.{what}: the op point's name", name)
        if name not in self._op_points:
            raise OperationalPointNotFound(name, list(self._op_points)).but(
                f"{self.get_name()}.{what}: create the op point first (createOpPoint(name, frame))")
        return name
