"""A plain lexicographic reference for the hierarchical QP: the timing peer of ``bench/run.py``.

Written independently of ``sotdrake``'s solver, as one would write it first. Level by level, the
variable lives in the null space ``N`` of every equality row held so far (one SVD of their stack,
recomputed from scratch), ``x = x_prev + N y``, and one dense QP (quadprog, Goldfarb-Idnani) per
level minimises

    ‖A_e (x_prev + N y) − b_e‖² + ‖w‖² + ε‖y‖²
    s.t.  lower_i − w_i ≤ A_i x ≤ upper_i + w_i,  w ≥ 0     (this level's inequality rows, one slack each)
          the bounds and the inequality rows above, relaxed to contain y = 0 and held at their optimum.

Each level's equality rows then join the null-space stack; its inequality rows are held within
1e-9 of their optimal violation. The rows must be given as objects with ``A``, ``lower`` and ``upper``.
"""

from __future__ import annotations

import numpy as np
import quadprog

EPSILON = 1e-10  # makes the Hessian definite; moves the solution by ~ε, far below any tolerance


def plain_lexicographic(n: int, levels, x_lower: np.ndarray, x_upper: np.ndarray) -> np.ndarray:
    """The lexicographic optimum ``x`` (n) of ``levels`` within the bounds (see the module docstring)."""
    fixed = x_lower == x_upper
    held = [np.eye(n)[fixed]]
    x = np.where(fixed, x_lower, 0.0)
    hard = [(np.eye(n)[~fixed], x_lower[~fixed], x_upper[~fixed])]  # (A, lower, upper) rows kept
    for level in levels:
        E = np.vstack(held)
        _, sigma, Vt = np.linalg.svd(E) if len(E) else (None, np.zeros(0), np.eye(n))
        N = Vt[int(np.sum(sigma > 1e-9)):].T
        equality = level.lower == level.upper
        Ae, be = level.A[equality] @ N, level.lower[equality] - level.A[equality] @ x
        Ai = level.A[~equality]
        r, k = N.shape[1], len(Ai)
        G = np.zeros((r + k, r + k))
        G[:r, :r] = 2.0 * Ae.T @ Ae + EPSILON * np.eye(r)
        G[r:, r:] = 2.0 * np.eye(k)
        a = np.concatenate([2.0 * Ae.T @ be, np.zeros(k)])
        rows, rhs = [], []
        for A, lo, hi in hard:  # relaxed to contain y = 0: the previous point satisfies them
            at, AN = A @ x, A @ N
            for coefficient, value in ((AN, np.minimum(lo, at) - at), (-AN, at - np.maximum(hi, at))):
                keep = np.isfinite(value)
                rows.append(np.hstack([coefficient[keep], np.zeros((int(keep.sum()), k))]))
                rhs.append(value[keep])
        at, AN = Ai @ x, Ai @ N
        for coefficient, value in ((AN, level.lower[~equality] - at), (-AN, at - level.upper[~equality])):
            keep = np.isfinite(value)
            rows.append(np.hstack([coefficient[keep], np.eye(k)[keep]]))
            rhs.append(value[keep])
        rows.append(np.hstack([np.zeros((k, r)), np.eye(k)]))
        rhs.append(np.zeros(k))
        C, b = np.vstack(rows), np.concatenate(rhs)
        if r + k == 0:  # nothing left to move and nothing to relax
            z = np.zeros(0)
        else:
            z = quadprog.solve_qp(G, a, C.T, b - 1e-10, 0)[0] if len(b) else np.linalg.solve(G, a)
        x = x + N @ z[:r]
        value = level.A[~equality] @ x
        violation = np.maximum(np.maximum(level.lower[~equality] - value, value - level.upper[~equality]), 0.0)
        held.append(level.A[equality])
        hard.append((Ai, level.lower[~equality] - violation - 1e-9, level.upper[~equality] + violation + 1e-9))
    return x
