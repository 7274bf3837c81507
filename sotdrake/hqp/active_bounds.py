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

**Held rows.** The same rounds take inequality rows ``c_lo ≤ C x ≤ c_hi`` (every level's, stacked,
:func:`solve_held_rows`): a row *held* at a side is one more equality row at that bound, stacked
after the levels' rows (certified as one more block: full row rank in what the levels leave free),
and its multiplier is its component of ``ν``: a row held at its upper side needs ``ν ≥ 0``, at its
lower side ``ν ≤ 0`` (the same tolerance). A row not held must hold (on unit rows, to
``feasibility`` relative above 1), else it is held at the side it passes; a wrong-signed one is
released. The rows held at the start are a guess too (typically those held in the previous tick's
answer, when the stack's rows have the same layout): like the bounds' guess, it changes the cost,
never the answer. A passing point meets every equality row exactly and holds every inequality row:
each level's objective (residual, violation) is at its least value, 0, so the hierarchy's optimal
set is the polyhedron of all the rows and bounds, and the point, which satisfies the KKT conditions
of ``min ½‖x‖²`` over it, is the QP's answer.

Cost: one QR of an ``|F| × m`` matrix, one triangular inverse and a few matrix-vector products per
round, instead of a factorisation per level and an active-set stage per level a bound is in the way of.
The rounds are compiled with numba (cached on disk; the first call after an install compiles them,
about ten seconds), their QR and triangular inverse scipy's LAPACK routines (:mod:`.kernels.lapack`): the
Python version's fifteen numpy calls a round cost more than their arithmetic.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit

from ..compiled import compiled_input
from .kernels.lapack import certified_blocks, geqrf, level_residuals, ormqr, row_norms, upper_inverse
from .tolerances import CERTIFIED, FEASIBILITY, MULTIPLIER_TOLERANCE, REPORTED_ACTIVE, VERIFIED

#: No guess of the held rows.
_NO_ROWS = np.zeros(0, np.int64)


@njit(cache=True)
def _certified(R_inv, sizes, certified):
    """Whether every level's diagonal block of ``R⁻¹`` has ``‖R_kk⁻¹‖_F < 1/certified`` (then
    ``σ_min`` of its rows in what is left free exceeds ``certified``). The whole ``R⁻¹`` is tried
    first: its norm bounds every block's."""
    if np.sum(R_inv * R_inv) < 1.0 / (certified * certified):
        return True
    return certified_blocks(R_inv, sizes, certified) == sizes.size


@njit(cache=True)
def _solve(A, b, norms, sizes, C, c_lower, c_upper, c_norms, x_lower, x_upper, fixed, guess, row_guess, certified,
           feasibility, rounds):
    """:func:`solve_with_active_bounds` (``C`` without rows) and :func:`solve_held_rows`,
    compiled: ``(ok, x, sides, row sides)``; ``row_guess``: the side each row of ``C`` is held at
    first (a side at an infinite bound is not held)."""
    m, n = A.shape
    p = C.shape[0]
    U = A / norms.reshape(-1, 1)  # the unit rows
    c = b / norms
    V = C / c_norms.reshape(-1, 1)  # the unit inequality rows and their bounds
    v_lower, v_upper = c_lower / c_norms, c_upper / c_norms
    side = np.where(fixed, 0, guess)
    row_side = np.zeros(p, dtype=np.int64)
    for i in range(min(p, row_guess.size)):
        if (row_guess[i] > 0 and math.isfinite(c_upper[i])) or (row_guess[i] < 0 and math.isfinite(c_lower[i])):
            row_side[i] = 1 if row_guess[i] > 0 else -1
    x = np.zeros(n)
    for _ in range(rounds):
        free = np.flatnonzero(~(fixed | (side != 0)))
        held = np.flatnonzero(row_side != 0)
        n_free, h = free.size, held.size
        k = m + h  # the equality rows, then the held inequality rows at their side's bound
        if k > n_free:
            return False, x, side, row_side
        W, d = U, c
        blocks = sizes
        if h:
            W, d = np.empty((k, n)), np.empty(k)
            W[:m], d[:m] = U, c
            for j in range(h):
                W[m + j] = V[held[j]]
                d[m + j] = v_upper[held[j]] if row_side[held[j]] > 0 else v_lower[held[j]]
            blocks = np.append(sizes, h)  # (certified last: full row rank in what the levels leave free)
        x = np.where(side > 0, x_upper, x_lower)  # the held values (the free ones are written below)
        x[free] = 0.0
        R_inv = np.zeros((k, k))
        u = np.zeros(k)
        if k:
            qr = np.empty((k, n_free)).T  # Bᵀ = Q R (column-major, n_free × k)
            for i in range(n_free):
                qr[i, :] = W[:, free[i]]
            tau = np.empty(k)
            if geqrf(qr, tau) != 0:
                return False, x, side, row_side
            ok, R_inv = upper_inverse(qr[:k])
            if not ok or not _certified(R_inv, blocks, certified):
                return False, x, side, row_side
            u = R_inv.T @ (d - W @ x)  # R⁻ᵀ ρ
            padded = np.zeros((1, n_free)).T
            padded[:k, 0] = u
            if ormqr(qr, tau, padded, False) != 0:
                return False, x, side, row_side
            x[free] = padded[:, 0]
        x_free = x[free]
        squared_norm = x @ x
        if not math.isfinite(squared_norm):  # (an infinite side in the guess)
            return False, x, side, row_side
        # Dual: ν = -R⁻¹R⁻ᵀρ for the unit rows. The multipliers of the guessed bounds,
        # λ = -x_i - (Bᵀν)_i, for every component at once (side 0 gives no sign to check), and those of
        # the held rows, ν; a wrong sign releases the bound or the row.
        w = R_inv @ u
        lam = W.T @ w - x if k else -x
        tolerance = MULTIPLIER_TOLERANCE * max(1.0, math.sqrt(squared_norm))
        wrong = side * lam < -tolerance
        changed = bool(wrong.any())
        was_held = row_side != 0
        for j in range(h):
            if row_side[held[j]] * -w[m + j] < -tolerance:
                row_side[held[j]] = 0
                changed = True
        # Primal: every component inside its bounds (the held ones are on them, the fixed ones too),
        # a point inside them exactly passing at once, else the free ones checked to ``feasibility``:
        # a violated bound is held next (the free components are not among the released ones); the
        # same for the rows not held.
        if np.any((x < x_lower) | (x > x_upper)):
            for i in range(n_free):
                lo, hi = x_lower[free[i]], x_upper[free[i]]
                if x_free[i] < lo - feasibility * max(1.0, abs(lo)):
                    side[free[i]] = -1
                    changed = True
                elif x_free[i] > hi + feasibility * max(1.0, abs(hi)):
                    side[free[i]] = 1
                    changed = True
        if p:  # (the most violated row only: holding every violated one at once may cycle)
            value = V @ x
            worst, worst_side, worst_excess = -1, 0, 0.0
            for i in range(p):
                if was_held[i]:
                    continue
                below = v_lower[i] - feasibility * max(1.0, abs(v_lower[i])) - value[i]
                above = value[i] - v_upper[i] - feasibility * max(1.0, abs(v_upper[i]))
                if below > worst_excess:
                    worst, worst_side, worst_excess = i, -1, below
                elif above > worst_excess:
                    worst, worst_side, worst_excess = i, 1, above
            if worst >= 0:
                row_side[worst] = worst_side
                changed = True
        if not changed:
            return True, x, side, row_side
        side[wrong] = 0
    return False, x, side, row_side


def solve_with_active_bounds(
    A: np.ndarray,
    b: np.ndarray,
    norms: np.ndarray,
    sizes: Sequence[int],
    x_lower: np.ndarray,
    x_upper: np.ndarray,
    fixed: np.ndarray,
    guess: np.ndarray,
    certified: float = CERTIFIED,
    feasibility: float = VERIFIED,
    rounds: int = 3,
) -> tuple[np.ndarray, np.ndarray] | None:
    """``(x, sides)``: the answer of the equality hierarchy ``A x = b`` (levels of ``sizes`` rows,
    stacked; ``norms``: the rows' norms, 1 for a zero row) under the bounds, and the sides of the
    bounds held at it; or None (see the module docstring). ``fixed``: ``x_lower == x_upper``;
    ``guess``: a side per component (-1, 0, +1; one at an infinite bound gives None). The start of
    the QP (0) must lie inside the bounds of the free components, as the caller checks. Compiled
    (numba, cached on disk; :mod:`.kernels.lapack`)."""
    given = compiled_input
    A, none = given(A), np.zeros(0)
    ok, x, sides, _ = _solve(A, given(b), given(norms), given(sizes, np.int64), np.zeros((0, A.shape[1])), none, none, none,
                             given(x_lower), given(x_upper), given(fixed, np.bool_), given(guess, np.int64), _NO_ROWS, float(certified),
                             float(feasibility), int(rounds))
    return (x, sides) if ok else None


#: What :func:`solve_stack` says of a stack: answered, the path does not apply (0 outside the bounds
#: of a free component), no guess verified.
SOLVED, NOT_APPLICABLE, NOT_VERIFIED = 0, 1, 2


@njit(cache=True)
def _solve_stack(A, b, sizes, x_lower, x_upper, guess, certified, feasibility, rounds, tolerance):
    """:func:`solve_stack`, compiled: ``(status, x, sides, A x − b, slack norms, active bounds)``."""
    fixed = x_lower == x_upper
    none, empty = np.zeros(0, dtype=np.int64), np.zeros(0)
    for i in range(x_lower.size):
        # (NaN bounds fail the test: every comparison with NaN is False.)
        if not fixed[i] and not (x_lower[i] <= 0.0 and x_upper[i] >= 0.0):
            return NOT_APPLICABLE, empty, guess, empty, empty, none
    ok, x, sides, _ = _solve(A, b, row_norms(A), sizes, np.zeros((0, A.shape[1])), np.zeros(0), np.zeros(0), np.zeros(0),
                             x_lower, x_upper, fixed, guess, none, certified, feasibility, rounds)
    if not ok:
        return NOT_VERIFIED, x, sides, empty, empty, none
    x, residual, slack_norms, active = _outcome(A, b, sizes, x, x_lower, x_upper, fixed, tolerance)
    return SOLVED, x, sides, residual, slack_norms, active


def solve_stack(A: np.ndarray, b: np.ndarray, sizes: np.ndarray, x_lower: np.ndarray, x_upper: np.ndarray,
                guess: np.ndarray, certified: float, feasibility: float, tolerance: float, rounds: int = 3):
    """One call for a stack of equality levels (the QP's path of :meth:`~.hqp.HierarchicalQP.solve_equalities`):
    ``(status, x, sides, A x − b, slack norms, active bounds)``. The status is :data:`NOT_APPLICABLE`
    when 0 is outside the bounds of a free component (the QP's start: then the other arrays are
    empty), :data:`NOT_VERIFIED` when :func:`solve_with_active_bounds` gives None, else :data:`SOLVED`
    with its answer as :func:`outcome` gives it (put on the bounds it passes by at most ``tolerance``).
    ``sizes``: int64, ``guess``: a side per component (int64)."""
    given = compiled_input
    status, x, sides, residual, slack_norms, active = _solve_stack(
        given(A), given(b), given(sizes, np.int64), given(x_lower), given(x_upper), given(guess, np.int64),
        float(certified), float(feasibility), int(rounds), float(tolerance))
    return int(status), x, sides, residual, slack_norms, active


@njit(cache=True)
def _split_rows(A, lower, upper, sizes):
    """``(ok, A_eq, b_eq, eq_sizes, C, c_lower, c_upper, has_inequality)`` of levels ``lower ≤ A x ≤
    upper`` stacked (``sizes`` rows each): each level's equality rows (``lower = upper``), then every
    inequality row; not ok on a coefficient that is not finite, a NaN side, sides out of order or an
    equality row at an infinite value (the stages then say what is wrong)."""
    m, n = A.shape
    equality = np.empty(m, np.bool_)
    for i in range(m):
        equality[i] = lower[i] == upper[i]
        ok = lower[i] <= upper[i] and (not equality[i] or math.isfinite(lower[i]))  # (False on NaN too)
        for j in range(n):
            ok = ok and math.isfinite(A[i, j])
        if not ok:
            return (False, A[:0], lower[:0], sizes[:0], A[:0], lower[:0], upper[:0], np.zeros(0, np.bool_))
    rows = np.flatnonzero(equality)
    others = np.flatnonzero(~equality)
    eq_sizes = np.zeros(sizes.size, np.int64)
    has_inequality = np.zeros(sizes.size, np.bool_)
    start = 0
    for k in range(sizes.size):
        for i in range(start, start + sizes[k]):
            if equality[i]:
                eq_sizes[k] += 1
            else:
                has_inequality[k] = True
        start += sizes[k]
    return True, A[rows], lower[rows], eq_sizes, A[others], lower[others], upper[others], has_inequality


@njit(cache=True)
def _level_outcome(A, lower, upper, sizes, x, x_lower, x_upper, fixed):
    """``(slacks, each level's slack norm, active rows, active bounds)`` at ``x``, as
    :func:`~.problem.result_of` gives them: per row the signed residual of an equality row or the
    violation (``≥ 0``) of an inequality row, the inequality rows at a side and the free components
    at a bound (within :data:`~.tolerances.REPORTED_ACTIVE`, relative above 1)."""
    r = A @ x
    slacks = np.empty(r.size)
    active = np.zeros(r.size, np.bool_)
    for i in range(r.size):
        if lower[i] == upper[i]:
            slacks[i] = r[i] - lower[i]
            continue
        slacks[i] = max(max(lower[i] - r[i], r[i] - upper[i]), 0.0)
        scale = REPORTED_ACTIVE * max(1.0, abs(r[i]))
        active[i] = abs(r[i] - lower[i]) <= scale or abs(r[i] - upper[i]) <= scale
    norms = np.zeros(sizes.size)
    start = 0
    for k in range(sizes.size):
        for i in range(start, start + sizes[k]):
            norms[k] += slacks[i] * slacks[i]
        norms[k] = math.sqrt(norms[k])
        start += sizes[k]
    scale = REPORTED_ACTIVE * np.maximum(1.0, np.abs(x))
    bounds = np.flatnonzero(~fixed & ((np.abs(x - x_lower) <= scale) | (np.abs(x - x_upper) <= scale)))
    return slacks, norms, active, bounds


@njit(cache=True)
def _solve_held_rows(A, lower, upper, sizes, x_lower, x_upper, guess, row_guess, certified, feasibility, rounds,
                     tolerance):
    """:func:`solve_held_rows`, compiled: ``(status, x, sides, row sides, slacks, slack norms, active
    rows, active bounds, levels with inequality rows)``."""
    fixed = x_lower == x_upper
    none = np.zeros(0, np.int64)
    ok, A_eq, b_eq, eq_sizes, C, c_lower, c_upper, has_inequality = _split_rows(A, lower, upper, sizes)
    if not ok:
        return NOT_APPLICABLE, np.zeros(0), guess, none, np.zeros(0), np.zeros(0), np.zeros(0, np.bool_), none, has_inequality
    for i in range(x_lower.size):
        if not fixed[i] and not (x_lower[i] <= 0.0 and x_upper[i] >= 0.0):  # (False on NaN too)
            return NOT_APPLICABLE, np.zeros(0), guess, none, np.zeros(0), np.zeros(0), np.zeros(0, np.bool_), none, has_inequality
    ok, x, sides, row_sides = _solve(A_eq, b_eq, row_norms(A_eq), eq_sizes, C, c_lower, c_upper, row_norms(C), x_lower,
                                     x_upper, fixed, guess, row_guess, certified, feasibility, rounds)
    if not ok:
        return NOT_VERIFIED, x, sides, row_sides, np.zeros(0), np.zeros(0), np.zeros(0, np.bool_), none, has_inequality
    _onto_bounds(x, x_lower, x_upper, tolerance)
    slacks, norms, active, bounds = _level_outcome(A, lower, upper, sizes, x, x_lower, x_upper, fixed)
    return SOLVED, x, sides, row_sides, slacks, norms, active, bounds, has_inequality


def solve_held_rows(A: np.ndarray, lower: np.ndarray, upper: np.ndarray, sizes: np.ndarray, x_lower: np.ndarray,
                    x_upper: np.ndarray, guess: np.ndarray, certified: float, feasibility: float, tolerance: float,
                    rounds: int = 16, row_guess: np.ndarray | None = None
                    ) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                               np.ndarray]:
    """A stack with inequality rows whose equality rows can all be met (see the module docstring's
    last part): levels ``lower ≤ A x ≤ upper`` stacked (levels of ``sizes`` rows, int64; a row with
    ``lower = upper`` is an equality row). ``(status, x, sides, row sides, slacks, slack norms, active
    rows, active bounds, levels with inequality rows)``: the first three as :func:`solve_stack`'s, then
    the side of each inequality row held at ``x`` (inequality rows in stack order), and, when solved,
    each row's slack (the signed residual of an equality row, the violation of an inequality row),
    each level's slack norm, the inequality rows at a side (a mask over every row), the free
    components at a bound, and which levels have inequality rows. ``guess``: a side per component,
    ``row_guess`` (None: none) the side each inequality row is held at first (int64, in stack order;
    a side at an infinite bound, or past the rows there are, is not held); then a violated row is
    held, a wrong-signed one released, up to ``rounds`` rounds. Rows that are not finite, or sides
    out of order: :data:`NOT_APPLICABLE`."""
    given = compiled_input
    status, *answer = _solve_held_rows(
        given(A), given(lower), given(upper), given(sizes, np.int64), given(x_lower), given(x_upper),
        given(guess, np.int64), _NO_ROWS if row_guess is None else given(row_guess, np.int64), float(certified),
        float(feasibility), int(rounds), float(tolerance))
    return (int(status), *answer)


