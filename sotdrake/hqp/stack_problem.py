"""One stack for the whole-stack paths (:mod:`.stack_paths`): :class:`StackProblem`, its arguments
converted and checked once, before any path is tried.

What does not depend on the number of variables is checked when the problem is made (the levels
are triples of real numbers, the bounds vectors, the damping a finite number ≥ 0, the start finite,
``held`` a pair of sequences of component indices ≥ 0); what does (the start's length) by
:func:`check_sizes`, which :func:`.stack_paths.solve_stack` calls before its first path. A path
therefore never meets an argument the stages would refuse by another name (a bare numpy error, or
an answer to a mistake).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..exceptions import InvalidInput
from .equality_hierarchy import StackedLevels
from .linalg import all_true
from .problem import ACTIVE_SET, FLOAT64, MAX_MAGNITUDE, LevelRows, check_damping, checked_bounds, floats
from .warm import WarmStart

_SIDES = ("lower", "upper")


@dataclass
class StackProblem:
    """One stack to solve: ``levels`` ``[(A_k, lower_k, upper_k), …]``, highest first (an equality
    level has ``lower_k is upper_k``), or the same levels already ``stacked`` (equalities only),
    the bounds ``x_lower ≤ x ≤ x_upper``, the damping ``μ`` of the last level (``‖w‖² + μ‖x −
    x_{k−1}‖²``, a finite number ≥ 0), the solver's name, the stages' start (None: 0), the warm start
    of the call, and ``held``: the components (indices ≥ 0) expected at their lower and at their upper
    bound (the QR sweep's first guess: a wrong guess costs another sweep, never the answer; an index
    ``≥ n`` is a guess of a larger problem whose first ``n`` variables are these, as ``SolverDyn``'s
    full problem's for its reduced one, and is not held). The arrays may be (nested) lists of real
    numbers (converted once here); ``levels`` that are not a sequence of triples, bounds that are not
    vectors of real numbers, a damping that is not a finite number ≥ 0, a start that is not finite real
    numbers and a ``held`` that is not a pair of sequences of integers ≥ 0 raise :class:`InvalidInput`
    here; the start's size against ``n`` is checked by :func:`check_sizes` before any path, the levels'
    values by the paths (:func:`what_is_wrong`)."""

    levels: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]]
    x_lower: np.ndarray
    x_upper: np.ndarray
    damping: float = 0.0
    solver: str = ACTIVE_SET
    start: np.ndarray | None = None
    warm: WarmStart | None = None
    held: tuple[Sequence[int], Sequence[int]] = ((), ())
    stacked: StackedLevels | None = None

    def __post_init__(self) -> None:
        levels = self.levels
        if self.stacked is None:
            if type(levels) is not list and (isinstance(levels, (str, bytes)) or not isinstance(levels, Sequence)):
                raise InvalidInput(f"StackProblem: levels: a sequence of (A, lower, upper) triples, got {levels!r:.100}")
            self.levels = _float_levels(levels)
        self.x_lower, self.x_upper = _bound("x_lower", self.x_lower), _bound("x_upper", self.x_upper)
        try:
            check_damping(self.damping)
        except InvalidInput as error:
            raise InvalidInput(f"StackProblem: {error}") from None
        if self.start is not None:
            start = self.start = floats("StackProblem: start", self.start)
            if start.ndim != 1 or not all_true(np.abs(start) <= MAX_MAGNITUDE):  # (False on NaN)
                raise InvalidInput(f"StackProblem: start must be a vector of finite numbers within ±{MAX_MAGNITUDE:g}, "
                                   f"got {self.start!r:.80}")
        _check_held(self.held)

    @property
    def equalities_only(self) -> bool:
        """Every level an equality (a level without rows, e.g. a collision level with no pair in
        range, counts as one)."""
        return self.stacked is not None or all(lower is upper or len(lower) == 0 for _, lower, upper in self.levels)


def _check_held(held: object) -> None:
    """:class:`InvalidInput` naming ``held`` unless it is a pair (tuple or list) of sequences (or
    integer arrays) of integers ≥ 0 (a bool is not an index)."""
    if not isinstance(held, tuple | list) or len(held) != 2:
        raise InvalidInput(f"StackProblem: held: a pair (components at their lower bound, at their upper bound) of "
                           f"index sequences, got {held!r:.80}")
    for side, indices in zip(_SIDES, held, strict=True):
        if isinstance(indices, np.ndarray):
            if indices.ndim != 1 or (indices.size and indices.dtype.kind not in "iu"):
                raise InvalidInput(f"StackProblem: held: the {side}-bound components must be integer indices, got {indices!r:.80}")
        elif isinstance(indices, (str, bytes)) or not isinstance(indices, Sequence):
            raise InvalidInput(f"StackProblem: held: the {side}-bound components must be a sequence of indices, "
                               f"got {indices!r:.80}")
        for index in indices:
            if isinstance(index, bool | np.bool_) or not isinstance(index, int | np.integer) or index < 0:
                raise InvalidInput(f"StackProblem: held: the {side}-bound components must be integers ≥ 0 (indices of "
                                   f"variables), got {index!r:.40} in {indices!r:.80}")


def check_sizes(problem: StackProblem, n: int) -> None:
    """:class:`InvalidInput` naming ``start`` unless ``problem``'s start (if given) has ``n`` components.
    (``held``'s indices past the variables are a guess of a larger problem, not a mistake: see
    :class:`StackProblem`.)"""
    start = problem.start
    if start is not None and start.shape != (n,):
        raise InvalidInput(f"StackProblem: start must be {n} finite numbers within ±{MAX_MAGNITUDE:g}, got {start.shape[0]} numbers")


def what_is_wrong(problem: StackProblem, n: int) -> str | None:
    """What keeps ``problem`` from being a stack the QP takes (the refusal of :class:`LevelRows` or
    of :func:`~.problem.checked_bounds`: a NaN, an infinite coefficient or equality value, a
    magnitude beyond ±1e150, bounds crossed), or None: asked only when no path answered, so that a
    path that gives up on bad input is not taken for a failure of the solver."""
    try:
        if problem.stacked is None:
            for k, level in enumerate(problem.levels):
                try:
                    LevelRows(*level)
                except InvalidInput as error:
                    raise InvalidInput(f"level {k}: {error}") from None
        checked_bounds(n, problem.x_lower, problem.x_upper)
    except InvalidInput as error:
        return str(error)
    return None


def _bound(what: str, value: object) -> np.ndarray:
    """A :class:`StackProblem`'s bound as a vector of floats, or :class:`InvalidInput` naming ``what``."""
    if type(value) is np.ndarray and value.dtype is FLOAT64 and value.ndim == 1:
        return value
    array = floats(f"StackProblem: {what}", value)
    if array.ndim != 1:
        raise InvalidInput(f"StackProblem: {what}: expected a vector of numbers (one per variable), got {value!r:.80}")
    return array


def _float_levels(levels: Sequence) -> Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``levels`` itself when they are triples of float64 arrays (the solvers' every call), else the
    triples with their arrays converted (an equality level's ``lower is upper`` kept), or
    :class:`InvalidInput` naming the level."""
    ndarray, float64 = np.ndarray, FLOAT64
    for level in levels:
        if type(level) is not tuple or len(level) != 3:
            break
        A, lower, upper = level
        if (type(A) is not ndarray or A.dtype is not float64 or type(lower) is not ndarray or lower.dtype is not float64
                or type(upper) is not ndarray or upper.dtype is not float64):
            break
    else:
        return levels
    converted = []
    for k, level in enumerate(levels):
        if not isinstance(level, tuple | list) or len(level) != 3:
            raise InvalidInput("StackProblem: levels are (A, lower, upper) triples (an equality level's lower is its "
                               f"upper), got {levels!r:.100}")
        A, lower, upper = level
        A_k, lower_k = floats(f"StackProblem: level {k}: A", A), floats(f"StackProblem: level {k}: lower", lower)
        converted.append((A_k, lower_k, lower_k if upper is lower else floats(f"StackProblem: level {k}: upper", upper)))
    return converted


