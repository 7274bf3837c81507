"""SoT selection masks.

A mask is a string of ``'0'``/``'1'`` read **right to left**, as in the sot-core of the seed's scripts
(before 4.11.1, which reads left to right): the last character is component 0. For a 6D feature
with components ``(X, Y, Z, RX, RY, RZ)``, ``'000011'`` selects X and Y, ``'111'`` selects X, Y and Z,
``'111111'`` everything. A mask shorter than the feature is padded with zeros on the left; a longer
one is an error unless its extra characters are zeros.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .exceptions import MAX_COUNT, InvalidInput, check_count


def parse_selection(mask: str, dimension: int) -> np.ndarray:
    """Indices of the selected components of a ``dimension``-vector, in increasing order
    (a read-only array, cached: features call this every tick). A mask that is not a non-empty
    string of ``'0'`` and ``'1'``, or a dimension that is not an integer ≥ 1, is an :class:`InvalidInput`."""
    if not isinstance(mask, str):  # (before the cache, which would fail to hash a list)
        raise InvalidInput(f"selection mask must be a non-empty string of '0' and '1', got {mask!r:.100}")
    return _parse_selection(mask, check_count("selection: dimension", dimension, 1, MAX_COUNT))


@lru_cache(maxsize=256)
def _parse_selection(mask: str, dimension: int) -> np.ndarray:
    if not mask or set(mask) - {"0", "1"}:
        raise InvalidInput(f"selection mask must be a non-empty string of '0' and '1', got {mask!r:.100}")
    flags = [c == "1" for c in reversed(mask)]
    if any(flags[dimension:]):
        raise InvalidInput(
            f"selection mask {mask!r:.100} selects component {len(flags) - 1} of a {dimension}-vector"
        )
    selected = np.flatnonzero(flags[:dimension])
    if selected.size == 0:
        raise InvalidInput(f"selection mask {mask!r:.100} selects nothing")
    selected.flags.writeable = False
    return selected
