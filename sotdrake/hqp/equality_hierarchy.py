"""A hierarchy of equality levels under bounds, solved by QR factorizations when it is clear-cut.

The problem is :class:`~.hqp.HierarchicalQP`'s: levels ``A_k x = b_k`` in strict priority (each
a least-squares problem in what the levels above leave free), hard bounds ``x_min ≤ x ≤ x_max``,
then the minimum-norm ``x`` of the optimal set. Fixed components (``x_min = x_max``) are
eliminated. With ``Z`` an orthonormal basis of what the levels above leave free (``r`` columns),
``B = A_k Z`` and ``ρ = b_k − A_k x``, a level is *clear-cut* when either

* ``m_k ≤ r`` and ``B`` has full row rank: one Householder QR ``Bᵀ = Q R`` solves it exactly,
  ``x ← x + Z Q_1 R⁻ᵀ ρ``, and ``Z ← Z Q_2`` (``Q = [Q_1, Q_2]``); consecutive such levels are
  stacked into one QR (level k's rows below the ones above are ``R_kkᵀ Q_kᵀ``, see
  :func:`_row_rank_prefix`);
* ``m_k > r`` and ``B`` has full column rank: its least-squares solution ``x ← x + Z Π R⁻¹ Q_1ᵀ ρ``
  (QR with column pivoting ``B Π = Q R``) fixes every remaining direction, and the levels below
  only read their residuals;
* otherwise, the scaled rows ``D B`` have a clear rank gap (every singular value above
  :data:`CERTIFIED` or below :data:`NEGLIGIBLE`): a least-squares step ``x ← x + Z z``
  (``z`` minimizes ``‖B z − ρ‖``, the raw rows, as the level's objective is ``‖A_k x − b_k‖``)
  and ``Z ← Z V_0``, ``V_0`` an orthonormal basis of the null space; from a QR with column
  pivoting when its triangle certifies the gap (:func:`_pivoted_step`), else from the SVD
  ``D B = U Σ Vᵀ``.

Rank is certified on the rows scaled to unit norm (their norm before projection), as the
hierarchical QP decides it, with a margin: in the first two cases the smallest singular value of
the scaled ``B`` must be at least :data:`CERTIFIED` (``10³ τ``, ``τ`` the QP's rank threshold), through
``σ_min(R) ≥ 1/‖R⁻¹‖_F`` (row rank: ``σ(D B) = σ(R D)`` with ``D`` the row scaling; column rank:
``σ_min(D B) ≥ σ_min(D) σ_min(B)``). The optimum without the free bounds is then unique up to the
final minimum-norm step. If it lies within the bounds it is the optimum with them (the bounded
optimal set is a subset of the unbounded one and contains that point), and so the hierarchical
QP's answer; :func:`solve_equality_hierarchy` returns it.

A bound in the way (passed by more than :data:`IN_THE_WAY`, the QP's feasibility tolerance; a point
that passes a bound by less is put on it) is held at equality: its component becomes a fixed one and
the hierarchy is solved again (:func:`_sweep`), the bound most in the way first. That point is the QP's answer if
holding the bound is optimal in the lexicographic sense, which the sweep certifies by the sign of
the bound's multiplier at the level that decides it. Along the bound's direction ``p`` (+1 on the
held component, or −1 at an upper bound, the free components following so that every level above
keeps its value, ``A_l p = 0``), level k's objective ``‖A_k x − b_k‖²`` changes at the rate
``λ_k = −ρ_kᵀ E_k`` (``E_k = A_k p`` less what the free directions can compensate, ``ρ_k`` the level's
residual at its optimum). If ``E_k`` is round-off, level k is indifferent and ``p`` passes to the
levels below; otherwise level k decides: ``λ_k ≥ 0`` certifies the bound (the objective is convex,
strictly along what is left of ``p``: no point off the bound does as well), ``λ_k < 0`` releases
it and the sweep is redone. A direction that reaches the end is decided by the minimum-norm stage
(``λ = xᵀ p ≥ 0``). Several bounds are certified together when the levels that decide them see
them independently (:func:`_certify`); the set may change :data:`ACTIVE_SET_CHANGES` times. The
caller may pass the bounds it expects held (those of the previous tick), which then cost no
extra sweep; a wrong guess is released by its multiplier. Otherwise (a rank or survival decision
that is not clear-cut, the set still changing, a non-finite level) it returns None and the
hierarchical QP decides. Cost: one QR and one triangular inverse per group of full-row-rank
levels, a QR (pivoted when rank-deficient; an SVD only when that cannot certify the gap) for the
others, per sweep, instead of the QP's SVDs and stages.

A sweep is compiled with numba (:func:`_compiled_sweep`), its factorizations the LAPACK routines of
``scipy.linalg.lapack`` (:mod:`.kernels.lapack`): the Python version made about a hundred numpy and
LAPACK calls per sweep, whose overhead, not their arithmetic, was most of its time. The compiled
code is cached on disk; the first solve after an install compiles it (about half a minute, said in
the log).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from ..compiled import announce_compilation, compiled_input
from .kernels.lapack import row_norms
from .kernels.sweep import IN_THE_WAY, _compiled_sweep, _most_in_the_way, _outcome  # noqa: F401  (IN_THE_WAY: its tolerance, named here)
from .linalg import all_true
from .problem import MAX_MAGNITUDE, NO_ACTIVE_ROWS, HqpResult, LevelRows

SOLVER_NAME = "qr"

#: How many times the set of bounds held at equality may change before the QP decides.
ACTIVE_SET_CHANGES = 6


class StackedLevels(NamedTuple):
    """The levels' rows stacked once per solve: ``A`` (M × n), ``b``, the rows' norms (0 → 1: the
    rank decisions scale the rows to unit norm) and ``starts`` (level k's rows are
    ``starts[k]:starts[k + 1]``). A caller that assembles its levels stacked (``SolverDyn``'s fast
    path) builds one directly: C-ordered writeable float arrays, ``starts`` int64."""

    A: np.ndarray
    b: np.ndarray
    norms: np.ndarray
    starts: np.ndarray

    @staticmethod
    def of(levels: Sequence[tuple[np.ndarray, np.ndarray]]) -> StackedLevels | None:
        """None when the levels do not stack (rows of different widths): not clear-cut."""
        try:
            starts = np.array([0, *itertools.accumulate(A.shape[0] for A, _ in levels)], dtype=np.int64)
            A = levels[0][0] if len(levels) == 1 else np.concatenate([A for A, _ in levels])
            b = levels[0][1] if len(levels) == 1 else np.concatenate([b for _, b in levels])
            A, b = compiled_input(A), compiled_input(b)
        except (ValueError, TypeError, IndexError):  # (a level that is not a matrix: not clear-cut)
            return None
        if A.ndim != 2 or b.shape != (A.shape[0],):
            return None
        return StackedLevels(A, b, row_norms(A), starts)  # before projection, as the QP's

    def levels(self) -> list[LevelRows]:
        """The equality levels as the hierarchical QP takes them (views of ``A`` and ``b``)."""
        bounds = self.starts.tolist()
        return [LevelRows(self.A[i:j], self.b[i:j], self.b[i:j]) for i, j in itertools.pairwise(bounds)]


def _sweep(stack: StackedLevels, x_lower: np.ndarray, x_upper: np.ndarray, held: dict[int, float]) -> tuple[np.ndarray, list[int]] | None:
    """The hierarchy with the bounds ``held`` (component → sign: +1 its lower bound, −1 its upper)
    as fixed components: ``(x, released)``, ``released`` the held bounds whose multiplier says the
    optimum leaves them (then ``x`` is not the answer), or None when not clear-cut (compiled:
    :func:`_compiled_sweep`)."""
    announce_compilation(_compiled_sweep, "the QR path of the dynamic solver", "about half a minute")
    indices = np.fromiter(held, dtype=np.int64, count=len(held))
    signs = np.fromiter(held.values(), dtype=float, count=len(held))
    ok, x, released = _compiled_sweep(stack.A, stack.b, stack.norms, stack.starts, x_lower, x_upper, indices, signs)
    return (x, released.tolist()) if ok else None


def _checked_input(stack: StackedLevels, x_lower: np.ndarray, x_upper: np.ndarray) -> bool:
    """Whether the levels and the bounds are what the sweep takes: every coefficient and value
    finite and within ±:data:`~.problem.MAX_MAGNITUDE` (a row's norm too), the bounds without NaN
    and ``x_lower ≤ x_upper``. Otherwise the answer is not clear-cut: the QP's stages name what is
    wrong. (NaN fails every comparison.)"""
    if stack.norms.size and not (stack.norms.max() <= MAX_MAGNITUDE and np.abs(stack.b).max() <= MAX_MAGNITUDE):
        return False
    return all_true(x_lower <= x_upper)


def solve_equality_hierarchy(levels: Sequence[tuple[np.ndarray, np.ndarray]], x_lower: np.ndarray,
                             x_upper: np.ndarray, at_lower: Sequence[int] = (), at_upper: Sequence[int] = ()) -> HqpResult | None:
    """The hierarchical QP's answer to the equality ``levels`` ``[(A_k, b_k), …]`` under the bounds,
    or None when it is not clear-cut (see the module docstring). The bounds are expected as the QP
    checks them (same sizes, ``x_lower ≤ x_upper``, no NaN); a non-finite level is never clear-cut
    (the QP then says what is wrong with it). ``at_lower``/``at_upper``: the components expected at
    one of their bounds (e.g. those of the previous tick), held first; a guess that is wrong costs
    another sweep, never the answer."""
    start = time.perf_counter()
    if not levels:
        return None
    stack = StackedLevels.of(levels)
    if stack is None:
        return None
    return solve_stacked(stack, x_lower, x_upper, at_lower, at_upper, start)


def solve_stacked(stack: StackedLevels, x_lower: np.ndarray, x_upper: np.ndarray, at_lower: Sequence[int] = (),
                  at_upper: Sequence[int] = (), start: float | None = None) -> HqpResult | None:
    """:func:`solve_equality_hierarchy` of levels already stacked (``start``: when the solve began,
    by ``time.perf_counter``, for the result's ``solve_time_s``; default now)."""
    start = time.perf_counter() if start is None else start
    if stack.A.shape[1] != len(x_lower) or len(stack.starts) < 2:
        return None
    n = len(x_lower)
    x_lower, x_upper = compiled_input(x_lower), compiled_input(x_upper)
    if not _checked_input(stack, x_lower, x_upper):
        return None
    free = x_lower != x_upper
    held: dict[int, float] = {}
    for guess, sign, bound in ((at_lower, 1.0, x_lower), (at_upper, -1.0, x_upper)):
        for index in guess:
            if 0 <= index < n and free[index] and np.isfinite(bound[index]):
                held[int(index)] = sign
    for _ in range(ACTIVE_SET_CHANGES + 1):
        swept = _sweep(stack, x_lower, x_upper, held)
        if swept is None:
            return None
        x, released = swept
        if released:
            for index in released:
                del held[index]
            continue
        # The bound most in the way (relative to its size) is held next: several at once may hold
        # bounds that the optimum of a level they tie does not need (not clear-cut then).
        index, sign = _most_in_the_way(x, x_lower, x_upper)
        if index == -1:
            break
        if index == -2:  # not finite
            return None
        held[index] = sign
    else:
        return None
    x = np.minimum(np.maximum(x, x_lower), x_upper)  # (what passes a bound by round-off, put on it)
    residuals, slack_norms, active_bounds = _outcome(stack.A, stack.b, stack.starts, x, x_lower, x_upper)
    starts = stack.starts.tolist()
    count = len(starts) - 1
    return HqpResult(
        x=x, slacks=[residuals[starts[k] : starts[k + 1]] for k in range(count)], slack_norms=slack_norms,
        active_rows=[NO_ACTIVE_ROWS] * count, active_bounds=active_bounds,
        solve_time_s=time.perf_counter() - start, level_solvers=[SOLVER_NAME] * count, iterations=[0] * count)
