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
QP's answer; :func:`solve_equality_hierarchy` returns it. Otherwise (a rank decision that is not
clear-cut, a bound in the way, a non-finite level) it returns None and the hierarchical QP decides.
Cost: one QR and one triangular inverse per group of full-row-rank levels, a QR (pivoted when
rank-deficient; an SVD only when that cannot certify the gap) for the others, instead of the QP's
SVDs and stages.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np
from scipy.linalg.lapack import dgeqp3 as _geqp3
from scipy.linalg.lapack import dgeqrf as _geqrf
from scipy.linalg.lapack import dgesdd as _gesdd
from scipy.linalg.lapack import dorgqr as _orgqr
from scipy.linalg.lapack import dormqr as _ormqr

from .active_set import RANK_THRESHOLD, upper_inverse, upper_triangle
from .hqp import HqpResult

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
    d_min, d_max = 1.0 / float(norms.max()), 1.0 / float(norms.min())
    k = int(np.count_nonzero(np.abs(np.diagonal(qr)) * d_min > CERTIFIED))
    if k == 0:
        return None
    R11_inverse = upper_inverse(qr[:k, :k])
    if R11_inverse is None:
        return None
    flat = R11_inverse.ravel()
    if not flat.dot(flat) * CERTIFIED * CERTIFIED < d_min * d_min:  # False on NaN too
        return None
    if k < r:
        R22 = np.where(upper_triangle(r - k)[: min(m, r) - k], qr[k : min(m, r), k:], 0.0)
        if not float(np.sum(R22 * R22)) * d_max * d_max < NEGLIGIBLE * NEGLIGIBLE:
            return None
    projected, _, info = _ormqr("L", "T", qr[:, : len(tau)], tau, residual, lwork=max(1, m))
    if info != 0:
        return None
    columns = pivots - 1
    z = np.zeros(r)
    z[columns[:k]] = R11_inverse @ projected[:k]
    if k == r:  # full column rank: the level fixes what is left
        return z, np.zeros((r, 0))
    null = np.empty((r, r - k))
    null[columns[:k]] = -R11_inverse @ qr[:k, k:]
    null[columns[k:]] = np.eye(r - k)
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
    projected, _, info = _ormqr("L", "T", qr, tau, residual, lwork=max(1, C.shape[0]))
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


def solve_equality_hierarchy(levels: Sequence[tuple[np.ndarray, np.ndarray]], x_lower: np.ndarray,
                             x_upper: np.ndarray) -> HqpResult | None:
    """The hierarchical QP's answer to the equality ``levels`` ``[(A_k, b_k), …]`` under the bounds,
    or None when it is not clear-cut (see the module docstring). The bounds are expected as the QP
    checks them (same sizes, ``x_lower ≤ x_upper``, no NaN); a non-finite level is never clear-cut
    (the QP then says what is wrong with it)."""
    start = time.perf_counter()
    fixed = x_lower == x_upper
    free = ~fixed
    x = np.where(fixed, x_lower, 0.0)
    n_free = int(free.sum())
    all_free = n_free == len(x)
    Z: np.ndarray | None = None  # None: the identity on the free components
    r = n_free
    x_free = np.zeros(n_free)
    i = 0
    while i < len(levels) and r:
        # The next levels whose rows fit in what is left, stacked: solved by one QR if full rank.
        group, total = [], 0
        for A_full, _ in levels[i:]:
            if not 0 < total + A_full.shape[0] <= r:
                break
            group.append(A_full.shape[0])
            total += A_full.shape[0]
        if levels[i][0].shape[0] == 0:
            i += 1
            continue
        count = len(group) or 1
        if not all_free:
            x[free] = x_free
        A_full = levels[i][0] if count == 1 else np.vstack([A for A, _ in levels[i : i + count]])
        b = levels[i][1] if count == 1 else np.concatenate([b for _, b in levels[i : i + count]])
        A = A_full if all_free else A_full[:, free]
        residual = b - A_full @ (x_free if all_free else x)
        B = A if Z is None else A @ Z
        norms = np.sqrt(np.einsum("ij,ij->i", A_full, A_full))  # before projection, as the QP's
        norms = np.where(norms > 0.0, norms, 1.0)
        step: np.ndarray | None
        basis: np.ndarray | None
        prefix = _row_rank_prefix(B, residual, norms, group) if group else None
        if prefix is not None:
            solved, step, basis = prefix
        else:  # the first level alone
            m = levels[i][0].shape[0]
            step_basis = _clear_cut_step(B[:m], residual[:m], norms[:m])
            if step_basis is None:
                return None
            solved, (step, basis) = 1, step_basis
        if step is not None:
            x_free = x_free + (step if Z is None else Z @ step)
        if basis is not None:
            Z = basis if Z is None else Z @ basis
            r = Z.shape[1]
        i += solved
    if r and Z is not None:
        x_free = x_free - Z @ (Z.T @ x_free)  # the minimum-norm point of what is left
    x[free] = x_free
    if not (np.all(x >= x_lower) and np.all(x <= x_upper)):  # False on NaN too
        return None
    slacks = [A @ x - b for A, b in levels]
    return HqpResult(
        x=x, slacks=slacks, slack_norms=np.array([float(np.sqrt(s @ s)) for s in slacks]),
        active_rows=[np.zeros(0, dtype=int) for _ in levels],
        active_bounds=np.flatnonzero(free & ((x <= x_lower) | (x >= x_upper))),
        solve_time_s=time.perf_counter() - start, level_solvers=[SOLVER_NAME] * len(levels),
        iterations=[0] * len(levels))
