"""The active-set method's iterations (:func:`.active_set.python_solve`), compiled.

The same method as the Python function it stands for, step by step and in the same order: the
guess checked (:func:`_check`), the working set made independent (:func:`_independent_rows`,
LAPACK's ``dgeqp3`` as :func:`..linalg.independent_rows`), the iterations (ratio test, Bland's
rule after a repeated working set, the multipliers' signs), and the final minimum-norm point
(:func:`_finish`), each step the compiled :func:`.eqp.eqp`. A stage of the hierarchical QP runs
these iterations once or twice, and the Python version's per-iteration numpy calls cost more than
their arithmetic on these small matrices. Imported on the first call (numba: not for a script that
never solves a stage), cached on disk.

:func:`solve` returns a status: :data:`SOLVED`, :data:`NO_CONVERGENCE` (the iteration cap, where the
Python version raises) or :data:`GAVE_WAY` (LAPACK refused a factorisation where the Python version
goes on with numpy or raises its own error): the caller then runs the Python version.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..tolerances import MULTIPLIER_FLOOR, MULTIPLIER_TOLERANCE, NO_STEP, RATIO_TIE
from .eqp import eqp
from .lapack import fortran, geqp3

SOLVED, NO_CONVERGENCE, GAVE_WAY = 0, 1, 2


@njit(cache=True)
def _rows(A, index):
    """``A[index]`` (a C-ordered copy)."""
    out = np.empty((index.size, A.shape[1]))
    for i in range(index.size):
        out[i] = A[index[i]]
    return out


@njit(cache=True)
def _held(side, lower, upper):
    """The held rows' indices and the sides they are held at (``upper`` for +1, ``lower`` for -1)."""
    held = np.nonzero(side)[0]
    e = np.empty(held.size)
    for i in range(held.size):
        e[i] = upper[held[i]] if side[held[i]] > 0 else lower[held[i]]
    return held, e


@njit(cache=True)
def _abs_max(a):
    """``max |a|``, 0 for an empty ``a``."""
    out = 0.0
    for value in a:
        out = max(out, abs(value))
    return out


@njit(cache=True, error_model="numpy")
def feasible(G, lower, upper, z, feasibility):
    """:func:`.active_set.feasible`."""
    value = G @ z
    inside = True
    for i in range(value.size):
        if not (value[i] >= lower[i] and value[i] <= upper[i]):
            inside = False
            break
    if inside:
        return True
    for i in range(value.size):
        if value[i] < lower[i] - feasibility * max(1.0, abs(lower[i])):
            return False
        if value[i] > upper[i] + feasibility * max(1.0, abs(upper[i])):
            return False
    return True


@njit(cache=True)
def _independent_rows(E, threshold):
    """``(ok, indices)``: :func:`..linalg.independent_rows` (not ok: LAPACK refused)."""
    h = E.shape[0]
    if h == 0:
        return True, np.zeros(0, np.int64)
    a = fortran(E.T)
    pivots = np.zeros(h, np.int32)
    tau = np.empty(min(a.shape[0], h))
    if geqp3(a, pivots, tau) != 0:
        return False, np.zeros(0, np.int64)
    count = 0
    for i in range(tau.size):
        if abs(a[i, i]) > threshold:
            count += 1
    return True, np.sort(pivots[:count].astype(np.int64) - 1)


@njit(cache=True, error_model="numpy")
def _residual_scale(M, t, z, m_max):
    """:func:`.active_set.multiplier_scale`."""
    if M.shape[0] == 0:
        return 1.0
    residual = M @ z - t
    terms = m_max * math.sqrt(z @ z) + math.sqrt(t @ t)
    return m_max * max(math.sqrt(residual @ residual), MULTIPLIER_FLOOR * terms)


@njit(cache=True, error_model="numpy")
def _row_round_off(M, t, m_scale, E, z, cut):
    """:func:`..multipliers.row_round_off`."""
    residual = M @ z - t
    size = math.sqrt(z @ z)
    delta = np.empty(residual.size)
    for j in range(residual.size):
        delta[j] = max(abs(residual[j]), MULTIPLIER_FLOOR * (m_scale[j] * size + abs(t[j])))
    U, s, Vt = np.linalg.svd(E, full_matrices=False)
    k = 0
    for value in s:
        if value > cut:
            k += 1
    W = np.ascontiguousarray(U[:, :k] / s[:k]) @ np.ascontiguousarray(Vt[:k])
    return np.abs(W) @ (np.ascontiguousarray(np.abs(M).T) @ delta)


