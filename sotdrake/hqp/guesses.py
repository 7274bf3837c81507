"""Guesses of a stage's working set from dual methods on the stage made strictly convex: quadprog's
Goldfarb-Idnani (:func:`dual_guess`), DAQP's (:func:`daqp_guess`), and DAQP's on the minimum-norm
stage's projection (:func:`projection_guess`). A guess changes how fast the active set finds the
optimum (:mod:`.active_set`), never which point it returns."""

from __future__ import annotations

import daqp
import numpy as np
import quadprog

from .linalg import any_true
from .problem import Stage

DAQP_RETRY_REGULARIZATION = 1e-6
"""The regularisation (relative to ``‖M‖²/p``) of :func:`daqp_guess`'s second try (measured on 1108
level stages of the random stacks: DAQP reports infeasibility on 105 at 1e-9, on 28 at 1e-6)."""


def dual_guess(M: np.ndarray, t: np.ndarray, G: np.ndarray, lower: np.ndarray, upper: np.ndarray,
               regularization: float = 1e-9) -> np.ndarray | None:
    """A guess of the working set (a side per row of ``G``) from Goldfarb-Idnani's dual active-set
    method (quadprog, compiled) on the problem made strictly convex by ``regularization``·I (scaled
    by ``‖M‖²``). Only a guess: the caller checks it exactly. None if quadprog refuses. A row is
    never held at an infinite side (those sides are not given to quadprog)."""
    p = G.shape[1]
    H = M.T @ M  # (a new C-ordered array: reshape gives a view of its diagonal)
    if not (any_true(lower > -np.inf) or any_true(upper < np.inf)):
        return np.zeros(len(G), dtype=int)
    H.reshape(-1)[:: p + 1] += regularization * max(1.0, float(H.trace()) / max(p, 1))
    found = _goldfarb_idnani(H, M.T @ t, G, lower, upper)
    return None if found is None else found[1]


def dual_point(M: np.ndarray, t: np.ndarray, G: np.ndarray, lower: np.ndarray, upper: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray] | None:
    """``(z, side)``: the optimum of ``min ½‖M z - t‖² s.t. lower ≤ G z ≤ upper`` by Goldfarb-Idnani's
    dual method (quadprog) and the side of each row it holds, or None if quadprog refuses. A dual
    method reaches the optimum through feasible steps of the dual, so it does not walk along a
    sliver of the primal feasible set the way a primal active set can (see
    :class:`.paths.DualPoint`); its point is checked by the caller like any other.

    Only a strictly convex objective is solved (``MᵀM`` has a Cholesky factor: its optimum is
    unique, the dual method's point is it); None otherwise (a regularised objective's optimum can be
    far from the level's own on an ill-conditioned stage). quadprog's test of the rows' consistency
    is not scale-free on such a degenerate stage: it may call the rows inconsistent at one scale of
    the objective and answer at another (on the two damping-level stages of
    :class:`.paths.DualPoint`, with ``trace(MᵀM)/p`` scaled to 1e-2 … 1e-4 both answered, at 1
    neither). The objective (the same minimiser at every scale) is tried at the scales of
    :data:`DUAL_POINT_SCALES`, in order."""
    p = G.shape[1]
    H = M.T @ M
    weight = float(H.trace()) / max(p, 1)
    if not (weight > 0.0 and np.isfinite(weight)):
        return None
    try:
        np.linalg.cholesky(H)
    except np.linalg.LinAlgError:
        return None
    f = M.T @ t
    for scale in DUAL_POINT_SCALES:
        found = _goldfarb_idnani(H * (scale / weight), f * (scale / weight), G, lower, upper)
        if found is not None:
            return found
    return None


DUAL_POINT_SCALES = (1e-3, 1e-2, 1e-4, 1e-6, 1.0)
"""The sizes of ``trace(MᵀM)/p`` at which :func:`dual_point` asks quadprog, in order."""


