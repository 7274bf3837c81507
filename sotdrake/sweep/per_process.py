"""A per-process cache for case functions: what a case builds once and every later case in the same
process (the local engine, or one Ray worker) reuses, such as a diagram. It lives here, in an
importable module, so that it is never pickled with a case function sent to Ray workers: each
worker fills its own. Only for things whose content never changes a result (every case still
gets a fresh context)."""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import TypeVar

T = TypeVar("T")
_CACHE: dict[Hashable, object] = {}


def per_process(key: Hashable, build: Callable[[], T]) -> T:
    """``build()`` the first time ``key`` is asked for in this process, the same object after."""
    if key not in _CACHE:
        _CACHE[key] = build()
    return _CACHE[key]  # type: ignore[return-value]
