"""LAPACK for numba-compiled code: the routines of ``scipy.linalg.lapack`` called from compiled code.

The compiled solvers (:mod:`..equality_hierarchy`, :mod:`..active_bounds`, :mod:`.eqp`,
:mod:`.active_set`) run the same LAPACK factorizations as the ``scipy.linalg.lapack`` wrappers,
from the same library (``scipy.linalg.cython_lapack`` gives their C entry points), without a Python
call between them.
Each routine's address is registered with LLVM under a ``sotdrake_`` name when this module is
imported, and the compiled code calls that name rather than an address, so numba caches it on disk
(``cache=True``): a new process loads the compiled code instead of compiling it again. (numba
checks a cached function against its own file only: after a change to this file, delete the
``*.nbi`` and ``*.nbc`` files of ``sotdrake/hqp/kernels/__pycache__``, or the solvers keep the old code.)
The wrappers compile when first called (from Python or from a solver being compiled), not when this
module is imported: ``import sotdrake`` compiles nothing.

Every wrapper takes column-major (Fortran-ordered) float64 matrices and contiguous vectors of the
dtype LAPACK writes; any other array is refused while the call is typed (numba's ``TypingError``,
raised before LAPACK runs: nothing is written),
overwrites them as the LAPACK routine does (with ``NUMBA_DISABLE_JIT=1``, through
``scipy.linalg.lapack``'s routine of the same name), and returns LAPACK's ``info`` (0: success, < 0: a bad
argument, > 0: the routine's own failure). :func:`fortran` makes such a copy; :func:`contiguous`, :func:`upper_inverse`,
:func:`norm`, :func:`row_norms`, :func:`level_residuals` and :func:`certified_blocks` are the compiled solvers' shared helpers,
:func:`~sotdrake.compiled.compiled_input` the arrays they take.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from llvmlite import binding
from numba import config, njit, types
from numba.core.errors import TypingError
from numba.extending import get_cython_function_address, overload
from scipy.linalg import lapack as _lapack

_ARGUMENTS = {"dgeqrf": 8, "dgeqp3": 9, "dorgqr": 9, "dormqr": 13, "dtrtri": 6, "dtrtrs": 10}


def _declare(name: str) -> Any:  # (a numba type, called from compiled code only)
    symbol = f"sotdrake_{name}"
    binding.add_symbol(symbol, get_cython_function_address("scipy.linalg.cython_lapack", name))
    return types.ExternalFunction(symbol, types.void(*[types.voidptr] * _ARGUMENTS[name]))


_dgeqrf, _dgeqp3, _dorgqr, _dormqr, _dtrtri, _dtrtrs = (_declare(name) for name in _ARGUMENTS)


def _requirement(dtype: Any, ndim: int, layout: str, what: str) -> Any:
    """A function compiled code calls on an argument to refuse, while it is typed, any array other
    than a writable ``ndim``-D ``dtype`` of ``layout`` ('F': column-major, 'C': contiguous): LAPACK
    reads memory by its own layout, and another array's memory would be read as a wrong matrix."""

    def require(array):  # (called from compiled code only)
        pass

    @overload(require)
    def _typed(array):
        if not (isinstance(array, types.Array) and array.dtype == dtype and array.ndim == ndim and array.layout == layout
                and array.mutable):
            raise TypingError(f"LAPACK wrapper: expected {what}, got {array}")
        return lambda array: None

    return require


_matrix = _requirement(types.float64, 2, "F", "a column-major float64 matrix (lapack.fortran(a))")
_vector = _requirement(types.float64, 1, "C", "a contiguous float64 vector")
_pivots = _requirement(types.int32, 1, "C", "a contiguous int32 vector")

#: Workspace per column (LAPACK's block size is at most 64 for these routines on small matrices).
_BLOCK = 64


@njit(cache=True)
def _integer(value):
    """A Fortran ``INTEGER`` argument (32 bits: scipy's LAPACK)."""
    out = np.empty(1, np.int32)
    out[0] = value
    return out


@njit(cache=True)
def _character(code):
    """A Fortran ``CHARACTER`` argument, by its code (``ord('L')``)."""
    out = np.empty(1, np.uint8)
    out[0] = code
    return out


@njit(cache=True)
def fortran(a):
    """A column-major copy of the 2-D array ``a``."""
    out = np.empty((a.shape[1], a.shape[0])).T
    out[:, :] = a
    return out