def _goldfarb_idnani(H: np.ndarray, f: np.ndarray, G: np.ndarray, lower: np.ndarray, upper: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray] | None:
    """quadprog's ``min ½ zᵀHz - fᵀz s.t. lower ≤ G z ≤ upper`` (``H`` positive definite; infinite
    sides left out): its point and the side of each row it holds, or None if it refuses."""
    lower_rows, upper_rows = (lower > -np.inf).nonzero()[0], (upper < np.inf).nonzero()[0]
    n_low = len(lower_rows)
    rows = np.concatenate([lower_rows, upper_rows])
    side = np.zeros(len(G), dtype=int)
    try:
        if len(rows) == 0:
            return quadprog.solve_qp(H, f)[0], side
        C = G[rows]
        C[n_low:] *= -1.0
        b = np.concatenate([lower, -upper])[np.concatenate([lower_rows, upper_rows + len(G)])]
        solution = quadprog.solve_qp(H, f, C.T, b, 0)
    except ValueError:
        return None
    active = solution[5] - 1  # (quadprog's 1-based indices of its active rows of C: the lower sides first)
    if len(active):  # (a row held at both sides has lower == upper: the caller holds it as an equality)
        side[rows[active]] = np.where(active < n_low, -1, 1)
    return solution[0], side


def daqp_guess(M: np.ndarray, t: np.ndarray, G: np.ndarray, lower: np.ndarray, upper: np.ndarray,
               regularization: float = 1e-9) -> np.ndarray | None:
    """A guess of the working set (a side per row of ``G``) from DAQP's dual active-set method on the
    problem made strictly convex by ``regularization``·I (scaled by ``‖M‖²``, as :func:`dual_guess`):
    DAQP takes the two-sided rows as they are (no row is doubled) and costs about a third of
    quadprog on a level's stage. The sides are the signs of its multipliers (> 0 at the upper side,
    < 0 at the lower one). :func:`dual_guess` (quadprog) if DAQP reports no solution. Only a guess:
    the caller checks it exactly. A nearly singular ``MᵀM`` (most of a level's directions
    unweighted) makes DAQP report the (feasible) problem infeasible in about 1 stage in 10 on the
    random stacks: it is then asked once more with :data:`DAQP_RETRY_REGULARIZATION` added."""
    if len(G) == 0:
        return np.zeros(0, dtype=int)
    p = G.shape[1]
    H = M.T @ M
    diagonal = H.reshape(-1)[:: p + 1]  # (a view: H is a new C-ordered array)
    weight = max(1.0, float(H.trace()) / max(p, 1))
    f = -(M.T @ t)
    for extra in (regularization, DAQP_RETRY_REGULARIZATION):
        diagonal += extra * weight
        _, _, exitflag, info = daqp.solve(H, f, G, upper, lower)
        if exitflag > 0:
            return np.sign(info["lam"]).astype(int)
    return dual_guess(M, t, G, lower, upper, regularization)


def projection_guess(t: np.ndarray, G: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray | None:
    """A guess of the working set of ``min ½‖z - t‖² s.t. lower ≤ G z ≤ upper`` (a projection:
    strictly convex, its optimum is unique, so a guess can change the path to it, never the point)
    from DAQP's dual active-set method, which takes this least-distance form and two-sided rows
    as they are (the signs of its multipliers: > 0 at the upper side, < 0 at the lower one);
    quadprog's guess if DAQP reports no solution."""
    if len(G) == 0:
        return np.zeros(0, dtype=int)
    p = G.shape[1]
    _, _, exitflag, info = daqp.solve(np.eye(p), -t, G, upper, lower)
    if exitflag > 0:
        return np.sign(info["lam"]).astype(int)
    return dual_guess(np.eye(p), t, G, lower, upper, regularization=0.0)


DAQP_SPREAD = 1e6
"""A level's cold guess comes from DAQP when its objective rows' reference norms are within this
factor (``MᵀM``'s weights within 1e12, where the Cholesky factor DAQP works on still holds digits);
beyond, from quadprog. Both are only guesses checked exactly; on the random stacks DAQP's costs
about a third of quadprog's (measured: median 27 against 79 µs on 1108 level stages)."""


def level_guess(stage: Stage) -> tuple[np.ndarray | None, bool]:
    """The cold guess of a level's working set: DAQP's (:func:`~.guesses.daqp_guess`) when the
    objective's rows are of comparable weights (reference norms within :data:`DAQP_SPREAD`),
    else quadprog's (:func:`~.guesses.dual_guess`). On a level whose weights spread further
    the two guesses can lead to different points of a numerically flat optimum (the same
    objective to 9 digits), and the levels below then differ: quadprog's is kept there. With
    whether the guess is valid as it is (quadprog's holds no row at an infinite side: those sides
    are not given to it; DAQP's sides are checked by the active set)."""
    m_scale = stage.m_scale
    if len(m_scale) and float(m_scale.max()) <= DAQP_SPREAD * float(m_scale.min()):
        return daqp_guess(stage.M, stage.t, stage.G, stage.lower, stage.upper), False
    return dual_guess(stage.M, stage.t, stage.G, stage.lower, stage.upper), True
