"""The robot's measured CoM: position and velocity from a state ``(q, v)``.

``MeasuredCom`` evaluates the control model's CoM ``p_WCm`` and its velocity ``v_WCm`` (world; m,
m/s; Drake's ``CalcCenterOfMassPositionInWorld`` and ``CalcCenterOfMassTranslationalVelocityInWorld``)
at the state on its input ``state`` (the physics plant's, in the same coordinates as the control
model). On the simulated robot that state is exact: it stands for the estimator a real robot runs
(IMU and leg odometry). The plant context lives in a cache entry.
"""

from __future__ import annotations

from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, LeafSystem, ValueProducer

from ..configuration import PlantContextHolder
from ..exceptions import InvalidInput, check_name, check_type
from ..robots import RobotModel


class MeasuredCom(LeafSystem):
    """Input ``state`` (nq + nv); outputs ``com`` and ``com_velocity`` (3 each, world)."""

    def __init__(self, model: RobotModel, name: str = "measured_com"):
        check_name("MeasuredCom: name", name)
        check_type(f"{name}: model", model, RobotModel, "RobotModel (robot.model)")
        LeafSystem.__init__(self)
        self.set_name(name)
        self.plant = model.plant
        self.nq, nv = self.plant.num_positions(), self.plant.num_velocities()
        if self.nq != model.nq:
            raise InvalidInput(f"{name}: the model's nq ({model.nq}) differs from its plant's ({self.nq})")
        self.state = self.DeclareVectorInputPort("state", self.nq + nv)
        self._plant_context = self.DeclareCacheEntry(
            "plant_context",
            ValueProducer(allocate=lambda: AbstractValue.Make(PlantContextHolder(self.plant)), calc=self._set_state),
            prerequisites_of_calc={self.input_port_ticket(self.state.get_index())},
        )
        self.DeclareVectorOutputPort("com", 3, self._calc_com)
        self.DeclareVectorOutputPort("com_velocity", 3, self._calc_com_velocity)

    def _set_state(self, context: Context, value: AbstractValue) -> None:
        self.plant.SetPositionsAndVelocities(value.get_mutable_value().context, self.state.Eval(context))

    def _calc_com(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self.plant.CalcCenterOfMassPositionInWorld(self._plant_context.Eval(context).context))

    def _calc_com_velocity(self, context: Context, output: BasicVector) -> None:
        output.SetFromVector(self.plant.CalcCenterOfMassTranslationalVelocityInWorld(self._plant_context.Eval(context).context))
