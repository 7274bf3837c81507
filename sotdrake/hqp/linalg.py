"""The linear algebra the hierarchical QP's stages share: rank-revealing factorisations against one
absolute threshold τ on unit rows (:func:`independent_qr`, :func:`independent_rows`, :func:`svd`),
least-squares steps (:func:`full_rank_least_squares`, :func:`scaled_least_squares`), the inverse of
an upper-triangular factor, and mask tests that cost one C call (:func:`all_true`, :func:`any_true`).
Every LAPACK call is scipy's (``dgeqrf``, ``dgeqp3``, ``dgesdd``, ``dtrtri``, ``dtrtrs``, ``dormqr``,
``dorgqr``); a refusal gives None or falls back, never a silent wrong answer."""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from scipy.linalg import lapack

QR_MIN_SIZE = 4
"""Below this smaller dimension LAPACK's SVD costs about as much as the QR route's several calls, so
it is taken directly (measured, full SVD against the QR route with its full Q: 3 × 20 7.9 against
8.4 µs, 5 × 20 17 against 11 µs, 9 × 21 34 against 14 µs, 12 × 30 60 against 19 µs)."""


class ActiveSetFailure(RuntimeError):
    """The active set's iterations did not converge (an iteration cap met on a degenerate problem), or a
    factorisation it needs was refused."""


def all_true(mask: np.ndarray) -> bool:
    """``mask.all()`` through ``np.count_nonzero``, a direct C call: ``ndarray.all`` and ``any`` go
    through a Python wrapper that costs more than the test itself on these small arrays (measured:
    0.4 against 1.3 µs)."""
    return np.count_nonzero(mask) == mask.size


def any_true(mask: np.ndarray) -> bool:
    """``mask.any()`` (for a float array: any nonzero entry), see :func:`all_true`."""
    return bool(np.count_nonzero(mask))


@lru_cache(maxsize=128)
def upper_triangle(k: int) -> np.ndarray:
    """The k × k boolean mask of the upper triangle (read-only, cached): in LAPACK's square output of
    a QR, what is R (below it lie the Householder vectors)."""
    mask = np.triu(np.ones((k, k), dtype=bool))
    mask.flags.writeable = False
    return mask


@lru_cache(maxsize=128)
def _strict_lower_triangle(k: int) -> np.ndarray:
    """The k × k boolean mask below the diagonal (read-only, cached)."""
    mask = ~upper_triangle(k)
    mask.flags.writeable = False
    return mask


def upper_inverse(R: np.ndarray) -> np.ndarray | None:
    """``R⁻¹`` of the upper triangle of the square ``R`` (LAPACK ``dtrtri``, which reads only that
    triangle), zeros below; None if singular. What lies below the triangle (dtrtri's copy of ``R``'s)
    is overwritten with zeros, not multiplied away, so a NaN there stays out (``np.copyto`` in place:
    half the cost of ``np.where``'s new array at these sizes)."""
    inverse, info = lapack.dtrtri(R)
    if info != 0:
        return None
    np.copyto(inverse, 0.0, where=_strict_lower_triangle(R.shape[0]))
    return inverse


def svd(a: np.ndarray, full_matrices: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``U, σ, Vᵀ`` of ``a`` (σ decreasing): LAPACK's ``dgesdd`` called directly (the same routine
    as ``numpy.linalg.svd``, without its per-call overhead, which dominates on the small matrices
    of a level), numpy's if LAPACK reports a failure or ``a`` is empty."""
    if a.shape[0] and a.shape[1]:
        U, sigma, Vt, info = lapack.dgesdd(a, compute_uv=1, full_matrices=int(full_matrices))
        if info == 0:
            return U, sigma, Vt
    return np.linalg.svd(a, full_matrices=full_matrices)


def independent_rows(E: np.ndarray, threshold: float) -> np.ndarray:
    """Indices of a linearly independent subset of ``E``'s (unit) rows spanning the same space:
    QR with column pivoting of ``Eᵀ`` (LAPACK ``dgeqp3``), pivots with ``|R_ii| > threshold``."""
    if len(E) == 0:
        return np.zeros(0, dtype=int)
    R, pivots, _, _, info = lapack.dgeqp3(np.array(E.T, order="F"))
    if info != 0:
        raise ActiveSetFailure(f"QR with column pivoting failed (LAPACK info {info})")
    diagonal = np.abs(np.diag(R))
    return np.sort(pivots[: int(np.count_nonzero(diagonal > threshold))] - 1)


def full_rank_least_squares(B: np.ndarray, r: np.ndarray) -> np.ndarray:
    """``argmin_c ‖B c - r‖`` for ``B`` (m × k, m ≥ k) of full column rank: Householder QR
    (LAPACK ``dgeqrf``), ``Qᵀ r``, then the triangular solve ``R c = (Qᵀ r)_{:k}``."""
    k = B.shape[1]
    qr, tau, _, info = lapack.dgeqrf(B)
    if info == 0:
        qtr, _, info = lapack.dormqr("L", "T", qr, tau, r[:, None], max(1, len(r)))
    if info == 0:
        c, info = lapack.dtrtrs(qr[:k, :k], qtr[:k], lower=0)
    if info != 0:  # LAPACK refused (a zero pivot): numpy's QR and solve raise their own error
        Q, R = np.linalg.qr(B)
        return np.linalg.solve(R, Q.T @ r)
    return c[:, 0]


