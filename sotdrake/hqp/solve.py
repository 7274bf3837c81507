"""Hierarchical QP (soth / sot-dyninv ``SolverKine``): strict priority, hard bounds, exact levels.

Variables ``x`` (size n). Hard constraints above every level: ``x_min ≤ x ≤ x_max``. Level k holds
rows ``lo_k ≤ A_k x ≤ hi_k`` (an equality row has ``lo = hi = b``) and solves::

    min_{x, w}  ‖w‖² (+ μ‖x - x_{k-1}‖² on the damped last level)
    s.t.        x_min ≤ x ≤ x_max
                every higher level j held at its optimum:
                    equality rows    A_j x = A_j x_j           (their optimal residual w_j*)
                    inequality rows  lo_j - w_j* ≤ A_j x ≤ hi_j + w_j*   (w_j* ≥ 0: optimal violation)
                lo_k - w ≤ A_k x ≤ hi_k + w

which is the LSE/LSI hierarchy (for an equality row the optimal ``|w|`` is ``|A x - b|``, for an
inequality row its violation). ``w*`` of a level is unique, the objective being strictly convex in
``w``. Last, unless ``regularize=False``, the minimum-norm ``x`` of the whole optimal set is taken.

How a level is solved:

* held equality rows and fixed bounds (``x_min = x_max``) are eliminated: ``x = x_{k-1} + Z y`` with
  ``Z`` an orthonormal basis of their null space, so they hold exactly and no solver ever sees a
  degenerate equality. The level's equality rows enter the objective, its inequality rows become
  constraints ``lo ≤ a y - w ≤ hi`` with one slack ``w`` each, and the bounds and held inequality
  rows are constraints on ``y``;
* the default path (``"active-set"``) is the exact primal active-set method of :mod:`.active_set`,
  started from the previous level's point (``y = 0``, feasible), and warm-started by a guess of the
  working set: the one this level had at the previous call with the same sizes (a cache: the answer
  is a function of the final working set only), else the active set of Goldfarb-Idnani's dual
  method on the level made strictly convex (DAQP's, or quadprog's on a level whose row weights spread
  beyond 10⁶), else (both refusing) the sides of the
  bounds and held rows active at the end of the level above. An equality-only level with no bound in the way is one
  least-squares step (from the factorisation, QR or SVD, that also gives the next ``Z``), checked against the bounds and
  held rows in ``x`` before any stage is built; the minimum-norm stage likewise tries its
  unconstrained point first when its previous call ended with an empty working set;
* before any stage, a stack of equality levels (no inequality row, no extension, no damping, the
  start inside the bounds) is tried at once from the bounds held at the previous answer
  (:mod:`.active_bounds`, reported as ``"active-bounds"`` for every stage): those bounds fixed, one
  QR of all the levels' unit rows gives the minimum-norm solution; it is kept only if every level is
  certified of full row rank (σ ≥ 10³ τ, so every level is met exactly) and the KKT conditions of
  the minimum-norm stage hold (the other bounds, the signs of the held bounds' multipliers), which
  make it the point the stages return. Up to three rounds release wrong-signed bounds and hold
  violated ones; otherwise the stages decide (after failures in a row the next calls skip the try:
  a back-off). :meth:`HierarchicalQP.solve_equalities` takes such a stack as plain arrays;
* a Drake solver (``"clarabel"``, ``"osqp"``, ``"snopt"``) can be chosen instead, for every level or
  per level: the level is then a ``MathematicalProgram`` in ``(y, w)``, and the solver's answer is
  *polished*: its active set is tried as the working-set guess of the same active-set method, which
  returns the exact optimum (from that guess if it satisfies the KKT conditions, else by iterating).
  A level whose rows carry an ``extend`` callback (a user's extra costs or constraints) goes through
  its ``MathematicalProgram`` and keeps the solver's answer (it is not a least-squares level any
  more); so do the stages below it, which receive the callback again with ``own=False`` to add
  the constraints that must keep holding (not the costs);
* nothing fails silently: if a path fails (no convergence, a non-finite point, a point outside the
  bounds by more than ``feasibility_tolerance``) the next one is tried: the active set warm, then
  cold (from the dual method's guess), then Clarabel polished, then OSQP polished; each failure is
  reported in :attr:`HqpResult.fallbacks`. If every path ended outside a hard row, a path's point
  that holds each hard row to the feasibility tolerance relative to the size of the row's terms
  (a point so large, 1e14 on some random stacks, that doubles cannot verify it closer to the bound)
  is the answer, said in the fallbacks (:data:`ROUND_OFF_LIMITED`); otherwise a :class:`SolverError`
  means all failed.

**The one threshold.** Every rank decision (the null space ``Z`` of the held equality rows, the
least-squares steps, the working-set matrices, which projected rows are constant) compares singular
values of matrices whose rows are scaled to unit norm (the norm of the row *before* projection, so
that a task already fixed by the levels above projects to round-off and is seen as zero) with one
absolute threshold τ, ``rank_threshold`` (default :data:`~.active_set.RANK_THRESHOLD` = 1e-8). No
library default cutoff is used.
"""

from __future__ import annotations

import functools
import itertools
import math
import time
import types
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from pydrake.solvers import (
    ClarabelSolver,
    MathematicalProgram,
    OsqpSolver,
    SnoptSolver,
    SolverOptions,
)

from ..compiled import announce_compilation, compiled_input
from ..exceptions import InvalidInput, SolverError
from .active_set import (
    QR_MIN_SIZE,
    RANK_THRESHOLD,
    ActiveSetFailure,
    all_true,
    any_true,
    daqp_guess,
    dual_guess,
    independent_qr,
    projection_guess,
    scaled_least_squares,
    solve_least_squares_qp,
    svd,
)
from .tolerances import (
    DEGENERATE_RETRY,
    FEASIBILITY,
    HELD_SIDE,
    REPORTED_ACTIVE,
    ROUND_OFF,
    SIDE,
    VERIFIED,
)
from .warm import WarmStart

