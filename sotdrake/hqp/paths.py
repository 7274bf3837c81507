"""The paths a stage of the hierarchical QP tries, declared once, in order.

A stage (one level, or the minimum-norm stage) is built once (:meth:`.solve.HierarchicalQP._build`),
then its paths are tried in the order of :func:`stage_paths` until one's point is accepted
(finite, inside the bounds and held rows to the feasibility tolerance, or moved onto them by the
round-off rescue :func:`.rescue.onto_hard_rows`); when none is, the rescues after every path decide
(:func:`.rescue.after_every_path`). Each path is an object with one method, :meth:`Path.attempt`:
the active-set solution it ends with and its label, or None (its failure recorded).

The order, for the default solver (``"active-set"``):

1. the active set from the working set this stage ended with at the last call of the same sizes
   (the warm start, kept in the :class:`~.warm.WarmStart`), if there is one;
2. the active set cold, from the dual method's guess (DAQP's or quadprog's, :meth:`Attempt.cold_guess`);
3. the active set with its working set's rank decisions at :data:`~.tolerances.DEGENERATE_RETRY`
   fractions of τ, only if a path above ended outside the bounds or cycled (a degenerate vertex):
   from the dual guess, then from the empty working set at the stage's start;
4. Clarabel, then OSQP, each point polished by the active set.

With a Drake solver chosen, that solver first, then the active set (warm, then cold), the other
Drake solvers, and the degenerate retries last. A stage whose levels carry extensions (rows added
to Drake's program) is solved by Drake's programs alone (:func:`extended_paths`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .active_set import ActiveSetResult, solve_least_squares_qp
from .guesses import dual_point, level_guess, projection_guess
from .linalg import ActiveSetFailure, all_true, any_true
from .tolerances import DEGENERATE_RETRY, VERIFIED

if TYPE_CHECKING:
    from .owner import StageOwner
    from .problem import LevelRows, Stage

ACTIVE_SET = "active-set"
OUTSIDE = "a point outside the bounds"
CYCLING = "no convergence in"  # the active set's failure when its working sets cycle (see DegenerateRetry)
DRAKE_PATHS = ("clarabel", "osqp")  # the Drake solvers every stage may fall back on, in order


@dataclass
class Attempt:
    """One stage as its paths see it: the QP, the level (None: the minimum-norm stage), the start
    ``x0`` and the basis ``Z`` of what is left free, the hard rows, the damping, the built stage,
    the cached working set (None: none), and what the paths leave: failures, points outside."""

    qp: StageOwner
    level: LevelRows | None
    x0: np.ndarray
    Z: np.ndarray
    hard: tuple
    mu: float
    stage: Stage
    cached: np.ndarray | None
    failures: list[str] = field(default_factory=list)
    outside: list[tuple] = field(default_factory=list)  # finite points that ended outside the hard rows

    def cold_guess(self) -> tuple[np.ndarray, bool]:
        """The dual method's guess of the working set, and whether it is valid as it is (see
        :func:`.guesses.level_guess`); the built stage's own guess if it has none."""
        stage = self.stage
        dual, valid = ((projection_guess(stage.t, stage.G, stage.lower, stage.upper), False) if self.level is None
                       else level_guess(stage))
        return (stage.guess, False) if dual is None else (dual, valid)

    def polish(self, guess: np.ndarray | None, valid: bool, working_threshold: float | None = None) -> ActiveSetResult:
        """The active set on the stage from ``guess`` (None: the empty working set at the stage's start;
        raises :class:`~.linalg.ActiveSetFailure`)."""
        stage = self.stage
        return solve_least_squares_qp(
            stage.M, stage.t, stage.m_scale, stage.G, stage.lower, stage.upper, stage.z0,
            guess=guess, threshold=self.qp.rank_threshold, errstate=False, kind=stage.kind, guess_valid=valid,
            working_threshold=working_threshold,
            max_iterations=(2 * (len(stage.G) + len(stage.z0)) + 50) if working_threshold is not None else None,
        )


