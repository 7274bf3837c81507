"""Bounding a solver's velocity by the robot's velocity limits, by scaling it uniformly.

Given the stack's solution ``v`` and positive limits ``v̄`` (nv, ``inf`` for none), the command is

    ``v_s = s·v``, with ``s = min(1, min_i v̄_i / |v_i|)``

the largest uniform scaling that keeps every component within its limit. The direction of ``v`` is
kept, so each level's reference is scaled by the same factor: a higher level asking for nothing
(a contact held, ``ė* ≈ 0``) still gets ``J v_s = s·J v ≈ 0``, while a near-singular lower level's
huge velocity (``1/σ`` just above the SVD threshold) is brought down to what the joints can do.
Clipping each component instead would change the direction and break the higher levels.
"""

from __future__ import annotations

import numpy as np


def velocity_scale(v: np.ndarray, limit: np.ndarray) -> float:
    """``s = min(1, min_i limit_i / |v_i|)`` (1 when ``v`` is within ``limit``)."""
    magnitude = np.abs(v)
    over = magnitude > limit
    if not over.any():
        return 1.0
    return float(np.min(limit[over] / magnitude[over]))


def scale_to_limits(v: np.ndarray, limit: np.ndarray) -> tuple[np.ndarray, float]:
    """``(s·v, s)`` with :func:`velocity_scale`'s ``s``."""
    s = velocity_scale(v, limit)
    return (v if s == 1.0 else s * v), s
