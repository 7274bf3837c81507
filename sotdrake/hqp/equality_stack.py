"""The active bounds path of a whole equality stack: every level an equality, solved at once by
:func:`.active_bounds.solve_stack` from the bounds held at the last answer (the warm start), before
any stage is built; and of a stack with inequality rows whose equality rows can all be met
(:func:`solve_held_rows`: the violated inequality rows held at their bounds). Both apply to levels
without extensions, the default path on every stage, the minimum-norm stage, no damping, and a
start inside the bounds of the free components; a stack they cannot verify goes to the stages, and
failures in a row make the next calls skip them for a while (the back-offs, kept in the
:class:`~.warm.WarmStart`).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..compiled import compiled_input, kernels
from .linalg import all_true
from .problem import ACTIVE_BOUNDS, ACTIVE_SET, NO_ACTIVE_ROWS, HqpResult
from .tolerances import CERTIFIED_FACTOR, VERIFIED

if TYPE_CHECKING:
    from .owner import StageOwner


_active_bounds_path = kernels(".active_bounds", __package__, "_solve_stack", "the hierarchical QP's path for equality stacks",
                              "about ten seconds")


def start_inside(x_lower: np.ndarray, x_upper: np.ndarray, fixed: np.ndarray, start: np.ndarray | float) -> bool:
    """Whether the QP's start is inside the bounds of every free component (NaN bounds and bounds out
    of order fail: every comparison with NaN is False, and ``lower > upper`` cannot hold it); the
    compiled :func:`.active_bounds.solve_stack` makes the same check for the start 0."""
    return all_true(((x_lower <= start) & (x_upper >= start)) | fixed)


def default_stages(qp: StageOwner) -> bool:
    """Whether the stages the whole-stack paths stand for are the default ones: the active set on
    every level, then the minimum-norm stage."""
    return qp.regularize and all(name == ACTIVE_SET for name in qp.level_solvers)


def equalities_only(qp: StageOwner, levels, x_lower, x_upper, fixed, damping, start) -> bool:
    """Whether :mod:`.active_bounds` may solve the stack: equality levels without extensions,
    the default path on every stage, the minimum-norm stage, no damping, and the start (0, or
    ``start``) inside the bounds of the free components (no bound is relaxed to it)."""
    for level in levels:
        if not level.all_equality or level.extend is not None:
            return False
    if not default_stages(qp) or (damping > 0.0 and len(levels)):
        return False
    return start_inside(x_lower, x_upper, fixed, 0.0 if start is None else start)


def try_active_bounds(qp: StageOwner, jacobians, values, x_lower, x_upper, began) -> HqpResult | None:
    """:meth:`_solve_active_bounds` unless failures in a row make this call skip it (the
    back-off: after f failures, the next 2^(f-1) calls, at most 16, skip it; a call to which the
    path does not apply, 0 outside the bounds of a free component, is not counted)."""
    if qp.warm.skips:
        with np.errstate(invalid="ignore"):
            if start_inside(x_lower, x_upper, x_lower == x_upper, 0.0):
                qp.warm.skipped("bounds")
        return None
    return solve_active_bounds(qp, jacobians, values, x_lower, x_upper, began)


def solve_active_bounds(qp: StageOwner, jacobians, values, x_lower, x_upper, began) -> HqpResult | None:
    """The equality stack by :func:`~.active_bounds.solve_stack` from the bounds held at the last
    answer, or None (then the stages decide)."""
    path = _active_bounds_path()
    sizes = np.array([len(J) for J in jacobians], dtype=np.int64)
    if len(jacobians) == 1:
        A, b = jacobians[0], values[0]
    elif jacobians:
        A, b = np.concatenate(jacobians), np.concatenate(values)
    else:
        A, b = np.zeros((0, qp.n)), np.zeros(0)
    guess = bound_guess(qp, x_lower, x_upper)
    status, x, sides, residual, slack_norms, active_bounds = path.solve_stack(
        A, b, sizes, x_lower, x_upper, guess, certified=CERTIFIED_FACTOR * qp.rank_threshold,
        feasibility=min(VERIFIED, qp.feasibility_tolerance), tolerance=qp.feasibility_tolerance)
    if status == path.NOT_APPLICABLE:  # (0 outside the bounds of a free component, as _equalities_only)
        return None
    qp.warm.record("bounds", status != path.NOT_VERIFIED)
    if status == path.NOT_VERIFIED:
        return None
    qp.warm.bound_sides = sides
    slacks, start = [], 0
    for size in sizes.tolist():
        slacks.append(residual[start : start + size])
        start += size
    stages = len(jacobians) + 1
    return HqpResult(
        x=x,
        slacks=slacks,
        slack_norms=slack_norms,
        active_rows=[NO_ACTIVE_ROWS] * len(jacobians),
        active_bounds=active_bounds,
        solve_time_s=time.perf_counter() - began,
        level_solvers=[ACTIVE_BOUNDS] * stages,
        iterations=[0] * stages,
    )


def bound_guess(qp: StageOwner, x_lower: np.ndarray, x_upper: np.ndarray) -> np.ndarray:
    """The sides of the bounds held at the last answer (the warm start's)."""
    guess = qp.warm.bound_sides
    if isinstance(guess, tuple):  # the stages' last answer: the sides of the bounds it holds
        given = compiled_input
        return _active_bounds_path().sides_at_bounds(given(guess[0]), given(guess[1]), given(guess[2]), x_lower == x_upper)
    assert guess is not None  # (set at the warm start's creation)
    return guess


def solve_held_rows(qp: StageOwner, levels: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]], x_lower: np.ndarray,
                    x_upper: np.ndarray, began: float) -> HqpResult | None:
    """A stack (at least one level ``(A_k, lower_k, upper_k)``) with inequality rows by
    :func:`~.active_bounds.solve_held_rows` (every equality row met, the violated inequality rows
    held), from the bounds held at the last answer and, when the rows have the same places (level
    sizes, which rows are inequalities), the rows it held (tried once more without them when they
    do not lead to a verified answer), or None (then the stages decide; also for rows that do not
    fit or are not finite: the stages say what is wrong). With a ``hold_tolerance`` the stages let
    the levels below a held row pass it by that much: an answer that holds a row is then not
    theirs, and None is given."""
    path = _active_bounds_path()
    n = len(x_lower)
    try:
        rows = [(np.asarray(A, dtype=float), np.asarray(lower, dtype=float), np.asarray(upper, dtype=float))
                for A, lower, upper in levels]
    except (TypeError, ValueError):
        return None
    if any(A.ndim != 2 or A.shape[1] != n or lower.shape != (len(A),) or upper.shape != (len(A),) for A, lower, upper in rows):
        return None
    sizes = np.array([len(level[0]) for level in rows], dtype=np.int64)
    starts = [0, *itertools.accumulate(sizes.tolist())]
    A, lower, upper = (np.concatenate([level[i] for level in rows]) for i in range(3))
    layout = sizes.tobytes() + (lower != upper).tobytes()  # (the rows' places: the held rows' guess is by place)
    row_guess = qp.warm.row_sides[1] if qp.warm.row_sides is not None and qp.warm.row_sides[0] == layout else None
    bound_sides = bound_guess(qp, x_lower, x_upper)
    for guess in (row_guess, None) if row_guess is not None else (None,):  # a wrong guess: once more without it
        status, x, sides, row_sides, slacks, slack_norms, active, bounds, has_inequality = path.solve_held_rows(
            A, lower, upper, sizes, x_lower, x_upper, bound_sides, certified=CERTIFIED_FACTOR * qp.rank_threshold,
            feasibility=min(VERIFIED, qp.feasibility_tolerance), tolerance=qp.feasibility_tolerance, row_guess=guess)
        if status != path.NOT_VERIFIED:
            break
    qp.warm.row_sides = (layout, row_sides) if status == path.SOLVED else None
    if status != path.SOLVED or (qp.hold_tolerance and row_sides.any()):
        return None
    qp.warm.bound_sides = sides
    level_slacks, active_rows = [], []
    for k, inequality in enumerate(has_inequality.tolist()):
        level_slacks.append(slacks[starts[k] : starts[k + 1]])
        active_rows.append(np.flatnonzero(active[starts[k] : starts[k + 1]]) if inequality else NO_ACTIVE_ROWS)
    stages = len(rows) + 1
    return HqpResult(x=x, slacks=level_slacks, slack_norms=slack_norms, active_rows=active_rows, active_bounds=bounds,
                     solve_time_s=time.perf_counter() - began,
                     level_solvers=[ACTIVE_BOUNDS] * stages, iterations=[0] * stages)
