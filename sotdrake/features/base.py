"""What every feature shares: a selection mask, and one computation of ``(e, J, ė_ref)``.

A feature gives its full error ``e``, its Jacobian ``J = ∂e/∂v`` and ``ė_ref``, the rate of change
of ``e`` due to a moving reference alone (``errordot``; zero for a fixed one). The output
``signals`` carries the selected rows of all three together (a :class:`FeatureValue`), computed
once per change of the feature's inputs; a task reads it through one port (sot-core's
``task.add(feature)``). The outputs ``error``, ``jacobian`` and ``errordot`` are the same rows, one
signal each, for the gain, the tracer and introspection. A task with a moving reference then asks
``J v = -λ e - ė_ref`` (velocity feed-forward).

Each feature's maths is a pure function over numpy arrays (``…_error_and_jacobian``), which its
``_compute`` calls with the values of its input ports.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context

from ..entity import Entity
from ..exceptions import InvalidInput, check_count
from ..selection import parse_selection

#: Component names of the usual feature sizes (a mask reads them right to left).
_COMPONENTS = {6: "X, Y, Z, RX, RY, RZ", 3: "X, Y, Z", 2: "x, y (image)"}


def check_mask(mask: object, dimension: int, what: str) -> str:
    """``mask`` if it is a valid selection mask of a ``dimension``-vector, else
    :class:`InvalidInput` naming ``what``, the expected length and alphabet and an example."""
    components = _COMPONENTS.get(dimension)
    named = f" ({components}; the last character is {components.split(', ')[0]})" if components else ""
    expected = (f"a string of at most {dimension} characters '0' or '1', read right to left, one per component"
                f"{named}, e.g. {'1' * min(dimension, 3)!r} or {'1' * dimension!r} for all")
    if not isinstance(mask, str):
        raise InvalidInput(f"{what}: the selection mask must be {expected}; got {mask!r:.100}")
    try:
        parse_selection(mask, dimension)
    except InvalidInput:
        if mask and not set(mask) - {"0"} and len(mask) <= dimension:
            raise InvalidInput(f"{what}: the selection mask {mask!r} selects no component: expected {expected}") from None
        if mask and not set(mask) - {"0", "1"} and len(mask) > dimension:
            raise InvalidInput(f"{what}: the selection mask {mask!r} has {len(mask)} characters, the feature has "
                               f"{dimension} components: expected {expected}") from None
        raise InvalidInput(f"{what}: invalid selection mask {mask!r}: expected {expected}") from None
    return mask


class FeatureValue(NamedTuple):
    """The selected rows of a feature: error ``e``, Jacobian ``J = ∂e/∂v``, ``ė_ref``."""

    error: np.ndarray
    jacobian: np.ndarray
    errordot: np.ndarray


def optional_input(port, context: Context, default):
    """The value of an optional input port, or ``default`` when it is not connected (for a port
    seldom connected: ``HasValue`` is cheap then)."""
    return port.Eval(context) if port.HasValue(context) else default


def usual_input(port, context: Context, default):
    """:func:`optional_input` for a port usually connected: one evaluation on that path
    (``HasValue`` evaluates the upstream port too), the check only when the evaluation fails."""
    try:
        return port.Eval(context)
    except RuntimeError:
        if port.HasValue(context):
            raise
        return default


def feature_signals(context: Context, feature, error, jacobian, errordot) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``(e, J, ė_ref)`` that a task reads: from its ``feature`` port (a :class:`FeatureValue`, the
    usual wiring), else from its ``error``, ``jacobian`` and optional ``errordot`` ports (``ė_ref``
    None when not connected)."""
    value = usual_input(feature, context, None)
    if value is not None:
        return value
    return error.Eval(context), jacobian.Eval(context), optional_input(errordot, context, None)


@dataclass
class FeatureSettings:
    selection: str


class Feature(Entity):
    """Base of the features: subclasses set ``dimension`` and implement ``_compute``.

    Output ``signals``: a :class:`FeatureValue` (``e`` in the feature's unit, ``J = ∂e/∂v``,
    rows × nv, ``ė_ref`` in unit/s), the selected rows only; the seed's ``error``, ``jacobian``
    and ``errordot`` outputs carry the same three values one by one; ``selected_rows``: the indices
    of the selected components (ints, increasing), for a consumer of a full-size companion signal
    (a dynamic task's ``J̇ v`` or reference acceleration) to take the same rows.
    """

    def __init__(self, name: str, dimension: int, nv: int, settings: FeatureSettings | None = None):
        dimension = check_count(f"{type(self).__name__}({name!r:.60}): dimension", dimension, low=0)
        nv = check_count(f"{type(self).__name__}({name!r:.60}): nv (the velocities)", nv)
        Entity.__init__(self, name, settings or FeatureSettings("1" * dimension))
        self.dimension, self.nv = dimension, nv

    def _declare_outputs(self) -> None:
        """Call once the inputs are declared (``signals`` depends on all of them)."""
        nv = self.nv
        empty = FeatureValue(np.zeros(0), np.zeros((0, nv)), np.zeros(0))
        self.signals = self.DeclareAbstractOutputPort("signals", lambda: AbstractValue.Make(empty), self._calc)
        ticket = {self.cache_entry_ticket(self.signals.cache_entry().cache_index())}
        for i, name in enumerate(FeatureValue._fields):
            self.DeclareAbstractOutputPort(name, lambda i=i: AbstractValue.Make(empty[i]),
                                           lambda c, o, i=i: o.set_value(self.signals.Eval(c)[i]),
                                           prerequisites_of_calc=ticket)
        self.DeclareAbstractOutputPort(
            "selected_rows", lambda: AbstractValue.Make(np.zeros(0, dtype=int)),
            lambda c, o: o.set_value(parse_selection(self._settings_of(c).selection, self.dimension)),
            prerequisites_of_calc={self.abstract_state_ticket(self._settings_index)})

    def _calc(self, context: Context, value: AbstractValue) -> None:
        settings = self._settings_of(context)
        rows = parse_selection(settings.selection, self.dimension)
        all_rows = rows.size == self.dimension
        e, J, e_dot = self._compute(context, settings, None if all_rows else rows)
        value.set_value(FeatureValue(e, J, e_dot) if all_rows or e.size == rows.size
                        else FeatureValue(e[rows], J[rows], e_dot[rows]))

    def _compute(self, context: Context, settings, rows: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(e, J, ė_ref)``: all rows, or, when ``rows`` (the selected ones, None for all) is
        given, either all rows or only those (a feature may skip the work of the others)."""
        raise NotImplementedError

    def selec(self, mask: str, context: Context | None = None) -> None:
        """Selection mask, read right to left (``'000011'`` selects components 0 and 1)."""
        check_mask(mask, self.dimension, f"{self.name}.selec")
        self._command(context, lambda s: setattr(s, "selection", mask))
