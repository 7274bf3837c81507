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
import math
import time
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from numba import njit

from ..compiled import announce_compilation, compiled_input
from .kernels.lapack import (
    contiguous,
    fortran,
    geqp3,
    geqrf,
    level_residuals,
    orgqr,
    ormqr,
    row_norms,
    upper_inverse,
)
from .solve import HqpResult, LevelRows
from .tolerances import CERTIFIED, FEASIBILITY, MULTIPLIER_TOLERANCE, NEGLIGIBLE

SOLVER_NAME = "qr"

#: A component counts as in the way of a bound when it passes it by more than this (relative above 1):
#: the hierarchical QP's feasibility tolerance, far above the round-off of a point that lies on the
#: bound in exact arithmetic (whose side would otherwise depend on the CPU's last bits). A point
#: within it is put on the bound.
IN_THE_WAY = FEASIBILITY

#: How many times the set of bounds held at equality may change before the QP decides.
ACTIVE_SET_CHANGES = 6

# The compiled functions: every matrix handed to LAPACK is a column-major copy, the others are
# C-ordered. A function that cannot decide returns ``ok = False``.

@njit(cache=True)
def _none():
    """The empty matrix that stands for "no step" or "no basis"."""
    return np.zeros((0, 0))


@njit(cache=True)
def _pivoted_step(B, residual, norms):
    """``(ok, z, V_0)`` of a level of rank ``k ≤ r`` in the free space, from one QR with column pivoting
    ``B Π = Q [[R_11, R_12], [0, R_22]]``: ``z = Π [R_11⁻¹ Q_1ᵀ ρ; 0]`` minimizes ``‖B z − ρ‖``
    (another minimizer differs by a null vector, which the levels below and the final
    minimum-norm step take care of), and ``V_0`` is an orthonormal basis of the null space
    ``Π [−R_11⁻¹ R_12; I]``. The rank must be clear-cut for the scaled rows ``D B``
    (``D = diag(1/‖row‖)``): ``σ_k(D B) ≥ min(D)/‖R_11⁻¹‖_F > CERTIFIED`` and
    ``σ_{k+1}(D B) ≤ max(D) ‖R_22‖_F < NEGLIGIBLE``; else not ok."""
    m, r = B.shape
    columns = residual.shape[1]
    if not np.all(np.isfinite(norms)):
        return False, _none(), _none()
    qr = fortran(B)
    pivots = np.zeros(r, np.int32)
    tau = np.empty(min(m, r))
    if geqp3(qr, pivots, tau) != 0:
        return False, _none(), _none()
    d_min, d_max = 1.0 / np.max(norms), 1.0 / np.min(norms)
    k = 0
    for i in range(min(m, r)):
        if abs(qr[i, i]) * d_min > CERTIFIED:
            k += 1
    if k == 0:
        return False, _none(), _none()
    ok, R11_inverse = upper_inverse(qr[:k, :k])
    if not ok or not np.sum(R11_inverse * R11_inverse) * CERTIFIED * CERTIFIED < d_min * d_min:  # False on NaN too
        return False, _none(), _none()
    if k < r:
        R22 = 0.0
        for i in range(k, min(m, r)):
            for j in range(i, r):
                R22 += qr[i, j] * qr[i, j]
        if not R22 * d_max * d_max < NEGLIGIBLE * NEGLIGIBLE:
            return False, _none(), _none()
    projected = fortran(residual)
    if ormqr(qr, tau, projected, True) != 0:
        return False, _none(), _none()
    z = np.zeros((r, columns))
    head = R11_inverse @ contiguous(projected[:k])
    for a in range(k):
        z[pivots[a] - 1] = head[a]
    if k == r:  # full column rank: the level fixes what is left
        return True, z, np.zeros((r, 0))
    null = np.zeros((r, r - k))
    coupling = R11_inverse @ contiguous(qr[:k, k:])
    for a in range(k):
        null[pivots[a] - 1] = -coupling[a]
    for j in range(r - k):
        null[pivots[k + j] - 1, j] = 1.0
    basis = fortran(null)
    tau = np.empty(r - k)
    if geqrf(basis, tau) != 0 or orgqr(basis, r - k, tau) != 0:
        return False, _none(), _none()
    return True, z, contiguous(basis)