@njit(cache=True)
def sides_at_bounds(x, x_lower, x_upper, fixed):
    """+1 where ``x`` is at its (finite) upper bound, -1 at its lower bound (to :data:`FEASIBILITY`,
    relative above 1), 0 elsewhere and on the ``fixed`` components (those of the call the guess is
    for): the sides of the bounds an answer holds, the next call's guess (int64)."""
    sides = np.zeros(x.size, np.int64)
    for i in range(x.size):
        if fixed[i]:
            continue
        if x_upper[i] < np.inf and x[i] >= x_upper[i] - FEASIBILITY * max(1.0, abs(x_upper[i])):
            sides[i] = 1
        elif x_lower[i] > -np.inf and x[i] <= x_lower[i] + FEASIBILITY * max(1.0, abs(x_lower[i])):
            sides[i] = -1
    return sides


@njit(cache=True)
def _onto_bounds(x, x_lower, x_upper, tolerance):
    """``x`` put on each bound it passes by at most ``tolerance`` (relative above 1: round-off), in
    place; a component farther out stays."""
    for i in range(x.size):
        if x_lower[i] - tolerance * max(1.0, abs(x_lower[i])) <= x[i] < x_lower[i]:
            x[i] = x_lower[i]
        elif x_upper[i] < x[i] <= x_upper[i] + tolerance * max(1.0, abs(x_upper[i])):
            x[i] = x_upper[i]