class Path:
    """A way to solve a stage: :meth:`attempt` gives ``(solution, label)`` or None."""

    name: str

    def attempt(self, a: Attempt) -> tuple[ActiveSetResult, str] | None:
        try:
            return self.solve(a)
        except ActiveSetFailure as error:
            a.failures.append(f"{self.name}: {error}")
            return None

    def solve(self, a: Attempt) -> tuple[ActiveSetResult, str] | None:
        raise NotImplementedError


class WarmActiveSet(Path):
    """The active set from the cached working set (cold when there is none)."""

    name = ACTIVE_SET

    def solve(self, a: Attempt) -> tuple[ActiveSetResult, str] | None:
        if a.cached is not None:
            return a.polish(a.cached, False), ACTIVE_SET
        return a.polish(*a.cold_guess()), ACTIVE_SET


class ColdActiveSet(Path):
    """The active set from the dual method's guess (after a warm start failed)."""

    name = "cold"

    def solve(self, a: Attempt) -> tuple[ActiveSetResult, str] | None:
        return a.polish(*a.cold_guess()), ACTIVE_SET


@dataclass
class DegenerateRetry(Path):
    """The active set cold, its working set's rank decisions at ``fraction`` τ; tried only once a
    path ended outside the bounds or did not converge (see :data:`~.tolerances.DEGENERATE_RETRY`).

    Both are the same degenerate vertex: a row dropped from a working set of nearly dependent rows
    stays implied by the others to within τ, so it cannot block the next step (it counts as
    dependent) yet the step moves it off its bound by about τ times the step; the next step is then
    blocked by it at once, it is added back, and the working sets cycle (seen on ``SolverDyn``'s
    posture level: a cycle of four working sets, the dropped row 2e-8 past its bound) or the path
    ends outside the bounds."""

    fraction: float
    empty: bool = False  # from the empty working set (at the stage's start) rather than the dual guess

    @property
    def name(self) -> str:  # type: ignore[override]
        return f"active-set (working set at {self.fraction:g} τ{', from the start' if self.empty else ''})"

    def attempt(self, a: Attempt) -> tuple[ActiveSetResult, str] | None:
        if not any(failure.endswith(OUTSIDE) or CYCLING in failure for failure in a.failures):
            return None
        return super().attempt(a)

    def solve(self, a: Attempt) -> tuple[ActiveSetResult, str] | None:
        if self.empty:
            return a.polish(None, False, self.fraction * a.qp.rank_threshold), self.name
        return a.polish(*a.cold_guess(), self.fraction * a.qp.rank_threshold), self.name


@dataclass
class PolishedDrake(Path):
    """Drake's ``name`` on the stage's program (:mod:`.drake_program`), its point polished by the
    active set from the sides it holds."""

    name: str

    def solve(self, a: Attempt) -> tuple[ActiveSetResult, str] | None:
        level, stage, x0, Z = a.level, a.stage, a.x0, a.Z
        x, message = a.qp.programs.solve(level, x0, Z, a.hard, a.mu, self.name)
        if x is None:
            a.failures.append(f"{self.name}: {message}")
            return None
        r = Z.shape[1]
        y = Z.T @ (x - x0)
        z = np.concatenate([y, stage.z0[r:]])
        if level is not None and len(stage.z0) > r:  # the level's slacks v = w / ‖a‖, from its rows
            A_in = level.A_in
            value = A_in @ x
            z[r:] = (value - np.clip(value, level.lower_in, level.upper_in)) / level.in_norms
        return a.polish(sides(stage, z), False), self.name + "+polish"


