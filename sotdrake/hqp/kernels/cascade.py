"""The basic SoT cascade in two compiled calls: the full-rank prefix (:func:`prefix`, for
:func:`.cascade._full_rank_prefix`) and the SVD levels below it (:func:`svd_levels`).

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
    """``(solved, v, reflectors, scales, L_inverse_T, free)``: how many levels (of ``sizes`` rows,
    those with rows) are certified, ``v`` (nv × c) solving them for each column of ``references``
    (M × c: the cascade is linear in its references, one factorisation serves them all), the first ``K``
    Householder reflectors and their scales (``Q_K``), ``(L_K⁻¹)ᵀ`` (K × K) and, when some level is
    not certified or ``more`` levels follow those stacked, ``free``: the last ``nv − K`` columns of
    the full ``Q`` (an orthonormal basis of what the solved levels leave free; else nv × 0). ``solved`` 0:
    nothing certified (or LAPACK failed), the other values empty."""
    M, nv = B.shape
    c = references.shape[1]
    empty = np.zeros((nv, 0))
    nothing = (0, np.zeros((nv, c)), np.zeros((0, nv)).T, np.zeros(0), np.zeros((0, 0)), empty)
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
    return solved, np.ascontiguousarray(y), reflectors, scales, L_inverse_T, free


@njit(cache=True)
def svd_levels(J, sizes, references, mask, Z, v, first, threshold, dampings):
    """The SVD cascade (:func:`.cascade.svd_cascade`) from level ``first`` on: ``(v, ranks)``.
    ``J`` and ``references``: every level's rows stacked (levels of ``sizes`` rows; ``references``
    M × c, a velocity per column, ``v`` nv × c); ``mask``: the
    control selection's ``P_0`` as nv ones and zeros; ``Z`` (nv × d) and ``v``: what the levels
    above ``first`` leave free and their velocity (the identity and 0 from the top); ``dampings``:
    one δ per level. Per level, the SVD ``(J P_0 Z)ᵀ = W Σ Uᵀ`` (LAPACK's ``gesdd``, as
    ``np.linalg.svd``), the singular values above ``threshold`` kept (``σ/(σ² + δ)`` inverted) and
    ``Z ← Z W_{>rank}``. A non-finite level raises ``np.linalg.LinAlgError``."""
    levels = sizes.size
    ranks = np.zeros(levels, dtype=np.int64)
    starts = np.zeros(levels + 1, dtype=np.int64)
    for i in range(levels):
        starts[i + 1] = starts[i] + sizes[i]
    v = v.copy()
    for i in range(first, levels):
        rows = J[starts[i]:starts[i + 1]]
        if rows.shape[0] == 0 or Z.shape[1] == 0:  # nothing asked, or nothing left free
            continue
        A = (rows * mask) @ Z  # J P_0 P_{i-1} in what is left free (m × d)
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
            residual = np.ascontiguousarray(references[starts[i]:starts[i + 1]]) - rows @ v
            v = v + V @ (inverse.reshape(-1, 1) * (np.ascontiguousarray(Ut[:rank]) @ residual))
        if i < levels - 1:
            Z = Z @ np.ascontiguousarray(W[:, rank:])
    return v, ranks