@njit(cache=True)
def _least_squares(C, residual):
    """``(ok, argmin ‖C z − residual‖)`` of a full-column-rank ``C`` (m × k, m ≥ k), by QR."""
    k = C.shape[1]
    qr = fortran(C)
    tau = np.empty(k)
    if geqrf(qr, tau) != 0:
        return False, _none()
    ok, R_inverse = upper_inverse(qr[:k, :k])
    projected = fortran(residual)
    if not ok or ormqr(qr, tau, projected, True) != 0:
        return False, _none()
    return True, R_inverse @ contiguous(projected[:k])


@njit(cache=True)
def _row_rank_prefix(B, residual, norms, sizes):
    """``(ok, c, step, basis)`` for the first ``c ≥ 1`` of consecutive levels stacked in ``B`` (``sizes``
    rows each, ``M ≤ r`` in all) certified of full row rank below each other: one QR
    ``Bᵀ = Q R``; level k's rows in what the ones above leave free are ``R_kkᵀ Q_kᵀ``, certified when
    ``σ_min(R_kk D_k) ≥ 1/‖D_k⁻¹ R_kk⁻¹‖_F > CERTIFIED`` (``R_kk⁻¹``: the diagonal block of ``R⁻¹``);
    their exact solution ``step = Q_1 R_1⁻ᵀ ρ_1`` (the first ``K`` rows) and ``basis = Q_2``. Not ok
    when not even the first is certified. (The QR of the first rows does not depend on the rows below.)"""
    M, r = B.shape
    qr = fortran(B.T)
    tau = np.empty(M)
    if geqrf(qr, tau) != 0:
        return False, 0, _none(), _none()
    ok, R_inverse = upper_inverse(qr[:M, :M])
    if not ok:
        return False, 0, _none(), _none()
    count, K = 0, 0
    for size in sizes:  # (R D)⁻¹ = D⁻¹ R⁻¹, D = diag(1/‖row‖)
        block = 0.0
        for i in range(K, K + size):
            for j in range(K, K + size):
                scaled = R_inverse[i, j] * norms[i]
                block += scaled * scaled
        if not block * CERTIFIED * CERTIFIED < 1.0:  # False on NaN too
            break
        count, K = count + 1, K + size
    if count == 0:
        return False, 0, _none(), _none()
    square = np.zeros((r, r)).T
    square[:, :K] = qr[:, :K]
    if orgqr(square, K, tau[:K].copy()) != 0:  # r × r: Q_1 then Q_2
        return False, 0, _none(), _none()
    Q = contiguous(square)
    step = contiguous(Q[:, :K]) @ (contiguous(R_inverse[:K, :K].T) @ contiguous(residual[:K]))
    return True, count, step, contiguous(Q[:, K:])


@njit(cache=True)
def _clear_cut_step(B, residual, norms):
    """``(ok, step, basis)`` of one level that is not of full row rank in the free space (or has more
    rows than it): the least-squares step ``z`` (no columns: none) and the basis of what is left in
    the free space's coordinates (no rows: unchanged), or not ok when the level's rank is not
    clear-cut. ``B``: the level's rows in the free space (m × r), ``norms``: the rows' norms before
    projection. One QR with column pivoting (full column rank included), else the SVD of the scaled
    rows."""
    ok, z, V0 = _pivoted_step(B, residual, norms)
    if ok:
        return True, z, V0
    scaled = B / contiguous(norms).reshape(-1, 1)
    if not np.all(np.isfinite(scaled)):
        return False, _none(), _none()
    _, sigma, Vt = np.linalg.svd(scaled)
    rank = 0
    for value in sigma:
        if not (value > CERTIFIED or value < NEGLIGIBLE):
            return False, _none(), _none()
        if value > CERTIFIED:
            rank += 1
    if rank == 0:
        return True, _none(), _none()
    kept = contiguous(Vt[:rank].T)
    ok, z = _least_squares(B @ kept, residual)  # raw rows: the level's objective is ‖B z − ρ‖
    if not ok:
        return False, _none(), _none()
    return True, kept @ z, contiguous(Vt[rank:].T)