@njit(cache=True)
def geqrf(a, tau):
    """QR ``A = Q R`` of ``a`` (m × n, column-major, overwritten as ``dgeqrf`` leaves it: R on and
    above the diagonal, the Householder vectors below); ``tau``: min(m, n) scales, written."""
    _matrix(a)
    _vector(tau)
    m, n = a.shape
    lwork = max(1, n) * _BLOCK
    work, info = np.empty(lwork), _integer(0)
    _dgeqrf(_integer(m).ctypes, _integer(n).ctypes, a.ctypes, _integer(max(1, m)).ctypes, tau.ctypes, work.ctypes,
            _integer(lwork).ctypes, info.ctypes)
    return info[0]


@njit(cache=True)
def geqp3(a, pivots, tau):
    """QR with column pivoting ``A Π = Q R`` (``dgeqp3``): ``a`` as :func:`geqrf`; ``pivots`` (n
    int32, zeros: every column free) receives Π's columns, 1-based."""
    _matrix(a)
    _pivots(pivots)
    _vector(tau)
    m, n = a.shape
    lwork = 2 * n + (n + 1) * _BLOCK
    work, info = np.empty(lwork), _integer(0)
    _dgeqp3(_integer(m).ctypes, _integer(n).ctypes, a.ctypes, _integer(max(1, m)).ctypes, pivots.ctypes, tau.ctypes,
            work.ctypes, _integer(lwork).ctypes, info.ctypes)
    return info[0]


@njit(cache=True)
def orgqr(a, k, tau):
    """``Q``'s first n columns from the first ``k`` reflectors of a :func:`geqrf` (``dorgqr``),
    written over ``a`` (m × n, m ≥ n ≥ k)."""
    _matrix(a)
    _vector(tau)
    m, n = a.shape
    lwork = max(1, n) * _BLOCK
    work, info = np.empty(lwork), _integer(0)
    _dorgqr(_integer(m).ctypes, _integer(n).ctypes, _integer(k).ctypes, a.ctypes, _integer(max(1, m)).ctypes, tau.ctypes,
            work.ctypes, _integer(lwork).ctypes, info.ctypes)
    return info[0]


@njit(cache=True)
def ormqr(a, tau, c, transposed):
    """``c ← Qᵀ c`` (``transposed``) or ``c ← Q c`` (``dormqr``, side L) with ``Q`` the product of the
    ``tau.size`` reflectors stored in ``a`` (a :func:`geqrf` or :func:`geqp3` output with ``c``'s row
    count)."""
    _matrix(a)
    _vector(tau)
    _matrix(c)
    m, columns = c.shape
    lwork = max(1, columns) * _BLOCK
    work, info = np.empty(lwork), _integer(0)
    _dormqr(_character(76).ctypes, _character(84 if transposed else 78).ctypes, _integer(m).ctypes, _integer(columns).ctypes,
            _integer(tau.size).ctypes, a.ctypes, _integer(max(1, a.shape[0])).ctypes, tau.ctypes, c.ctypes,
            _integer(max(1, m)).ctypes, work.ctypes, _integer(lwork).ctypes, info.ctypes)
    return info[0]


@njit(cache=True)
def trtri_upper(a):
    """``a ← a⁻¹`` on and above the diagonal of the square upper triangular ``a`` (``dtrtri``, non-unit
    diagonal; what lies below is neither read nor written); ``info > 0``: singular."""
    _matrix(a)
    n = a.shape[0]
    info = _integer(0)
    _dtrtri(_character(85).ctypes, _character(78).ctypes, _integer(n).ctypes, a.ctypes, _integer(max(1, n)).ctypes,
            info.ctypes)
    return info[0]


@njit(cache=True)
def trtrs_upper(a, b):
    """``b ← a⁻¹ b`` for the upper triangle of the square ``a`` (``dtrtrs``, no transpose, non-unit
    diagonal; ``b``: n × nrhs); ``info > 0``: singular."""
    _matrix(a)
    _matrix(b)
    n, columns = a.shape[0], b.shape[1]
    info = _integer(0)
    _dtrtrs(_character(85).ctypes, _character(78).ctypes, _character(78).ctypes, _integer(n).ctypes, _integer(columns).ctypes,
            a.ctypes, _integer(max(1, n)).ctypes, b.ctypes, _integer(max(1, n)).ctypes, info.ctypes)
    return info[0]


# With the JIT disabled (NUMBA_DISABLE_JIT=1, to run the compiled solvers as plain Python, e.g. to
# check them under another round-off) the LLVM symbols above are out of reach: called from Python
# they would do nothing. The wrappers are then these, which call scipy.linalg.lapack's routine of the
# same name and write its results over the same arguments, as the compiled ones do.
def _python_geqrf(a, tau):
    if a.size == 0:
        return np.int32(0)
    qr, tau_out, _, info = _lapack.dgeqrf(a)
    a[:, :], tau[:] = qr, tau_out
    return np.int32(info)


