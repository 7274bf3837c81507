"""Gains of sot-core: ``λ(e)``, a function of the error norm ``‖e‖``.

``GainAdaptive``: ``λ(e) = a·exp(-b‖e‖) + c``, with ``λ(0) = a + c = λ0`` and ``λ(∞) = c = λ∞``:

* ``setConstant(λ)``: ``a = 0, b = 0, c = λ``;
* ``set(λ0, λ∞, slope)``: ``a = λ0 - λ∞``, ``b = slope / a``, ``c = λ∞``
  (``slope = -dλ/d‖e‖`` at 0);
* ``setByPoint(λ0, λ∞, e_ref, p)``: ``a = λ0 - λ∞``, ``c = λ∞``, ``b = -ln(p)/e_ref``: at
  ``‖e‖ = e_ref`` the exponential part has decayed to ``p·a``.

``GainHyperbolic``: ``λ(e) = a·½(tanh(-b(‖e‖ - d)) + 1) + c``:

* ``setConstant(λ)``: ``a = 0, c = λ``;
* ``set(λ0, λ∞, tanAt0, decal0)``: ``a = λ0 - λ∞``, ``b = tanAt0/(2a)``, ``c = λ∞``, ``d = decal0``
  (as sot-core's ``GainHyperbolic::init``; with ``d = 0``, ``λ(0) = a/2 + c``).

Units: λ in 1/s (the task asks ``ė* = -λ e``), ``‖e‖`` in the feature's units.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.systems.framework import Context

from .entity import Entity
from .exceptions import InvalidInput, finite_number
from .gain_checks import AdaptiveCoefficients, HyperbolicCoefficients, check_gain, error_norm
from .ranges import ERROR_SCALE

#: Largest magnitude of a number given to a gain command (λ0, λ∞, slope, tanAt0 …).
MAX_GAIN_INPUT = 1e9


def hyperbolic(gain0: float, gain_inf: float, tan_at0: float, decal0: float) -> HyperbolicCoefficients:
    """sot-core ``GainHyperbolic.set(λ0, λ∞, tanAt0, decal0)``."""
    _finite(gain0=gain0, gain_inf=gain_inf, tan_at0=tan_at0, decal0=decal0)
    if gain_inf < 0 or gain0 < gain_inf or tan_at0 < 0:
        raise InvalidInput(f"expected λ0 ≥ λ∞ ≥ 0 and tanAt0 ≥ 0, got ({gain0}, {gain_inf}, {tan_at0}, {decal0})")
    a = gain0 - gain_inf
    return HyperbolicCoefficients(a, tan_at0 / a / 2 if a > 0 else 0.0, gain_inf, decal0)


_SYMBOLS = {"gain": "λ", "gain0": "λ0", "gain_inf": "λ∞", "tan_at0": "tanAt0", "decal0": "decal0",
            "slope": "slope", "error_ref": "e_ref", "fraction": "p"}


def _finite(**values: float) -> None:
    for key, value in values.items():
        name = _SYMBOLS.get(key, key)
        if not finite_number(value):
            raise InvalidInput(f"gain {name} must be a finite number, got {value!r}")
        if abs(value) > MAX_GAIN_INPUT:
            raise InvalidInput(f"gain {name} must be in [-{MAX_GAIN_INPUT:g}, {MAX_GAIN_INPUT:g}], got {value!r}")


def constant(gain: float) -> AdaptiveCoefficients:
    _finite(gain=gain)
    if gain < 0:
        raise InvalidInput(f"a gain must be ≥ 0, got {gain}")
    return AdaptiveCoefficients(0.0, 0.0, float(gain))


def from_slope(gain0: float, gain_inf: float, slope: float) -> AdaptiveCoefficients:
    """sot-core ``GainAdaptive.set(λ0, λ∞, slope)``."""
    _finite(gain0=gain0, gain_inf=gain_inf, slope=slope)
    if gain_inf < 0 or gain0 < gain_inf or slope < 0:
        raise InvalidInput(f"expected λ0 ≥ λ∞ ≥ 0 and slope ≥ 0, got ({gain0}, {gain_inf}, {slope})")
    a = gain0 - gain_inf
    return AdaptiveCoefficients(a, slope / a if a > 0 else 0.0, gain_inf)


def from_point(gain0: float, gain_inf: float, error_ref: float, fraction: float) -> AdaptiveCoefficients:
    """sot-core ``GainAdaptive.setByPoint(λ0, λ∞, e_ref, p)``."""
    _finite(gain0=gain0, gain_inf=gain_inf, error_ref=error_ref, fraction=fraction)
    if gain_inf < 0 or gain0 < gain_inf or not ERROR_SCALE[0] <= error_ref <= ERROR_SCALE[1] or not 0 < fraction < 1:
        raise InvalidInput(
            f"expected λ0 ≥ λ∞ ≥ 0, e_ref in [{ERROR_SCALE[0]:g}, {ERROR_SCALE[1]:g}], 0 < p < 1, "
            f"got ({gain0}, {gain_inf}, {error_ref}, {fraction})"
        )
    return AdaptiveCoefficients(gain0 - gain_inf, -math.log(fraction) / error_ref, gain_inf)


def from_numbers(numbers) -> AdaptiveCoefficients:
    """``gotoNd``'s gain argument: 1 number (constant), 3 (``set``) or 4 (``setByPoint``)."""
    try:
        if isinstance(numbers, (str, bytes, dict)) or numbers is None:
            raise TypeError("not numbers")
        values = [x for x in (numbers if np.ndim(numbers) else [numbers])]
        for x in values:
            _finite(gain=x)
        values = [float(x) for x in values]
    except (TypeError, ValueError):
        raise InvalidInput(f"a gain is given by 1, 3 or 4 finite numbers, got {numbers!r:.200}") from None
    makers: dict[int, Callable[..., AdaptiveCoefficients]] = {1: constant, 3: from_slope, 4: from_point}
    if len(values) not in makers:
        raise InvalidInput(f"a gain is given by 1, 3 or 4 numbers, got {len(values)}: {values}")
    return makers[len(values)](*values)