@njit(cache=True)
def _column_norms(M):
    out = np.zeros(M.shape[1])
    for i in range(M.shape[0]):
        for j in range(M.shape[1]):
            out[j] += M[i, j] * M[i, j]
    return np.sqrt(out)


@njit(cache=True)
def _certify(C, B, Y, rho, norms, P):
    """The level's verdict on the bound directions (the columns of ``P``): ``(ok, alive, released)``
    masks, not ok if not clear-cut. ``Y``: the least-squares solution of ``B Y = −C`` (``B`` the
    level's rows in the free space, ``C = A P``), ``rho`` the level's residual ``b − A x`` at its optimum.

    Moving along ``Σ_j t_j p_j`` (``t ≥ 0``, the free components following at their optimum, ``Y t``)
    the level's objective is ``‖ρ − E t‖²`` with ``E = C + B Y`` (orthogonal to ``B``'s range, as ``ρ``),
    that is ``‖ρ‖² + 2 λ·t + ‖E t‖²``, ``λ = −Eᵀ ρ`` the bounds' multipliers at this level. A direction
    whose ``E_j`` is round-off (scaled rows, relative to ``‖p_j‖``) survives: the level is indifferent
    to it and the levels below decide. The others: a negative ``λ_j`` releases its bound (the level
    improves along ``p_j``); otherwise ``t = 0`` is optimal (convex objective, ``λ ≥ 0``) and the only
    optimum if the directions with ``λ_j ≈ 0`` change the level independently (``E`` of full column
    rank on them; else not clear-cut): their bounds hold from this level on."""
    u = P.shape[1]
    E = C + B @ Y if B.shape[1] else C.copy()
    scaled = E / contiguous(norms).reshape(-1, 1) / _column_norms(P)
    change = _column_norms(scaled)
    dies = np.zeros(u, np.bool_)
    for j in range(u):
        if not np.isfinite(change[j]) or NEGLIGIBLE <= change[j] <= CERTIFIED:
            return False, dies, dies
        dies[j] = change[j] > CERTIFIED
    if not dies.any():
        return True, ~dies, dies
    multiplier = -(rho @ E)
    tolerance = MULTIPLIER_TOLERANCE * math.sqrt(rho @ rho) * _column_norms(E)
    released = dies & (multiplier < -tolerance)
    if released.any():
        return True, ~dies, released
    tied = dies & (multiplier <= tolerance)
    if np.count_nonzero(tied) > 1:
        sigma = np.linalg.svd(contiguous(scaled[:, np.flatnonzero(tied)]))[1]
        if sigma.min() <= CERTIFIED:
            return False, dies, dies
    return True, ~dies, released


