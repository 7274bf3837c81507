"""An exact primal active-set method for one least-squares level with two-sided linear constraints.

Problem (all arrays numpy, ``z`` of size p)::

    min_z  ½‖M z - t‖²    s.t.  lower ≤ G z ≤ upper

``G``'s rows have unit norm (the caller scales them, and their bounds, by their norms), so every
tolerance below is absolute on unit rows. ``M``'s rows keep their weights (they are the level's
objective); ``m_scale`` gives each row's reference norm, and every rank decision on ``M`` is taken
on ``M / m_scale`` (rows at unit reference norm): a row that a projection has shrunk to round-off
(a task already fixed by the levels above) is then seen as zero instead of being inverted.

**The rank threshold.** One absolute number τ (``threshold``, default :data:`RANK_THRESHOLD`) makes
every rank decision: a singular value of the (unit-row) working-set matrix or of the (unit-row)
reduced objective ``M N`` at most τ counts as zero. No library default cutoff is used anywhere.
(Only the hierarchical QP's retry at a degenerate vertex, :data:`~.hqp.DEGENERATE_RETRY`, takes the
working set's decisions at a fixed fraction of τ: ``working_threshold``.)

**The equality-constrained step (EQP).** For a working set ``W`` (rows held at one side
``s_i ∈ {-1: lower, +1: upper}``) the EQP point is the *minimum-norm* minimiser

    z_W = argmin { ‖z‖ : z minimises ½‖M z - t‖² subject to G_W z = g_W },

computed from the SVD of ``G_W`` (particular solution plus null-space basis ``N``) and the SVD of
``(M N)/m_scale`` cut at τ, then a weighted least squares on the kept right singular vectors. It is
a function of ``W`` alone, so the returned point is a function of the final working set only (a
warm start changes the path, never the answer beyond round-off).

**Factorisations.** LAPACK is called directly (``dgesdd``, ``dgeqrf``, ``dorgqr``, ``dgeqp3``,
``dtrtri``): numpy's wrappers cost more than the factorisations of these small matrices. A matrix
with at least :data:`QR_MIN_SIZE` rows and columns that *provably* has every singular value above τ
(``σ_min ≥ 1/‖R⁻¹‖_F > 2τ`` from its Householder QR) is handled by that QR instead of an SVD: no
singular value would be cut, so both give the same point in exact arithmetic, and the QR costs a
fraction of the SVD there. Any other matrix gets the SVD, which makes the rank decision.
The iterations (:func:`python_solve`) and their EQP step (:func:`python_eqp`) run compiled with numba
(:mod:`.kernels.active_set` and :mod:`.kernels.eqp`, imported on the first call and cached on disk): the same
computation and LAPACK routines. The Python versions stay as the reference (tested against them)
and run where the compiled ones give way.

**Iterations.** From a feasible ``z`` (the previous level's point): step towards ``z_W``; the ratio
test stops at the first blocking row (smallest index among ties, Bland's rule), which joins ``W``.
After a full step the multipliers ``λ`` of ``∇f + G_Wᵀ λ = 0`` are checked: a row at its upper side
needs ``λ ≥ 0``, at its lower side ``λ ≤ 0`` (to round-off: :mod:`.multipliers`); the most wrong one
leaves ``W``. When every sign is right the point satisfies the KKT conditions of the convex problem:
it is optimal.

A *guess* of the working set (the previous tick's, or one read off another solver's answer) is tried
first: if its EQP point is feasible and its multipliers have the right signs it is the optimum and no
iteration is needed; otherwise the iterations start from the feasible point, keeping the guessed
rows that are active there.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np

from ..compiled import compiled_input, kernels
from .linalg import (
    QR_MIN_SIZE,
    ActiveSetFailure,
    _full_rank_step,
    all_true,
    any_true,
    independent_qr,
    independent_rows,
    scaled_least_squares,
    svd,
)
from .multipliers import wrong_signs
from .tolerances import NO_STEP, RANK_THRESHOLD, RATIO_TIE, VERIFIED


@dataclass
class ActiveSetResult:
    z: np.ndarray
    side: np.ndarray  # per row of G: -1 held at lower, +1 held at upper, 0 free (the final working set)
    iterations: int
    guess_accepted: bool
    verified: bool = False  # z was checked to satisfy every row to ``feasibility``


def objective_kind(M: np.ndarray, m_scale: np.ndarray) -> tuple[bool, bool]:
    """``(identity, uniform)`` of an objective ``½‖M z - t‖²``: whether ``M`` is the identity with unit
    reference norms (a projection), and whether every reference norm is the same."""
    p = M.shape[1]
    uniform = len(m_scale) > 0 and all_true(m_scale == m_scale[0])
    identity = (uniform and M.shape[0] == p and float(m_scale[0]) == 1.0 and np.count_nonzero(M) == p
                and all_true(M.diagonal() == 1.0))
    return identity, uniform


def eqp(
    M: np.ndarray,
    t: np.ndarray,
    m_scale: np.ndarray,
    E: np.ndarray,
    e: np.ndarray,
    threshold: float,
    kind: tuple[bool, bool] | None = None,
    working_threshold: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """:func:`python_eqp`, compiled (:mod:`.kernels.eqp`, imported on the first call): the same
    computation and LAPACK routines; the Python version runs where the compiled one gives way."""
    identity, uniform = objective_kind(M, m_scale) if kind is None else kind
    cut = threshold if working_threshold is None else working_threshold
    compiled, given = _jit_eqp(), compiled_input
    ok, z, lam, N, has_N = compiled.eqp(given(M), given(t), given(m_scale), given(E), given(e), float(threshold),
                                        bool(identity), bool(uniform), float(cut))
    if not ok:
        return python_eqp(M, t, m_scale, E, e, threshold, kind, working_threshold)
    return z, lam, (N if has_N else None)


_load_eqp = kernels(".kernels.eqp", __package__, "eqp", "the hierarchical QP's equality-constrained step",
                    "about twenty seconds")


@cache
def _jit_eqp() -> Any:
    """:mod:`.kernels.eqp`, loaded on the first call (its size switch checked against this module's)."""
    compiled = _load_eqp()
    assert compiled.QR_MIN_SIZE == QR_MIN_SIZE
    return compiled


def python_eqp(
    M: np.ndarray,
    t: np.ndarray,
    m_scale: np.ndarray,
    E: np.ndarray,
    e: np.ndarray,
    threshold: float,
    kind: tuple[bool, bool] | None = None,
    working_threshold: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The minimum-norm minimiser of ``½‖M z - t‖²`` s.t. ``E z = e`` (``E`` with unit rows), the
    multipliers ``λ`` of ``Mᵀ(M z - t) + Eᵀ λ = 0`` (minimum norm if ``E`` is rank deficient), and
    an orthonormal basis ``N`` of ``E``'s null space (None: the whole space). ``kind``: the
    objective's :func:`objective_kind` (computed if None). ``working_threshold``: the rank
    threshold of ``E`` alone (default ``threshold``; see :func:`solve_least_squares_qp`).

    Each factorisation is a QR when the matrix provably has full rank for τ (:func:`independent_qr`)
    and an SVD cut at τ otherwise; both give the same point in exact arithmetic."""
    p = M.shape[1]
    identity, uniform = objective_kind(M, m_scale) if kind is None else kind
    cut = threshold if working_threshold is None else working_threshold
    if len(E):
        factors = independent_qr(E.T, cut, full=True)
        if factors is not None:
            Q, R_inv = factors
            k = len(E)
            z = Q[:, :k] @ (R_inv.T @ e)
            N = Q[:, k:]
        else:
            U, s, Vt = svd(E)
            k = int(np.count_nonzero(s > cut))
            U_k, s_k, V_k = U[:, :k], s[:k], Vt[:k].T
            z = V_k @ ((U_k.T @ e) / s_k)
            N = Vt[k:].T
    else:
        z, N = np.zeros(p), None
    if identity:  # ½‖z - t‖² (the minimum-norm stage): N has orthonormal columns, no decomposition
        r = t - z
        z = z + (r if N is None else N @ (N.T @ r))
    elif len(M):
        B = M if N is None else M @ N
        if B.shape[1]:
            r = t - M @ z
            u = _full_rank_step(B, m_scale, r, threshold, uniform) if min(B.shape) >= QR_MIN_SIZE else None
            if u is None:
                U2, s2, V2t = svd(B / m_scale[:, None], full_matrices=False)
                k2 = int(np.count_nonzero(s2 > threshold))
                u = scaled_least_squares(U2, s2, V2t, k2, m_scale, r, uniform) if k2 else None
            if u is not None:
                z = z + (u if N is None else N @ u)
    if len(E):
        gradient = (z - t if identity else M.T @ (M @ z - t)) if len(M) else np.zeros(p)
        if factors is not None:
            lam = -(R_inv @ (Q[:, :k].T @ gradient))
        else:
            lam = -(U_k @ ((V_k.T @ gradient) / s_k))
    else:
        lam = np.zeros(0)
    return z, lam, N


def solve_least_squares_qp(
    M: np.ndarray,
    t: np.ndarray,
    m_scale: np.ndarray,
    G: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    z: np.ndarray,
    guess: np.ndarray | None = None,
    threshold: float = RANK_THRESHOLD,
    feasibility: float = VERIFIED,
    max_iterations: int | None = None,
    errstate: bool = True,
    kind: tuple[bool, bool] | None = None,
    guess_valid: bool = False,
    working_threshold: float | None = None,
) -> ActiveSetResult:
    """Solve the problem of the module docstring from the feasible point ``z`` (``G`` unit rows).

    ``guess``: a side per row of ``G`` (-1, 0, +1), tried first. Raises :class:`ActiveSetFailure`
    if the iterations do not converge. ``errstate=False``: the caller has already silenced numpy's
    warnings on ±∞ sides (``np.errstate(divide="ignore", invalid="ignore")``). ``kind``: the
    objective's :func:`objective_kind`, if the caller knows it. ``z`` is not written to.
    ``guess_valid``: no row of ``guess`` is held at an infinite side (as in :func:`.guesses.dual_guess`'s).

    ``working_threshold`` (default ``threshold``): the rank decisions on the working set alone (a
    row independent of the held ones can block, and the held rows' factorisation), for the retry of
    :meth:`~.hqp.HierarchicalQP` at a degenerate vertex. With τ, rows that the held ones imply only
    to within τ are not held and may move off their bound by up to about τ times the step."""
    if kind is None:
        kind = objective_kind(M, m_scale)
    args = (M, t, m_scale, G, lower, upper, z, guess, threshold, feasibility, max_iterations, kind, guess_valid,
            threshold if working_threshold is None else working_threshold)
    if not errstate:
        return _solve(*args)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # ±∞ sides: once here, not per operation
        return _solve(*args)


def _solve(M, t, m_scale, G, lower, upper, z, guess, threshold, feasibility, max_iterations, kind, guess_valid,
           working) -> ActiveSetResult:
    """:func:`python_solve`, compiled (:mod:`.kernels.active_set`, imported on the first call): the same
    iterations, each step the compiled :func:`eqp`; the Python version runs where the compiled one
    gives way (LAPACK refusing a factorisation)."""
    compiled, given = _jit_active_set(), compiled_input
    has_guess = guess is not None
    status, z_out, side, iterations, accepted, verified = compiled.solve(
        given(M), given(t), given(m_scale), given(G), given(lower), given(upper), given(z),
        given(guess, np.int64) if has_guess else _NO_GUESS, has_guess, float(threshold), float(feasibility),
        -1 if max_iterations is None else int(max_iterations), bool(kind[0]), bool(kind[1]), bool(guess_valid),
        float(working))
    if status == compiled.SOLVED:
        return ActiveSetResult(z_out, side, iterations, accepted, verified)
    if status == compiled.NO_CONVERGENCE:
        raise ActiveSetFailure(f"no convergence in {iterations} active-set iterations")
    return python_solve(M, t, m_scale, G, lower, upper, z, guess, threshold, feasibility, max_iterations, kind,
                        guess_valid, working)


_NO_GUESS = np.zeros(0, dtype=np.int64)


_jit_active_set = kernels(".kernels.active_set", __package__, "solve", "the hierarchical QP's active-set iterations",
                          "about thirty seconds")


def python_solve(M, t, m_scale, G, lower, upper, z, guess, threshold, feasibility, max_iterations, kind, guess_valid,
                 working) -> ActiveSetResult:
    """The iterations of :func:`solve_least_squares_qp` (its arguments, ``kind`` and ``working``
    given), in Python: the reference of the compiled :func:`_solve`."""
    m = len(G)
    equality = lower == upper
    accepted, side = _first_working_set(M, t, m_scale, G, lower, upper, z, guess, threshold, feasibility, kind,
                                        guess_valid, working, equality)
    if accepted is not None:
        return accepted
    if max_iterations is None:
        max_iterations = 10 * (m + M.shape[1]) + 50
    seen: set[bytes] = set()
    m_max = float(m_scale.max(initial=0.0))
    bland = False
    last_dropped, dropped_side = -1, 0
    for iteration in range(1, max_iterations + 1):
        held = side != 0
        E = G[held]
        e = np.where(side > 0, upper, lower)[held]
        # The minimum-norm step from z: along it a dropped row is left on its feasible side
        # (the absolute minimum-norm point is recomputed at the end).
        step, lam, N = eqp(M, t - M @ z, m_scale, E, e - E @ z, threshold, kind, working)
        target = z + step
        value, rate = G @ z, G @ step
        # Only rows independent of the working set can block (a dependent row's rate is round-off).
        if N is None:
            movable = ~held
        else:
            GN = G @ N
            movable = ~held & (np.sqrt(np.einsum("ij,ij->i", GN, GN)) > working)
        up = np.where(movable & (rate > 0.0), (upper - value) / rate, np.inf)  # (errstate: set by the caller)
        down = np.where(movable & (rate < 0.0), (lower - value) / rate, np.inf)
        ratio = np.maximum(np.minimum(up, down), 0.0)
        alpha = float(ratio.min(initial=np.inf))
        if alpha < 1.0:
            blocking = int((ratio <= alpha * (1 + RATIO_TIE)).nonzero()[0][0]) if bland else int(np.argmin(ratio))
            if blocking == last_dropped and (
                alpha * float(np.abs(step).max(initial=0.0)) <= NO_STEP * max(1.0, float(np.abs(z).max(initial=0.0)))
            ):
                # The row just dropped blocks at once: its multiplier's sign was round-off, the
                # previous point (where it was held) is optimal.
                side[blocking] = dropped_side
                return _finish(M, t, m_scale, G, lower, upper, side, threshold, feasibility, z, iteration, kind, working)
            z = z + alpha * step
            side[blocking] = 1 if up[blocking] <= down[blocking] else -1
            last_dropped = -1
            if alpha == 0.0:
                key = side.tobytes()
                if key in seen:
                    bland = True
                seen.add(key)
            continue
        at_origin = not any_true(z)  # then the step is the absolute EQP point itself (bit for bit)
        z = target
        # Multipliers: λ ≥ 0 at an upper side, ≤ 0 at a lower side (equality rows: free), up to a
        # round-off tolerance relative to the gradient's scale.
        held_index = held.nonzero()[0]
        wrong = np.where(equality[held_index], 0.0, -side[held_index] * lam)
        excess = wrong_signs(M, t, m_scale, E, z, wrong, m_max, working)  # (None: every sign right to round-off)
        if excess is not None:
            leaving = held_index[int((excess > 0.0).nonzero()[0][0]) if bland else int(np.argmax(excess))]
            last_dropped, dropped_side = leaving, side[leaving]
            side[leaving] = 0
            key = side.tobytes()
            if key in seen:
                bland = True
            seen.add(key)
            continue
        if at_origin:  # _finish would recompute this very point
            return ActiveSetResult(z, side, iteration, False)
        return _finish(M, t, m_scale, G, lower, upper, side, threshold, feasibility, z, iteration, kind, working)
    raise ActiveSetFailure(f"no convergence in {max_iterations} active-set iterations")


def _first_working_set(M, t, m_scale, G, lower, upper, z, guess, threshold, feasibility, kind, guess_valid, working,
                       equality) -> tuple[ActiveSetResult | None, np.ndarray]:
    """:func:`python_solve`'s start: the guess's own answer if it checks (then the working set is
    the guess), else the working set the iterations start from (the guess's rows held at ``z``,
    linearly independent; the equality rows alone without a guess)."""
    if guess is None or len(guess) != len(G):
        return None, np.where(equality, 1, 0)
    side = np.where(equality, 1, guess) if guess_valid else _guessed_sides(guess, lower, upper, equality)
    candidate = _check(M, t, m_scale, G, lower, upper, side, threshold, feasibility, kind, equality, working)
    if candidate is not None:
        return ActiveSetResult(candidate, side, 0, True, True), side
    value = G @ z
    near = feasibility * 10
    side = np.where((side < 0) & (value <= lower + near), -1, np.where((side > 0) & (value >= upper - near), 1, 0))
    side[equality] = 1
    held = side.nonzero()[0]
    dependent = np.setdiff1d(held, held[independent_rows(G[held], working)])
    side[dependent] = 0  # a working set is linearly independent (equality rows come first in rank)
    return None, side


def _guessed_sides(guess: np.ndarray, lower: np.ndarray, upper: np.ndarray, equality: np.ndarray) -> np.ndarray:
    """A guess made a valid working set: equality rows held, no row held at an infinite side
    (``equality``: ``lower == upper``)."""
    side = np.where(equality, 1, guess)
    side[((side < 0) & (lower == -np.inf)) | ((side > 0) & (upper == np.inf))] = 0  # (no NaN: refused at input)
    return side


def _finish(M, t, m_scale, G, lower, upper, side, threshold, feasibility, z, iteration, kind, working) -> ActiveSetResult:
    """The optimum: the absolute minimum-norm EQP point of the final working set if it is feasible
    (a function of the working set alone), else the iterate (same objective value)."""
    held = side != 0
    final = eqp(M, t, m_scale, G[held], np.where(side > 0, upper, lower)[held], threshold, kind, working)[0]
    if not feasible(G, lower, upper, final, feasibility):
        return ActiveSetResult(z, side, iteration, False, False)
    return ActiveSetResult(final, side, iteration, False, True)


def feasible(G: np.ndarray, lower: np.ndarray, upper: np.ndarray, z: np.ndarray, feasibility: float) -> bool:
    """Whether ``lower ≤ G z ≤ upper`` holds to ``feasibility`` (absolute, relative above 1); the
    caller silences numpy's warnings on ±∞ sides. A point inside the sides exactly passes at once."""
    value = G @ z
    if all_true(value >= lower) and all_true(value <= upper):
        return True
    return not (any_true(value < lower - feasibility * np.maximum(1.0, np.abs(lower)))
                or any_true(value > upper + feasibility * np.maximum(1.0, np.abs(upper))))


def _check(M, t, m_scale, G, lower, upper, side, threshold, feasibility, kind, equality, working=None) -> np.ndarray | None:
    """The EQP point of the working set ``side`` if it satisfies the KKT conditions, else None."""
    held = side.nonzero()[0]
    held_side = side[held]
    z, lam, _ = eqp(M, t, m_scale, G[held], np.where(side > 0, upper, lower)[held], threshold, kind, working)
    if not feasible(G, lower, upper, z, feasibility):
        return None
    if len(held):
        wrong = -held_side * lam
        wrong[equality[held]] = 0.0  # equality rows: either sign
        cut = threshold if working is None else working
        if wrong_signs(M, t, m_scale, G[held], z, wrong, float(m_scale.max(initial=0.0)), cut) is not None:
            return None
    return z
