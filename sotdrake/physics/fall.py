"""Did the robot fall? A definition for the physics summaries.

The robot *fell* at the first instant where its base (the pelvis, ``base_link``) is lower than
``FALL_BASE_HEIGHT`` (0.6 m; ≈ 1.02 m standing in half-sitting, ≈ 0.2 m lying on the ground), or
where a body other than the soles presses on the ground with more than ``FALL_CONTACT_FORCE``
(10 N: a knee, a hand or the pelvis touching down).
"""

from __future__ import annotations

import numpy as np

FALL_BASE_HEIGHT = 0.6  # m
FALL_CONTACT_FORCE = 10.0  # N


def fall_time(time: np.ndarray, base_height: np.ndarray, other_contact: np.ndarray) -> float | None:
    """The first time (s) at which the robot fell (see the module docstring), or None."""
    fell = (np.asarray(base_height) < FALL_BASE_HEIGHT) | (np.asarray(other_contact) > FALL_CONTACT_FORCE)
    return float(np.asarray(time)[np.argmax(fell)]) if fell.any() else None
