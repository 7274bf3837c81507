"""The hierarchy of equality levels solved from a guess of its active bounds, verified by the KKT conditions.

The problem is :class:`~.hqp.HierarchicalQP`'s when every level is made of equality rows: levels
``A_k x = b_k`` in strict priority, hard bounds ``x_min ≤ x ≤ x_max`` (``x_min = x_max``: a fixed
component), then the minimum-norm ``x`` of the optimal set. A *guess* gives a side ``s_i ∈ {-1, 0,
+1}`` per component (held at its lower bound, free, held at its upper bound), typically the bounds
active in the previous tick's answer. With the held components ``H`` (the fixed ones and the guessed
ones) at their bound values ``x_H``, the free components ``F`` solve

    B x_F = ρ,    B = D A_F,   ρ = D (b - A_H x_H),   D = diag(1/‖rows of A‖)

(every level's rows stacked, ``A_F``/``A_H`` their columns in ``F``/``H``; rows scaled to unit norm by
their norm in ``x``, as the QP's rank decisions). One Householder QR ``Bᵀ = Q R`` (``Q`` of size
``|F| × m``) gives the minimum-norm solution ``x_F = Q R⁻ᵀ ρ``. It is accepted only when each level is
*certified* of full row rank in what the levels above and the held components leave free: level
k's rows there are ``R_kkᵀ Q_kᵀ`` (``R_kk``: its diagonal block of R), and ``σ_min ≥ 1/‖R_kk⁻¹‖_F``
must exceed :data:`~.equality_hierarchy.CERTIFIED` (10³ τ, τ the QP's rank threshold; ``R_kk⁻¹`` is
the diagonal block of ``R⁻¹``). Then every level is solved exactly (slack 0, its least possible
value, so every level is at its optimum whatever the bounds), and the point is the QP's answer if
it is the minimum-norm point of the optimal set ``{A x = b} ∩ bounds``, which (a strictly convex
problem) holds iff the KKT conditions of ``min ½‖x‖²`` there hold:

* primal: every free component inside its bounds (to ``feasibility``, absolute, relative above 1);
* dual: ``x + Aᵀμ + Σ_{i held by the guess} λ_i e_i = 0``. On ``F``: ``x_F = -A_Fᵀμ``, i.e.
  ``ν = D⁻¹μ = -R⁻¹R⁻ᵀρ``; on a guessed component ``λ_i = -x_i - (Bᵀ ν)_i`` with ``B`` here its
  scaled column of ``A``; a held upper bound needs ``λ_i ≥ 0``, a held lower bound ``λ_i ≤ 0``, to
  ``1e-9·max(1, ‖x‖)`` (the active-set method's tolerance on multipliers).

If they fail, the guess is corrected as a primal-dual active-set method does (a wrong-signed bound is
released, a violated one is held) and tried again, up to ``rounds`` times; None means that no guess
passed (or a level is not certified, or there are more rows than free components) and the QP's
general path decides. A passing guess gives the QP's point to round-off (it satisfies the
conditions that define it), so the guess changes the cost, never the answer.

Cost: one QR of an ``|F| × m`` matrix, one triangular inverse and a few matrix-vector products per
round, instead of a factorisation per level and an active-set stage per level a bound is in the way of.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.linalg import lapack

from .active_set import upper_inverse

CERTIFIED = 1e-5
"""The smallest singular value of a level's unit rows, in what is left free, that counts as clearly
non-zero: 10³ τ (τ = :data:`~.active_set.RANK_THRESHOLD`), the margin of :mod:`.equality_hierarchy`."""

MULTIPLIER_TOLERANCE = 1e-9
"""A held bound's multiplier may have the wrong sign by this much, relative to ``max(1, ‖x‖)``."""

_NONE = np.zeros(0, dtype=int)
_NONE.flags.writeable = False


