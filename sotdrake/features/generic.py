"""Generic feature (sot-core ``FeatureGeneric``): ``e = s - s*`` for a vector signal ``s``.

Inputs ``errorIN`` (``s``, size n), ``jacobianIN`` (``∂s/∂v``, n×nv), ``reference`` (``s*``) and,
optional, ``reference_velocity`` (``ṡ*``: then ``ė_ref = -ṡ*``). :class:`sotdrake.meta_tasks.
MetaTaskKineCom` plugs the CoM (``p_WCm``, metres, world frame) into it, as sot-core does.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context

from ..entity import Entity
from ..exceptions import check_count, check_finite
from ..ranges import MAX_TARGET_POSITION, MAX_TARGET_VELOCITY
from .base import Feature, optional_input, usual_input


@dataclass
class FeatureGenericDesiredSettings:
    errorIN: np.ndarray = field(default_factory=lambda: np.zeros(0))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(0))


class FeatureGenericDesired(Entity[FeatureGenericDesiredSettings]):
    """Desired value ``s*`` of a generic feature. Outputs ``errorIN`` (``s*``) and ``velocity``
    (``ṡ*``). Optional inputs ``value_in`` and ``velocity_in`` override the settings (a moving
    target, e.g. from Drake's ``TrajectorySource`` or ``Sine``)."""

    def __init__(self, name: str, dimension: int):
        dimension = check_count(f"FeatureGenericDesired({name!r}): dimension", dimension)
        Entity.__init__(self, name, FeatureGenericDesiredSettings(np.zeros(dimension), np.zeros(dimension)))
        self.dimension = dimension
        self.value_in = self.DeclareVectorInputPort("value_in", dimension)
        self.velocity_in = self.DeclareVectorInputPort("velocity_in", dimension)
        # Narrow prerequisites: computed once, until a setting or a connected input changes.
        settings = self.abstract_state_ticket(self._settings_index)
        self.DeclareVectorOutputPort("errorIN", dimension, lambda c, o: o.SetFromVector(
            optional_input(self.value_in, c, self._settings_of(c).errorIN)),
            prerequisites_of_calc={settings, self.input_port_ticket(self.value_in.get_index())})
        self.DeclareVectorOutputPort("velocity", dimension, lambda c, o: o.SetFromVector(
            optional_input(self.velocity_in, c, self._settings_of(c).velocity)),
            prerequisites_of_calc={settings, self.input_port_ticket(self.velocity_in.get_index())})

    def setReference(self, value, context: Context | None = None) -> None:
        """Set ``s*``."""
        s_star = check_finite(f"{self.name}.errorIN", value, (self.dimension,), MAX_TARGET_POSITION).copy()
        self._command(context, lambda s: setattr(s, "errorIN", s_star))

    def setVelocity(self, value, context: Context | None = None) -> None:
        """Set ``ṡ*`` (feed-forward)."""
        v = check_finite(f"{self.name}.velocity", value, (self.dimension,), MAX_TARGET_VELOCITY).copy()
        self._command(context, lambda s: setattr(s, "velocity", v))


class FeatureGeneric(Feature):
    """``e = (s - s*)[selected]``, ``J = (∂s/∂v)[selected]``, ``ė_ref = -ṡ*[selected]``.

    Inputs: ``errorIN`` (``s``), ``jacobianIN`` (``∂s/∂v``, dimension × nv), ``reference``
    (``s*``) and ``reference_velocity`` (``ṡ*``, unit/s). Output ``signals`` (see :class:`Feature`).
    """

    def __init__(self, name: str, dimension: int, nv: int):
        Feature.__init__(self, name, dimension, nv)
        self.errorIN = self.DeclareVectorInputPort("errorIN", dimension)
        self.jacobianIN = self.DeclareAbstractInputPort("jacobianIN", AbstractValue.Make(np.zeros((dimension, nv))))
        self.reference = self.DeclareVectorInputPort("reference", dimension)
        self.reference_velocity = self.DeclareVectorInputPort("reference_velocity", dimension)
        self._declare_outputs()

    def _compute(self, context: Context, settings, rows):
        velocity = usual_input(self.reference_velocity, context, None)
        return generic_error_and_jacobian(self.errorIN.Eval(context), self.jacobianIN.Eval(context),
                                          self.reference.Eval(context), velocity, rows)


def generic_error_and_jacobian(
    s: np.ndarray, J_s: np.ndarray, s_star: np.ndarray, s_star_dot: np.ndarray | None = None,
    rows: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``e = s - s*``, ``J = ∂s/∂v``, ``ė_ref = -ṡ*`` (zero for None), the ``rows`` only (None: all)."""
    e = s - s_star
    e_dot = np.zeros(e.shape) if s_star_dot is None else -s_star_dot
    if rows is None:
        return e, J_s, e_dot
    return e[rows], J_s[rows], e_dot[rows]
