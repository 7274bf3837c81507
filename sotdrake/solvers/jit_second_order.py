"""The tick-curvature correction of :mod:`.second_order`, compiled with numba: :func:`correction`.

The same quantities as ``curvature_correction`` of ``tests/oracles.py`` in one pass over ``J``:
``J v_{k-1}``, ``‖J‖_F²`` and ``‖v_{k-1}‖²`` (in Python, five numpy calls of about a microsecond each,
per level and per tick).
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def correction(J, previous_velocity, previous_task_velocity, max_relative_change):
    """``(True, ½ (J v − y))``, or ``(False, J v − y)`` when the Jacobian jumped rather than moved:
    ``‖J v − y‖² > max_relative_change² ‖J‖_F² ‖v‖²`` (``v``, ``y``: the last tick's command and the
    level's velocity then). The sizes are the caller's to check."""
    m, n = J.shape
    change = np.empty(m)
    jacobian_squared, change_squared, velocity_squared = 0.0, 0.0, 0.0
    for i in range(m):
        value = 0.0
        for j in range(n):
            entry = J[i, j]
            value += entry * previous_velocity[j]
            jacobian_squared += entry * entry
        change[i] = value - previous_task_velocity[i]
        change_squared += change[i] * change[i]
    for j in range(n):
        velocity_squared += previous_velocity[j] * previous_velocity[j]
    if change_squared > max_relative_change * max_relative_change * jacobian_squared * velocity_squared:
        return False, change
    return True, 0.5 * change