@dataclass
class GainSettings:
    coefficients: AdaptiveCoefficients | HyperbolicCoefficients


class _Gain(Entity[GainSettings]):
    """Input ``error`` (any size); output ``gain`` = ``λ(‖error‖)`` (1-vector). Starts at λ = 1."""

    def __init__(self, name: str, dt: float | None = None):
        """``dt``: the control period (s) of the loop the gain serves; with it, gains with
        ``λ·dt ≥ 2`` are refused (see :mod:`sotdrake.gain_checks`)."""
        Entity.__init__(self, name, GainSettings(constant(1.0)))
        if dt is not None and not (finite_number(dt) and dt > 0):
            raise InvalidInput(f"{name}: dt must be a number > 0 (s), got {dt!r}")
        self.dt = dt
        self.error = self.DeclareAbstractInputPort("error", AbstractValue.Make(np.zeros(0)))
        self.DeclareVectorOutputPort("gain", 1, self._calc_gain)

    def _calc_gain(self, context: Context, output) -> None:
        coefficients = self._settings_of(context).coefficients
        # A constant gain does not read its error (nor makes the feature compute it).
        output.SetAtIndex(0, coefficients.c if coefficients.is_constant else coefficients(error_norm(self.error.Eval(context))))

    def setConstant(self, gain: float, context: Context | None = None) -> None:
        self.setCoefficients(constant(gain), context)

    def setCoefficients(self, coefficients, context: Context | None = None) -> None:
        check_gain(coefficients, self.dt, self.name)
        self._command(context, lambda s: setattr(s, "coefficients", coefficients))


class GainAdaptive(_Gain):
    """sot-core ``GainAdaptive``: ``λ(e) = a·exp(-b‖e‖) + c``."""

    def set(self, gain0: float, gain_inf: float, slope: float, context: Context | None = None) -> None:
        self.setCoefficients(from_slope(gain0, gain_inf, slope), context)

    def setByPoint(
        self, gain0: float, gain_inf: float, error_ref: float, fraction: float, context: Context | None = None
    ) -> None:
        self.setCoefficients(from_point(gain0, gain_inf, error_ref, fraction), context)


class GainHyperbolic(_Gain):
    """sot-core ``GainHyperbolic``: ``λ(e) = a·½(tanh(-b(‖e‖ - d)) + 1) + c``."""

    def set(self, gain0: float, gain_inf: float, tan_at0: float, decal0: float, context: Context | None = None) -> None:
        self.setCoefficients(hyperbolic(gain0, gain_inf, tan_at0, decal0), context)
