"""The dynamic entity (sot-dyninv ``Dynamic`` with its dynamic outputs): from the measured state
``(q, v)``, the kinematics of :class:`sotdrake.kinematics.Dynamic` plus the dynamics terms.

Input ``state`` (``(q, v)``, size nq + nv). Outputs:

* ``position`` (q), ``velocity`` (v);
* ``com`` (``p_WCm``, m), ``Jcom`` (3×nv), ``com_drift`` (``J̇_CoM v``, m/s²), the last two from
  the floating-base rows of ``M`` and ``C v`` (:func:`.terms.com_terms`);
* ``dynamics``: :class:`.terms.DynamicsTerms` (``M`` from ``CalcMassMatrix``, ``C v`` from
  ``CalcBiasTerm``, ``τ_g`` from ``CalcGravityGeneralizedForces``, ``h = C v − τ_g + D v`` with
  ``D`` the joints' damping, ``B`` from ``MakeActuationMatrix``);
* per op point (:meth:`createOpPoint`): ``<name>`` (``X_WF``), ``J<name>`` (``J_WF``, rows
  ``(ω; v)`` world) and ``<name>_drift`` (``J̇_WF v``, the bias spatial acceleration of F's origin,
  ``CalcBiasSpatialAcceleration``, rows ``(α; a)`` world).

The plant context lives in one cache entry that depends on ``state`` only.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.tree import JacobianWrtVariable
from pydrake.systems.framework import BasicVector, Context, OutputPort, ValueProducer

from ..configuration import Layout
from ..exceptions import InvalidInput
from ..kinematics import Dynamic, PlantContextHolder
from ..robots import RobotModel
from .terms import DynamicsTerms, com_terms


class DynamicEntity(Dynamic):
    """``dynamic`` over the measured state (see the module docstring)."""

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
            ValueProducer(allocate=lambda: AbstractValue.Make(PlantContextHolder(plant)), calc=self._calc_state_context),
            prerequisites_of_calc={self.input_port_ticket(self.state.get_index())},
        )
        self._terms = self.DeclareCacheEntry(
            "dynamics_terms",
            ValueProducer(allocate=lambda: AbstractValue.Make(self._empty_terms()), calc=self._calc_terms),
            prerequisites_of_calc={self.cache_entry_ticket(self._state_context.cache_index())},
        )
        self.DeclareVectorOutputPort("position", self.nq, lambda c, o: o.SetFromVector(self.state.Eval(c)[: self.nq]))
        self.DeclareVectorOutputPort("velocity", self.nv, lambda c, o: o.SetFromVector(self.state.Eval(c)[self.nq :]))
        self.DeclareAbstractOutputPort("dynamics", lambda: AbstractValue.Make(self._empty_terms()),
                                       lambda c, o: o.set_value(self._terms.Eval(c)))
        self.DeclareVectorOutputPort("com_drift", 3, self._calc_com_drift)

    def _empty_terms(self) -> DynamicsTerms:
        nv = self.nv
        return DynamicsTerms(np.eye(nv), np.zeros(nv), np.zeros(nv), self.B, np.zeros(self.nq), np.zeros(nv), self.mass)

    # The kinematics reads the state's plant context (the position input of Dynamic is unused).
    def _plant_ctx(self, context: Context):
        return self._state_context.Eval(context).context

    def _calc_state_context(self, context: Context, value: AbstractValue) -> None:
        x = self.state.Eval(context)
        if not np.all(np.isfinite(x)):  # Drake would abort the process
            raise InvalidInput(f"{self.get_name()}: non-finite state at t = {context.get_time()}")
        self.plant.SetPositionsAndVelocities(value.get_mutable_value().context, x)

    def _calc_terms(self, context: Context, value: AbstractValue) -> None:
        plant, pc = self.plant, self._plant_ctx(context)
        M = plant.CalcMassMatrix(pc)
        Cv = plant.CalcBiasTerm(pc)
        x = self.state.Eval(context)  # a fresh copy: q and v are views of it
        v = x[self.nq :]
        h = Cv - plant.CalcGravityGeneralizedForces(pc) + self.damping * v
        value.set_value(DynamicsTerms(M, h, Cv, self.B, x[: self.nq], v, self.mass))

    def _calc_com_jacobian(self, context: Context, output: AbstractValue) -> None:
        terms = self._terms.Eval(context)
        output.set_value(com_terms(terms.M, terms.Cv, self.mass, self.layout)[0])

    def _calc_com_drift(self, context: Context, output: BasicVector) -> None:
        terms = self._terms.Eval(context)
        output.SetFromVector(com_terms(terms.M, terms.Cv, self.mass, self.layout)[1])

    def createOpPoint(self, name: str, frame_name: str) -> tuple[OutputPort, OutputPort]:
        """As :meth:`Dynamic.createOpPoint`, plus the output ``<name>_drift`` (``J̇_WF v``)."""
        pose, jacobian = Dynamic.createOpPoint(self, name, frame_name)
        if not self.HasOutputPort(name + "_drift"):
            frame = self._op_points[name][0]
            self.DeclareVectorOutputPort(name + "_drift", 6, lambda c, o, f=frame: o.SetFromVector(self._drift(c, f)))
        return pose, jacobian

    def _drift(self, context: Context, frame) -> np.ndarray:
        A = self.plant.CalcBiasSpatialAcceleration(
            self._plant_ctx(context), JacobianWrtVariable.kV, frame, np.zeros(3), self._world, self._world
        )
        return A.get_coeffs()

    def drift_port(self, name: str) -> OutputPort:
        return self.GetOutputPort(name + "_drift")
