"""What every numba-compiled path shares: the arrays it takes and the notice of its compilation.

Compiled functions are cached on disk (``cache=True``): the first call after an install compiles
them, once, and says so in the log (:func:`announce_compilation`); later processes load them.
numba compiles a function again for every new kind of argument (another dtype, a read-only or
non-contiguous array), so their callers hand them :func:`compiled_input` arrays.
"""

from __future__ import annotations

import functools
import importlib
import logging
import os
import types
from collections.abc import Callable
from typing import Any

import numpy as np

log = logging.getLogger("sotdrake.compiled")


def compiled_input(a: Any, dtype: type = float) -> np.ndarray:
    """``a`` as the compiled functions take it: a C-ordered, writeable array of ``dtype``, a copy only
    when it is not (another kind of array, read-only or strided, would make numba compile them
    again). The flags are read first: ``np.require`` alone costs a few µs a call."""
    if type(a) is np.ndarray and a.dtype == dtype and a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.require(a, dtype=dtype, requirements=("C", "A", "W"))


def read_only(array: np.ndarray) -> np.ndarray:
    """``array`` made read-only, in place (a cached constant, the same object at every tick: nothing
    may write it; numba compiles once for read-only arrays, which stay of that kind)."""
    array.flags.writeable = False
    return array


@functools.cache
def announce_compilation(function: Any, what: str, duration: str) -> None:
    """Log that numba is about to compile ``function`` (a ``cache=True`` dispatcher) rather than load
    it from its cache on disk: the first call after an install (or a change of its file) waits
    ``duration`` for it. Looked at once per process (cached): callers may call it before every use."""
    try:
        cached = os.path.exists(function._cache._cache_file._index_path)  # numba's index of the cached code
    except AttributeError:  # another numba: say nothing
        cached = True
    if not cached:
        log.warning("compiling %s, once after an install (%s) …", what, duration)


def kernels(module: str, package: str | None, entry: str, what: str, duration: str) -> Callable[[], types.ModuleType]:
    """The one way a wing reaches its compiled kernels: a function that imports ``module`` (relative
    to ``package``, as ``importlib.import_module``) on its first call, announces the compilation of
    its function ``entry`` (:func:`announce_compilation`: ``what``, ``duration``) and returns the
    module; later calls return it at once. A process that never calls it never imports numba's code."""

    @functools.cache
    def load() -> types.ModuleType:
        loaded = importlib.import_module(module, package)
        announce_compilation(getattr(loaded, entry), what, duration)
        return loaded

    load.__doc__ = f"{module}, imported on the first call (compiled with numba: {what})."
    return load
