"""A task whose error stops decreasing is reported once: :class:`ProgressWatch`.

A target out of reach (or held back by a higher-priority task or a joint limit) leaves the task's
error ``‖e‖`` at a floor instead of at zero; nothing fails, the robot just stops short. Each
equality task of a stack watches its error as the solver evaluates it: every
:data:`CHECK_PERIOD` seconds of simulated time it compares ``‖e‖`` with the smallest value seen;
when that has not fallen by more than :data:`RELATIVE_PROGRESS` for :data:`PATIENCE` seconds while
``‖e‖`` is above :data:`MIN_ERROR`, it logs one warning (logger ``sotdrake.task``) naming the task
and the remaining ``‖e‖`` (m for positions, rad for angles): the distance to the target. A task
that makes progress again (a new target, the task pushed into the stack) is no longer stalled, and
may be warned about again if it stalls again.

Logging only: the control never depends on it. A simulation that starts again (time going back)
starts the watch again.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from .introspection import all_systems

log = logging.getLogger("sotdrake.task")

#: Simulated time between two looks at the error (s).
CHECK_PERIOD = 0.05
#: How long the error may stay at its floor before the warning (s).
PATIENCE = 1.0
#: A fall of the error by this fraction of its smallest value so far counts as progress.
RELATIVE_PROGRESS = 1e-3
#: Errors below this (m, rad) are reached targets, whatever their progress.
MIN_ERROR = 1e-3


class ProgressWatch:
    """The smallest ``‖e‖`` of one task and when it was seen (see the module docstring)."""

    __slots__ = ("best", "best_time", "last_time", "next_time", "remaining", "task", "warned")

    def __init__(self, task: str):
        self.task = task
        self.warned = False
        self.remaining = math.nan  # ‖e‖ when the warning was given
        self.reset(0.0)

    def reset(self, t: float) -> None:
        self.best, self.best_time, self.last_time, self.next_time = math.inf, t, t, t

    def observe(self, t: float, e: np.ndarray) -> None:
        """Look at the error ``e`` at time ``t`` (s); cheap between two checks."""
        if t < self.next_time and t >= self.last_time:
            return
        if t < self.last_time:  # a new simulation
            self.reset(t)
        self.last_time, self.next_time = t, t + CHECK_PERIOD
        norm = math.sqrt(float(e @ e)) if e.size else 0.0
        if norm < self.best * (1.0 - RELATIVE_PROGRESS) or norm < MIN_ERROR:
            self.best, self.best_time = norm, t
            self.warned, self.remaining = False, math.nan  # (progress: not stalled any more)
        elif not self.warned and t - self.best_time >= PATIENCE:
            self.warned, self.remaining = True, norm
            log.warning(
                "%s: t = %.2f s: the error has not decreased for %.1f s and stays at ‖e‖ = %.4g (m, rad): the "
                "target is out of reach, or a higher-priority task or a joint limit holds the task back "
                "(warned once)",
                self.task,
                t,
                t - self.best_time,
                norm,
            )


def stalled_tasks(diagram) -> dict[str, float]:
    """The tasks of ``diagram`` (a Drake ``Diagram``, searched through its subdiagrams) whose error
    stopped decreasing, by name, with the ``‖e‖`` they were left at (m, rad): what the scripts'
    ``summary.json`` reports as ``stalled_tasks`` (empty when every task made progress)."""
    stalled: dict[str, float] = {}
    for system in all_systems(diagram):
        watch = getattr(system, "_progress", None)
        if isinstance(watch, ProgressWatch) and watch.warned:
            stalled[watch.task] = float(watch.remaining)
    return stalled
