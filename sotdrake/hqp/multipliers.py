"""The active set's test of its multipliers' signs (:mod:`.active_set`; compiled in :mod:`.kernels.active_set`).

At the EQP point ``z`` of a working set ``E`` (unit rows) the multipliers are ``λ = −W g`` with
``g = Mᵀ(M z − t)`` the gradient and ``W = (Eᵀ)⁺`` (cut at the working set's rank threshold). A
held row at its upper side needs ``λ ≥ 0``, at its lower side ``λ ≤ 0``; ``wrong = −side · λ`` is how
far each sign is wrong. A sign wrong by less than the round-off of ``λ`` is not trusted:

1. the whole level's scale first: ``MULTIPLIER_TOLERANCE · max(m_scale) · max(‖M z − t‖,
   MULTIPLIER_FLOOR (max(m_scale) ‖z‖ + ‖t‖))`` (:func:`multiplier_scale`); beyond it a sign is wrong;
2. below it, each row's own: the residual of objective row ``j`` is known to ``δ_j = max(|r_j|,
   MULTIPLIER_FLOOR (m_scale_j ‖z‖ + |t_j|))`` at that relative precision, so the gradient's
   component ``c`` to ``(|M|ᵀ δ)_c`` and the multiplier ``i`` to ``(|W| |M|ᵀ δ)_i``; a sign wrong by
   more than the smaller of 1.'s tolerance and ``MULTIPLIER_TOLERANCE`` times that is wrong too.

The first alone is relative to the largest row: on a level whose rows' norms spread over many orders
(0.03 to 2e5) a bound that only the small rows decide, its sign wrong by 8.8e-4, fell inside it
(9.1e-4) though that was over three times the second (2.6e-4), and the bound was held against the
gradient: a residual nine times the optimum's. The second keeps 1.'s margin over round-off for the
rows that the large rows decide, and tightens it where they do not reach (both are
:data:`~.tolerances.MULTIPLIER_TOLERANCE` times a scale of the data).
"""

from __future__ import annotations

import math

import numpy as np

from .tolerances import MULTIPLIER_FLOOR, MULTIPLIER_TOLERANCE


def multiplier_scale(M: np.ndarray, t: np.ndarray, z: np.ndarray, m_max: float) -> float:
    """The scale of the multipliers at ``z`` (their tolerance is :data:`MULTIPLIER_TOLERANCE` times
    it): ``max(m_scale) · max(‖M z − t‖, MULTIPLIER_FLOOR (max(m_scale) ‖z‖ + ‖t‖))``, 1 without
    objective rows. Relative to the level's data, so a nearly flat level (rows of norm 1e-6 deciding
    its optimum) keeps the sign of its small multipliers."""
    if len(M) == 0:
        return 1.0
    residual = M @ z - t
    terms = m_max * math.sqrt(float(z @ z)) + math.sqrt(float(t @ t))
    return m_max * max(math.sqrt(float(residual @ residual)), MULTIPLIER_FLOOR * terms)


def row_round_off(M: np.ndarray, t: np.ndarray, m_scale: np.ndarray, E: np.ndarray, z: np.ndarray, cut: float) -> np.ndarray:
    """Each held row's multiplier's round-off scale ``|W| |M|ᵀ δ`` (see the module docstring), ``W``
    from the SVD of ``E`` cut at ``cut``."""
    residual = M @ z - t
    delta = np.maximum(np.abs(residual), MULTIPLIER_FLOOR * (m_scale * math.sqrt(float(z @ z)) + np.abs(t)))
    U, s, Vt = np.linalg.svd(E, full_matrices=False)
    k = int(np.count_nonzero(s > cut))
    W = (U[:, :k] / s[:k]) @ Vt[:k]
    return np.abs(W) @ (np.abs(M).T @ delta)


def wrong_signs(M: np.ndarray, t: np.ndarray, m_scale: np.ndarray, E: np.ndarray, z: np.ndarray, wrong: np.ndarray,
                m_max: float, cut: float) -> np.ndarray | None:
    """How far beyond its tolerance each held row's sign is wrong (a row is wrong where > 0), or None
    when every sign is right to round-off (``wrong``: ``−side · λ``, 0 for equality rows)."""
    worst = float(wrong.max(initial=0.0))
    if worst <= 0.0:
        return None
    tolerance = MULTIPLIER_TOLERANCE * multiplier_scale(M, t, z, m_max)
    if worst > tolerance:
        return wrong - tolerance
    if len(M) == 0:
        return None
    excess = wrong - np.minimum(tolerance, MULTIPLIER_TOLERANCE * row_round_off(M, t, m_scale, E, z, cut))
    return excess if float(excess.max()) > 0.0 else None
