"""Manipulability feature: Yoshikawa's measure ``μ = √det(J Jᵀ)`` of an op point's Jacobian.

``J`` is the op point F's Jacobian ``J_WF`` (rows ``(ω; v)``, world) restricted to the rows of
``rows`` (a mask over the 6 rows, right to left: ``'111000'``, the default, the translation) and to
the velocity ``columns`` (nv booleans, e.g. one arm's joints: the measure of that arm alone; None:
every column). The feature's error is ``e = μ`` (one row, dimensionless up to the Jacobian's
units) and its Jacobian the gradient ``g = ∂μ/∂v`` from the Jacobian's derivative
(:mod:`sotdrake.manipulability`); ``ė_ref = 0``. With a ``TaskInequality`` bounded below,
``μ ≥ μ_min``, the op point stays away from its singularities (``MetaTaskKineManipulability``).

Inputs ``position`` (``X_WF``) and ``Jq`` (``J_WF``), from the ``dynamic`` entity's op point.
"""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import Context

from ..exceptions import InvalidInput
from ..manipulability import manipulability_and_gradient
from ..selection import parse_selection
from .base import Feature, check_mask


def manipulability_error_and_jacobian(J_WF: np.ndarray, p_WF: np.ndarray, upstream: np.ndarray, rows: np.ndarray,
                                      columns: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(e, J, ė_ref) = ([μ], gᵀ, [0])`` (see the module docstring)."""
    mu, gradient = manipulability_and_gradient(J_WF, p_WF, upstream, rows, columns)
    return np.array([mu]), gradient[None, :], np.zeros(1)


class FeatureManipulability(Feature):
    """``e = μ`` of an op point's Jacobian (see the module docstring). ``upstream``: the plant's
    :func:`~sotdrake.manipulability.upstream_coordinates`.

    Inputs: ``position`` (the op point's pose, a ``RigidTransform``) and ``Jq`` (its 6 × nv
    Jacobian). Output ``signals`` (see :class:`~.base.Feature`).
    """

    def __init__(self, name: str, nv: int, upstream: np.ndarray, rows: str = "111000", columns: np.ndarray | None = None):
        Feature.__init__(self, name, 1, nv)
        check_mask(rows, 6, f"{name}: rows")
        self._rows = parse_selection(rows, 6)
        if columns is not None:
            columns = np.asarray(columns)
            if columns.dtype != bool or columns.shape != (nv,) or columns.sum() < self._rows.size:
                raise InvalidInput(f"{name}: columns must be {nv} booleans selecting at least as many velocities as rows "
                                   f"({self._rows.size}), got {columns!r:.100}")
        upstream = np.asarray(upstream)
        if upstream.shape != (nv, nv) or upstream.dtype != bool:
            raise InvalidInput(f"{name}: upstream must be {nv}×{nv} booleans (upstream_coordinates(plant))")
        self._columns, self._upstream = columns, upstream
        self.position = self.DeclareAbstractInputPort("position", AbstractValue.Make(RigidTransform()))
        self.Jq = self.DeclareAbstractInputPort("Jq", AbstractValue.Make(np.zeros((6, nv))))
        self._declare_outputs()

    def _compute(self, context: Context, settings, rows):
        X_WF = self.position.Eval(context)
        return manipulability_error_and_jacobian(self.Jq.Eval(context), X_WF.translation(), self._upstream, self._rows,
                                                 self._columns)
