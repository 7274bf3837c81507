"""DAQP's own hierarchical mode: a compiled peer of the hierarchical QP on the random stacks.

DAQP (a dual active-set QP solver in C, already a dependency) solves a stack of prioritised
constraint levels in one call (``break_points``): level by level, it minimises the level's
violation with its constraints soft (each slack weighted by ``1/rho_soft`` against ``½‖x‖²``),
then holds the violation it reached and moves down. The bounds on ``x`` come first and stay hard.
It is fast, but a level's violation is only minimised up to that weighting, so its answer can be
lexicographically worse than the strict optimum: :func:`compare` counts how often, on the same
stacks, against ``sotdrake``'s answer (and the other way round, an independent strictness check).
"""

from __future__ import annotations

import daqp
import numpy as np

#: DAQP's infinity (bounds beyond it are absent)
INF = 1e30
#: two violations (squared norms) differ when they differ by more than this, relatively (plus
#: :data:`ABSOLUTE`): far above DAQP's weighting (a violation held ~1e-6 loose lets the levels below
#: gain as much), far below the differences its weighting makes when it does decide a level
RELATIVE = 1e-3
ABSOLUTE = 1e-6


def daqp_hierarchical(n: int, levels, x_lower: np.ndarray, x_upper: np.ndarray) -> tuple[np.ndarray, int]:
    """DAQP's answer ``x`` (n) for ``levels`` (objects with ``A``, ``lower``, ``upper``) within the
    bounds, and its exit flag (1, 2: optimal, soft optimal; 3: no freedom left for the levels below)."""
    A = np.ascontiguousarray(np.vstack([level.A for level in levels]))
    lower = np.clip(np.concatenate([x_lower] + [level.lower for level in levels]), -INF, INF)
    upper = np.clip(np.concatenate([x_upper] + [level.upper for level in levels]), -INF, INF)
    sense = np.zeros(len(lower), dtype=np.intc)
    breaks = (n + np.concatenate([[0], np.cumsum([len(level.A) for level in levels])])).astype(np.intc)
    x, _, flag, _ = daqp.solve(None, None, A, upper, lower, sense, break_points=breaks)  # (no f: a least-distance problem)
    return np.asarray(x), int(flag)


def violations(levels, x: np.ndarray) -> np.ndarray:
    """Each level's violation at ``x``: the squared norm of how far its rows are outside their bounds."""
    out = []
    for level in levels:
        r = level.A @ x
        v = np.maximum(level.lower - r, 0.0) + np.maximum(r - level.upper, 0.0)
        out.append(float(v @ v))
    return np.array(out)


def compare(levels, x_a: np.ndarray, x_b: np.ndarray) -> tuple[int, bool]:
    """-1 if ``x_a`` is lexicographically better than ``x_b`` (the first level where their
    violations differ beyond :data:`RELATIVE` favours ``x_a``), 1 if worse, 0 if equal; and whether
    the winner held a level above that one looser than the loser did (by any amount beyond 1e-12
    relative: within the tolerance, it bought the lower level with it)."""
    va, vb = violations(levels, x_a), violations(levels, x_b)
    for k, (a, b) in enumerate(zip(va, vb, strict=True)):
        if abs(a - b) > RELATIVE * max(a, b) + ABSOLUTE:
            winner, loser = (va, vb) if a < b else (vb, va)
            looser = bool(np.any(winner[:k] > loser[:k] * (1 + 1e-12) + 1e-30))
            return (-1 if a < b else 1), looser
    return 0, False