def _python_geqp3(a, pivots, tau):
    if a.size == 0:
        pivots[:] = np.arange(1, pivots.size + 1)
        return np.int32(0)
    qr, jpvt, tau_out, _, info = _lapack.dgeqp3(a)
    a[:, :], pivots[:], tau[:] = qr, jpvt, tau_out
    return np.int32(info)


def _python_orgqr(a, k, tau):
    if a.size == 0:
        return np.int32(0)
    q, _, info = _lapack.dorgqr(a, tau[:k], lwork=max(1, a.shape[1]) * _BLOCK)
    a[:, :] = q
    return np.int32(info)


def _python_ormqr(a, tau, c, transposed):
    if c.size == 0 or tau.size == 0:
        return np.int32(0)
    cq, _, info = _lapack.dormqr("L", "T" if transposed else "N", a[:, : tau.size], tau, c,
                                 lwork=max(1, c.shape[1]) * _BLOCK)
    c[:, :] = cq
    return np.int32(info)


def _python_trtri_upper(a):
    if a.size == 0:
        return np.int32(0)
    inverse, info = _lapack.dtrtri(a, lower=0, unitdiag=0)
    n = a.shape[0]
    upper = np.triu(np.ones((n, n), dtype=bool))
    a[upper] = inverse[upper]
    return np.int32(info)


def _python_trtrs_upper(a, b):
    if b.size == 0:
        return np.int32(0)
    x, info = _lapack.dtrtrs(a, b, lower=0, trans=0, unitdiag=0)
    b[:, :] = x
    return np.int32(info)


if config.DISABLE_JIT:  # type: ignore[attr-defined]
    globals().update({name: globals()[f"_python_{name}"] for name in ("geqrf", "geqp3", "orgqr", "ormqr", "trtri_upper", "trtrs_upper")})


@njit(cache=True)
def contiguous(a):
    """``a`` C-ordered (a copy when it is not): what the compiled ``@`` is fastest on."""
    return np.ascontiguousarray(a)


@njit(cache=True)
def level_residuals(A, b, x, sizes):
    """``(A x − b, each level's slack norm)`` for levels of ``sizes`` rows stacked in ``A``."""
    residual = A @ x - b
    norms = np.empty(sizes.size)
    start = 0
    for k in range(sizes.size):
        level = residual[start : start + sizes[k]]
        norms[k] = math.sqrt(level @ level)
        start += sizes[k]
    return residual, norms


@njit(cache=True)
def upper_inverse(R):
    """``(ok, R⁻¹)`` of the upper triangle of the square ``R`` (:func:`trtri_upper`; C-ordered, zeros
    below the diagonal; not ok when singular)."""
    k = R.shape[0]
    a = fortran(R)
    inverse = np.zeros((k, k))
    if trtri_upper(a) != 0:
        return False, inverse
    for j in range(k):
        for i in range(j + 1):
            inverse[i, j] = a[i, j]
    return True, inverse


@njit(cache=True)
def certified_blocks(R_inv, sizes, certified):
    """How many leading levels (of ``sizes`` rows) are certified: their diagonal block of the upper
    triangular ``R⁻¹`` has ``‖R_kk⁻¹‖_F < 1/certified``, so the level's rows have ``σ_min >
    certified`` in what the levels above leave free (a NaN is not certified)."""
    square = certified * certified
    limit = 1.0 / square if square > 0.0 else np.inf  # (a threshold of 0, or below 1e-154: no bound)
    count, start = 0, 0
    for size in sizes:
        block = 0.0
        for i in range(start, start + size):
            for j in range(i, start + size):
                block += R_inv[i, j] * R_inv[i, j]
        if not block < limit:  # (False on NaN too)
            break
        count += 1
        start += size
    return count


@njit(cache=True)
def norm(row):
    """The Euclidean norm of the vector ``row`` (a loop: a BLAS call per row costs more at these sizes)."""
    square = 0.0
    for value in row:
        square += value * value
    return math.sqrt(square)


@njit(cache=True)
def row_norms(A):
    """Each row's norm, 1 for a zero row (as :attr:`~.hqp.LevelRows.eq_norms`), compiled."""
    norms = np.empty(A.shape[0])
    for i in range(A.shape[0]):
        norms[i] = norm(A[i])
        if not norms[i] > 0.0:
            norms[i] = 1.0
    return norms
