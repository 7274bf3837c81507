"""The checks a stage's point must pass, and the rescues of a stage whose paths all failed.

A path's point is accepted if it is finite and holds the hard rows (the bounds and the held rows of
the levels above) to the feasibility tolerance (:func:`accept`); one that misses them by round-off
only is moved onto them (:func:`onto_hard_rows`). When every path failed, :func:`after_every_path`
decides: the minimum-norm stage keeps the last level's point (:data:`~.problem.KEPT_LAST_LEVEL`); a
level takes a point that holds its rows to the tolerance of their terms
(:data:`~.problem.ROUND_OFF_LIMITED`), else the dual method's own point if it holds every row
(:class:`~.paths.DualPoint`); else :class:`~sotdrake.exceptions.SolverError`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from ..exceptions import SolverError
from .linalg import all_true, any_true
from .paths import OUTSIDE, Attempt, DualPoint
from .problem import KEPT_LAST_LEVEL, ROUND_OFF_LIMITED, HqpResult, Stage, least_norm
from .tolerances import ROUND_OFF, VERIFIED

if TYPE_CHECKING:
    from .active_set import ActiveSetResult
    from .owner import StageOwner

REFINEMENTS = 2
"""The round-off rescue's corrections, at most."""


def accept(qp: StageOwner, stage: Stage, y: np.ndarray) -> bool:
    """A path's point is kept if it is finite and inside the bounds."""
    return all_true(np.isfinite(y)) and bounds_hold(qp, stage, y)


def bounds_hold(qp: StageOwner, stage: Stage, y: np.ndarray) -> bool:
    _, below, above = missed_hard_rows(qp, stage, y)
    return not any_true(below | above)