@njit(cache=True)
def _compiled_sweep(A, b, norms, starts, x_lower, x_upper, held_indices, held_signs):
    """:func:`_sweep` on arrays: ``(ok, x, released)``, ``released`` the indices of the held bounds
    to release. ``Z`` (``have_Z``; else the identity on the free components) is an n × r basis,
    zero on the fixed components; the right-hand sides are ``[ρ, −A P]`` (one column per direction)."""
    n = x_lower.size
    fixed = x_lower == x_upper
    x = np.where(fixed, x_lower, 0.0)
    u = held_indices.size
    P = np.zeros((n, u))
    for j in range(u):
        index = held_indices[j]
        fixed[index] = True
        x[index] = x_lower[index] if held_signs[j] > 0 else x_upper[index]
        P[index, j] = held_signs[j]
    directions = held_indices.copy()
    free = np.flatnonzero(~fixed)
    r = free.size
    all_free = r == n
    Z = np.zeros((n, 0))
    have_Z = False
    none = np.zeros(0, np.int64)
    count_levels = starts.size - 1
    i = 0
    while i < count_levels and (r or u):
        if starts[i + 1] == starts[i]:  # an empty level changes nothing
            i += 1
            continue
        # The next levels whose rows fit in what is left, stacked: solved by one QR if full rank.
        j = i
        while j < count_levels and 0 < starts[j + 1] - starts[i] <= r:
            j += 1
        group = starts[i + 1 : j + 1] - starts[i:j]
        count = max(group.size, 1)
        first, last = starts[i], starts[i + count]
        A_rows = A[first:last]
        residual = b[first:last] - A_rows @ x
        if have_Z:
            B = A_rows @ Z
        elif all_free:
            B = A_rows.copy()
        else:
            B = np.empty((last - first, r))
            for column in range(r):
                B[:, column] = A_rows[:, free[column]]
        rows_norms = norms[first:last]
        rhs = np.empty((last - first, 1 + u))
        rhs[:, 0] = residual
        C = A_rows @ P
        rhs[:, 1:] = -C
        ok, solved, step, basis = False, 1, _none(), _none()
        if group.size:
            ok, solved, step, basis = _row_rank_prefix(B, rhs, rows_norms, group)
        prefix = ok
        if not prefix:  # the first level alone
            m = starts[i + 1] - starts[i]
            B_level = contiguous(B[:m])
            if r:
                ok, step, basis = _clear_cut_step(B_level, contiguous(rhs[:m]), rows_norms[:m])
                if not ok:
                    return False, x, none
            solved = 1
            if u:
                has_step = step.shape[1] > 0
                Y = contiguous(step[:, 1:]) if has_step else np.zeros((r, u))
                rho = residual[:m] - B_level @ contiguous(step[:, 0]) if has_step else residual[:m].copy()
                ok, alive, released = _certify(contiguous(C[:m]), B_level, Y, rho, rows_norms[:m], P)
                if not ok:
                    return False, x, none
                if released.any():
                    return True, x, directions[released]
        if step.shape[1] > 0:
            if have_Z:
                step = Z @ step
            elif not all_free:
                full = np.zeros((n, 1 + u))
                for row in range(r):
                    full[free[row]] = step[row]
                step = full
            P += step[:, 1:]
            x += step[:, 0]
        if u and not prefix:
            directions, P = directions[alive], contiguous(P[:, np.flatnonzero(alive)])
            u = directions.size
        if basis.shape[0] > 0:
            if have_Z:
                Z = Z @ basis
            elif all_free:
                Z = basis
            else:
                Z = np.zeros((n, basis.shape[1]))
                for row in range(r):
                    Z[free[row]] = basis[row]
            have_Z = True
            r = Z.shape[1]
        i += solved
    if r and have_Z:
        x -= Z @ (Z.T @ x)  # the minimum-norm point of what is left (Z is zero on the fixed components)
    if u:  # the final minimum-norm stage: λ_j = x · p_j ≥ 0
        released = x @ P < -MULTIPLIER_TOLERANCE * math.sqrt(x @ x) * _column_norms(P)
        return True, x, directions[released]
    return True, x, none


@njit(cache=True)
def _most_in_the_way(x, x_lower, x_upper):
    """``(index, sign)`` of the bound most in the way of ``x`` (relative to its size; sign +1 below its
    lower bound, −1 above its upper one) among those passed by more than :data:`IN_THE_WAY`,
    ``(-1, 0)`` when ``x`` is within its bounds to that tolerance, ``(-2, 0)`` when it is not finite."""
    index, sign, worst = -1, 0.0, IN_THE_WAY
    for i in range(x.size):
        if not np.isfinite(x[i]):
            return -2, 0.0
        if x[i] < x_lower[i] or x[i] > x_upper[i]:
            bound = x_lower[i] if x[i] < x_lower[i] else x_upper[i]
            distance = abs(x[i] - bound) / max(1.0, abs(bound))
            if distance > worst:
                index, sign, worst = i, (1.0 if x[i] < x_lower[i] else -1.0), distance
    return index, sign


@njit(cache=True)
def _outcome(A, b, starts, x, x_lower, x_upper):
    """``(A x − b, each level's slack norm, the free components at a bound)``."""
    residuals, norms = level_residuals(A, b, x, np.diff(starts))
    at_bound = (x_lower != x_upper) & ((x <= x_lower) | (x >= x_upper))
    return residuals, norms, np.flatnonzero(at_bound)


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


_NO_ROWS = np.zeros(0, dtype=int)  # the active rows of an equality level (shared, read only)
_NO_ROWS.flags.writeable = False


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
        active_rows=[_NO_ROWS] * count, active_bounds=active_bounds,
        solve_time_s=time.perf_counter() - start, level_solvers=[SOLVER_NAME] * count, iterations=[0] * count)
