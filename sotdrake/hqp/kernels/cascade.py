"""The basic SoT cascade in one compiled call (:func:`cascade`): the full-rank prefix (:func:`prefix`)
and the SVD levels below it (:func:`svd_levels`).

The stacked levels ``B`` (M × nv, ``M ≤ nv``, rows in priority order, the control selection
applied) are factorised once, ``Bᵀ = Q R`` (Householder, no pivoting: ``B = L Qᵀ`` with ``L = Rᵀ``),
and the leading levels whose diagonal block of ``R⁻¹`` has ``‖R_kk⁻¹‖_F · τ < 1`` (upper triangle;
then ``σ_min(L_kk) > τ``, the SVD threshold) are *certified*: the first ``K`` rows are solved
exactly by ``v = Q_K L_K⁻¹ r_K``. A level that is not certified (a NaN included) stops the prefix.
At these sizes a numpy call costs more than its arithmetic, and the prefix is about thirty of them:
here it is LAPACK's ``dgeqrf``, ``dtrtri``, ``dormqr`` and ``dorgqr`` (:mod:`.lapack`) without a
Python call between them.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .lapack import certified_blocks, fortran, geqrf, orgqr, ormqr, upper_inverse


@njit(cache=True)
def prefix(B, sizes, references, threshold, more):
    """``(solved, v, free)``: how many levels (of ``sizes`` rows, those with rows) are certified,
    ``v`` (nv × c) solving them for each column of ``references`` (M × c: the cascade is linear in
    its references, one factorisation serves them all) and, when some level is not certified or
    ``more`` levels follow those stacked, ``free``: the last ``nv − K`` columns of the full ``Q`` (an
    orthonormal basis of what the solved levels leave free; else nv × 0). ``solved`` 0: nothing
    certified (or LAPACK failed), the other values empty."""
    M, nv = B.shape
    c = references.shape[1]
    empty = np.zeros((nv, 0))
    nothing = (0, np.zeros((nv, c)), empty)
    qr = fortran(B.T)  # nv × M, column-major
    tau = np.empty(M)
    if geqrf(qr, tau) != 0:
        return nothing
    ok, R_inverse = upper_inverse(qr[:M])
    if not ok:
        return nothing
    solved = certified_blocks(R_inverse, sizes, threshold)
    K = 0
    for k in range(solved):
        K += sizes[k]
    if solved == 0:
        return nothing
    L_inverse_T = np.ascontiguousarray(R_inverse[:K, :K].T)
    y = np.zeros((c, nv)).T  # nv × c, column-major
    y[:K, :] = L_inverse_T @ np.ascontiguousarray(references[:K])
    reflectors = fortran(qr[:, :K])  # (the later columns may hold a NaN)
    scales = tau[:K].copy()
    if ormqr(reflectors, scales, y, False) != 0:
        return nothing
    free = empty
    if more or solved < sizes.size:
        padded = np.zeros((nv, nv)).T
        padded[:, :K] = reflectors
        if orgqr(padded, K, scales) != 0:
            return nothing
        free = np.ascontiguousarray(padded[:, K:])
    return solved, np.ascontiguousarray(y), free


@njit(cache=True)
def _without_masked(Z, mask):
    """``Z`` (nv × d, orthonormal columns) without the masked coordinates' directions: ``Z N``, ``N``
    an orthonormal basis of the null space of ``Z``'s masked rows, when those rows are orthonormal
    (each masked unit vector lies in ``range(Z)``, as when no level above has a masked column);
    else ``Z`` as it is. The directions removed are in every level's null space (``J P_0`` is zero
    on them): the levels' non-zero singular values, hence the cascade, do not change."""
    g = 0
    for value in mask:
        if value == 0.0:
            g += 1
    d = Z.shape[1]
    if g == 0 or g >= d:
        return Z
    rows = np.zeros((g, d))  # the masked rows of Z
    k = 0
    for i in range(mask.size):
        if mask[i] == 0.0:
            rows[k] = Z[i]
            k += 1
    for a in range(g):  # orthonormal to round-off, or left as it is
        for b in range(g):
            if abs(rows[a] @ rows[b] - (1.0 if a == b else 0.0)) > 1e-9:
                return Z
    reflectors = fortran(rows.T)  # d × g: its QR's full Q = [·, N], N the last d − g columns
    tau = np.empty(g)
    if geqrf(reflectors, tau) != 0:
        return Z
    rotated = fortran(Z.T)  # Qᵀ Zᵀ by the g reflectors: its last d − g rows are (Z N)ᵀ
    if ormqr(reflectors, tau, rotated, True) != 0:
        return Z
    return np.ascontiguousarray(rotated[g:].T)


@njit(cache=True)
def _least_squares(A, residual, threshold):
    """``(ok, z)``: the least-squares solution of ``A z = residual`` (m × d, m ≥ d; one column of
    ``z`` per column of ``residual``) by one QR, ``A = Q R``, when ``σ_min(A) ≥ 1/‖R⁻¹‖_F >
    threshold`` certifies that the SVD would keep every direction (then it is the truncated SVD's
    solution); not ok otherwise (the SVD decides)."""
    d = A.shape[1]
    qr = fortran(A)
    tau = np.empty(d)
    if geqrf(qr, tau) != 0:
        return False, residual
    ok, R_inverse = upper_inverse(qr[:d])
    if not ok or not np.sum(R_inverse * R_inverse) * threshold * threshold < 1.0:  # (False on NaN too)
        return False, residual
    projected = fortran(residual)
    if ormqr(qr, tau, projected, True) != 0:
        return False, residual
    return True, R_inverse @ np.ascontiguousarray(projected[:d])