def _certified(R_inv: np.ndarray, sizes: list[int], certified: float) -> bool:
    """Whether every level's diagonal block of ``R⁻¹`` has ``‖R_kk⁻¹‖_F < 1/certified`` (then
    ``σ_min`` of its rows in what is left free exceeds ``certified``). The whole ``R⁻¹`` is tried
    first: its norm bounds every block's."""
    flat = R_inv.ravel()
    limit = 1.0 / (certified * certified)
    if float(flat @ flat) < limit:
        return True
    start = 0
    for size in sizes:
        block = R_inv[start : start + size, start : start + size].ravel()
        if not float(block @ block) < limit:  # (False on NaN too)
            return False
        start += size
    return True


def solve_with_active_bounds(
    A: np.ndarray,
    b: np.ndarray,
    norms: np.ndarray,
    sizes: list[int],
    x_lower: np.ndarray,
    x_upper: np.ndarray,
    fixed: np.ndarray,
    guess: np.ndarray,
    certified: float = CERTIFIED,
    feasibility: float = 1e-10,
    rounds: int = 3,
) -> tuple[np.ndarray, np.ndarray] | None:
    """``(x, sides)``: the answer of the equality hierarchy ``A x = b`` (levels of ``sizes`` rows,
    stacked; ``norms``: the rows' norms, 1 for a zero row) under the bounds, and the sides of the
    bounds held at it; or None (see the module docstring). ``fixed``: ``x_lower == x_upper``;
    ``guess``: a side per component (-1, 0, +1; one at an infinite bound gives None). The caller
    silences numpy's warnings on ±∞ bounds; the start of the QP (0) must lie inside the bounds of the
    free components, as the caller checks."""
    m = len(b)
    if m:
        U, c = A / norms[:, None], b / norms  # the unit rows
    side = np.where(fixed, 0, guess)
    for _ in range(rounds):
        held = fixed | (side != 0)
        free = (~held).nonzero()[0]
        n_free = len(free)
        if m > n_free:
            return None
        x = np.where(side > 0, x_upper, x_lower)  # the held values (the free ones are written below)
        x[free] = 0.0
        if m:
            qr, tau, _, info = lapack.dgeqrf(U[:, free].T)  # Bᵀ = Q R
            if info != 0:
                return None
            R_inv = upper_inverse(qr[:m])
            if R_inv is None or not _certified(R_inv, sizes, certified):
                return None
            u = R_inv.T @ (c - U @ x)  # R⁻ᵀ ρ
            padded = np.zeros((n_free, 1))
            padded[:m, 0] = u
            x_free, _, info = lapack.dormqr("L", "N", qr, tau, padded, max(1, n_free))
            if info != 0:
                return None
            x_free = x_free[:, 0]
            x[free] = x_free
        else:
            x_free = x[free]
        squared_norm = float(x @ x)
        if not math.isfinite(squared_norm):  # (an infinite side in the guess)
            return None
        # Primal: every component inside its bounds (the held ones are on them, the fixed ones too),
        # a point inside them exactly passing at once, else the free ones checked to ``feasibility``.
        below = above = _NONE
        if np.count_nonzero((x < x_lower) | (x > x_upper)):
            lo, hi = x_lower[free], x_upper[free]
            below = (x_free < lo - feasibility * np.maximum(1.0, np.abs(lo))).nonzero()[0]
            above = (x_free > hi + feasibility * np.maximum(1.0, np.abs(hi))).nonzero()[0]
        # Dual: the multipliers of the guessed bounds, λ = -x_i - (Aᵀμ)_i = -x_i + (Bᵀ R⁻¹ u)_i, for
        # every component at once (side 0 gives no sign to check).
        lam = U.T @ (R_inv @ u) - x if m else -x
        tolerance = MULTIPLIER_TOLERANCE * max(1.0, math.sqrt(squared_norm))
        wrong = (side * lam < -tolerance).nonzero()[0]
        if not (len(below) or len(above) or len(wrong)):
            return x, side
        side[wrong] = 0
        side[free[below]] = -1
        side[free[above]] = 1
    return None