def scaled_least_squares(U: np.ndarray, s: np.ndarray, Vt: np.ndarray, k: int, m_scale: np.ndarray,
                         r: np.ndarray, uniform: bool | None = None) -> np.ndarray:
    """The minimum-norm ``u`` minimising ``‖B u - r‖`` given the SVD ``U diag(s) Vt`` of the unit-row
    matrix ``B / m_scale`` cut at its first ``k`` singular values (``B = D U_k s_k V_kᵀ`` with
    ``D = diag(m_scale)``: a weighted least squares in ``c``, ``u = V_k c``). ``uniform``: whether
    every entry of ``m_scale`` is the same (computed if None)."""
    U_k, s_k = U[:, :k], s[:k]
    if uniform is None:
        uniform = all_true(m_scale == m_scale[0])
    if uniform:
        c = (U_k.T @ r) / (m_scale[0] * s_k)
    elif k == len(m_scale):  # independent rows: B u = r is solved exactly, c = s⁻¹ Uᵀ D⁻¹ r (U square)
        c = (U_k.T @ (r / m_scale)) / s_k
    else:
        c = full_rank_least_squares(m_scale[:, None] * (U_k * s_k), r)
    return Vt[:k].T @ c


def _proven_full_rank_qr(A: np.ndarray, bound: float) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """LAPACK ``dgeqrf``'s ``(qr, tau)`` of the p × k matrix ``A`` (p ≥ k ≥ :data:`QR_MIN_SIZE`) and
    ``R⁻¹``, when they prove ``σ_min(A) ≥ 1/‖R⁻¹‖_F > bound``; else None."""
    p, k = A.shape
    if k > p or k < QR_MIN_SIZE:
        return None
    qr, tau, _, info = lapack.dgeqrf(A)
    if info != 0:
        return None
    R_inv = upper_inverse(qr[:k])
    if R_inv is None:
        return None
    flat = R_inv.ravel(order="K")
    if not bound * math.sqrt(float(flat @ flat)) < 1.0:
        return None
    return qr, tau, R_inv


def independent_qr(A: np.ndarray, threshold: float, full: bool = False) -> tuple[np.ndarray, np.ndarray] | None:
    """``(Q, R⁻¹)`` of the Householder QR ``A = Q R`` (LAPACK ``dgeqrf``; ``A`` is p × k, k at least
    :data:`QR_MIN_SIZE`) if every singular value of ``A`` is *provably* above ``threshold``, else None (then the caller takes the
    SVD, which decides the rank itself). The proof: ``σ_min(A) = σ_min(R) ≥ 1/‖R⁻¹‖_F``, asked to
    exceed ``2·threshold`` (a margin far above the round-off of R). With every singular value above
    τ the SVD-based computations keep them all, so a QR-based one is the same computation in exact
    arithmetic, at a fraction of the cost. ``Q``: p × p if ``full`` (the last p − k columns: an
    orthonormal basis of the orthogonal complement of A's columns), else p × k."""
    p, k = A.shape
    factors = _proven_full_rank_qr(A, 2.0 * threshold)
    if factors is None:
        return None
    qr, tau, R_inv = factors
    if full and k < p:
        padded = np.zeros((p, p), order="F")
        padded[:, :k] = qr
        qr = padded
    Q, _, info = lapack.dorgqr(qr, tau)
    return (Q, R_inv) if info == 0 else None


def _full_rank_step(B: np.ndarray, m_scale: np.ndarray, r: np.ndarray, threshold: float, uniform: bool) -> np.ndarray | None:
    """The minimum-norm ``u`` minimising ``‖B u - r‖`` when ``B / m_scale`` provably has full rank
    (every singular value above τ, see :func:`independent_qr`): then no singular value is cut and
    the answer is the plain least-squares solution (full column rank) or the minimum-norm solution
    of ``B u = r`` (full row rank). None otherwise."""
    m, q = B.shape
    if m >= q and not uniform:
        u = _weighted_full_rank_step(B, m_scale, r, threshold)
        if u is not None:
            return u
    unit = B / m_scale[:, None]
    if m >= q:
        factors = independent_qr(unit, threshold)
        if factors is None:
            return None
        Q1, R_inv = factors
        if uniform:
            return R_inv @ (Q1.T @ r) / m_scale[0]
        return full_rank_least_squares(B, r)
    factors = independent_qr(unit.T, threshold)
    if factors is None:
        return None
    Q1, R_inv = factors  # unit = Rᵀ Q1ᵀ: B u = r ⇔ Rᵀ Q1ᵀ u = r / m_scale
    return Q1 @ (R_inv.T @ (r / m_scale))


def _weighted_full_rank_step(B: np.ndarray, m_scale: np.ndarray, r: np.ndarray, threshold: float) -> np.ndarray | None:
    """:func:`full_rank_least_squares` ``(B, r)`` from one Householder QR ``B = Q R`` when that QR
    alone proves ``B / m_scale`` of full column rank for τ, else None (then the unit-row matrix is
    factorised as well). The proof: ``σ_min(B / m_scale) ≥ σ_min(B) / max(m_scale)`` and
    ``σ_min(B) ≥ 1/‖R⁻¹‖_F``, asked to exceed ``2τ`` as :func:`independent_qr`; the point is then the
    one the two-factorisation route computes, by the same LAPACK calls on ``B``."""
    q = B.shape[1]
    factors = _proven_full_rank_qr(B, 2.0 * threshold * float(m_scale.max()))
    if factors is None:
        return None
    qr, tau, _ = factors
    qtr, _, info = lapack.dormqr("L", "T", qr, tau, r[:, None], max(1, len(r)))
    if info == 0:
        c, info = lapack.dtrtrs(qr[:q, :q], qtr[:q], lower=0)
    return c[:, 0] if info == 0 else None
