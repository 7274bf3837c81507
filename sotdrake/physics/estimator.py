"""The closed loop's state estimate: measured joints, base pose by leg odometry."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem, ValueProducer

from ..configuration import Layout, PlantContextHolder
from ..exceptions import InvalidInput, check_finite


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
        self._base_q: int = self.layout.base_q  # where the base's (quaternion, position) sits in q
        self._base = self.plant.get_body(next(iter(self.plant.GetFloatingBaseBodies()))).body_frame()
        self._soles = [model.frame("left-sole"), model.frame("right-sole")]
        q0 = check_finite(f"{name}: q0", q0, (self.plant.num_positions(),))
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
                 for X_WS0, sole in zip(self._X_WS0, self._soles, strict=False)]
        quaternions = [X.rotation().ToQuaternion().wxyz() for X in poses]
        if quaternions[0] @ quaternions[1] < 0:
            quaternions[1] = -quaternions[1]
        mean = quaternions[0] + quaternions[1]  # (w, x, y, z), as Drake's q
        iq = self._base_q
        q[iq : iq + 4] = mean / np.linalg.norm(mean)
        q[iq + 4 : iq + 7] = 0.5 * (poses[0].translation() + poses[1].translation())
        output.SetFromVector(q)