@njit(cache=True, error_model="numpy")
def _wrong_signs(M, t, m_scale, E, z, wrong, m_max, cut):
    """``(any, excess)``: :func:`..multipliers.wrong_signs` (``any`` False: its None)."""
    worst = wrong.max() if wrong.size else 0.0
    if not worst > 0.0:
        return False, wrong
    tolerance = MULTIPLIER_TOLERANCE * _residual_scale(M, t, z, m_max)
    if worst > tolerance:
        return True, wrong - tolerance
    if M.shape[0] == 0:
        return False, wrong
    excess = wrong - np.minimum(tolerance, MULTIPLIER_TOLERANCE * _row_round_off(M, t, m_scale, E, z, cut))
    return excess.max() > 0.0, excess


@njit(cache=True, error_model="numpy")
def _check(M, t, m_scale, G, lower, upper, side, threshold, feasibility, identity, uniform, equality, working):
    """``(status, z)``: :func:`.active_set._check`, status 0: ``z`` satisfies the KKT conditions,
    1: it does not (the Python version's None), :data:`GAVE_WAY`."""
    held, e = _held(side, lower, upper)
    ok, z, lam, _, _ = eqp(M, t, m_scale, _rows(G, held), e, threshold, identity, uniform, working)
    if not ok:
        return GAVE_WAY, z
    if not feasible(G, lower, upper, z, feasibility):
        return 1, z
    if held.size:
        wrong = np.empty(held.size)
        for i in range(held.size):
            wrong[i] = 0.0 if equality[held[i]] else -side[held[i]] * lam[i]
        if _wrong_signs(M, t, m_scale, _rows(G, held), z, wrong, m_scale.max() if m_scale.size else 0.0, working)[0]:
            return 1, z  # (False on NaN, as the Python version's)
    return 0, z


@njit(cache=True, error_model="numpy")
def _finish(M, t, m_scale, G, lower, upper, side, threshold, feasibility, z, iteration, identity, uniform, working):
    """:func:`.active_set._finish`, as :func:`solve`'s return."""
    held, e = _held(side, lower, upper)
    ok, final, _, _, _ = eqp(M, t, m_scale, _rows(G, held), e, threshold, identity, uniform, working)
    if not ok:
        return GAVE_WAY, z, side, iteration, False, False
    if not feasible(G, lower, upper, final, feasibility):
        return SOLVED, z, side, iteration, False, False
    return SOLVED, final, side, iteration, False, True


@njit(cache=True)
def _seen_before(seen, count, side):
    """Whether ``side`` is one of the first ``count`` rows of ``seen``."""
    for k in range(count):
        same = True
        for i in range(side.size):
            if seen[k, i] != side[i]:
                same = False
                break
        if same:
            return True
    return False


@njit(cache=True)
def _remember(seen, count, side):
    """``(seen, count, was_seen)`` with ``side`` added (``seen`` grown when full)."""
    was_seen = _seen_before(seen, count, side)
    if count == seen.shape[0]:
        grown = np.empty((2 * count + 4, side.size), np.int64)
        grown[:count] = seen[:count]
        seen = grown
    seen[count] = side
    return seen, count + 1, was_seen


