"""The active-set method's equality-constrained step (:func:`.active_set.eqp`), compiled.

The same computation as the Python functions of :mod:`.active_set` it stands for, in the same
order, each factorisation the same LAPACK routine (:mod:`.lapack`; the SVD numba's, also
LAPACK's ``dgesdd``): :func:`eqp` (with :func:`_independent_qr`, :func:`_full_rank_step`,
:func:`_scaled_least_squares`, :func:`_full_rank_least_squares`). ``eqp`` runs a few times per
stage of the hierarchical QP, and its Python version's forty-odd numpy and LAPACK calls cost more
than their arithmetic on these small matrices. Imported on the first call (numba: not for a script
that never solves a stage), cached on disk.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .lapack import contiguous, fortran, geqrf, orgqr, ormqr, trtrs_upper, upper_inverse

#: :data:`..linalg.QR_MIN_SIZE` (the same value; asserted there).
QR_MIN_SIZE = 4


@njit(cache=True)
def _proven_full_rank_qr(A, bound):
    """``(ok, qr, tau, R⁻¹)``: :func:`..linalg._proven_full_rank_qr` (``qr`` column-major)."""
    p, k = A.shape
    empty = np.zeros((0, 0))
    if k > p or k < QR_MIN_SIZE:
        return False, empty.T, np.zeros(0), empty
    qr = fortran(A)
    tau = np.empty(k)
    if geqrf(qr, tau) != 0:
        return False, qr, tau, empty
    ok, R_inv = upper_inverse(qr[:k, :k])
    if not ok or not bound * math.sqrt(np.sum(R_inv * R_inv)) < 1.0:
        return False, qr, tau, empty
    return True, qr, tau, R_inv


@njit(cache=True)
def _independent_qr(A, threshold, full):
    """``(ok, Q, R⁻¹)``: :func:`..linalg.independent_qr` (``Q`` C-ordered)."""
    p, k = A.shape
    ok, qr, tau, R_inv = _proven_full_rank_qr(A, 2.0 * threshold)
    if not ok:
        return False, np.zeros((0, 0)), R_inv
    if full and k < p:
        padded = np.zeros((p, p)).T
        padded[:, :k] = qr
        qr = padded
    if orgqr(qr, k, tau) != 0:
        return False, np.zeros((0, 0)), R_inv
    return True, contiguous(qr), R_inv


@njit(cache=True)
def _solve_from_qr(qr, tau, r):
    """``(ok, c)``: ``argmin ‖B c − r‖`` from ``dgeqrf``'s ``(qr, tau)`` of ``B`` (m × k, full column
    rank): ``Qᵀ r`` (``dormqr``), then ``R c = (Qᵀ r)_{:k}`` (``dtrtrs``); not ok: LAPACK refused."""
    k = qr.shape[1]
    qtr = fortran(r.reshape(-1, 1))
    if ormqr(qr, tau, qtr, True) != 0:
        return False, np.zeros(k)
    c = fortran(contiguous(qtr[:k]))
    if trtrs_upper(fortran(qr[:k, :k]), c) != 0:
        return False, np.zeros(k)
    return True, contiguous(c[:, 0])


@njit(cache=True)
def _full_rank_least_squares(B, r):
    """``(ok, c)``: :func:`..linalg.full_rank_least_squares` (not ok: LAPACK refused)."""
    k = B.shape[1]
    qr = fortran(B)
    tau = np.empty(min(B.shape[0], k))
    if geqrf(qr, tau) != 0:
        return False, np.zeros(k)
    return _solve_from_qr(qr, tau, r)


@njit(cache=True)
def _scaled_least_squares(U, s, Vt, k, m_scale, r, uniform):
    """``(ok, u)``: :func:`..linalg.scaled_least_squares` (not ok: LAPACK refused, where the
    Python version goes on with numpy's QR)."""
    U_k, s_k = contiguous(U[:, :k]), s[:k]
    if uniform:
        c = (U_k.T @ r) / (m_scale[0] * s_k)
    elif k == m_scale.size:
        c = (U_k.T @ (r / m_scale)) / s_k
    else:
        ok, c = _full_rank_least_squares(m_scale.reshape(-1, 1) * (U_k * s_k), r)
        if not ok:
            return False, np.zeros(Vt.shape[1])
    return True, contiguous(Vt[:k].T) @ c


@njit(cache=True)
def _weighted_full_rank_step(B, m_scale, r, threshold):
    """``(ok, u)``: :func:`..linalg._weighted_full_rank_step`."""
    ok, qr, tau, _ = _proven_full_rank_qr(B, 2.0 * threshold * m_scale.max())
    if not ok:
        return False, np.zeros(B.shape[1])
    return _solve_from_qr(qr, tau, r)


@njit(cache=True)
def _full_rank_step(B, m_scale, r, threshold, uniform):
    """``(status, u)``: :func:`..linalg._full_rank_step`; status 0: ``u``, 1: None (not proven of
    full rank), 2: LAPACK refused the least squares (the Python version goes on with numpy's QR)."""
    m, q = B.shape
    if m >= q and not uniform:
        ok, u = _weighted_full_rank_step(B, m_scale, r, threshold)
        if ok:
            return 0, u
    unit = B / m_scale.reshape(-1, 1)
    if m >= q:
        ok, Q1, R_inv = _independent_qr(unit, threshold, False)
        if not ok:
            return 1, np.zeros(q)
        if uniform:
            return 0, R_inv @ (Q1.T @ r) / m_scale[0]
        ok, u = _full_rank_least_squares(B, r)
        return (0 if ok else 2), u
    ok, Q1, R_inv = _independent_qr(contiguous(unit.T), threshold, False)
    if not ok:
        return 1, np.zeros(q)
    return 0, Q1 @ (R_inv.T @ (r / m_scale))


@njit(cache=True)
def eqp(M, t, m_scale, E, e, threshold, identity, uniform, cut):
    """``(ok, z, λ, N, has_N)``: :func:`.active_set.eqp` with the objective's kind given and ``cut`` the
    working set's rank threshold (``has_N`` False: no basis, the whole space). Not ok where LAPACK
    refused a least squares that the Python version then solves with numpy (never seen: it needs an
    exactly singular triangle behind a proof of full rank): the caller runs that version."""
    p = M.shape[1]
    k = 0
    has_factors, Q, R_inv = False, np.zeros((0, 0)), np.zeros((0, 0))
    U_k, s_k, V_k = np.zeros((0, 0)), np.zeros(0), np.zeros((0, 0))
    z, N, has_N = np.zeros(p), np.zeros((p, 0)), False
    if E.shape[0]:
        has_factors, Q, R_inv = _independent_qr(contiguous(E.T), cut, True)
        if has_factors:
            k = E.shape[0]
            z = contiguous(Q[:, :k]) @ (R_inv.T @ e)
            N, has_N = contiguous(Q[:, k:]), True
        else:
            U, s, Vt = np.linalg.svd(E)
            k = int(np.count_nonzero(s > cut))
            U_k, s_k, V_k = contiguous(U[:, :k]), s[:k], contiguous(Vt[:k].T)
            z = V_k @ ((U_k.T @ e) / s_k)
            N, has_N = contiguous(Vt[k:].T), True
    if identity:  # ½‖z - t‖² (the minimum-norm stage): N has orthonormal columns, no decomposition
        r = t - z
        z = z + (N @ (N.T @ r) if has_N else r)
    elif M.shape[0]:
        B = M @ N if has_N else M.copy()
        if B.shape[1]:
            r = t - M @ z
            status = 1
            u = np.zeros(B.shape[1])
            if min(B.shape[0], B.shape[1]) >= QR_MIN_SIZE:
                status, u = _full_rank_step(B, m_scale, r, threshold, uniform)
            if status == 2:
                return False, z, np.zeros(0), N, has_N
            if status == 1:
                U2, s2, V2t = np.linalg.svd(B / m_scale.reshape(-1, 1), full_matrices=False)
                k2 = int(np.count_nonzero(s2 > threshold))
                if k2:
                    ok, u = _scaled_least_squares(U2, s2, V2t, k2, m_scale, r, uniform)
                    if not ok:
                        return False, z, np.zeros(0), N, has_N
                    status = 0
            if status == 0:
                z = z + (N @ u if has_N else u)
    lam = np.zeros(0)
    if E.shape[0]:
        if M.shape[0]:
            gradient = z - t if identity else M.T @ (M @ z - t)
        else:
            gradient = np.zeros(p)
        if has_factors:
            lam = -(R_inv @ (contiguous(Q[:, :k]).T @ gradient))
        else:
            lam = -(U_k @ ((V_k.T @ gradient) / s_k))
    return True, z, lam, N, has_N