SOLVERS = {"clarabel": ClarabelSolver, "osqp": OsqpSolver, "snopt": SnoptSolver}
"""The Drake solvers a level can use (then polished by the active-set method)."""
ACTIVE_SET = "active-set"
"""The default path: the exact active-set method alone."""
ACTIVE_BOUNDS = "active-bounds"
"""How every stage was solved when the equality levels were solved at once from the guessed active
bounds (:mod:`.active_bounds`), part of the default path."""
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


def check_solver(name: str) -> str:
    """``name`` if it is ``"active-set"`` or one of :data:`SOLVERS`, else :class:`InvalidInput`."""
    if name != ACTIVE_SET and name not in SOLVERS:
        raise InvalidInput(f"unknown QP solver {name!r}; available: {[ACTIVE_SET, *sorted(SOLVERS)]}")
    return name


def _options(name: str) -> SolverOptions:
    options = SolverOptions()
    settings = {
        "clarabel": {"tol_gap_abs": 1e-11, "tol_gap_rel": 1e-11, "tol_feas": 1e-11, "max_iter": 500},
        "osqp": {"eps_abs": 1e-9, "eps_rel": 1e-9, "polishing": 1, "max_iter": 50000},
        "snopt": {"Major optimality tolerance": 1e-10, "Major feasibility tolerance": 1e-10},
    }[name]
    solver_id = SOLVERS[name]().solver_id()
    for key, value in settings.items():
        options.SetOption(solver_id, key, value)
    return options


Extension = Callable[[MathematicalProgram, np.ndarray, bool], None]
"""``extend(prog, x, own)``: add costs and constraints to a level's program (``own=True``), or, on
the stages below it (``own=False``), the constraints that must keep holding there; ``x`` holds the
affine expressions of the variables (``x = x_{k-1} + Z y``)."""


class LevelRows:
    """Rows ``lower ≤ A x ≤ upper`` of one level (``lower[i] == upper[i]``: an equality row).

    ``extend`` (optional): a callback adding costs or constraints to this level's
    ``MathematicalProgram`` (see :data:`Extension`); such a level is solved by its Drake solver."""

    def __init__(self, A: np.ndarray, lower: np.ndarray, upper: np.ndarray, extend: Extension | None = None):
        same = upper is lower  # (a task's equality rows: one array of values, no order to check)
        A, lower = np.asarray(A, dtype=float), np.asarray(lower, dtype=float)
        upper = lower if same else np.asarray(upper, dtype=float)
        if A.ndim != 2 or lower.shape != (A.shape[0],) or upper.shape != (A.shape[0],):
            raise InvalidInput(f"level rows: A {A.shape}, lower {lower.shape}, upper {upper.shape} do not fit")
        if same:
            if not all_true(np.isfinite(A)):
                raise InvalidInput("level rows: NaN or infinite coefficients (A must be finite, lower/upper not NaN)")
            if not all_true(np.isfinite(lower)):
                raise InvalidInput("level rows: an equality row needs a finite value (NaN or infinite)")
        else:
            ordered = lower <= upper  # False on a NaN side too: the cause is looked for only then
            if not all_true(np.isfinite(A)) or (not all_true(ordered) and any_true(np.isnan(lower) | np.isnan(upper))):
                raise InvalidInput("level rows: NaN or infinite coefficients (A must be finite, lower/upper not NaN)")
            if not all_true(ordered):
                raise InvalidInput(f"level rows: lower bound above upper bound in rows {np.flatnonzero(lower > upper)}")
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


class _Program:
    """One cached program in (y, w): min ‖w‖² + μ‖y‖² (or ‖x0 + Z y‖²) s.t. the stacked rows
    ``lower ≤ [C, D] (y, w) ≤ upper`` (bounds, held inequalities and the level's rows)."""

    def __init__(self, r: int, m_constraints: int, m: int):
        self.prog = prog = MathematicalProgram()
        self.y = prog.NewContinuousVariables(r, "y")
        self.w = prog.NewContinuousVariables(m, "w")
        variables = np.concatenate([self.y, self.w])
        self.rows = prog.AddLinearConstraint(
            np.zeros((m_constraints, r + m)), np.zeros(m_constraints), np.zeros(m_constraints), variables
        ) if m_constraints else None
        self.cost = prog.AddQuadraticCost(np.eye(r + m), np.zeros(r + m), variables, is_convex=True)


_FREE_MINIMUM_NORM = "free minimum-norm stage"
_DAQP_SPREAD = 1e6
"""A level's cold guess comes from DAQP when its objective rows' reference norms are within this
factor (``MᵀM``'s weights within 1e12, where the Cholesky factor DAQP works on still holds digits);
beyond, from quadprog. Both are only guesses checked exactly; on the random stacks DAQP's costs
about a third of quadprog's (measured: median 27 against 79 µs on 1108 level stages)."""
_NO_ROWS = np.zeros(0, dtype=int)  # the active rows of an equality-only level (shared, read only)
_NO_ROWS.flags.writeable = False
_NO_ROW_MASK = np.zeros(0, dtype=bool)
_NO_ROW_MASK.flags.writeable = False
_WARM_PATHS = (ACTIVE_SET, "cold", "clarabel", "osqp")  # the default path's order, with a cached working set
_COLD_PATHS = (ACTIVE_SET, "clarabel", "osqp")
_OUTSIDE = "a point outside the bounds"
_REFINEMENTS = 2  # the round-off rescue's corrections, at most


_NO_LEVEL = (np.zeros((0, 0)), *[np.zeros(0)] * 2, np.zeros((0, 0)), *[np.zeros(0)] * 3)
"""The level's arrays given to :func:`.kernels.stage.build` for the minimum-norm stage (not read)."""


@functools.cache
def _jit_stage() -> types.ModuleType:
    """:mod:`.kernels.stage`, imported on the first stage (see :func:`_active_bounds_path`)."""
    from .kernels import stage as jit_stage

    announce_compilation(jit_stage.build, "the hierarchical QP's stage assembly", "about ten seconds")
    return jit_stage


@functools.cache
def _active_bounds_path() -> types.ModuleType:
    """:mod:`.active_bounds`, imported on the first solve (an equality stack's path, or an answer put
    on its bounds): it is compiled with numba."""
    from . import active_bounds

    announce_compilation(active_bounds._solve_stack, "the hierarchical QP's path for equality stacks", "about ten seconds")
    return active_bounds


