"""The warm-start state of a hierarchical QP: what one solve leaves for the next.

The answer of a solve does not depend on it to the tolerances (every path's point is checked the
same way), but which path answers does, and so do the last bits of the point. A system keeps it
in its Context (abstract state) and hands it to every solve, so that a cloned or reset Context
replays a run bit for bit.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np

BACK_OFF_LIMIT = 16
"""The most calls a whole-stack path skips after failing (:func:`back_off`)."""


def back_off(failures: int) -> int:
    """How many calls a whole-stack path skips after ``failures`` failed tries in a row (≥ 1):
    2^(f−1), at most :data:`BACK_OFF_LIMIT` (the active bounds' and the held rows' back-off)."""
    return min(2 ** (failures - 1), BACK_OFF_LIMIT)


#: Each whole-stack path's back-off fields in :class:`WarmStart`: ``(failures, skips)``.
BACK_OFFS = {"bounds": ("failures", "skips"), "row": ("row_failures", "row_skips"),
             "sweep": ("sweep_failures", "sweep_skips"), "inactive": ("inactive_failures", "inactive_skips")}


@dataclass
class WarmStart:
    """The state a :class:`~.solve.HierarchicalQP` reads and writes during a solve (``n``: its
    number of variables).

    ``working_sets``: each stage's working set at the last call with the same sizes (keyed by the
    stage's index and shapes), and under ``FREE_MINIMUM_NORM`` whether the last minimum-norm stage
    ended with an empty working set; ``bound_sides``: the side of each bound held at the last
    answer, or that answer ``(x, x_lower, x_upper)`` (read off when the next call needs it);
    ``row_sides``: the held-rows path's last answer's ``(layout, side of each inequality row)``
    (:func:`~.equality_stack.solve_held_rows`; None after a call it did not answer);
    ``failures``/``skips``: the active bounds' back-off (after f failed tries in a row, the next
    2^(f-1) calls, at most 16, skip them); ``row_failures``/``row_skips``: the same back-off for the
    held-rows path (:class:`~.stack_paths.HeldRows`), ``sweep_failures``/``sweep_skips`` for the
    warm QR sweep (:class:`~.stack_paths.WarmQrSweep`), ``inactive_failures``/``inactive_skips`` for
    the inactive rows (:class:`~.stack_paths.InactiveRows`)."""

    n: int
    working_sets: dict = field(default_factory=dict)
    bound_sides: np.ndarray | tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
    row_sides: tuple[bytes, np.ndarray] | None = None
    failures: int = 0
    skips: int = 0
    row_failures: int = 0
    row_skips: int = 0
    sweep_failures: int = 0
    sweep_skips: int = 0
    inactive_failures: int = 0
    inactive_skips: int = 0

    def __post_init__(self) -> None:
        if self.bound_sides is None:
            self.bound_sides = np.zeros(self.n, dtype=int)

    def clear(self) -> None:
        """Forget everything: the next solve is cold."""
        self.working_sets.clear()
        self.bound_sides = np.zeros(self.n, dtype=int)
        self.row_sides = None
        self.failures = self.skips = self.row_failures = self.row_skips = 0
        self.sweep_failures = self.sweep_skips = self.inactive_failures = self.inactive_skips = 0

    def skipped(self, path: str) -> bool:
        """Whether this call skips the whole-stack path ``path`` (a key of :data:`BACK_OFFS`: its
        back-off), counting the skip."""
        skips = BACK_OFFS[path][1]
        left = getattr(self, skips)
        if left:
            setattr(self, skips, left - 1)
        return left > 0

    def record(self, path: str, answered: bool) -> None:
        """The outcome of a try of ``path``: an answer resets its failures, a failure starts its back-off."""
        failures, skips = BACK_OFFS[path]
        count = 0 if answered else getattr(self, failures) + 1
        setattr(self, failures, count)
        if count:
            setattr(self, skips, back_off(count))

    def __deepcopy__(self, memo: dict) -> WarmStart:  # what a Context's clone calls
        return WarmStart(self.n, copy.deepcopy(self.working_sets, memo), copy.deepcopy(self.bound_sides, memo),
                         copy.deepcopy(self.row_sides, memo), self.failures, self.skips, self.row_failures, self.row_skips,
                         self.sweep_failures, self.sweep_skips, self.inactive_failures, self.inactive_skips)


class WarmStarts(dict):
    """The warm starts of a system that solves several problems (keyed by the system, e.g. by size):
    one abstract state of its Context. :meth:`of` gives (and creates) one."""

    def of(self, key: object, n: int) -> WarmStart:
        warm = self.get(key)
        if warm is None:
            warm = self[key] = WarmStart(n)
        return warm

    def __deepcopy__(self, memo: dict) -> WarmStarts:
        return WarmStarts({key: copy.deepcopy(value, memo) for key, value in self.items()})
