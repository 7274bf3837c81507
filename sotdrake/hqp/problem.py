"""The problem types of the hierarchical QP: a level's rows (:class:`LevelRows`), the answer
(:class:`HqpResult`), a built stage (:class:`Stage`), the names of the paths an answer reports, and
the rank-revealing linear algebra the stages share (:func:`null_space`, :func:`least_norm`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pydrake.solvers import ClarabelSolver, MathematicalProgram, OsqpSolver, SnoptSolver

from ..exceptions import InvalidInput, finite_number
from .linalg import QR_MIN_SIZE, all_true, any_true, independent_qr, scaled_least_squares, svd
from .tolerances import REPORTED_ACTIVE

_NO_ROW_MASK = np.zeros(0, dtype=bool)
_NO_ROW_MASK.flags.writeable = False

SOLVERS = {"clarabel": ClarabelSolver, "osqp": OsqpSolver, "snopt": SnoptSolver}
"""The Drake solvers a level can use (then polished by the active-set method)."""
ACTIVE_SET = "active-set"
"""The default path: the exact active-set method alone."""
ACTIVE_BOUNDS = "active-bounds"
"""How every stage was solved when the equality levels were solved at once from the guessed active
bounds (:mod:`.active_bounds`), part of the default path."""
MAX_MAGNITUDE = 1e150
"""The largest magnitude of a level's coefficient or finite side, of a finite bound and of a start:
the squared norms the solver forms overflow beyond about 1e154."""
KEPT_LAST_LEVEL = "kept the last level's point"
"""How the minimum-norm stage ended when every path failed on it: the last level's point, which is
in the optimal set (every level at its optimum, bounds held), kept instead of the minimum-norm one.
Seen on random stacks whose last level's exact optimum is about 1e14 in size, where no double holds
the held rows to the feasibility tolerance (tests/test_hqp.py)."""
ROUND_OFF_LIMITED = "a point that holds its rows to the feasibility tolerance of their terms"
"""Said in the fallbacks when every path of a level ended outside a hard row and one of their points
misses each hard row ``g`` by at most ``feasibility_tolerance · Σ_j |g_j| |y_j|``, the tolerance taken
relative to the size of the row's terms rather than of its bound (:meth:`HierarchicalQP._relative_miss`):
that point is the level's answer. The product ``g·y`` alone carries a round-off of up to
``γ_r Σ_j |g_j| |y_j|`` (Higham, ``γ_r = r ε / (1 − r ε)``, about 6e-15 for r = 28), and a
backward-stable solve of condition ``κ`` misses by about ``κ ε`` of that: the tolerance, 1e-9 by
default, stands five orders of magnitude above the product's round-off, so which side of it a point
falls on does not hang on the CPU's last bits. Seen on random stacks whose level has an exact optimum
of size 1e14, where the bound-relative tolerance is below what doubles can verify."""


def check_solver(name: str, what: str = "solver") -> str:
    """``name`` if it is ``"active-set"`` or one of :data:`SOLVERS`, else :class:`InvalidInput`
    naming ``what`` (a name that is not a string, e.g. a list of names, included)."""
    if isinstance(name, str) and (name == ACTIVE_SET or name in SOLVERS):
        return name
    raise InvalidInput(f"{what}: unknown QP solver {name!r:.80}; available: {[ACTIVE_SET, *sorted(SOLVERS)]}")


def checked_solvers(solver: str, level_solvers: Any) -> list[str]:
    """``level_solvers`` (None: none) as a list, after :func:`check_solver` of ``solver`` and of each
    of them; :class:`InvalidInput` for a string (not a list of names) or a non-sequence."""
    if isinstance(level_solvers, str):
        raise InvalidInput(f"level_solvers is a list of solver names, one per level, got the string {level_solvers!r:.60}: "
                           f"give [{level_solvers!r:.60}]")
    if level_solvers is not None and not isinstance(level_solvers, (Sequence, np.ndarray)):
        raise InvalidInput(f"level_solvers: a list of solver names, one per level (or None), got {level_solvers!r:.60}")
    check_solver(solver)
    names = [] if level_solvers is None else list(level_solvers)
    for name in names:
        check_solver(name, "level_solvers")
    return names


def check_damping(damping: Any) -> None:
    """:class:`InvalidInput` unless ``damping`` is a finite number ≥ 0 (a Python float first: the
    solvers' every call)."""
    if not (type(damping) is float and 0.0 <= damping < math.inf) and not (finite_number(damping) and damping >= 0):
        raise InvalidInput(f"damping must be a finite number ≥ 0, got {damping!r:.60}")


def beyond(values: np.ndarray) -> bool:
    """Whether a finite entry of ``values`` is beyond ±:data:`MAX_MAGNITUDE`."""
    large = np.abs(values) > MAX_MAGNITUDE
    return any_true(large) and any_true(large & np.isfinite(values))


def _row_norms(A: np.ndarray) -> np.ndarray:
    """Each row's norm, 1 for a zero row: the scale that puts the rows at unit norm for the rank
    decisions."""
    norms = np.sqrt(np.einsum("ij,ij->i", A, A))
    return np.where(norms > 0.0, norms, 1.0)


Extension = Callable[[MathematicalProgram, np.ndarray, bool], None]
"""``extend(prog, x, own)``: add costs and constraints to a level's program (``own=True``), or, on
the stages below it (``own=False``), the constraints that must keep holding there; ``x`` holds the
affine expressions of the variables (``x = x_{k-1} + Z y``)."""


def float_array(what: str, value: Any) -> np.ndarray:
    """``value`` as a float array (not copied when it is one), or :class:`InvalidInput` naming
    ``what`` when it is not real numbers (a string, a ragged list, complex numbers)."""
    try:
        complex_numbers = np.iscomplexobj(value)
        array = np.asarray(value, dtype=float) if not complex_numbers else None
    except (TypeError, ValueError):
        raise InvalidInput(f"{what} must be numbers (a matrix or vector of floats), got {value!r:.80}") from None
    if array is None:
        raise InvalidInput(f"{what} must be real numbers, got complex ones")
    return array


FLOAT64 = np.dtype(np.float64)
"""The dtype of the arrays the solvers hand over (compared by identity: ``==`` costs 70 ns)."""


def floats(what: str, value: Any) -> np.ndarray:
    """``value`` itself if it is a float64 array (the solvers' every call: no cost), else
    :func:`float_array` (a list converted, strings and complex numbers refused by ``what``)."""
    if type(value) is np.ndarray and value.dtype is FLOAT64:
        return value
    return float_array(what, value)


def float_arrays(what: str, items: Any) -> list[np.ndarray]:
    """``items`` (a sequence of arrays, one per level) as a list of float arrays: itself when it is a
    list of float64 arrays (no cost), else each converted by :func:`floats`, or :class:`InvalidInput`
    naming ``what`` (and the index of an item that is not real numbers)."""
    if type(items) is not list and (isinstance(items, (str, bytes)) or not isinstance(items, (Sequence, np.ndarray))):
        raise InvalidInput(f"{what}: a list of arrays, one per level, got {items!r:.80}")
    for item in items:
        if type(item) is not np.ndarray or item.dtype is not FLOAT64:
            return [floats(f"{what}[{k}]", item) for k, item in enumerate(items)]
    return items if type(items) is list else list(items)


def checked_bounds(n: int, x_lower: Any, x_upper: Any) -> tuple[np.ndarray, np.ndarray]:
    """``(x_lower, x_upper)`` as float arrays of ``n`` numbers, or :class:`InvalidInput` naming
    what is wrong: a NaN, a lower bound above its upper one, a fixed component (lower == upper)
    that is not finite, a finite bound beyond ±:data:`MAX_MAGNITUDE`."""
    x_lower, x_upper = float_array("bounds", x_lower), float_array("bounds", x_upper)
    if x_lower.shape != (n,) or x_upper.shape != (n,):
        raise InvalidInput(f"bounds must be {n} numbers without NaN")
    if not all_true(x_lower <= x_upper):  # (False on a NaN too: the cause is looked for only then)
        if any_true(np.isnan(x_lower) | np.isnan(x_upper)):
            raise InvalidInput(f"bounds must be {n} numbers without NaN")
        raise InvalidInput(f"lower bound above upper bound at {np.flatnonzero(x_lower > x_upper)}")
    if not all_true(np.isfinite(x_lower[x_lower == x_upper])):
        raise InvalidInput("a fixed component (lower == upper) needs a finite value")
    if beyond(x_lower) or beyond(x_upper):
        raise InvalidInput(f"a finite bound beyond ±{MAX_MAGNITUDE:g}")
    return x_lower, x_upper


class LevelRows:
    """Rows ``lower ≤ A x ≤ upper`` of one level (``lower[i] == upper[i]``: an equality row).

    ``extend`` (optional): a callback adding costs or constraints to this level's
    ``MathematicalProgram`` (see :data:`Extension`); such a level is solved by its Drake solver."""

    def __init__(self, A: np.ndarray, lower: np.ndarray, upper: np.ndarray, extend: Extension | None = None):
        same = upper is lower  # (a task's equality rows: one array of values, no order to check)
        A, lower = float_array("level rows: A", A), float_array("level rows: lower", lower)
        upper = lower if same else float_array("level rows: upper", upper)
        if extend is not None and not callable(extend):
            raise InvalidInput(f"level rows: extend must be a callable (program, x) or None, got {extend!r:.60}")
        if A.ndim != 2 or lower.shape != (A.shape[0],) or upper.shape != (A.shape[0],):
            raise InvalidInput(f"level rows: A {A.shape}, lower {lower.shape}, upper {upper.shape} do not fit")
        if same:
            if not all_true(np.abs(A) <= MAX_MAGNITUDE):  # (False on NaN)
                raise InvalidInput(f"level rows: NaN, infinite or beyond ±{MAX_MAGNITUDE:g} coefficients "
                                   "(A must be finite, lower/upper not NaN)")
            if not all_true(np.abs(lower) <= MAX_MAGNITUDE):
                raise InvalidInput(f"level rows: an equality row needs a finite value within ±{MAX_MAGNITUDE:g} "
                                   "(NaN, infinite or beyond)")
        else:
            ordered = lower <= upper  # False on a NaN side too: the cause is looked for only then
            if not all_true(np.abs(A) <= MAX_MAGNITUDE) or (not all_true(ordered) and any_true(np.isnan(lower) | np.isnan(upper))):
                raise InvalidInput(f"level rows: NaN, infinite or beyond ±{MAX_MAGNITUDE:g} coefficients "
                                   "(A must be finite, lower/upper not NaN)")
            if not all_true(ordered):
                raise InvalidInput(f"level rows: lower bound above upper bound in rows {np.flatnonzero(lower > upper)}")
            if beyond(lower) or beyond(upper):
                raise InvalidInput(f"level rows: a finite side beyond ±{MAX_MAGNITUDE:g}")
        self.A, self.lower, self.upper = A, lower, upper
        self.extend = extend
        # The split the solver reads at every stage, made once.
        self.all_equality = same or all_true(lower == upper)
        if self.all_equality:
            self.any_equality = len(A) > 0
            self.equality = np.ones(len(A), dtype=bool)
            self.inequality = _NO_ROW_MASK if len(A) == 0 else ~self.equality
            self.A_eq, self.b_eq = A, lower
            self.A_in, self.lower_in, self.upper_in = A[:0], lower[:0], upper[:0]
        else:
            self.equality = equality = lower == upper
            self.inequality = inequality = ~equality
            self.any_equality = any_true(equality)
            self.A_eq, self.b_eq = A[equality], lower[equality]
            self.A_in, self.lower_in, self.upper_in = A[inequality], lower[inequality], upper[inequality]
        if not same and not all_true(np.isfinite(self.b_eq)):
            raise InvalidInput("level rows: an equality row needs a finite value")

    @functools.cached_property
    def eq_norms(self) -> np.ndarray:
        """The norms of the equality rows (1 for a zero row): their reference norms."""
        return _row_norms(self.A_eq)

    @functools.cached_property
    def in_norms(self) -> np.ndarray:
        """The norms of the inequality rows (1 for a zero row): their reference norms once held."""
        return _row_norms(self.A_in) if len(self.A_in) else self.lower[:0]

    def slack(self, x: np.ndarray, r: np.ndarray | None = None) -> np.ndarray:
        """Signed residual ``A x - b`` on equality rows, violation ``≥ 0`` on inequality rows
        (``r``: ``A x`` if the caller has it)."""
        r = self.A @ x if r is None else r
        if self.all_equality:
            return r - self.lower
        violation = np.maximum(np.maximum(self.lower - r, r - self.upper), 0.0)
        return np.where(self.equality, r - self.lower, violation)


@dataclass
class HqpResult:
    x: np.ndarray
    slacks: list[np.ndarray]  # per level, see LevelRows.slack
    slack_norms: np.ndarray
    active_rows: list[np.ndarray]  # per level, inequality rows at one of their bounds
    active_bounds: np.ndarray  # components of x at one of their bounds (not the fixed ones)
    solve_time_s: float = 0.0
    level_solvers: list[str] = field(default_factory=list)  # per stage: "active-set" or "<drake solver>+polish"
    iterations: list[int] = field(default_factory=list)  # active-set iterations per stage (0: the guess held)
    fallbacks: list[str] = field(default_factory=list)  # why a path failed before the next one succeeded

    @property
    def solver_calls(self) -> int:
        """How many stages called a Drake solver."""
        return sum(name.split("+")[0] in SOLVERS for name in self.level_solvers)


def null_space(M: np.ndarray, threshold: float) -> np.ndarray:
    """Orthonormal basis of ``{y : M y = 0}``; ``M``'s rows are expected at unit (reference) norm
    and singular values ≤ ``threshold`` count as zero."""
    if M.shape[0] == 0:
        return np.eye(M.shape[1])
    _, sigma, Vt = svd(M)
    return Vt[int(np.count_nonzero(sigma > threshold)):].T


def least_norm(A: np.ndarray, b: np.ndarray, threshold: float) -> np.ndarray:
    """The minimum-norm least-squares solution of ``A x = b``: ``x = V_k Σ_k⁻¹ U_kᵀ b`` over the
    singular values ``σ > threshold`` (``A``'s rows are expected at unit reference norm, so the cut
    is the one absolute τ of every rank decision; the directions below it are left unmoved)."""
    U, sigma, Vt = svd(A, full_matrices=False)
    keep = sigma > threshold
    return Vt[keep].T @ ((U[:, keep].T @ b) / sigma[keep])


class _EqualityFactors:
    """A level's projected equality rows at unit norm, ``B = (A_eq Z) / ‖rows of A_eq‖`` (m × r),
    factorised once: the orthonormal basis ``null`` of ``{y : B y = 0}`` (the next levels' ``Z`` is
    ``Z @ null``) and the minimum-norm least-squares step :meth:`step`. Householder QR of ``Bᵀ`` if
    it proves every singular value of ``B`` above τ (:func:`~.linalg.independent_qr`: the rows
    are independent, the step solves them exactly), else the SVD cut at τ; both give the same
    subspace and step in exact arithmetic. A row of ``B`` of norm at most τ is fixed by the levels
    above (its residual is constant): it is zeroed first, so that its round-off, weighted back by its
    norm in the step, pulls ``y`` nowhere."""

    __slots__ = ("norms", "null", "qr", "rank", "svd")

    def __init__(self, B: np.ndarray, norms: np.ndarray, threshold: float):
        self.norms = norms
        m, r = B.shape
        constant = np.einsum("ij,ij->i", B, B) <= threshold * threshold
        if any_true(constant):  # rows the levels above fix: their round-off would pull the weighted step anywhere
            B = np.where(constant[:, None], 0.0, B)
        self.qr = independent_qr(B.T, threshold, full=True) if m >= QR_MIN_SIZE else None
        if self.qr is not None:
            self.null, self.rank = self.qr[0][:, m:], m
        else:
            U, sigma, Vt = svd(B)
            self.svd = (U, sigma, Vt)
            self.rank = rank = int(np.count_nonzero(sigma > threshold))
            self.null = Vt[rank:].T

    def step(self, rhs: np.ndarray) -> np.ndarray:
        """The minimum-norm ``y`` minimising ``‖A_eq Z y - rhs‖`` (rank decisions on ``B``)."""
        if self.qr is not None:  # B = Rᵀ Q1ᵀ: B y = rhs / norms exactly, y = Q1 R⁻ᵀ (rhs / norms)
            Q, R_inv = self.qr
            return Q[:, :self.rank] @ (R_inv.T @ (rhs / self.norms))
        U, sigma, Vt = self.svd
        return scaled_least_squares(U, sigma, Vt, self.rank, self.norms, rhs)



@dataclass
class Stage:
    """One stage in ``z = (y, w)``: min ½‖M z - t‖² s.t. lower ≤ G z ≤ upper (G unit rows)."""

    M: np.ndarray
    t: np.ndarray
    m_scale: np.ndarray
    G: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    z0: np.ndarray
    r: int
    hard: np.ndarray | None  # indices (into the full list of hard rows) of G's first rows (None: all of them)
    guess: np.ndarray  # a side per row of G
    m_hard: int = 0  # how many of G's first rows are hard rows
    kind: tuple[bool, bool] | None = None  # the objective's active_set.objective_kind, if known


NO_ACTIVE_ROWS = np.zeros(0, dtype=int)
"""The active rows of an equality-only level, shared by every answer (read only)."""
NO_ACTIVE_ROWS.flags.writeable = False


def result_of(levels, x: np.ndarray, x_lower: np.ndarray, x_upper: np.ndarray, fixed: np.ndarray, used: list[str]) -> HqpResult:
    """The answer at ``x``: each level's slack and the inequality rows at a bound, the components at
    a bound (not the ``fixed`` ones), within :data:`~.tolerances.REPORTED_ACTIVE` (relative above 1)."""
    slacks, active = [], []
    for level in levels:
        r = level.A @ x
        slacks.append(level.slack(x, r))
        if level.all_equality:
            active.append(NO_ACTIVE_ROWS)
            continue
        scale = REPORTED_ACTIVE * np.maximum(1.0, np.abs(r))
        at_bound = (np.abs(r - level.lower) <= scale) | (np.abs(r - level.upper) <= scale)
        active.append((at_bound & level.inequality).nonzero()[0])
    scale = REPORTED_ACTIVE * np.maximum(1.0, np.abs(x))
    bounds = (~fixed & ((np.abs(x - x_lower) <= scale) | (np.abs(x - x_upper) <= scale))).nonzero()[0]
    return HqpResult(
        x=x,
        slacks=slacks,
        slack_norms=np.array([math.sqrt(float(s @ s)) for s in slacks]),
        active_rows=active,
        active_bounds=bounds,
        level_solvers=used,
    )