@njit(cache=True)
def svd_levels(J, sizes, references, mask, Z, v, first, threshold, dampings):
    """The SVD cascade (:func:`.cascade.svd_cascade`) from level ``first`` on: ``(v, ranks)``.
    ``J`` and ``references``: every level's rows stacked (levels of ``sizes`` rows; ``references``
    M × c, a velocity per column, ``v`` nv × c); ``mask``: the
    control selection's ``P_0`` as nv ones and zeros; ``Z`` (nv × d) and ``v``: what the levels
    above ``first`` leave free and their velocity (the identity and 0 from the top); ``dampings``:
    one δ per level. Per level, the SVD ``(J P_0 Z)ᵀ = W Σ Uᵀ`` (LAPACK's ``gesdd``, as
    ``np.linalg.svd``), the singular values above ``threshold`` kept (``σ/(σ² + δ)`` inverted) and
    ``Z ← Z W_{>rank}``. An undamped level with at least as many rows as directions left (a posture
    task at the bottom) is first tried by one QR (:func:`_least_squares`), several times cheaper at
    these sizes: certified of full column rank, its solution is the SVD's and it leaves nothing
    free. The masked directions are taken out of ``Z`` first (:func:`_without_masked`), so that they
    do not make such a level rank deficient. A non-finite level raises ``np.linalg.LinAlgError``."""
    levels = sizes.size
    ranks = np.zeros(levels, dtype=np.int64)
    starts = np.zeros(levels + 1, dtype=np.int64)
    for i in range(levels):
        starts[i + 1] = starts[i] + sizes[i]
    v = v.copy()
    Z = _without_masked(Z, mask)
    for i in range(first, levels):
        rows = J[starts[i]:starts[i + 1]]
        if rows.shape[0] == 0 or Z.shape[1] == 0:  # nothing asked, or nothing left free
            continue
        A = (rows * mask) @ Z  # J P_0 P_{i-1} in what is left free (m × d)
        residual = np.ascontiguousarray(references[starts[i]:starts[i + 1]]) - rows @ v
        if dampings[i] == 0.0 and A.shape[0] >= A.shape[1]:
            ok, z = _least_squares(A, residual, threshold)
            if ok:
                ranks[i] = A.shape[1]
                v = v + Z @ z
                Z = np.zeros((Z.shape[0], 0))
                continue
        W, sigma, Ut = np.linalg.svd(np.ascontiguousarray(A.T), full_matrices=i < levels - 1)
        rank = 0
        for s in sigma:
            if s > threshold:
                rank += 1
        ranks[i] = rank
        if rank:
            s = sigma[:rank]
            inverse = 1.0 / s if dampings[i] == 0.0 else s / (s * s + dampings[i])
            V = Z @ np.ascontiguousarray(W[:, :rank])
            v = v + V @ (inverse.reshape(-1, 1) * (np.ascontiguousarray(Ut[:rank]) @ residual))
        if i < levels - 1:
            Z = Z @ np.ascontiguousarray(W[:, rank:])
    return v, ranks


@njit(cache=True)
def cascade(J, sizes, references, mask, threshold, dampings):
    """The whole cascade (:func:`.cascade.cascade_factorization`): ``(v, ranks, solved)``. ``J``
    (M × nv) and ``references`` (M × c): every level's rows stacked, levels of ``sizes`` rows;
    ``mask``: the control selection's ``P_0`` as nv ones and zeros; ``dampings``: one δ per level.
    Without damping, the leading levels whose rows fit in nv go to :func:`prefix` (``J P_0``, the
    mask applied by an elementwise product, as the SVD levels apply it); the ``solved`` ones it
    certifies keep their rows as ranks, and :func:`svd_levels` goes on from what they leave free
    (0: the SVD levels from the top). The masked velocities are set to zero. A non-finite level below
    the prefix raises ``np.linalg.LinAlgError``."""
    nv, levels, c = J.shape[1], sizes.size, references.shape[1]
    undamped = True
    for damping in dampings:
        if damping != 0.0:
            undamped = False
    first, v, Z = 0, np.zeros((nv, c)), np.eye(nv)
    if undamped:
        taken, M = 0, 0
        while taken < levels and M + sizes[taken] <= nv:
            M += sizes[taken]
            taken += 1
        if M:
            solved, y, free = prefix(J[:M] * mask, sizes[:taken], np.ascontiguousarray(references[:M]), threshold,
                                     taken < levels)
            if solved:
                first, v, Z = solved, y, free
    if first == levels:
        ranks = sizes.copy()
    else:
        v, ranks = svd_levels(J, sizes, references, mask, Z, v, first, threshold, dampings)
        ranks[:first] = sizes[:first]
    for i in range(nv):  # zero in exact arithmetic; the QR and SVD leave round-off
        if mask[i] == 0.0:
            v[i] = 0.0
    return v, ranks, first
