"""Command-time checks of a gain ``λ(‖e‖)`` against the ranges of :mod:`sotdrake.ranges`.

The task asks ``ė* = -λ e``; the device integrates it over one period ``dt``, so the error of an
exactly tracked task follows ``e_{k+1} = (1 - λ dt) e_k``: it converges monotonically for
``λ dt < 1``, oscillates while converging for ``1 ≤ λ dt < 2`` and diverges from ``λ dt = 2``.
:func:`check_gain` therefore refuses a gain whose largest value ``λ_max = sup_{‖e‖ ≥ 0} λ(‖e‖)``
gives ``λ_max dt ≥ 2`` and logs a warning from ``λ_max dt ≥ 1``; without ``dt`` only the absolute
range ``0 ≤ λ ≤ MAX_GAIN`` applies. Called by the gain entities' commands, never per tick.
"""

from __future__ import annotations

import logging
import math
import numbers
from dataclasses import dataclass

import numpy as np

from .exceptions import InvalidInput
from .ranges import (
    ERROR_SCALE,
    GAIN_DT_REFUSED,
    GAIN_DT_WARNED,
    MAX_GAIN,
    MAX_GAIN_DECAY,
)

log = logging.getLogger("sotdrake.gains")


def error_norm(x: np.ndarray) -> float:
    """``‖x‖ = √(x·x)``, what a gain reads of its error (the tick's cheapest form)."""
    return math.sqrt(x @ x)


@dataclass(frozen=True)
class AdaptiveCoefficients:
    """The adaptive gain ``λ(‖e‖) = a·exp(−b‖e‖) + c`` (1/s; ``b`` in 1/unit of the error)."""

    a: float = 0.0
    b: float = 0.0
    c: float = 1.0

    def __call__(self, error_norm: float) -> float:
        if self.b == 0.0:  # (a constant a + c, also for an infinite error norm: no 0·∞)
            return self.a + self.c
        return self.a * math.exp(-self.b * error_norm) + self.c

    @property
    def is_constant(self) -> bool:
        """``λ = c`` whatever the error (``a = 0``)."""
        return self.a == 0.0


@dataclass(frozen=True)
class HyperbolicCoefficients:
    """The hyperbolic gain ``λ(‖e‖) = a·½(tanh(−b(‖e‖ − d)) + 1) + c`` (1/s)."""

    a: float = 0.0
    b: float = 0.0
    c: float = 1.0
    d: float = 0.0

    def __call__(self, error_norm: float) -> float:
        return self.a * 0.5 * (math.tanh(-self.b * (error_norm - self.d)) + 1.0) + self.c

    @property
    def is_constant(self) -> bool:
        """``λ = c`` whatever the error (``a = 0``)."""
        return self.a == 0.0


def gain_extremes(coefficients) -> tuple[float, float]:
    """``(inf, sup)`` of ``λ(‖e‖)`` over ``‖e‖ ≥ 0`` for the adaptive (``a·exp(-b‖e‖) + c``) or
    hyperbolic (``a·½(tanh(-b(‖e‖ - d)) + 1) + c``) coefficients, ``b ≥ 0``: both are monotonic in
    ``‖e‖``, so the extremes are the value at 0 and the limit ``c`` at infinity."""
    at_zero = coefficients(0.0)
    return min(at_zero, coefficients.c), max(at_zero, coefficients.c)


def check_gain(coefficients, dt: float | None, name: str) -> None:
    """Refuse (``InvalidInput``) coefficients out of range; warn when ``λ_max dt ≥ 1``."""
    if not isinstance(coefficients, (AdaptiveCoefficients, HyperbolicCoefficients)):
        raise InvalidInput(f"{name}: coefficients must be AdaptiveCoefficients or HyperbolicCoefficients, "
                           f"got {type(coefficients).__name__}")
    fields = vars(coefficients)
    for key, value in fields.items():
        if isinstance(value, bool) or not (isinstance(value, numbers.Real) and math.isfinite(value)):
            raise InvalidInput(f"{name}: coefficient {key} must be a finite number, got {value!r}")
    if not 0.0 <= coefficients.b <= MAX_GAIN_DECAY:
        raise InvalidInput(f"{name}: decay rate b must be in [0, {MAX_GAIN_DECAY:g}], got {coefficients.b:g}")
    if abs(fields.get("d", 0.0)) > ERROR_SCALE[1]:
        raise InvalidInput(f"{name}: offset d must be in [-{ERROR_SCALE[1]:g}, {ERROR_SCALE[1]:g}], got {fields['d']:g}")
    low, high = gain_extremes(coefficients)
    if low < 0.0 or high > MAX_GAIN:
        raise InvalidInput(f"{name}: λ(‖e‖) must stay in [0, {MAX_GAIN:g}] 1/s, got values in [{low:g}, {high:g}]")
    if dt is not None:
        product = high * dt
        if product >= GAIN_DT_REFUSED:
            raise InvalidInput(
                f"{name}: λ·dt must be < {GAIN_DT_REFUSED:g} (the discrete loop diverges): λ must be "
                f"< {GAIN_DT_REFUSED / dt:g} 1/s at dt = {dt:g} s, got λ = {high:g}")
        if product >= GAIN_DT_WARNED:
            log.warning("%s: λ·dt = %.3g ≥ %g: the error overshoots and oscillates each tick (λ = %g 1/s, dt = %g s)",
                        name, product, GAIN_DT_WARNED, high, dt)

