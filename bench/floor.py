"""The framework's floor: the basic stack's graph with callbacks that do no maths.

Per task, the basic ``SOT`` tick runs five Python callbacks inside Drake's framework: the dynamic
entity's op-point pose and Jacobian, the feature, the gain and the task, and the solver evaluates
the task's port. This module builds a diagram with that topology (one kinematics source, then
feature → gain → task per task, a solver reading every task, a device integrating the solver's
output in a periodic discrete update at 1 ms) whose callbacks only evaluate their inputs and set a
precomputed value. Its tick is what Drake's port evaluations and the Python callbacks cost before any
kinematics, feature maths or solve: no per-task cost of the real stack can go below its slope.
``bench/run.py`` times it in the same turns as the real stacks (``scaling``).
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem

NV = 38  # TALOS reduced
_J = np.zeros((6, NV))
_E = np.zeros(6)


class _Kinematics(LeafSystem):
    def __init__(self, tasks: int):
        super().__init__()
        self.q = self.DeclareVectorInputPort("q", NV + 1)
        for i in range(tasks):
            for name in (f"pose{i}", f"J{i}"):
                self.DeclareAbstractOutputPort(name, lambda: AbstractValue.Make(_J), self._calc)

    def _calc(self, context, output) -> None:
        self.q.Eval(context)
        output.set_value(_J)


class _Feature(LeafSystem):
    def __init__(self):
        super().__init__()
        self.pose = self.DeclareAbstractInputPort("pose", AbstractValue.Make(_J))
        self.jacobian = self.DeclareAbstractInputPort("J", AbstractValue.Make(_J))
        self.DeclareAbstractOutputPort("signals", lambda: AbstractValue.Make((_E, _J)), self._calc)

    def _calc(self, context, output) -> None:
        self.pose.Eval(context)
        self.jacobian.Eval(context)
        output.set_value((_E, _J))


class _Gain(LeafSystem):
    def __init__(self):
        super().__init__()
        self.error = self.DeclareAbstractInputPort("error", AbstractValue.Make((_E, _J)))
        self.DeclareVectorOutputPort("gain", 1, self._calc)

    def _calc(self, context, output) -> None:
        self.error.Eval(context)
        output.SetAtIndex(0, 1.0)


class _Task(LeafSystem):
    def __init__(self):
        super().__init__()
        self.feature = self.DeclareAbstractInputPort("feature", AbstractValue.Make((_E, _J)))
        self.gain = self.DeclareVectorInputPort("gain", 1)
        self.DeclareAbstractOutputPort("task", lambda: AbstractValue.Make((_E, _J)), self._calc)

    def _calc(self, context, output) -> None:
        self.feature.Eval(context)
        self.gain.Eval(context)
        output.set_value((_E, _J))


class _Solver(LeafSystem):
    def __init__(self, tasks: int):
        super().__init__()
        self.tasks = [self.DeclareAbstractInputPort(f"task{i}", AbstractValue.Make((_E, _J))) for i in range(tasks)]
        self._zero = np.zeros(NV)
        self.DeclareVectorOutputPort("control", NV, self._calc)

    def _calc(self, context, output) -> None:
        for port in self.tasks:
            port.Eval(context)
        output.SetFromVector(self._zero)


class _Device(LeafSystem):
    def __init__(self, dt: float):
        super().__init__()
        self.control = self.DeclareVectorInputPort("control", NV)
        state = self.DeclareDiscreteState(NV + 1)
        self.DeclareStateOutputPort("state", state)
        self.DeclarePeriodicDiscreteUpdateEvent(dt, 0.0, self._update)

    def _update(self, context, discrete_state) -> None:
        self.control.Eval(context)
        discrete_state.get_mutable_vector(0).SetFromVector(context.get_discrete_state(0).get_value())


def build(tasks: int, dt: float = 1e-3) -> Diagram:
    """The floor's diagram with ``tasks`` tasks."""
    builder = DiagramBuilder()
    kinematics, solver, device = builder.AddSystem(_Kinematics(tasks)), builder.AddSystem(_Solver(tasks)), builder.AddSystem(_Device(dt))
    builder.Connect(device.get_output_port(0), kinematics.q)
    builder.Connect(solver.get_output_port(0), device.control)
    for i in range(tasks):
        feature, gain, task = builder.AddSystem(_Feature()), builder.AddSystem(_Gain()), builder.AddSystem(_Task())
        builder.Connect(kinematics.GetOutputPort(f"pose{i}"), feature.pose)
        builder.Connect(kinematics.GetOutputPort(f"J{i}"), feature.jacobian)
        builder.Connect(feature.get_output_port(0), gain.error)
        builder.Connect(feature.get_output_port(0), task.feature)
        builder.Connect(gain.get_output_port(0), task.gain)
        builder.Connect(task.get_output_port(0), solver.tasks[i])
    return builder.Build()
