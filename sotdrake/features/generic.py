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
from ..exceptions import check_finite
from ..ranges import MAX_TARGET_POSITION, MAX_TARGET_VELOCITY
from .base import Feature, optional_input


@dataclass
class FeatureGenericDesiredSettings:
    errorIN: np.ndarray = field(default_factory=lambda: np.zeros(0))
    velocity: np.ndarray = field(default_factory=lambda: np.zeros(0))


class FeatureGenericDesired(Entity[FeatureGenericDesiredSettings]):
    """Desired value ``s*`` of a generic feature. Outputs ``errorIN`` (``s*``) and ``velocity``
    (``ṡ*``). Optional inputs ``value_in`` and ``velocity_in`` override the settings (a moving
    target, e.g. from Drake's ``TrajectorySource`` or ``Sine``)."""

    def __init__(self, name: str, dimension: int):
        Entity.__init__(self, name, FeatureGenericDesiredSettings(np.zeros(dimension), np.zeros(dimension)))
        self.dimension = dimension
        self.value_in = self.DeclareVectorInputPort("value_in", dimension)
        self.velocity_in = self.DeclareVectorInputPort("velocity_in", dimension)
        self.DeclareVectorOutputPort("errorIN", dimension, lambda c, o: o.SetFromVector(
            optional_input(self.value_in, c, self._settings_of(c).errorIN)))
        self.DeclareVectorOutputPort("velocity", dimension, lambda c, o: o.SetFromVector(
            optional_input(self.velocity_in, c, self._settings_of(c).velocity)))

    def setReference(self, value, context: Context | None = None) -> None:
        """Set ``s*``."""
        s_star = check_finite(f"{self.name}.errorIN", value, (self.dimension,), MAX_TARGET_POSITION).copy()
        self._command(context, lambda s: setattr(s, "errorIN", s_star))

    def setVelocity(self, value, context: Context | None = None) -> None:
        """Set ``ṡ*`` (feed-forward)."""
        v = check_finite(f"{self.name}.velocity", value, (self.dimension,), MAX_TARGET_VELOCITY).copy()
        self._command(context, lambda s: setattr(s, "velocity", v))


class FeatureGeneric(Feature):
    """``e = (s - s*)[selected]``, ``J = (∂s/∂v)[selected]``, ``ė_ref = -ṡ*[selected]``."""

    def __init__(self, name: str, dimension: int, nv: int):
        Feature.__init__(self, name, dimension, nv)
        self.errorIN = self.DeclareVectorInputPort("errorIN", dimension)
        self.jacobianIN = self.DeclareAbstractInputPort("jacobianIN", AbstractValue.Make(np.zeros((dimension, nv))))
        self.reference = self.DeclareVectorInputPort("reference", dimension)
        self.reference_velocity = self.DeclareVectorInputPort("reference_velocity", dimension)
        self._declare_outputs()

    def _compute(self, context: Context, settings, rows):
        e = self.errorIN.Eval(context) - self.reference.Eval(context)
        e_dot = -optional_input(self.reference_velocity, context, np.zeros(self.dimension))
        return e, self.jacobianIN.Eval(context), e_dot
