"""A collision level's rows kept exact when one of them cannot be met.

A level of inequality rows that cannot all hold is solved, as every level of the hierarchy, in the
least-squares sense: its slacks ``w`` (each row's violation) minimise ``‖w‖²`` over what the levels
above leave free. When the rows are independent constraints (the collision pairs in range:
``TaskLevel.row_keys``), that spreads one infeasible row's violation over rows that could have
held: a pair that starts inside the safety distance, or that its joints cannot brake in time, asks
more than the robot can give, and the least-squares optimum lets other pairs close in, or through,
to shave a part of it.

Such a level (:func:`keyed_inequality`) is therefore refined. From its least-squares answer,
greedily: the row of the largest slack is moved to a level of its own just below the rest, and the
stack is solved again; if the rest now holds exactly (every violation within :data:`UNMET`,
relative above 1), that answer is taken, else the row of the rest's largest slack joins the
moved rows, at most :data:`MAX_ROUNDS` times, and the last answer is taken. The levels above are
untouched (the same optimal set); the rows kept are met as closely as they can be together (exactly
when they can: the least-squares answer is a point of their level, so they are never met worse than
in it); the moved rows are met as closely as the kept ones allow, and the levels below see what is
left. Finding the fewest rows to move is a minimum infeasible-subsystem problem (NP-hard in
general); with one such row, the largest slack is nearly always its own, found at the first
round. When a solve fails, the last answer (or the least-squares one) stands.

The answer is returned with the two levels merged back (its slacks in the level's own row order), so
its levels are the stack's. The extra solves happen only on ticks where the level cannot be met.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from ..hqp import HqpResult
from ..task import TaskLevel

UNMET = 1e-6
"""A row's violation beyond this (in the row's units, relative above 1 to its bound) is a row not met."""

MAX_ROUNDS = 3
"""The most rows moved below the rest of a level (each round one more solve of the stack)."""

Solve = Callable[[list[TaskLevel]], HqpResult | None]
"""The stack solved with these task levels in place of the stack's (None: it failed)."""


def keyed_inequality(task: TaskLevel) -> bool:
    """Whether ``task``'s rows are independent constraints refined by :func:`keep_met_rows`: an
    inequality level whose rows are keyed (the collision pairs in range)."""
    return task.row_keys is not None and not task.is_equality and len(task.lower) > 0


def unmet(task: TaskLevel, slack: np.ndarray) -> np.ndarray:
    """The rows of ``task`` whose ``slack`` (violation, :meth:`~sotdrake.hqp.problem.LevelRows.slack`)
    exceeds :data:`UNMET` relative above 1 to the bound it misses."""
    bound = np.where(np.isfinite(task.lower), np.abs(task.lower), 0.0)
    upper = np.where(np.isfinite(task.upper), np.abs(task.upper), 0.0)
    return np.abs(slack) > UNMET * np.maximum(1.0, np.maximum(bound, upper))


def split(task: TaskLevel, moved: np.ndarray) -> tuple[TaskLevel, TaskLevel]:
    """``task`` as two levels: the rows not ``moved`` (a boolean mask), then the moved ones."""
    kept = ~moved

    def rows(mask: np.ndarray) -> TaskLevel:
        keys = None if task.row_keys is None else task.row_keys[mask]
        return TaskLevel(task.jacobian[mask], task.lower[mask], task.upper[mask], task.error[mask], keys)

    return rows(kept), rows(moved)


def merged(result: HqpResult, level: int, moved: np.ndarray) -> HqpResult:
    """``result`` of a stack whose ``level`` was split by :func:`split` with ``moved``, its two
    levels ``level`` and ``level + 1`` merged back into one, in the original row order."""
    kept_rows, moved_rows = np.flatnonzero(~moved), np.flatnonzero(moved)
    slack = np.empty(len(moved))
    slack[kept_rows] = result.slacks[level]
    slack[moved_rows] = result.slacks[level + 1]
    active = np.sort(np.concatenate([kept_rows[result.active_rows[level]], moved_rows[result.active_rows[level + 1]]]))
    slacks = [*result.slacks[:level], slack, *result.slacks[level + 2 :]]
    return HqpResult(
        x=result.x,
        slacks=slacks,
        slack_norms=np.array([math.sqrt(float(s @ s)) for s in slacks]),
        active_rows=[*result.active_rows[:level], active, *result.active_rows[level + 2 :]],
        active_bounds=result.active_bounds,
        solve_time_s=result.solve_time_s,
        level_solvers=result.level_solvers,
        iterations=result.iterations,
        fallbacks=result.fallbacks,
    )


def keep_met_rows(solve: Solve, tasks: Sequence[TaskLevel], result: HqpResult, first: int) -> HqpResult:
    """``result`` (the stack with ``tasks``, the first of them at level ``first``) refined as the
    module docstring says for each :func:`keyed_inequality` task it did not meet; ``solve`` solves
    the stack with other task levels (same variables, bounds and levels above)."""
    current = list(tasks)  # the task levels solved last
    splits: list[tuple[int, np.ndarray]] = []  # (level, moved) of each split
    for i, task in enumerate(tasks):
        j = i + len(splits)  # (each split before it added a level)
        if (not keyed_inequality(task) or result.slack_norms[first + j] <= UNMET  # (no row beyond UNMET: met)
                or not unmet(task, result.slacks[first + j]).any()):
            continue
        slack, moved = result.slacks[first + j], np.zeros(len(task.lower), dtype=bool)
        last = None  # the last answer with rows moved, and which
        for _ in range(min(MAX_ROUNDS, len(moved) - 1)):
            moved[int(np.argmax(np.where(moved, -np.inf, np.abs(slack))))] = True
            kept, rest = split(task, moved)
            trial = solve([*current[:j], kept, rest, *current[j + 1 :]])
            if trial is None:
                break
            last = trial, moved.copy()
            if not unmet(kept, trial.slacks[first + j]).any():
                break
            slack = np.zeros(len(moved))
            slack[~moved] = trial.slacks[first + j]
        if last is not None:
            result, mask = last
            current[j : j + 1] = split(task, mask)
            splits.append((first + j, mask))
    for level, moved in reversed(splits):
        result = merged(result, level, moved)
    return result
