"""``Feature1D`` (sot-core): a scalar summary of another feature, ``e = ½‖e_in‖²``, ``J = e_inᵀ J_in``
(and ``ė_ref = e_inᵀ ė_ref,in``). Inputs ``errorIN``, ``jacobianIN`` and, optional, ``errordotIN``
(plug the outputs of another feature). Useful to give a whole feature one row of a stack."""

from __future__ import annotations

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context

from .base import Feature, optional_input


class Feature1D(Feature):
    """``e = ½‖e_in‖²`` (one row), ``J = e_inᵀ J_in``: see the module docstring. Inputs ``errorIN``,
    ``jacobianIN``, ``errordotIN`` (optional); outputs ``signals``, ``error``, ``jacobian``, ``errordot``."""

    def __init__(self, name: str, nv: int):
        Feature.__init__(self, name, 1, nv)
        self.errorIN = self.DeclareAbstractInputPort("errorIN", AbstractValue.Make(np.zeros(0)))
        self.jacobianIN = self.DeclareAbstractInputPort("jacobianIN", AbstractValue.Make(np.zeros((0, nv))))
        self.errordotIN = self.DeclareAbstractInputPort("errordotIN", AbstractValue.Make(np.zeros(0)))
        self._declare_outputs()

    def _compute(self, context: Context, settings, rows):
        e_in = self.errorIN.Eval(context)
        e_dot_in = optional_input(self.errordotIN, context, None)
        return feature1d_error_and_jacobian(e_in, self.jacobianIN.Eval(context), e_dot_in)


def feature1d_error_and_jacobian(
    e_in: np.ndarray, J_in: np.ndarray, e_dot_in: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``e = ½‖e_in‖²``, ``J = e_inᵀ J_in``, ``ė_ref = e_inᵀ ė_ref,in`` (zero for None), as 1-row arrays."""
    e_dot = 0.0 if e_dot_in is None else e_in @ e_dot_in
    return np.array([0.5 * e_in @ e_in]), (e_in @ J_in)[None, :], np.array([e_dot])
