"""SoT ``Task``: the reference behaviour ``ė* = -λ(e)·e`` of one feature.

Inputs ``error`` (``e``), ``jacobian`` (``J = ∂e/∂v``) and ``controlGain`` (``λ``, 1/s). Outputs
``task``, a :class:`TaskLevel` (``J``, ``ė*``) for the solvers, and ``error_norm`` (``‖e‖``, for
tracing).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, LeafSystem, ValueProducer


class TaskLevel(NamedTuple):
    """What a solver needs of a task: rows ``J v = ė*``."""

    jacobian: np.ndarray
    reference: np.ndarray
    error: np.ndarray


class Task(LeafSystem):
    def __init__(self, name: str, nv: int):
        LeafSystem.__init__(self)
        self.set_name(name)
        self.nv = nv
        self.error = self.DeclareAbstractInputPort("error", AbstractValue.Make(np.zeros(0)))
        self.jacobian = self.DeclareAbstractInputPort("jacobian", AbstractValue.Make(np.zeros((0, nv))))
        self.controlGain = self.DeclareVectorInputPort("controlGain", 1)
        empty = TaskLevel(np.zeros((0, nv)), np.zeros(0), np.zeros(0))
        self._level = self.DeclareCacheEntry(
            "level",
            ValueProducer(allocate=lambda: AbstractValue.Make(empty), calc=self._calc),
            prerequisites_of_calc={self.all_sources_ticket()},
        )
        self.DeclareAbstractOutputPort(
            "task", lambda: AbstractValue.Make(empty), lambda c, o: o.set_value(self._level.Eval(c))
        )
        self.DeclareVectorOutputPort(
            "error_norm", 1, lambda c, o: o.SetAtIndex(0, np.linalg.norm(self._level.Eval(c).error))
        )

    @property
    def name(self) -> str:
        return self.get_name()

    def _calc(self, context: Context, value: AbstractValue) -> None:
        e = self.error.Eval(context)
        gain = self.controlGain.Eval(context)[0]
        value.set_value(TaskLevel(self.jacobian.Eval(context), -gain * e, e))