def missed_hard_rows(qp: StageOwner, stage: Stage, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The hard rows' values at ``y`` and the rows missed below and above by more than the
    feasibility tolerance (relative above 1; a NaN value misses both)."""
    m_hard = stage.m_hard
    value = stage.G[:m_hard, :stage.r] @ y
    lo, hi = stage.lower[:m_hard], stage.upper[:m_hard]
    tol = qp.feasibility_tolerance
    return value, ~(value >= lo - tol * np.maximum(1.0, np.abs(lo))), ~(value <= hi + tol * np.maximum(1.0, np.abs(hi)))


def onto_hard_rows(qp: StageOwner, stage: Stage, y: np.ndarray, side: np.ndarray) -> np.ndarray | None:
    """A point that misses hard rows by round-off only, moved onto them: the least-norm correction
    ``δ`` that puts the rows of the working set (``side``) and the missed rows at their sides,
    at most :data:`REFINEMENTS` times; None when a row is missed by more than
    :data:`ROUND_OFF` relative to the point's size, or the correction would move it by more
    than ten times that (not round-off: the next path decides), or it does not bring every hard
    row within the feasibility tolerance. The active set's solves lose about ``cond · ε`` of a
    point's size: on a stage whose point is hundreds of times its rows' targets, a few 1e-9 on a
    bound row (level 5 of a TALOS stack with a task held against its limits)."""
    if not all_true(np.isfinite(y)):
        return None
    m, r = stage.m_hard, stage.r
    G, lower, upper = stage.G[:m, :r], stage.lower[:m], stage.upper[:m]
    held = side[:m]
    for corrections in range(REFINEMENTS + 1):
        value, below, above = missed_hard_rows(qp, stage, y)
        if not any_true(below | above):
            return y
        if corrections == REFINEMENTS:
            return None
        missed = float(np.max(np.where(below, lower - value, np.where(above, value - upper, 0.0))))
        if not missed <= ROUND_OFF * max(1.0, float(np.max(np.abs(y)))):
            return None
        at_lower = ((held < 0) | below) & np.isfinite(lower)
        at_upper = ((held > 0) | above) & np.isfinite(upper) & ~at_lower
        rows = at_lower | at_upper
        target = np.where(at_lower, lower, upper)[rows]
        A = G[rows]
        correction = least_norm(A, target - A @ y, qp.rank_threshold)
        if not float(np.max(np.abs(correction))) <= 10.0 * ROUND_OFF * max(1.0, float(np.max(np.abs(y)))):
            return None  # nearly dependent rows asked to move the point further than round-off
        y = y + correction
    return None


def relative_miss(qp: StageOwner, stage: Stage, y: np.ndarray) -> float:
    """The largest miss of a hard row beyond the feasibility tolerance, as a fraction of that
    tolerance taken relative to the size of the row's terms, ``tol · Σ_j |g_j| |y_j|``: ≤ 1 when
    ``y`` holds every hard row to the tolerance relative to its terms (see
    :data:`ROUND_OFF_LIMITED`). A unit bound row's product is exact (its terms are one
    component), so it is held to ``tol · |y_i|``. Only reached when every path ended outside."""
    value, below, above = missed_hard_rows(qp, stage, y)
    m_hard, r = stage.m_hard, stage.r
    lo, hi = stage.lower[:m_hard], stage.upper[:m_hard]
    tol = qp.feasibility_tolerance
    miss = np.where(below, lo - tol * np.maximum(1.0, np.abs(lo)) - value,
                    np.where(above, value - hi - tol * np.maximum(1.0, np.abs(hi)), 0.0))
    missed = miss > 0.0
    if not any_true(missed):
        return 0.0
    scale = tol * (np.abs(stage.G[:m_hard, :r]) @ np.abs(y))
    return float(np.max(miss[missed] / np.maximum(scale[missed], np.finfo(float).tiny)))



def after_every_path(attempt: Attempt, fallbacks: list[str], what: str) -> tuple[np.ndarray, np.ndarray, str, int]:
    """The stage's answer once every path failed: ``(x, side, label, iterations)``, ``side`` the
    hard rows' sides on the minimum-norm stage, else the stage rows' (see the module docstring);
    raises :class:`~sotdrake.exceptions.SolverError` naming the stage when no rescue applies."""
    failures, x0, Z = attempt.failures, attempt.x0, attempt.Z
    if attempt.level is None:
        # Every path failed on the minimum-norm stage: the last level's point, which its stage
        # verified (every level at its optimum, the bounds and held rows kept), is a point of the
        # optimal set; it is kept and only the minimum norm is given up (said in the fallbacks).
        fallbacks += [f"{what}: {failure}" for failure in failures]
        return x0, attempt.hard[5].copy(), KEPT_LAST_LEVEL, 0
    if attempt.outside:
        # Every path ended outside a hard row. If one of their points holds each row to the
        # feasibility tolerance relative to the row's terms (a point so large that doubles cannot
        # verify it closer to the bound), it is the answer, said in the fallbacks.
        misses = [relative_miss(attempt.qp, attempt.stage, candidate[0]) for candidate in attempt.outside]
        miss = min(misses)
        if miss <= 1.0:
            y, side, label, count = attempt.outside[misses.index(miss)]
            fallbacks += [f"{what}: {failure}" for failure in failures]
            fallbacks.append(f"{what}: {ROUND_OFF_LIMITED} (size {float(np.max(np.abs(y))):.3g}, "
                             f"{miss:.2g} of the tolerance)")
            return x0 + Z @ y, side, label, count
    dual = DualPoint().attempt(attempt)  # the last rescue: the dual method's own point, if it holds every row
    if dual is not None and accept(attempt.qp, attempt.stage, dual[0].z[:attempt.stage.r]):
        fallbacks += [f"{what}: {failure}" for failure in failures]
        fallbacks.append(f"{what}: the dual method's point (every row held)")
        return x0 + Z @ dual[0].z[:attempt.stage.r], dual[0].side, dual[1], 0
    if dual is not None:
        failures.append(f"{DualPoint.name}: {OUTSIDE}")
    raise SolverError(f"hierarchical QP: no solution on {what} ({'; '.join(failures)})")


def accepted(qp: StageOwner, attempt: Attempt, path: str, solution: ActiveSetResult, label: str) -> np.ndarray | None:
    """The step ``y`` of a path's solution if it is accepted (moved onto the hard rows if it
    misses them by round-off), else None with the failure recorded (and a finite point of a
    level kept for the round-off-limited rescue)."""
    stage = attempt.stage
    y = solution.z[:stage.r]
    # A point the active set verified on every row to 1e-10 (≤ the feasibility tolerance)
    # only needs to be finite; any other is checked on the bounds and held rows.
    verified = solution.verified and qp.feasibility_tolerance >= VERIFIED
    if all_true(np.isfinite(y)) if verified else accept(qp, stage, y):
        return y
    corrected = onto_hard_rows(qp, stage, y, solution.side)
    if corrected is None:
        attempt.failures.append(f"{path}: {OUTSIDE}")
        if attempt.level is not None and all_true(np.isfinite(y)):
            attempt.outside.append((y, solution.side, label, solution.iterations))
    return corrected


def cold_again(qp: StageOwner, error: SolverError, solve: Callable[[], HqpResult]) -> HqpResult:
    """The whole solve once more without the stages' cached working sets, after every path of a
    stage failed on a warm-started solve (re-raises ``error`` on a cold one). A warm start changes
    which path answers, not the answer beyond the tolerances; but on a level with a flat optimum
    (inequality rows, e.g. a collision level) the warm-started active set can end at another point
    of the optimal set than the cold one, and a level below can then be out of every path's reach
    from there (seen on ``SolverDyn``'s damping level in randomized collision reaches,
    ``bench/collision_runs.py --dynamic``: the active set cycling or ending outside the bounds,
    Clarabel and OSQP too, while the same problem solved cold is solved). Said in the answer's
    fallbacks."""
    if not qp.warm.working_sets:
        raise error
    qp.warm.working_sets.clear()
    result = solve()
    result.fallbacks.insert(0, f"the warm start was dropped and the stack solved cold ({error})")
    return result
