"""Centroidal momentum feature: ``h_G = A_G(q) v`` towards a desired momentum ``h*``.

Components ``(k_x, k_y, k_z, l_x, l_y, l_z)``: the angular momentum about the centre of mass
(kg·m²/s) then the linear momentum (kg·m/s), world frame (:mod:`sotdrake.centroidal`). A mask reads
them right to left: ``'111'`` selects the angular momentum, ``'111000'`` the linear one.

The momentum is a rate: there is no position whose error it is (the angular momentum does not
integrate to a configuration), so the feature is a *rate-only* feature. Its error ``e`` is zero,
its Jacobian ``J = A_G`` and ``ė_ref = −h*``, so that the error's rate is the momentum error,
``ė = J v + ė_ref = h_G − h*``. A kinematic :class:`~sotdrake.task.Task` then asks
``A_G v = h*`` (any gain: ``e = 0``), and a :class:`~sotdrake.dynamics.TaskDynPD` asks
``A_G q̈ = −K_v (h_G − h*) − Ȧ_G v`` (``K_p`` multiplies ``e = 0``; ``Ȧ_G v`` on its ``drift``
input): the momentum error decays at the rate ``K_v``. ``h* = 0`` damps the momentum.

Inputs ``momentum_matrix`` (``A_G``, 6×nv: the ``dynamic`` entity's output of that name). The
desired momentum ``h*`` (6 numbers) is a setting (``setReference``); ``momentum_error_and_jacobian``
is the pure function.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context

from ..exceptions import check_finite
from .base import Feature, FeatureSettings

#: Largest desired momentum component accepted (kg·m²/s or kg·m/s).
MAX_MOMENTUM = 1e4


def momentum_error_and_jacobian(A_G: np.ndarray, h_star: np.ndarray,
                                rows: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(e, J, ė_ref) = (0, A_G, −h*)``, the ``rows`` only (None: all): see the module docstring."""
    if rows is None:
        return np.zeros(6), A_G, -np.asarray(h_star, dtype=float)
    return np.zeros(rows.size), A_G[rows], -np.asarray(h_star, dtype=float)[rows]


@dataclass
class MomentumSettings(FeatureSettings):
    reference: np.ndarray = field(default_factory=lambda: np.zeros(6))


class FeatureMomentum(Feature):
    """The centroidal momentum towards ``h*`` (see the module docstring).

    Input ``momentum_matrix`` (``A_G``, 6 × nv: angular then linear). Output ``signals`` (see
    :class:`~.base.Feature`).
    """

    def __init__(self, name: str, nv: int):
        Feature.__init__(self, name, 6, nv, MomentumSettings("111111"))
        self.momentum_matrix = self.DeclareAbstractInputPort("momentum_matrix", AbstractValue.Make(np.zeros((6, nv))))
        self._declare_outputs()

    def setReference(self, h_star, context: Context | None = None) -> None:
        """The desired momentum ``h* = (k*; l*)`` (6 numbers, kg·m²/s then kg·m/s, world)."""
        value = check_finite(f"{self.name}.reference (h*)", h_star, (6,), MAX_MOMENTUM).copy()
        self._command(context, lambda s: setattr(s, "reference", value))

    def _compute(self, context: Context, settings, rows):
        return momentum_error_and_jacobian(self.momentum_matrix.Eval(context), settings.reference, rows)
