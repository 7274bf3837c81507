"""The QR sweep of the equality hierarchy (:mod:`..equality_hierarchy`), compiled: one pass over
the stacked levels with the bounds ``held`` fixed, each level's step by a clear-cut rank decision,
the held bounds' multipliers certified. Every matrix handed to LAPACK is a column-major copy, the
others are C-ordered; a function that cannot decide returns ``ok = False``."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..tolerances import CERTIFIED, FEASIBILITY, MULTIPLIER_TOLERANCE, NEGLIGIBLE
from .lapack import contiguous, fortran, geqp3, geqrf, level_residuals, orgqr, ormqr, upper_inverse

#: A component counts as in the way of a bound when it passes it by more than this (relative above 1):
#: the hierarchical QP's feasibility tolerance, far above the round-off of a point that lies on the
#: bound in exact arithmetic (whose side would otherwise depend on the CPU's last bits). A point
#: within it is put on the bound.
IN_THE_WAY = FEASIBILITY


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
    raw = B.copy()  # raw rows: the level's objective is ‖B z − ρ‖; a row the levels above fix
    for i in range(raw.shape[0]):  # (scaled norm below NEGLIGIBLE) is constant: its round-off must not
        if np.sqrt(np.sum(scaled[i] * scaled[i])) < NEGLIGIBLE:  # pull z along a row of the level
            raw[i] = 0.0  # whose norm is as small (1e-8 beside 1e6: z of 1e12)
    ok, z = _least_squares(raw @ kept, residual)
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