def onto_bounds(x: np.ndarray, x_lower: np.ndarray, x_upper: np.ndarray, tolerance: float) -> np.ndarray:
    """A copy of ``x`` put on each bound it passes by at most ``tolerance`` (relative above 1:
    round-off); a component farther out stays."""
    out = compiled_input(x).copy()
    _onto_bounds(out, compiled_input(x_lower), compiled_input(x_upper), float(tolerance))
    return out


@njit(cache=True)
def _outcome(A, b, sizes, x, x_lower, x_upper, fixed, tolerance):
    """``(x, A x − b, each level's slack norm, the free components at a bound)`` (to ``1e-7`` relative
    above 1: ``x`` is inside its bounds to ``1e-10``), ``x`` first put on each bound it passes by at
    most ``tolerance`` (:func:`onto_bounds`, in place)."""
    _onto_bounds(x, x_lower, x_upper, tolerance)
    residual, norms = level_residuals(A, b, x, sizes)
    scale = REPORTED_ACTIVE * np.maximum(1.0, np.abs(x))
    return x, residual, norms, np.flatnonzero(~fixed & ((x - x_lower <= scale) | (x_upper - x <= scale)))


def outcome(A: np.ndarray, b: np.ndarray, sizes: np.ndarray, x: np.ndarray, x_lower: np.ndarray, x_upper: np.ndarray,
            fixed: np.ndarray, tolerance: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """An answer of :func:`solve_with_active_bounds` put on the bounds it passes by round-off (at most
    ``tolerance``, relative above 1; ``x`` is changed in place), its residual, slack norms and active
    bounds (the arguments as it took them; ``sizes`` as int64)."""
    given = compiled_input
    return _outcome(given(A), given(b), given(sizes, np.int64), x, given(x_lower), given(x_upper), given(fixed, np.bool_),
                    float(tolerance))
