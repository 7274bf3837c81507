"""The parameter sets of a sweep: a full grid or a seeded random sample.

A *case* is a ``dict`` from parameter name to a plain value (float, int, str, bool). Cases are
numbered by their position in the list, the ``case`` column of the sweep's table. A sweep has at
most :data:`MAX_CASES` cases: :func:`grid` and :func:`random_cases` refuse more
(:class:`~sotdrake.exceptions.InvalidInput`) before building any.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence

import numpy as np

from ..exceptions import InvalidInput, all_numbers, check_count
from .table import check_parameter_name

Case = dict[str, object]
#: The most cases :func:`grid` and :func:`random_cases` make (each case a dict: about 100 MB of them).
MAX_CASES = 1_000_000


def _plain(value):
    """numpy scalars as Python ones, so that a table cell reads the same from any engine."""
    return value.item() if isinstance(value, np.generic) else value


def check_case_value(what: str, value: object) -> bool | int | float | str:
    """``value`` as a plain Python value (float, int, str, bool; a numpy scalar converted), else
    :class:`InvalidInput`: "``what`` holds <value> (<type>); a case value is …"."""
    plain = _plain(value)
    if not isinstance(plain, (bool, int, float, str)):
        raise InvalidInput(f"{what} holds {value!r:.60} ({type(value).__name__}); a case value is a "
                           "plain float, int, str or bool")
    return plain


def _check_values(name: str, values: Sequence) -> list:
    """The values of the axis ``name`` as plain Python values (float, int, str, bool; numpy scalars
    converted), else :class:`InvalidInput` naming the axis and the value."""
    return [check_case_value(f"grid: axis {name!r}", value) for value in values]


def grid(axes: Mapping[str, Sequence]) -> list[Case]:
    """Every combination of the values of ``axes`` (name → values: a non-empty list, tuple or array,
    not a 0-d one, of plain values: float, int, str, bool or numpy scalars of them; anything else
    is an :class:`InvalidInput` naming the axis), the last axis varying fastest
    (``itertools.product`` order): ``grid({'a': [1, 2], 'b': [0, 1]})`` gives
    ``(1, 0), (1, 1), (2, 0), (2, 1)``. More than :data:`MAX_CASES` combinations: refused before
    any is built."""
    if not isinstance(axes, Mapping):
        raise InvalidInput(f"grid: expected a dict of axis name → values, got {axes!r:.100}")
    if not axes:
        raise InvalidInput("grid: give at least one axis (name → values)")
    for name, values in axes.items():
        check_parameter_name(name, "grid")
        if (isinstance(values, (str, bytes)) or not isinstance(values, (Sequence, np.ndarray))
                or (isinstance(values, np.ndarray) and values.ndim == 0) or len(values) == 0):
            raise InvalidInput(f"grid: axis {name!r} needs a non-empty sequence of values (a list, a tuple, an array), "
                               f"got {values!r:.100}")
    count = math.prod(len(values) for values in axes.values())
    if count > MAX_CASES:
        sizes = " × ".join(str(len(values)) for values in axes.values())
        raise InvalidInput(f"grid: {sizes} = {count} cases; a sweep has at most {MAX_CASES} (MAX_CASES)")
    names = list(axes)
    columns = [_check_values(name, values) for name, values in axes.items()]
    return [dict(zip(names, combination, strict=True)) for combination in itertools.product(*columns)]


def random_cases(count: int, ranges: Mapping[str, tuple[float, float]], seed: int) -> list[Case]:
    """``count`` cases (an integer in [1, :data:`MAX_CASES`]) drawn uniformly in the box ``ranges``
    (name → (low, high)) by numpy's ``default_rng(seed)``: the same seed gives the same cases on any
    machine."""
    count = check_count("random_cases: count", count, 1, MAX_CASES)
    if not isinstance(ranges, Mapping) or not ranges:
        raise InvalidInput("random_cases: give at least one range (name → (low, high))")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InvalidInput(f"random_cases: seed must be an integer ≥ 0, got {seed!r}")
    for name, bounds in ranges.items():
        check_parameter_name(name, "random_cases")
        if not (isinstance(bounds, (Sequence, np.ndarray)) and len(bounds) == 2 and all_numbers(list(bounds))):
            raise InvalidInput(f"random_cases: range {name!r} is two numbers (low, high), got {bounds!r:.100}")
        low, high = (float(b) for b in bounds)
        if not (np.isfinite(high - low) and low <= high):  # (the width too: uniform draws need it finite)
            raise InvalidInput(f"random_cases: range {name!r} must be finite with low ≤ high, got {bounds!r}")
    rng = np.random.default_rng(seed)
    lows = np.array([float(b[0]) for b in ranges.values()])
    highs = np.array([float(b[1]) for b in ranges.values()])
    draws = rng.uniform(lows, highs, size=(count, len(ranges)))
    return [dict(zip(ranges, map(float, row), strict=False)) for row in draws]