class DualPoint(Path):
    """Goldfarb-Idnani's dual method's own point on a level's stage (:func:`.guesses.dual_point`),
    taken as it is (not polished) with the rows it holds: not a declared path, but the last rescue of
    a level on which every path failed (:func:`.rescue.after_every_path`), accepted only if it holds
    every hard row. It answers a degenerate vertex that the primal paths cannot leave: many rows
    through the stage's start, some implied by the held ones to within τ, and an objective that pulls
    far along the sliver they leave (seen on ``SolverDyn``'s damping level in randomized collision
    reaches: a row implied to within 7.8e-10 by five held ones, the active set's point 53 units along
    the sliver and 5.3e-8 past that row, where the dual method stops inside every row)."""

    name = "dual"

    def solve(self, a: Attempt) -> tuple[ActiveSetResult, str] | None:
        stage = a.stage
        found = dual_point(stage.M, stage.t, stage.G, stage.lower, stage.upper)
        if found is None:
            a.failures.append(f"{self.name}: refused by quadprog, or the objective not strictly convex")
            return None
        return ActiveSetResult(found[0], found[1], 0, False), self.name


def sides(stage: Stage, z: np.ndarray, tolerance: float | None = None) -> np.ndarray:
    """The side each row of the stage's ``G`` is held at by ``z`` (within ``tolerance``, relative above 1)."""
    from .tolerances import SIDE

    value = stage.G @ z
    near = (SIDE if tolerance is None else tolerance) * np.maximum(1.0, np.abs(value))
    return np.where(value >= stage.upper - near, 1, np.where(value <= stage.lower + near, -1, 0))


_WARM, _COLD = WarmActiveSet(), ColdActiveSet()
# Last, from the empty working set: where the feasible set is a sliver (held rows pinning a direction
# to within 1e-9), the dual guess can start on a vertex the finer steps then leave by 5e-7.
_RETRIES = (*(DegenerateRetry(fraction) for fraction in DEGENERATE_RETRY), DegenerateRetry(DEGENERATE_RETRY[0], True))


@functools.cache
def stage_paths(solver: str, warm: bool) -> tuple[Path, ...]:
    """The paths of a stage, in order (see the module docstring): ``solver`` the stage's, ``warm``
    whether a working set is cached for it (made once per pair: the paths hold no state)."""
    if solver == ACTIVE_SET:  # the retries right after the active set's paths: the Drake solvers cost far more
        return (_WARM, *([_COLD] if warm else []), *_RETRIES, *(PolishedDrake(name) for name in DRAKE_PATHS))
    first: list[Path] = [PolishedDrake(solver), _WARM, *([_COLD] if warm else [])]
    return (*first, *(PolishedDrake(name) for name in DRAKE_PATHS if name != solver), *_RETRIES)


def extended_paths(solver: str, solvers: dict) -> list[str]:
    """The Drake solvers a stage with extensions tries, in order: the chosen one (Clarabel when the
    active set is), then OSQP."""
    return list(dict.fromkeys([solver if solver in solvers else "clarabel", "osqp"]))


# --- the shortcuts: a stage's point without building it ---------------------------------------
def least_squares_level(qp: StageOwner, level, x0, Z, hard, eq_factors) -> np.ndarray | None:
    """An equality-only level by its least-squares step alone, or None: the EQP point of the
    empty working set (the minimum-norm weighted least-squares step, from the level's SVD) is
    the level's optimum if it satisfies the bounds and held rows (the KKT conditions with no
    multiplier). The check is the stage's own (unit rows, the constant rows left out, 1e-10
    absolute, relative above 1), written in x: a hard row ``c`` of projected norm ``s = ‖c Z‖``
    with the step ``d = Z y`` must satisfy ``lo - c·x0 - 1e-10·max(s, |lo - c·x0|) ≤ c·d``
    (and the same at the upper side), ``lo`` relaxed to ``c·x0`` where x0 is outside. A step
    that meets every row exactly passes it without the norms being computed."""
    y = eq_factors.step(level.lower - level.A @ x0) if eq_factors.rank else np.zeros(Z.shape[1])
    return free_step(qp, x0, Z, hard, y)


def free_step(qp: StageOwner, x0, Z, hard, y) -> np.ndarray | None:
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
        keep = scale > qp.rank_threshold * reference
        if any_true(keep & (lo == hi)):  # a pinned row: the general path holds it in the working set
            return None
        if any_true(keep & ((change < lo - VERIFIED * np.maximum(scale, np.abs(lo)))
                            | (change > hi + VERIFIED * np.maximum(scale, np.abs(hi))))):
            return None
    return x0 + d
