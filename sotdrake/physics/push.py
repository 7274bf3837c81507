"""A push on the simulated robot (an external force, as a hand pushing the torso)."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.plant import ExternallyAppliedSpatialForce, MultibodyPlant
from pydrake.multibody.tree import BodyIndex
from pydrake.systems.framework import Context, LeafSystem

from ..exceptions import InvalidInput, NotFound, check_finite, finite_number

#: Largest accepted push (N): ten times TALOS' weight.
MAX_PUSH_FORCE = 1e4


class Push(LeafSystem):
    """A push on a body: ``force`` (N, world frame, ‖force‖ ≤ ``MAX_PUSH_FORCE``) at the body
    origin during ``[start, start + duration)`` (s). Output ``applied_spatial_force`` for the plant.

    A discrete plant of step ``h`` reads the force once per step, at its start ``t``, and holds it
    over the step: the output is then the push's mean over ``[t, t + h)`` (``force`` times the share
    of the step the push covers), so that the impulse is ``force · duration`` whatever ``h`` and
    wherever the push starts within a step."""

    def __init__(self, plant: MultibodyPlant, body_name: str, force, start: float, duration: float):
        LeafSystem.__init__(self)
        self.set_name("push")
        if not (isinstance(body_name, str) and plant.HasBodyNamed(body_name)):
            raise NotFound(str(body_name), sorted(plant.get_body(BodyIndex(i)).name() for i in range(plant.num_bodies())))
        self.body_index = plant.GetBodyByName(body_name).index()
        self.force = self.check_arguments(force, start, duration)
        self.start, self.end = float(start), float(start) + float(duration)
        self.step = float(plant.time_step())  # (0: a continuous plant reads the force as it is)
        self.DeclareAbstractOutputPort("applied_spatial_force", lambda: AbstractValue.Make([ExternallyAppliedSpatialForce()]), self._calc)

    @staticmethod
    def check_arguments(force, start: float, duration: float) -> np.ndarray:
        """``force`` as an array if it, ``start`` and ``duration`` are valid (see the class docstring),
        else :class:`InvalidInput`; a ``force`` of None is no push (nothing to check)."""
        if force is None:
            return np.zeros(3)
        try:
            checked = check_finite("force", force)
            times_ok = finite_number(start) and finite_number(duration)
        except InvalidInput:
            checked, times_ok = np.full(1, np.nan), False
        if (checked.shape != (3,) or not np.all(np.isfinite(checked)) or np.linalg.norm(checked) > MAX_PUSH_FORCE
                or not times_ok or not duration > 0 or start < 0):
            raise InvalidInput(f"push: force a finite 3-vector of norm ≤ {MAX_PUSH_FORCE:g} N, start ≥ 0 s and "
                               f"duration > 0 s, got {force!r}, {start!r}, {duration!r}")
        return checked

    def _calc(self, context: Context, output: AbstractValue) -> None:
        push = ExternallyAppliedSpatialForce()
        push.body_index = self.body_index
        push.F_Bq_W = SpatialForce(np.zeros(3), self.force * self.share(context.get_time()))
        output.set_value([push])

    def share(self, t: float) -> float:
        """The share of the plant's step from ``t`` the push covers (1 or 0 on a continuous plant)."""
        if self.step <= 0:
            return 1.0 if self.start <= t < self.end else 0.0
        covered = min(t + self.step, self.end) - max(t, self.start)
        return min(1.0, max(0.0, covered / self.step))
