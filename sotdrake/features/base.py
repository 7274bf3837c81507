"""What every feature shares: a selection mask, and one cached computation of ``(e, J, ė_ref)``.

A feature gives its full error ``e``, its Jacobian ``J = ∂e/∂v`` and ``ė_ref``, the rate of change
of ``e`` due to a moving reference alone (``errordot``; zero for a fixed one). Outputs ``error``,
``jacobian`` and ``errordot`` are their selected rows. A task with a moving reference then asks
``J v = -λ e - ė_ref`` (velocity feed-forward).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context, ValueProducer

from ..entity import Entity
from ..exceptions import InvalidInput
from ..selection import parse_selection


def optional_input(port, context: Context, default):
    """The value of an optional input port, or ``default`` when it is not connected."""
    return port.Eval(context) if port.HasValue(context) else default


@dataclass
class FeatureSettings:
    selection: str


class Feature(Entity):
    """Base of the features: subclasses set ``dimension`` and implement ``_compute``."""

    def __init__(self, name: str, dimension: int, nv: int, settings: FeatureSettings | None = None):
        Entity.__init__(self, name, settings or FeatureSettings("1" * dimension))
        self.dimension, self.nv = dimension, nv

    def _declare_outputs(self) -> None:
        """Call once the inputs are declared (the cache depends on all of them)."""
        nv = self.nv
        self._result = self.DeclareCacheEntry(
            "error_jacobian_errordot",
            ValueProducer(allocate=lambda: AbstractValue.Make((np.zeros(0), np.zeros((0, nv)), np.zeros(0))),
                          calc=self._calc),
            prerequisites_of_calc={self.all_sources_ticket()},
        )
        for i, name in enumerate(("error", "jacobian", "errordot")):
            empty = np.zeros((0, nv)) if name == "jacobian" else np.zeros(0)
            self.DeclareAbstractOutputPort(name, lambda e=empty: AbstractValue.Make(e),
                                           lambda c, o, i=i: o.set_value(self._result.Eval(c)[i]))

    def _calc(self, context: Context, value: AbstractValue) -> None:
        settings = self._settings_of(context)
        rows = parse_selection(settings.selection, self.dimension)
        e, J, e_dot = self._compute(context, settings, rows)
        value.set_value((e[rows], J[rows], e_dot[rows]))

    def _compute(self, context: Context, settings, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The full ``(e, J, ė_ref)``; ``rows`` (the selected ones) may be used to skip work."""
        raise NotImplementedError

    def selec(self, mask: str, context: Context | None = None) -> None:
        """Selection mask, read right to left (``'000011'`` selects components 0 and 1)."""
        if not isinstance(mask, str):
            raise InvalidInput(f"{self.name}.selec: the mask must be a string of '0' and '1', got {mask!r}")
        parse_selection(mask, self.dimension)
        self._command(context, lambda s: setattr(s, "selection", mask))
