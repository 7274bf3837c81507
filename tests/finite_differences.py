"""The one finite-difference helper of the Jacobian tests: central differences stepping the
configuration on its manifold, ``q ⊕ h·δv`` (the device's integration: SE(3) for a floating base,
additive for the joints), as mink's ``tests/test_jacobians.py`` does."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from sotdrake.configuration import Layout, integrate


def manifold_jacobian(f: Callable[[np.ndarray], np.ndarray], q: np.ndarray, layout: Layout, nv: int,
                      h: float = 1e-6) -> np.ndarray:
    """``∂f/∂v`` at ``q``: column ``i`` is ``(f(q ⊕ h eᵢ) - f(q ⊕ -h eᵢ)) / 2h``."""
    return np.column_stack([(f(integrate(q, d, h, layout)) - f(integrate(q, d, -h, layout))) / (2 * h)
                            for d in np.eye(nv)])