@njit(cache=True, error_model="numpy")
def solve(M, t, m_scale, G, lower, upper, z, guess, has_guess, threshold, feasibility, max_iterations, identity,
          uniform, guess_valid, working):
    """``(status, z, side, iterations, guess_accepted, verified)``: :func:`.active_set.python_solve`
    (``max_iterations``: its default where it is negative)."""
    m, p = G.shape
    equality = lower == upper
    if has_guess and guess.size == m:
        side = np.empty(m, np.int64)
        for i in range(m):
            side[i] = 1 if equality[i] else guess[i]
            if not guess_valid and ((side[i] < 0 and lower[i] == -np.inf) or (side[i] > 0 and upper[i] == np.inf)):
                side[i] = 0
        status, candidate = _check(M, t, m_scale, G, lower, upper, side, threshold, feasibility, identity, uniform,
                                   equality, working)
        if status == GAVE_WAY:
            return GAVE_WAY, z, side, 0, False, False
        if status == 0:
            return SOLVED, candidate, side, 0, True, True
        value = G @ z
        near = feasibility * 10
        for i in range(m):
            if equality[i]:
                side[i] = 1
            elif side[i] < 0 and value[i] <= lower[i] + near:
                side[i] = -1
            elif side[i] > 0 and value[i] >= upper[i] - near:
                side[i] = 1
            else:
                side[i] = 0
        held = np.nonzero(side)[0]
        ok, independent = _independent_rows(_rows(G, held), working)
        if not ok:
            return GAVE_WAY, z, side, 0, False, False
        kept = np.zeros(held.size, np.bool_)
        kept[independent] = True
        for j in range(held.size):
            if not kept[j]:
                side[held[j]] = 0  # a working set is linearly independent
    else:
        side = np.zeros(m, np.int64)
        for i in range(m):
            if equality[i]:
                side[i] = 1
    if max_iterations < 0:
        max_iterations = 10 * (m + p) + 50
    seen, count = np.empty((8, m), np.int64), 0
    m_max = m_scale.max() if m_scale.size else 0.0
    bland = False
    last_dropped, dropped_side = -1, 0
    up, down, ratio = np.empty(m), np.empty(m), np.empty(m)
    for iteration in range(1, max_iterations + 1):
        held, e = _held(side, lower, upper)
        E = _rows(G, held)
        # The minimum-norm step from z: along it a dropped row is left on its feasible side.
        ok, step, lam, N, has_N = eqp(M, t - M @ z, m_scale, E, e - E @ z, threshold, identity, uniform, working)
        if not ok:
            return GAVE_WAY, z, side, iteration, False, False
        value, rate = G @ z, G @ step
        GN = G @ N if has_N else np.zeros((m, 0))
        for i in range(m):  # only rows independent of the working set can block
            movable = side[i] == 0
            if movable and has_N:
                square = 0.0
                for j in range(GN.shape[1]):
                    square += GN[i, j] * GN[i, j]
                movable = math.sqrt(square) > working
            up[i] = (upper[i] - value[i]) / rate[i] if movable and rate[i] > 0.0 else np.inf
            down[i] = (lower[i] - value[i]) / rate[i] if movable and rate[i] < 0.0 else np.inf
            ratio[i] = max(min(up[i], down[i]), 0.0)
        alpha = ratio.min() if m else np.inf
        if alpha < 1.0:
            blocking = 0
            if bland:
                while not ratio[blocking] <= alpha * (1 + RATIO_TIE):
                    blocking += 1
            else:
                blocking = int(np.argmin(ratio))
            if blocking == last_dropped and alpha * _abs_max(step) <= NO_STEP * max(1.0, _abs_max(z)):
                # The row just dropped blocks at once: the previous point (where it was held) is optimal.
                side[blocking] = dropped_side
                return _finish(M, t, m_scale, G, lower, upper, side, threshold, feasibility, z, iteration, identity,
                               uniform, working)
            z = z + alpha * step
            side[blocking] = 1 if up[blocking] <= down[blocking] else -1
            last_dropped = -1
            if alpha == 0.0:
                seen, count, was_seen = _remember(seen, count, side)
                bland = bland or was_seen
            continue
        at_origin = np.count_nonzero(z) == 0  # then the step is the absolute EQP point itself
        z = z + step
        # Multipliers: λ ≥ 0 at an upper side, ≤ 0 at a lower side (equality rows: free), up to a
        # round-off tolerance relative to the gradient's scale.
        wrong = np.empty(held.size)
        for i in range(held.size):
            wrong[i] = 0.0 if equality[held[i]] else -side[held[i]] * lam[i]
        any_wrong, excess = _wrong_signs(M, t, m_scale, E, z, wrong, m_max, working)  # (to round-off: ..multipliers)
        if any_wrong:
            first = 0
            if bland:
                while not excess[first] > 0.0:
                    first += 1
            else:
                first = int(np.argmax(excess))
            leaving = held[first]
            last_dropped, dropped_side = leaving, side[leaving]
            side[leaving] = 0
            seen, count, was_seen = _remember(seen, count, side)
            bland = bland or was_seen
            continue
        if at_origin:  # _finish would recompute this very point
            return SOLVED, z, side, iteration, False, False
        return _finish(M, t, m_scale, G, lower, upper, side, threshold, feasibility, z, iteration, identity, uniform,
                       working)
    return NO_CONVERGENCE, z, side, max_iterations, False, False
