"""Generic feature (sot-core ``FeatureGeneric``): ``e = s - s*`` for a vector signal ``s``.

Inputs ``errorIN`` (``s``, size n), ``jacobianIN`` (``∂s/∂v``, n×nv) and ``reference`` (``s*``);
outputs the selected rows of ``e = s - s*`` and of the Jacobian. :class:`sotdrake.meta_tasks.
MetaTaskKineCom` plugs the CoM (``p_WCm``, metres, world frame) into it, as sot-core does.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import BasicVector, Context, ValueProducer

from ..entity import Entity
from ..exceptions import check_finite
from ..selection import parse_selection


@dataclass
class FeatureGenericDesiredSettings:
    errorIN: np.ndarray = field(default_factory=lambda: np.zeros(0))


class FeatureGenericDesired(Entity[FeatureGenericDesiredSettings]):
    """Desired value ``s*`` of a generic feature. Output ``errorIN`` (size n)."""

    def __init__(self, name: str, dimension: int):
        Entity.__init__(self, name, FeatureGenericDesiredSettings(np.zeros(dimension)))
        self.dimension = dimension
        self.DeclareVectorOutputPort(
            "errorIN", dimension, lambda c, o: o.SetFromVector(self._settings_of(c).errorIN)
        )

    def setReference(self, value, context: Context | None = None) -> None:
        """Set ``s*``."""
        s_star = check_finite(f"{self.name}.errorIN", value, (self.dimension,)).copy()
        self._command(context, lambda s: setattr(s, "errorIN", s_star))


@dataclass
class FeatureGenericSettings:
    selection: str


class FeatureGeneric(Entity[FeatureGenericSettings]):
    """``e = (s - s*)[selected]``, ``J = (∂s/∂v)[selected]``."""

    def __init__(self, name: str, dimension: int, nv: int):
        Entity.__init__(self, name, FeatureGenericSettings("1" * dimension))
        self.dimension = dimension
        self.errorIN = self.DeclareVectorInputPort("errorIN", dimension)
        self.jacobianIN = self.DeclareAbstractInputPort(
            "jacobianIN", AbstractValue.Make(np.zeros((dimension, nv)))
        )
        self.reference = self.DeclareVectorInputPort("reference", dimension)
        self._result = self.DeclareCacheEntry(
            "error_and_jacobian",
            ValueProducer(allocate=lambda: AbstractValue.Make((np.zeros(0), np.zeros((0, nv)))), calc=self._calc),
            prerequisites_of_calc={self.all_sources_ticket()},
        )
        self.DeclareAbstractOutputPort(
            "error", lambda: AbstractValue.Make(np.zeros(0)), lambda c, o: o.set_value(self._result.Eval(c)[0])
        )
        self.DeclareAbstractOutputPort(
            "jacobian", lambda: AbstractValue.Make(np.zeros((0, nv))), lambda c, o: o.set_value(self._result.Eval(c)[1])
        )

    def _calc(self, context: Context, value: AbstractValue) -> None:
        rows = parse_selection(self._settings_of(context).selection, self.dimension)
        e = self.errorIN.Eval(context) - self.reference.Eval(context)
        value.set_value((e[rows], self.jacobianIN.Eval(context)[rows]))

    def selec(self, mask: str, context: Context | None = None) -> None:
        """Selection mask, read right to left (``'011'`` selects X and Y of the CoM)."""
        parse_selection(mask, self.dimension)
        self._command(context, lambda s: setattr(s, "selection", mask))
