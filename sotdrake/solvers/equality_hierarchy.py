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

A bound in the way is held at equality: its component becomes a fixed one and the hierarchy is
solved again (:func:`_sweep`), the bound most in the way first. That point is the QP's answer if
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
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np
from scipy.linalg.lapack import dgeqp3 as _geqp3
from scipy.linalg.lapack import dgeqrf as _geqrf
from scipy.linalg.lapack import dgesdd as _gesdd
from scipy.linalg.lapack import dorgqr as _orgqr
from scipy.linalg.lapack import dormqr as _ormqr

from .active_set import RANK_THRESHOLD, upper_inverse, upper_triangle
from .hqp import HqpResult, row_norms

#: The smallest singular value (rows at unit norm) that counts as clearly non-zero,
CERTIFIED = 1e3 * RANK_THRESHOLD
#: and the largest that counts as clearly zero (round-off of a row the levels above fix).
NEGLIGIBLE = 1e-3 * RANK_THRESHOLD

SOLVER_NAME = "qr"


def _pivoted_step(B: np.ndarray, residual: np.ndarray, norms: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """``(z, V_0)`` of a level of rank ``k ≤ r`` in the free space, from one QR with column pivoting
    ``B Π = Q [[R_11, R_12], [0, R_22]]``: ``z = Π [R_11⁻¹ Q_1ᵀ ρ; 0]`` minimizes ``‖B z − ρ‖``
    (another minimizer differs by a null vector, which the levels below and the final
    minimum-norm step take care of), and ``V_0`` is an orthonormal basis of the null space
    ``Π [−R_11⁻¹ R_12; I]``. The rank must be clear-cut for the scaled rows ``D B``
    (``D = diag(1/‖row‖)``): ``σ_k(D B) ≥ min(D)/‖R_11⁻¹‖_F > CERTIFIED`` and
    ``σ_{k+1}(D B) ≤ max(D) ‖R_22‖_F < NEGLIGIBLE``; else None."""
    m, r = B.shape
    qr, pivots, tau, _, info = _geqp3(B)
    if info != 0:
        return None
    d_min, d_max = 1.0 / float(np.maximum.reduce(norms)), 1.0 / float(np.minimum.reduce(norms))
    k = int(np.count_nonzero(np.abs(qr.diagonal()) * d_min > CERTIFIED))
    if k == 0:
        return None
    R11_inverse = upper_inverse(qr[:k, :k])
    if R11_inverse is None:
        return None
    flat = R11_inverse.ravel()
    if not flat.dot(flat) * CERTIFIED * CERTIFIED < d_min * d_min:  # False on NaN too
        return None
    if k < r:
        R22 = np.where(upper_triangle(r - k)[: min(m, r) - k], qr[k : min(m, r), k:], 0.0).ravel()
        if not float(R22.dot(R22)) * d_max * d_max < NEGLIGIBLE * NEGLIGIBLE:
            return None
    projected, _, info = _ormqr("L", "T", qr[:, : len(tau)], tau, residual, lwork=max(1, m, residual[0].size))
    if info != 0:
        return None
    columns = pivots - 1
    z = np.zeros((r,) + residual.shape[1:])
    z[columns[:k]] = R11_inverse @ projected[:k]
    if k == r:  # full column rank: the level fixes what is left
        return z, np.zeros((r, 0))
    null = np.zeros((r, r - k))
    null[columns[:k]] = -R11_inverse @ qr[:k, k:]
    null[columns[k:], np.arange(r - k)] = 1.0
    basis, tau, _, info = _geqrf(null)
    if info != 0:
        return None
    V0, _, info = _orgqr(basis, tau)
    return (z, V0) if info == 0 else None


def _least_squares(C: np.ndarray, residual: np.ndarray) -> np.ndarray | None:
    """``argmin ‖C z − residual‖`` of a full-column-rank ``C`` (m × k, m ≥ k), by QR."""
    k = C.shape[1]
    qr, tau, _, info = _geqrf(C)
    if info != 0:
        return None
    R_inverse = upper_inverse(qr[:k, :k])
    if R_inverse is None:
        return None
    projected, _, info = _ormqr("L", "T", qr, tau, residual, lwork=max(1, C.shape[0], residual[0].size))
    return R_inverse @ projected[:k] if info == 0 else None


def _row_rank_prefix(B: np.ndarray, residual: np.ndarray, norms: np.ndarray, sizes: list[int]) -> tuple[int, np.ndarray, np.ndarray] | None:
    """``(c, step, basis)`` for the first ``c ≥ 1`` of consecutive levels stacked in ``B`` (``sizes``
    rows each, ``M ≤ r`` in all) certified of full row rank below each other: one QR
    ``Bᵀ = Q R``; level k's rows in what the ones above leave free are ``R_kkᵀ Q_kᵀ``, certified when
    ``σ_min(R_kk D_k) ≥ 1/‖D_k⁻¹ R_kk⁻¹‖_F > CERTIFIED`` (``R_kk⁻¹``: the diagonal block of ``R⁻¹``);
    their exact solution ``step = Q_1 R_1⁻ᵀ ρ_1`` (the first ``K`` rows) and ``basis = Q_2``. None when
    not even the first is certified. (The QR of the first rows does not depend on the rows below.)"""
    M, r = B.shape[0], B.shape[1]
    qr, tau, _, info = _geqrf(B.T)
    if info != 0:
        return None
    R_inverse = upper_inverse(qr[:M, :M])
    if R_inverse is None:
        return None
    scaled = R_inverse * norms[:, None]  # (R D)⁻¹ = D⁻¹ R⁻¹, D = diag(1/‖row‖)
    count, K = 0, 0
    for size in sizes:
        block = scaled[K : K + size, K : K + size].ravel()
        if not block.dot(block) * CERTIFIED * CERTIFIED < 1.0:  # False on NaN too
            break
        count, K = count + 1, K + size
    if count == 0:
        return None
    square = np.zeros((r, r), order="F")
    square[:, :K] = qr[:, :K]
    Q, _, info = _orgqr(square, tau[:K])  # r × r: Q_1 then Q_2
    if info != 0:
        return None
    return count, Q[:, :K] @ (R_inverse[:K, :K].T @ residual[:K]), Q[:, K:]


def _clear_cut_step(B: np.ndarray, residual: np.ndarray, norms: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None] | None:
    """``(step, basis)`` of one level that is not of full row rank in the free space (or has more
    rows than it): the least-squares step ``z`` (None: none) and the basis of what is left in the
    free space's coordinates, or None when the level's rank is not clear-cut. ``B``: the level's
    rows in the free space (m × r), ``norms``: the rows' norms before projection. One QR with
    column pivoting (full column rank included), else the SVD of the scaled rows."""
    # The rank from a pivoted QR, else from the SVD of the scaled rows, if clear-cut.
    pivoted = _pivoted_step(B, residual, norms)
    if pivoted is not None:
        return pivoted
    scaled = B / norms[:, None]
    _, sigma, Vt, info = _gesdd(scaled, compute_uv=1, full_matrices=1)
    if info != 0 or not np.all((sigma > CERTIFIED) | (sigma < NEGLIGIBLE)):
        return None
    rank = int(np.count_nonzero(sigma > CERTIFIED))
    if rank == 0:
        return None, None
    kept = Vt[:rank].T
    z = _least_squares(B @ kept, residual)  # raw rows: the level's objective is ‖B z − ρ‖
    return None if z is None else (kept @ z, Vt[rank:].T)


#: How many times the set of bounds held at equality may change before the QP decides.
ACTIVE_SET_CHANGES = 6
#: A bound's multiplier ``λ`` counts as negative below ``−MULTIPLIER_TOLERANCE ‖ρ‖ ‖c‖`` (round-off).
MULTIPLIER_TOLERANCE = 1e-9


class _Directions:
    """The bound directions not yet certified: column j of ``P`` (n × u) is ``p_j``, equal to ``s_j`` on
    the held bound's component ``i_j`` (``s = +1`` at a lower bound, ``−1`` at an upper one), 0 on the
    other fixed components, and such that ``A_l p_j = 0`` for every level ``l`` above the current one."""

    def __init__(self, indices: np.ndarray, signs: np.ndarray, n: int):
        self.indices, self.signs = indices, signs
        self.P = np.zeros((n, len(indices)))
        self.P[indices, np.arange(len(indices))] = signs

    def keep(self, alive: np.ndarray) -> None:
        self.indices, self.signs, self.P = self.indices[alive], self.signs[alive], self.P[:, alive]


def _certify(C: np.ndarray, B: np.ndarray, Y: np.ndarray, rho: np.ndarray, norms: np.ndarray,
             directions: _Directions) -> tuple[np.ndarray, np.ndarray] | None:
    """The level's verdict on the bound directions: ``(alive, released)`` masks, or None if not
    clear-cut. ``Y``: the least-squares solution of ``B Y = −C`` (``B`` the level's rows in the free
    space, ``C = A p``), ``rho`` the level's residual ``b − A x`` at its optimum.

    Moving along ``Σ_j t_j p_j`` (``t ≥ 0``, the free components following at their optimum, ``Y t``)
    the level's objective is ``‖ρ − E t‖²`` with ``E = C + B Y`` (orthogonal to ``B``'s range, as ``ρ``),
    that is ``‖ρ‖² + 2 λ·t + ‖E t‖²``, ``λ = −Eᵀ ρ`` the bounds' multipliers at this level. A direction
    whose ``E_j`` is round-off (scaled rows, relative to ``‖p_j‖``) survives: the level is indifferent
    to it and the levels below decide. The others: a negative ``λ_j`` releases its bound (the level
    improves along ``p_j``); otherwise ``t = 0`` is optimal (convex objective, ``λ ≥ 0``) and the only
    optimum if the directions with ``λ_j ≈ 0`` change the level independently (``E`` of full column
    rank on them; else not clear-cut): their bounds hold from this level on."""
    E = C + B @ Y if B.shape[1] else C.copy()
    size = np.sqrt(np.einsum("ij,ij->j", directions.P, directions.P))
    scaled = E / norms[:, None] / size
    change = np.sqrt(np.einsum("ij,ij->j", scaled, scaled))
    if np.any((change >= NEGLIGIBLE) & (change <= CERTIFIED)) or not np.all(np.isfinite(change)):
        return None
    dies = change > CERTIFIED
    if not dies.any():
        return ~dies, dies
    multiplier = -(rho @ E)
    tolerance = MULTIPLIER_TOLERANCE * float(np.sqrt(rho @ rho)) * np.sqrt(np.einsum("ij,ij->j", E, E))
    released = dies & (multiplier < -tolerance)
    if released.any():
        return ~dies, released
    tied = dies & (multiplier <= tolerance)
    if np.count_nonzero(tied) > 1 and np.linalg.svd(scaled[:, tied], compute_uv=False).min() <= CERTIFIED:
        return None
    return ~dies, released


class _Stack(NamedTuple):
    """The levels' rows stacked once per solve: ``A`` (M × n), ``b``, the rows' norms (0 → 1: the
    rank decisions scale the rows to unit norm) and ``starts`` (level k's rows are
    ``starts[k]:starts[k + 1]``)."""

    A: np.ndarray
    b: np.ndarray
    norms: np.ndarray
    starts: list[int]

    @staticmethod
    def of(levels: Sequence[tuple[np.ndarray, np.ndarray]]) -> _Stack | None:
        """None when the levels do not stack (rows of different widths): not clear-cut."""
        starts = [0]
        for A, _ in levels:
            starts.append(starts[-1] + A.shape[0])
        try:
            A = levels[0][0] if len(levels) == 1 else np.vstack([A for A, _ in levels])
            b = levels[0][1] if len(levels) == 1 else np.concatenate([b for _, b in levels])
        except ValueError:
            return None
        if A.ndim != 2 or b.shape != (A.shape[0],):
            return None
        return _Stack(A, b, row_norms(A), starts)  # before projection, as the QP's


def _sweep(stack: _Stack, x_lower: np.ndarray, x_upper: np.ndarray, held: dict[int, float]) -> tuple[np.ndarray, list[int]] | None:
    """The hierarchy with the bounds ``held`` (component → sign: +1 its lower bound, −1 its upper)
    as fixed components: ``(x, released)``, ``released`` the held bounds whose multiplier says the
    optimum leaves them (then ``x`` is not the answer), or None when not clear-cut. ``x`` is kept in
    full coordinates, and ``Z`` (what the levels so far leave free) as an n × r basis that is zero on
    the fixed components (None: the identity on the free ones)."""
    fixed = x_lower == x_upper
    x = np.where(fixed, x_lower, 0.0)
    for index, sign in held.items():
        fixed[index] = True
        x[index] = x_lower[index] if sign > 0 else x_upper[index]
    free = ~fixed
    n = len(x)
    r = int(np.count_nonzero(free))
    all_free = r == n
    Z: np.ndarray | None = None
    indices = np.array(list(held), dtype=int)
    directions = _Directions(indices, np.array([held[i] for i in held], dtype=float), n)
    u = len(indices)
    starts = stack.starts
    count_levels = len(starts) - 1
    i = 0
    while i < count_levels and (r or u):
        if starts[i + 1] == starts[i]:  # an empty level changes nothing
            i += 1
            continue
        # The next levels whose rows fit in what is left, stacked: solved by one QR if full rank.
        group, j = [], i
        while j < count_levels and 0 < starts[j + 1] - starts[i] <= r:
            group.append(starts[j + 1] - starts[j])
            j += 1
        count = len(group) or 1
        rows = slice(starts[i], starts[i + count])
        A_full = stack.A[rows]
        residual = stack.b[rows] - A_full @ x
        B = A_full if Z is None and all_free else (A_full[:, free] if Z is None else A_full @ Z)
        norms = stack.norms[rows]
        C = A_full @ directions.P if u else None
        rhs = residual if C is None else np.column_stack([residual, -C])
        step: np.ndarray | None
        basis: np.ndarray | None
        prefix = _row_rank_prefix(B, rhs, norms, group) if group else None
        if prefix is not None:  # exact: every direction survives (λ = 0)
            solved, step, basis = prefix
        else:  # the first level alone
            m = starts[i + 1] - starts[i]
            if r:
                step_basis = _clear_cut_step(B[:m], rhs[:m], norms[:m])
                if step_basis is None:
                    return None
            else:
                step_basis = None, None
            solved, (step, basis) = 1, step_basis
            if C is not None:
                Y = np.zeros((r, u)) if step is None else step[:, 1:]
                rho = residual[:m] - (B[:m] @ step[:, 0] if step is not None else 0.0)
                verdict = _certify(C[:m], B[:m], Y, rho, norms[:m], directions)
                if verdict is None:
                    return None
                alive, released = verdict
                if released.any():
                    return x, [int(j) for j in directions.indices[released]]
        if step is not None:
            if Z is not None:
                step = Z @ step
            elif not all_free:
                full = np.zeros((n,) + step.shape[1:])
                full[free] = step
                step = full
            if C is not None:
                directions.P += step[:, 1:]
                step = step[:, 0]
            x += step
        if C is not None and prefix is None:
            directions.keep(alive)
            u = int(alive.sum())
        if basis is not None:
            if Z is not None:
                Z = Z @ basis
            elif all_free:
                Z = basis
            else:
                Z = np.zeros((n, basis.shape[1]))
                Z[free] = basis
            r = Z.shape[1]
        i += solved
    if r and Z is not None:
        x -= Z @ (Z.T @ x)  # the minimum-norm point of what is left (Z is zero on the fixed components)
    if u:  # the final minimum-norm stage: λ_j = x · p_j ≥ 0
        multiplier = x @ directions.P
        size = np.sqrt(np.einsum("ij,ij->j", directions.P, directions.P))
        released = multiplier < -MULTIPLIER_TOLERANCE * float(np.sqrt(x @ x)) * size
        if released.any():
            return x, [int(j) for j in directions.indices[released]]
    return x, []


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
    stack = _Stack.of(levels)
    if stack is None or stack.A.shape[1] != len(x_lower):
        return None
    n = len(x_lower)
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
        below, above = x < x_lower, x > x_upper
        if not (below.any() or above.any()):
            if not np.isfinite(x).all():
                return None
            break
        # The bound most in the way (relative to its size) is held next: several at once may hold
        # bounds that the optimum of a level they tie does not need (not clear-cut then).
        outside = np.flatnonzero(below | above)
        bound = np.where(below[outside], x_lower[outside], x_upper[outside])
        index = int(outside[np.argmax(np.abs(x[outside] - bound) / np.maximum(1.0, np.abs(bound)))])
        held[index] = 1.0 if below[index] else -1.0
    else:
        return None
    residuals = stack.A @ x - stack.b
    starts = stack.starts
    slacks = [residuals[starts[k] : starts[k + 1]] for k in range(len(levels))]
    return HqpResult(
        x=x, slacks=slacks, slack_norms=np.array([math.sqrt(s @ s) for s in slacks]),
        active_rows=[_NO_ROWS] * len(levels),
        active_bounds=np.flatnonzero(free & ((x <= x_lower) | (x >= x_upper))),
        solve_time_s=time.perf_counter() - start, level_solvers=[SOLVER_NAME] * len(levels),
        iterations=[0] * len(levels))