def _start_inside(x_lower: np.ndarray, x_upper: np.ndarray, fixed: np.ndarray, start: np.ndarray | float) -> bool:
    """Whether the QP's start is inside the bounds of every free component (NaN bounds and bounds out
    of order fail: every comparison with NaN is False, and ``lower > upper`` cannot hold it); the
    compiled :func:`.active_bounds.solve_stack` makes the same check for the start 0."""
    return all_true(((x_lower <= start) & (x_upper >= start)) | fixed)


def _sides_at_bounds(x: np.ndarray, x_lower: np.ndarray, x_upper: np.ndarray, fixed: np.ndarray) -> np.ndarray:
    """+1 where ``x`` is at its (finite) upper bound, -1 at its lower bound (to 1e-9, relative
    above 1), 0 elsewhere and on the ``fixed`` components (those of the call the guess is for):
    the guess of :mod:`.active_bounds`."""
    upper = ~fixed & (x >= x_upper - FEASIBILITY * np.maximum(1.0, np.abs(x_upper))) & (x_upper < np.inf)
    lower = ~fixed & (x <= x_lower + FEASIBILITY * np.maximum(1.0, np.abs(x_lower))) & (x_lower > -np.inf)
    return np.where(upper, 1, np.where(lower, -1, 0))


def _row_norms(A: np.ndarray) -> np.ndarray:
    """Each row's norm, 1 for a zero row: the scale that puts the rows at unit norm for the rank
    decisions."""
    norms = np.sqrt(np.einsum("ij,ij->i", A, A))
    return np.where(norms > 0.0, norms, 1.0)


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
    it proves every singular value of ``B`` above τ (:func:`~.active_set.independent_qr`: the rows
    are independent, the step solves them exactly), else the SVD cut at τ; both give the same
    subspace and step in exact arithmetic."""

    __slots__ = ("norms", "null", "qr", "rank", "svd")

    def __init__(self, B: np.ndarray, norms: np.ndarray, threshold: float):
        self.norms = norms
        m, r = B.shape
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
class _Stage:
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


class HierarchicalQP:
    """Solve stacks of :class:`LevelRows` in strict priority (see the module docstring).

    ``solver``: ``"active-set"`` (default) or a Drake solver of :data:`SOLVERS`; ``level_solvers``
    overrides it per level; ``rank_threshold``: the τ of every rank decision; ``hold_tolerance``: a
    relative band added to the held optimal violation of inequality rows (0: held exactly);
    ``feasibility_tolerance``: the bound violation (on unit rows, relative above 1) beyond which a
    path's point is refused and the next path tried; ``regularize``: end with the minimum-norm stage."""

    def __init__(
        self,
        n: int,
        solver: str = ACTIVE_SET,
        level_solvers: Sequence[str] | None = None,
        hold_tolerance: float = 0.0,
        rank_threshold: float = RANK_THRESHOLD,
        regularize: bool = True,
        feasibility_tolerance: float = FEASIBILITY,
    ):
        for name in [solver, *(level_solvers or [])]:
            check_solver(name)
        if not (np.isfinite(rank_threshold) and rank_threshold > 0):
            raise InvalidInput(f"rank_threshold must be finite and > 0, got {rank_threshold}")
        if not (np.isfinite(hold_tolerance) and hold_tolerance >= 0):
            raise InvalidInput(f"hold_tolerance must be finite and ≥ 0, got {hold_tolerance}")
        self.n, self.solver, self.level_solvers = n, solver, list(level_solvers or [])
        self.hold_tolerance, self.rank_threshold, self.regularize = hold_tolerance, rank_threshold, regularize
        self.feasibility_tolerance = feasibility_tolerance
        self._programs: dict[tuple[int, int, int], _Program] = {}  # a cache: results never depend on it
        self._solvers: dict[str, tuple] = {}
        self._identity = np.eye(n)  # a constant (never written to)
        self._all_components = np.arange(n)  # the bound rows' indices when every component is bounded
        # The warm starts (see .warm): the call's ``warm``, else this object's own.
        self._own_warm = self._warm = WarmStart(n)

    def forget_warm_starts(self) -> None:
        """Drop every warm start of this object's own (the working sets, the held bounds' guess, the
        back-off), so that the next call without ``warm`` is solved cold. Results never depend on
        them to the tolerances; timings and the last bits do."""
        self._own_warm.clear()

    def _use(self, warm: WarmStart | None) -> None:
        if warm is None:
            self._warm = self._own_warm
        elif isinstance(warm, WarmStart) and warm.n == self.n:
            self._warm = warm
        else:
            raise InvalidInput(f"warm must be a WarmStart of {self.n} variables, got {warm!r:.80}")

    def _drake(self, name: str):
        if name not in self._solvers:
            self._solvers[name] = (SOLVERS[name](), _options(name))
        return self._solvers[name]

    def solve(
        self,
        levels: Sequence[LevelRows],
        x_lower: np.ndarray,
        x_upper: np.ndarray,
        damping: float = 0.0,
        solver: str | None = None,
        start: np.ndarray | None = None,
        warm: WarmStart | None = None,
    ) -> HqpResult:
        """Solve in strict priority; ``damping`` μ applies to the last level; ``solver`` overrides
        the default path for this call. Raises :class:`SolverError` naming the stage if every path
        fails (which the tests have never seen with consistent bounds).

        ``start`` (n numbers, default 0): the point the first level starts from. Each stage
        relaxes a hard bound that its starting point violates to that point (a joint already past
        its limit may stay there rather than be pushed off at once), so a bound that excludes the
        start is not enforced: give a start inside the bounds (e.g. ``clip(0, x_lower, x_upper)``)
        to have every bound hold.

        ``warm``: the warm-start state to read and update (:class:`~.warm.WarmStart` of ``n``
        variables, e.g. kept in a system's Context); default: this object's own."""
        solver = self.solver if solver is None else check_solver(solver)
        self._use(warm)
        n = self.n
        x_lower, x_upper = np.asarray(x_lower, dtype=float), np.asarray(x_upper, dtype=float)
        if x_lower.shape != (n,) or x_upper.shape != (n,):
            raise InvalidInput(f"bounds must be {n} numbers without NaN")
        if not all_true(x_lower <= x_upper):  # (False on a NaN too: the cause is looked for only then)
            if any_true(np.isnan(x_lower) | np.isnan(x_upper)):
                raise InvalidInput(f"bounds must be {n} numbers without NaN")
            raise InvalidInput(f"lower bound above upper bound at {np.flatnonzero(x_lower > x_upper)}")
        fixed = x_lower == x_upper
        if not all_true(np.isfinite(x_lower[fixed])):
            raise InvalidInput("a fixed component (lower == upper) needs a finite value")
        if not (np.isfinite(damping) and damping >= 0):
            raise InvalidInput(f"damping must be finite and ≥ 0, got {damping}")
        for level in levels:
            if level.A.shape[1] != n:
                raise InvalidInput(f"a level has {level.A.shape[1]} columns, expected {n}")
        if start is not None:
            start = np.asarray(start, dtype=float)
            if start.shape != (n,) or not all_true(np.isfinite(start)):
                raise InvalidInput(f"start must be {n} finite numbers")
        began = time.perf_counter()
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # ±∞ bounds: once here, not per operation
            if solver == ACTIVE_SET and self._equalities_only(levels, x_lower, x_upper, fixed, damping, start):
                result = self._try_active_bounds([level.A for level in levels], [level.lower for level in levels],
                                                 x_lower, x_upper, began)
                if result is not None:
                    return result
            result = self._solve_stages(levels, x_lower, x_upper, damping, solver, began, start)
            self._warm.bound_sides = (result.x, x_lower, x_upper)
            return result

    def _equalities_only(self, levels, x_lower, x_upper, fixed, damping, start) -> bool:
        """Whether :mod:`.active_bounds` may solve the stack: equality levels without extensions,
        the default path on every stage, the minimum-norm stage, no damping, and the start (0, or
        ``start``) inside the bounds of the free components (no bound is relaxed to it)."""
        for level in levels:
            if not level.all_equality or level.extend is not None:
                return False
        if not self.regularize or (damping > 0.0 and len(levels)) or any(name != ACTIVE_SET for name in self.level_solvers):
            return False
        return _start_inside(x_lower, x_upper, fixed, 0.0 if start is None else start)

    def solve_equalities(
        self,
        jacobians: Sequence[np.ndarray],
        values: Sequence[np.ndarray],
        x_lower: np.ndarray,
        x_upper: np.ndarray,
        damping: float = 0.0,
        warm: WarmStart | None = None,
    ) -> HqpResult | None:
        """The stack of equality levels ``jacobians[k] x = values[k]`` (highest first) by the active
        bounds alone (:mod:`.active_bounds`), without building :class:`LevelRows`: the answer of
        :meth:`solve` on the default path, or None when that path does not apply (another solver,
        damping, no minimum-norm stage, 0 outside the bounds) or does not verify; then :meth:`solve`
        decides. The values are not checked here (a NaN or an infinite entry makes the path fail
        and :meth:`solve`'s checks name it); shapes that do not fit give None. ``warm``: as :meth:`solve`'s."""
        n = self.n
        self._use(warm)
        if (self.solver != ACTIVE_SET or not self.regularize or any(name != ACTIVE_SET for name in self.level_solvers)
                or (damping != 0.0 and len(jacobians)) or len(values) != len(jacobians)):
            return None
        x_lower, x_upper = np.asarray(x_lower, dtype=float), np.asarray(x_upper, dtype=float)
        if x_lower.shape != (n,) or x_upper.shape != (n,):
            return None
        for J, value in zip(jacobians, values, strict=True):
            if J.ndim != 2 or J.shape[1] != n or value.shape != (J.shape[0],):
                return None
        return self._try_active_bounds(jacobians, values, x_lower, x_upper, time.perf_counter())

    def _try_active_bounds(self, jacobians, values, x_lower, x_upper, began) -> HqpResult | None:
        """:meth:`_solve_active_bounds` unless failures in a row make this call skip it (the
        back-off: after f failures, the next 2^(f-1) calls, at most 16, skip it; a call to which the
        path does not apply, 0 outside the bounds of a free component, is not counted)."""
        if self._warm.skips:
            with np.errstate(invalid="ignore"):
                if _start_inside(x_lower, x_upper, x_lower == x_upper, 0.0):
                    self._warm.skips -= 1
            return None
        return self._solve_active_bounds(jacobians, values, x_lower, x_upper, began)

    def _solve_active_bounds(self, jacobians, values, x_lower, x_upper, began) -> HqpResult | None:
        """The equality stack by :func:`~.active_bounds.solve_stack` from the bounds held at the last
        answer, or None (then the stages decide)."""
        path = _active_bounds_path()
        sizes = np.array([len(J) for J in jacobians], dtype=np.int64)
        if len(jacobians) == 1:
            A, b = jacobians[0], values[0]
        elif jacobians:
            A, b = np.concatenate(jacobians), np.concatenate(values)
        else:
            A, b = np.zeros((0, self.n)), np.zeros(0)
        guess = self._warm.bound_sides
        if isinstance(guess, tuple):  # the stages' last answer: the sides of the bounds it holds
            guess = _sides_at_bounds(guess[0], guess[1], guess[2], x_lower == x_upper)
        status, x, sides, residual, slack_norms, active_bounds = path.solve_stack(
            A, b, sizes, x_lower, x_upper, guess, certified=1e3 * self.rank_threshold,
            feasibility=min(VERIFIED, self.feasibility_tolerance), tolerance=self.feasibility_tolerance)
        if status == path.NOT_APPLICABLE:  # (0 outside the bounds of a free component, as _equalities_only)
            return None
        if status == path.NOT_VERIFIED:
            self._warm.failures += 1
            self._warm.skips = min(2 ** (self._warm.failures - 1), 16)
            return None
        self._warm.failures, self._warm.bound_sides = 0, sides
        slacks, start = [], 0
        for size in sizes.tolist():
            slacks.append(residual[start : start + size])
            start += size
        stages = len(jacobians) + 1
        return HqpResult(
            x=x,
            slacks=slacks,
            slack_norms=slack_norms,
            active_rows=[_NO_ROWS] * len(jacobians),
            active_bounds=active_bounds,
            solve_time_s=time.perf_counter() - began,
            level_solvers=[ACTIVE_BOUNDS] * stages,
            iterations=[0] * stages,
        )

    def _solve_stages(self, levels, x_lower, x_upper, damping, solver, began, start=None) -> HqpResult:
        n = self.n
        fixed = x_lower == x_upper
        origin = 0.0 if start is None else start
        if any_true(fixed):
            x = np.where(fixed, x_lower, origin)
            Z = self._identity[:, ~fixed]
        elif start is None:
            x, Z = np.zeros(n), self._identity  # (read only: every later Z is a new array)
        else:
            x, Z = start.copy(), self._identity
        free = (~fixed & (np.isfinite(x_lower) | np.isfinite(x_upper))).nonzero()[0]  # bound rows that can bind
        # The hard rows, in x, with the side each was left at: the bounds of the free components (unit
        # rows, kept as indices), then the held inequality rows (their matrix: held).
        held, hard_lower, hard_upper = np.zeros((0, n)), x_lower[free], x_upper[free]
        hard_norms = np.ones(len(free))  # reference norms of the hard rows
        hard_side = np.zeros(len(free), dtype=int)
        if len(free) == n:  # every component bounded: its rows are read as views, not copied
            free = slice(None)
        used: list[str] = []
        iterations: list[int] = []
        carried: list[Extension] = []
        fallbacks: list[str] = []
        stages = list(levels) + ([None] if self.regularize else [])
        for k, level in enumerate(stages):
            mu = damping if k == len(levels) - 1 else 0.0
            name = self.level_solvers[k] if k < len(self.level_solvers) and level is not None else solver
            hard = (free, hard_norms, held, hard_lower, hard_upper, hard_side)
            # One factorisation of the level's (unit-row) projected equality rows: its null space is the
            # next levels' Z, and an equality-only level may be solved by its least-squares step alone.
            eq_factors = None
            if level is not None and level.any_equality and Z.shape[1]:
                norms = level.eq_norms
                eq_factors = _EqualityFactors(level.A_eq @ Z / norms[:, None], norms, self.rank_threshold)
            x, side, how, count = self._stage(k, level, x, Z, hard, mu, name, carried, fallbacks, eq_factors)
            if level is not None and level.extend is not None:
                carried.append(level.extend)
            used.append(how)
            iterations.append(count)
            if level is None:
                break
            hard_side = side
            if eq_factors is not None:  # = null_space(A_eq Z / ‖rows of A_eq‖), the same factorisation
                Z = Z @ eq_factors.null
            elif level.any_equality:
                Z = Z[:, :0]
            if not level.all_equality:
                A_in, lo, hi = level.A_in, level.lower_in, level.upper_in
                value = A_in @ x
                slack = np.maximum(np.maximum(lo - value, value - hi), 0.0)
                magnitude = np.maximum(1.0, np.abs(value))
                row_side = np.where(value >= hi - HELD_SIDE * magnitude, 1, np.where(value <= lo + HELD_SIDE * magnitude, -1, 0))
                held = np.concatenate([held, A_in])
                hard_norms = np.concatenate([hard_norms, level.in_norms])
                if self.hold_tolerance:
                    slack = slack + self.hold_tolerance * magnitude
                hard_lower = np.concatenate([hard_lower, lo - slack])
                hard_upper = np.concatenate([hard_upper, hi + slack])
                hard_side = np.concatenate([hard_side, row_side])
        result = self._result(levels, self._onto_bounds(x, x_lower, x_upper), x_lower, x_upper, fixed, used)
        result.iterations = iterations
        result.fallbacks = fallbacks
        result.solve_time_s = time.perf_counter() - began
        return result

    # --- one stage --------------------------------------------------------------------------
    def _build(self, level, x0, Z, hard, mu) -> _Stage:
        """The stage in ``z = (y, w)`` (see :class:`_Stage` and :mod:`.kernels.stage`), rows scaled to unit
        norm, assembled by compiled code."""
        free, reference, held, hard_lower, hard_upper, hard_side = hard
        compiled, given = _jit_stage(), compiled_input
        if isinstance(free, slice):  # every component bounded
            free = self._all_components
        rows = _NO_LEVEL if level is None else (
            given(level.A_eq), given(level.b_eq), given(level.eq_norms), given(level.A_in), given(level.lower_in),
            given(level.upper_in), given(level.in_norms))
        M, t, m_scale, G, lower, upper, z0, kept, all_kept, guess, m_hard, identity, uniform = compiled.build(
            level is not None, *rows, given(x0), given(Z), given(free, np.int64), given(reference), given(held),
            given(hard_lower), given(hard_upper), given(hard_side, np.int64), float(mu), float(self.rank_threshold))
        return _Stage(M, t, m_scale, G, lower, upper, z0, Z.shape[1], None if all_kept else kept, guess, m_hard,
                      (identity, uniform))

    def _stage(self, k, level, x0, Z, hard, mu, name, carried, fallbacks, eq_factors=None):
        """One level (or the minimum-norm stage when ``level`` is None): x, the sides of the hard
        rows at the end, how it was solved, the active-set iterations. ``eq_factors``: the
        :class:`_EqualityFactors` of the level's unit-row projected equality rows, if it has some."""
        r = Z.shape[1]
        if r == 0:
            return x0, hard[5].copy(), ACTIVE_SET, 0
        if (eq_factors is not None and name == ACTIVE_SET and mu == 0.0 and level.extend is None and not carried
                and level.all_equality):
            x = self._least_squares_level(level, x0, Z, hard, eq_factors)
            if x is not None:
                return x, np.zeros(len(hard[5]), dtype=int), ACTIVE_SET, 0
        if level is None and name == ACTIVE_SET and not carried and self._warm.working_sets.get(_FREE_MINIMUM_NORM, False):
            # The minimum-norm stage's unconstrained point y = -Zᵀx0 (x0's component in range(Z)
            # removed), tried while the last such stage ended with an empty working set (a warm
            # start: a cold solve, where it rarely holds, does not try it).
            x = self._free_step(x0, Z, hard, -(Z.T @ x0))
            if x is not None:
                return x, np.zeros(len(hard[5]), dtype=int), ACTIVE_SET, 0
        stage = self._build(level, x0, Z, hard, mu)
        hard_side = hard[5]
        key = (k, level is None, stage.G.shape, stage.M.shape)
        cached = self._warm.working_sets.get(key)
        guess = cached if cached is not None else stage.guess
        what = "the minimum-norm stage" if level is None else f"level {k}"
        failures: list[str] = []
        if (level is not None and level.extend is not None) or carried:
            drake_name = name if name in SOLVERS else "clarabel"
            for attempt in dict.fromkeys([drake_name, "osqp"]):
                x, message = self._program(level, x0, Z, hard, mu, attempt, carried)
                if x is not None and self._bounds_hold(stage, Z.T @ (x - x0)):
                    side = self._sides(stage, np.concatenate([Z.T @ (x - x0), np.zeros(len(stage.z0) - r)]))
                    return x, self._hard_sides(hard_side, stage, side), attempt, 0
                failures.append(f"{attempt}: {message}")
            raise SolverError(f"hierarchical QP: no solution on {what} ({'; '.join(failures)})")
        # The active set warm (the cached working set), then cold (the dual method's guess) if the
        # warm path failed, then the Drake solvers polished.
        paths: Sequence[str]
        if name == ACTIVE_SET:
            paths = _WARM_PATHS if cached is not None else _COLD_PATHS
        else:
            first = [name, ACTIVE_SET] + (["cold"] if cached is not None else [])
            paths = first + [p for p in ("clarabel", "osqp") if p not in first]
        working: dict[str, float] = {}  # the degenerate retries' working-set thresholds
        outside: list[tuple] = []  # the finite points the paths ended with outside the hard rows

        def retries():  # reached once the active set's paths have failed (see DEGENERATE_RETRY)
            if any(failure.endswith(_OUTSIDE) for failure in failures):
                for fraction in DEGENERATE_RETRY:
                    retry = f"active-set (working set at {fraction:g} τ)"
                    working[retry] = fraction * self.rank_threshold
                    yield retry

        if name == ACTIVE_SET:  # the retries right after the active set's paths: the Drake solvers cost far more
            split = sum(path in (ACTIVE_SET, "cold") for path in paths)
            order = itertools.chain(paths[:split], retries(), paths[split:])
        else:
            order = itertools.chain(paths, retries())
        for path in order:
            try:
                valid = False  # whether no row of the guess is held at an infinite side
                if path in (ACTIVE_SET, "cold") or path in working:
                    start_guess, label = guess, (path if path in working else ACTIVE_SET)
                    if cached is None or path != ACTIVE_SET:  # no warm start: ask the compiled dual method
                        start_guess = stage.guess
                        dual, valid = ((projection_guess(stage.t, stage.G, stage.lower, stage.upper), False) if level is None
                                       else self._level_guess(stage))
                        if dual is not None:
                            start_guess = dual
                        else:
                            valid = False
                else:
                    x, message = self._program(level, x0, Z, hard, mu, path)
                    if x is None:
                        failures.append(f"{path}: {message}")
                        continue
                    y = Z.T @ (x - x0)
                    z = np.concatenate([y, stage.z0[r:]])
                    if level is not None and len(stage.z0) > r:  # the level's slacks, from its rows
                        A_in = level.A[~level.equality]
                        value = A_in @ x
                        z[r:] = value - np.clip(value, level.lower[~level.equality], level.upper[~level.equality])
                    start_guess, label = self._sides(stage, z), path + "+polish"
                solution = solve_least_squares_qp(
                    stage.M, stage.t, stage.m_scale, stage.G, stage.lower, stage.upper, stage.z0,
                    guess=start_guess, threshold=self.rank_threshold, errstate=False, kind=stage.kind, guess_valid=valid,
                    working_threshold=working.get(path),
                    max_iterations=(2 * (len(stage.G) + len(stage.z0)) + 50) if path in working else None,
                )
            except ActiveSetFailure as error:
                failures.append(f"{path}: {error}")
                continue
            y = solution.z[:r]
            # A point the active set verified on every row to 1e-10 (≤ the feasibility tolerance)
            # only needs to be finite; any other is checked on the bounds and held rows.
            verified = solution.verified and self.feasibility_tolerance >= VERIFIED
            if not (all_true(np.isfinite(y)) if verified else self._accept(stage, y)):
                corrected = self._onto_hard_rows(stage, y, solution.side)
                if corrected is None:
                    failures.append(f"{path}: {_OUTSIDE}")
                    if level is not None and all_true(np.isfinite(y)):
                        outside.append((y, solution.side, label, solution.iterations))
                    continue
                y = corrected
            self._warm.working_sets[key] = solution.side
            if level is None:
                self._warm.working_sets[_FREE_MINIMUM_NORM] = not any_true(solution.side)
            if failures:
                fallbacks += [f"{what}: {failure}" for failure in failures]
            return x0 + Z @ y, self._hard_sides(hard_side, stage, solution.side), label, solution.iterations
        if level is None:
            # Every path failed on the minimum-norm stage: the last level's point, which its stage
            # verified (every level at its optimum, the bounds and held rows kept), is a point of the
            # optimal set; it is kept and only the minimum norm is given up (said in the fallbacks).
            fallbacks += [f"{what}: {failure}" for failure in failures]
            return x0, hard_side.copy(), KEPT_LAST_LEVEL, 0
        if outside:
            # Every path ended outside a hard row. If one of their points holds each row to the
            # feasibility tolerance relative to the row's terms (a point so large that doubles cannot
            # verify it closer to the bound), it is the answer, said in the fallbacks.
            misses = [self._relative_miss(stage, candidate[0]) for candidate in outside]
            miss = min(misses)
            if miss <= 1.0:
                y, side, label, count = outside[misses.index(miss)]
                fallbacks += [f"{what}: {failure}" for failure in failures]
                fallbacks.append(f"{what}: {ROUND_OFF_LIMITED} (size {float(np.max(np.abs(y))):.3g}, "
                                 f"{miss:.2g} of the tolerance)")
                self._warm.working_sets[key] = side
                return x0 + Z @ y, self._hard_sides(hard_side, stage, side), label, count
        raise SolverError(f"hierarchical QP: no solution on {what} ({'; '.join(failures)})")

    @staticmethod
    def _level_guess(stage: _Stage) -> tuple[np.ndarray | None, bool]:
        """The cold guess of a level's working set: DAQP's (:func:`~.active_set.daqp_guess`) when the
        objective's rows are of comparable weights (reference norms within :data:`_DAQP_SPREAD`),
        else quadprog's (:func:`~.active_set.dual_guess`). On a level whose weights spread further
        the two guesses can lead to different points of a numerically flat optimum (the same
        objective to 9 digits), and the levels below then differ: quadprog's is kept there. With
        whether the guess is valid as it is (quadprog's holds no row at an infinite side: those sides
        are not given to it; DAQP's sides are checked by the active set)."""
        m_scale = stage.m_scale
        if len(m_scale) and float(m_scale.max()) <= _DAQP_SPREAD * float(m_scale.min()):
            return daqp_guess(stage.M, stage.t, stage.G, stage.lower, stage.upper), False
        return dual_guess(stage.M, stage.t, stage.G, stage.lower, stage.upper), True

    def _least_squares_level(self, level, x0, Z, hard, eq_factors) -> np.ndarray | None:
        """An equality-only level by its least-squares step alone, or None: the EQP point of the
        empty working set (the minimum-norm weighted least-squares step, from the level's SVD) is
        the level's optimum if it satisfies the bounds and held rows (the KKT conditions with no
        multiplier). The check is the stage's own (unit rows, the constant rows left out, 1e-10
        absolute, relative above 1), written in x: a hard row ``c`` of projected norm ``s = ‖c Z‖``
        with the step ``d = Z y`` must satisfy ``lo - c·x0 - 1e-10·max(s, |lo - c·x0|) ≤ c·d``
        (and the same at the upper side), ``lo`` relaxed to ``c·x0`` where x0 is outside. A step
        that meets every row exactly passes it without the norms being computed."""
        y = eq_factors.step(level.lower - level.A @ x0) if eq_factors.rank else np.zeros(Z.shape[1])
        return self._free_step(x0, Z, hard, y)

    def _free_step(self, x0, Z, hard, y) -> np.ndarray | None:
        """``x0 + Z y`` if the step ``y`` (the EQP point of a stage's empty working set) is finite and
        satisfies the stage's bounds and held rows (see :meth:`_least_squares_level`), else None."""
        if not all_true(np.isfinite(y)):
            return None
        free, reference, held, hard_lower, hard_upper, _ = hard
        d = Z @ y  # the step in x: a hard row c (a bound's unit row, or a held row) changes by c·d
        if len(held):
            change = np.concatenate([d[free], held @ d])
            offset = np.concatenate([x0[free], held @ x0])
        else:
            change, offset = d[free], x0[free]
        lo = np.minimum(hard_lower, offset) - offset
        hi = np.maximum(hard_upper, offset) - offset
        if not (all_true(change >= lo) and all_true(change <= hi)):
            C = np.concatenate([Z[free], held @ Z]) if len(held) else Z[free]
            scale = np.sqrt(np.einsum("ij,ij->i", C, C))
            keep = scale > self.rank_threshold * reference
            if any_true(keep & (lo == hi)):  # a pinned row: the general path holds it in the working set
                return None
            if any_true(keep & ((change < lo - VERIFIED * np.maximum(scale, np.abs(lo)))
                                | (change > hi + VERIFIED * np.maximum(scale, np.abs(hi))))):
                return None
        return x0 + d

    def _accept(self, stage: _Stage, y: np.ndarray) -> bool:
        """A path's point is kept if it is finite and inside the bounds."""
        return all_true(np.isfinite(y)) and self._bounds_hold(stage, y)

    def _onto_hard_rows(self, stage: _Stage, y: np.ndarray, side: np.ndarray) -> np.ndarray | None:
        """A point that misses hard rows by round-off only, moved onto them: the least-norm correction
        ``δ`` that puts the rows of the working set (``side``) and the missed rows at their sides,
        at most :data:`_REFINEMENTS` times; None when a row is missed by more than
        :data:`ROUND_OFF` relative to the point's size, or the correction would move it by more
        than ten times that (not round-off: the next path decides), or it does not bring every hard
        row within the feasibility tolerance. The active set's solves lose about ``cond · ε`` of a
        point's size: on a stage whose point is hundreds of times its rows' targets, a few 1e-9 on a
        bound row (level 5 of a TALOS stack with a task held against its limits)."""
        if not all_true(np.isfinite(y)):
            return None
        m, r = stage.m_hard, stage.r
        G, lower, upper = stage.G[:m, :r], stage.lower[:m], stage.upper[:m]
        held = side[:m]
        for corrections in range(_REFINEMENTS + 1):
            value, below, above = self._missed_hard_rows(stage, y)
            if not any_true(below | above):
                return y
            if corrections == _REFINEMENTS:
                return None
            missed = float(np.max(np.where(below, lower - value, np.where(above, value - upper, 0.0))))
            if not missed <= ROUND_OFF * max(1.0, float(np.max(np.abs(y)))):
                return None
            at_lower = ((held < 0) | below) & np.isfinite(lower)
            at_upper = ((held > 0) | above) & np.isfinite(upper) & ~at_lower
            rows = at_lower | at_upper
            target = np.where(at_lower, lower, upper)[rows]
            A = G[rows]
            correction = least_norm(A, target - A @ y, self.rank_threshold)
            if not float(np.max(np.abs(correction))) <= 10.0 * ROUND_OFF * max(1.0, float(np.max(np.abs(y)))):
                return None  # nearly dependent rows asked to move the point further than round-off
            y = y + correction
        return None

    def _relative_miss(self, stage: _Stage, y: np.ndarray) -> float:
        """The largest miss of a hard row beyond the feasibility tolerance, as a fraction of that
        tolerance taken relative to the size of the row's terms, ``tol · Σ_j |g_j| |y_j|``: ≤ 1 when
        ``y`` holds every hard row to the tolerance relative to its terms (see
        :data:`ROUND_OFF_LIMITED`). A unit bound row's product is exact (its terms are one
        component), so it is held to ``tol · |y_i|``. Only reached when every path ended outside."""
        value, below, above = self._missed_hard_rows(stage, y)
        m_hard, r = stage.m_hard, stage.r
        lo, hi = stage.lower[:m_hard], stage.upper[:m_hard]
        tol = self.feasibility_tolerance
        miss = np.where(below, lo - tol * np.maximum(1.0, np.abs(lo)) - value,
                        np.where(above, value - hi - tol * np.maximum(1.0, np.abs(hi)), 0.0))
        missed = miss > 0.0
        if not any_true(missed):
            return 0.0
        scale = tol * (np.abs(stage.G[:m_hard, :r]) @ np.abs(y))
        return float(np.max(miss[missed] / np.maximum(scale[missed], np.finfo(float).tiny)))

    def _bounds_hold(self, stage: _Stage, y: np.ndarray) -> bool:
        _, below, above = self._missed_hard_rows(stage, y)
        return not any_true(below | above)

    def _missed_hard_rows(self, stage: _Stage, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The hard rows' values at ``y`` and the rows missed below and above by more than the
        feasibility tolerance (relative above 1; a NaN value misses both)."""
        m_hard = stage.m_hard
        value = stage.G[:m_hard, :stage.r] @ y
        lo, hi = stage.lower[:m_hard], stage.upper[:m_hard]
        tol = self.feasibility_tolerance
        return value, ~(value >= lo - tol * np.maximum(1.0, np.abs(lo))), ~(value <= hi + tol * np.maximum(1.0, np.abs(hi)))

    @staticmethod
    def _sides(stage: _Stage, z: np.ndarray, tolerance: float = SIDE) -> np.ndarray:
        value = stage.G @ z
        near = tolerance * np.maximum(1.0, np.abs(value))
        return np.where(value >= stage.upper - near, 1, np.where(value <= stage.lower + near, -1, 0))

    @staticmethod
    def _hard_sides(hard_side: np.ndarray, stage: _Stage, side: np.ndarray) -> np.ndarray:
        if stage.hard is None:
            return side[:stage.m_hard].copy()
        out = np.zeros(len(hard_side), dtype=int)
        out[stage.hard] = side[:stage.m_hard]
        return out

    def _program(self, level, x0, Z, hard, mu, name, carried=None):
        """The stage as a ``MathematicalProgram`` in ``(y, w)`` solved by Drake's ``name``:
        ``(x, "")`` or ``(None, why)``."""
        free, _, held, hard_lower, hard_upper, _ = hard
        hard_A = np.concatenate([np.eye(self.n)[free], held])  # the bound rows (unit rows of x), the held rows
        r = Z.shape[1]
        m = 0 if level is None else level.A.shape[0]
        extended = carried is not None
        offset = hard_A @ x0
        c_lower = np.minimum(hard_lower, offset) - offset
        c_upper = np.maximum(hard_upper, offset) - offset
        C = hard_A @ Z
        rows_A, rows_lower, rows_upper = [np.hstack([C, np.zeros((len(C), m))])], [c_lower], [c_upper]
        if level is not None:
            AZ, Ax0, identity = level.A @ Z, level.A @ x0, np.eye(m)
            rows_A += [np.hstack([AZ, -identity]), np.hstack([AZ, identity])]
            rows_lower += [np.full(m, -np.inf), level.lower - Ax0]
            rows_upper += [level.upper - Ax0, np.full(m, np.inf)]
        A_all = np.vstack(rows_A)
        if level is None:  # ‖x0 + Z y‖² = ‖y‖² + 2 (Zᵀx0)ᵀ y + const
            Q, b = 2.0 * np.eye(r), 2.0 * (Z.T @ x0)
        else:
            Q = np.diag(np.concatenate([np.full(r, 2.0 * mu), np.full(m, 2.0)]))
            b = np.zeros(r + m)
        if extended:
            program = _Program(r, len(A_all), m)
        else:
            cached = self._programs.get((r, len(A_all), m))
            program = cached if cached is not None else _Program(r, len(A_all), m)
            self._programs[(r, len(A_all), m)] = program
        if program.rows is not None:
            program.rows.evaluator().UpdateCoefficients(A_all, np.concatenate(rows_lower), np.concatenate(rows_upper))
        program.cost.evaluator().UpdateCoefficients(Q, b)
        if extended:
            with np.errstate(invalid="ignore"):  # numpy's checks on symbolic (object) arrays
                x_expression = x0 + Z @ program.y
            for extension in carried:
                extension(program.prog, x_expression, False)
            if level is not None and level.extend is not None:
                level.extend(program.prog, x_expression, True)
        drake_solver, options = self._drake(name)
        result = drake_solver.Solve(program.prog, np.zeros(r + m), options)
        x = x0 + Z @ result.GetSolution(program.y)
        if not np.isfinite(x).all():
            return None, str(result.get_solution_result())
        if extended and not result.is_success():
            return None, str(result.get_solution_result())
        return x, ""

    def _onto_bounds(self, x: np.ndarray, x_lower: np.ndarray, x_upper: np.ndarray) -> np.ndarray:
        """``x`` with each component past a bound by round-off only (within the feasibility tolerance,
        as the paths accept their points) put on that bound: the answer then holds its bounds
        exactly. A component farther out (a start kept outside a bound, see :meth:`solve`) stays.
        The compiled :func:`.active_bounds.onto_bounds`, which the active bounds' answers also go
        through (in their :func:`.active_bounds.outcome`)."""
        return _active_bounds_path().onto_bounds(x, x_lower, x_upper, self.feasibility_tolerance)

    def _result(self, levels, x, x_lower, x_upper, fixed, used) -> HqpResult:
        slacks, active = [], []
        for level in levels:
            r = level.A @ x
            slacks.append(level.slack(x, r))
            if level.all_equality:
                active.append(_NO_ROWS)
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
