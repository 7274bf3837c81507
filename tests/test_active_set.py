"""The active-set method's building blocks: the DAQP guess, the one-QR weighted least-squares step, and
the compiled EQP step and iterations against their Python references."""

import numpy as np
import pytest

from sotdrake.hqp import active_set
from sotdrake.hqp.active_set import _solve, eqp, objective_kind, python_eqp, python_solve, solve_least_squares_qp
from sotdrake.hqp.guesses import daqp_guess, dual_guess
from sotdrake.hqp.linalg import ActiveSetFailure, _weighted_full_rank_step, full_rank_least_squares
from sotdrake.hqp.solve import HierarchicalQP
from sotdrake.hqp.tolerances import RANK_THRESHOLD
from tests.conftest import compiled_only
from tests.hqp_stacks import random_stack


def strictly_convex_level(rng: np.random.Generator, p: int = 8, m: int = 12, rows: int = 10):
    """``min ½‖M z - t‖² s.t. lower ≤ G z ≤ upper`` with ``M`` of full column rank (a unique optimum),
    ``G`` unit rows, ``z = 0`` strictly inside, some sides infinite."""
    M = rng.normal(size=(m, p))
    t = 3.0 * rng.normal(size=m)
    G = rng.normal(size=(rows, p))
    G /= np.linalg.norm(G, axis=1)[:, None]
    lower, upper = -rng.uniform(0.1, 1.0, rows), rng.uniform(0.1, 1.0, rows)
    lower[rng.random(rows) < 0.2] = -np.inf
    upper[rng.random(rows) < 0.2] = np.inf
    return M, t, G, lower, upper


@pytest.mark.parametrize("seed", range(20))
def test_the_daqp_guess_is_the_optimal_working_set_of_a_strictly_convex_level(seed):
    """On a level with a unique, non-degenerate optimum DAQP's sides are the exact method's final
    working set (so the guess is accepted with no iteration), as quadprog's are, and no row is held
    at an infinite side."""
    M, t, G, lower, upper = strictly_convex_level(np.random.default_rng(seed))
    exact = solve_least_squares_qp(M, t, np.ones(len(M)), G, lower, upper, np.zeros(M.shape[1]))
    guess = daqp_guess(M, t, G, lower, upper)
    assert guess is not None
    np.testing.assert_array_equal(guess, exact.side)
    np.testing.assert_array_equal(guess, dual_guess(M, t, G, lower, upper))
    assert not np.any((guess > 0) & (upper == np.inf)) and not np.any((guess < 0) & (lower == -np.inf))
    warm = solve_least_squares_qp(M, t, np.ones(len(M)), G, lower, upper, np.zeros(M.shape[1]), guess=guess)
    assert warm.guess_accepted and warm.iterations == 0
    np.testing.assert_allclose(warm.z, exact.z, atol=1e-12)


def test_the_one_qr_step_is_the_two_factorisation_step_or_declines():
    """When the QR of ``B`` proves ``B / m_scale`` of full column rank the step is exactly
    :func:`full_rank_least_squares` (the same LAPACK calls) and the least-squares solution; when the
    weights make that proof fail (a row scaled by 10⁹ over a column that is almost zero) it declines
    and the caller factorises the unit rows."""
    rng = np.random.default_rng(3)
    B, r = rng.normal(size=(9, 5)), rng.normal(size=9)
    m_scale = 10.0 ** rng.uniform(-2, 2, 9)
    u = _weighted_full_rank_step(B, m_scale, r, RANK_THRESHOLD)
    assert u is not None
    np.testing.assert_array_equal(u, full_rank_least_squares(B, r))
    np.testing.assert_allclose(u, np.linalg.lstsq(B, r, rcond=None)[0], rtol=1e-10, atol=1e-12)
    B_weak = B.copy()
    B_weak[:, 4] *= 1e-10  # σ_min(B) ≈ 1e-10: the bound σ_min(B)/max(m_scale) cannot exceed 2τ
    assert _weighted_full_rank_step(B_weak, m_scale, r, RANK_THRESHOLD) is None
    assert _weighted_full_rank_step(B[:, :3], m_scale, r, RANK_THRESHOLD) is None  # below QR_MIN_SIZE: the SVD decides


@pytest.mark.parametrize("seed", range(40))
def test_the_compiled_eqp_is_the_python_one(seed):
    """:func:`eqp` (compiled) against :func:`python_eqp` on random equality-constrained least squares:
    projections, weighted and uniform rows, full and deficient rank, rows copied from others, and
    the working-set threshold of the degenerate retry; the same point, multipliers and basis."""
    rng = np.random.default_rng(seed)
    for trial in range(25):
        p = int(rng.integers(2, 30))
        m, k = int(rng.integers(0, 25)), int(rng.integers(0, min(p, 12) + 1))
        projection = trial % 5 == 0
        M = np.eye(p) if projection else rng.normal(size=(m, p)) * 10.0 ** rng.uniform(-1, 1, size=(m, 1))
        m_scale = np.ones(len(M)) if projection or trial % 3 == 0 else np.sqrt(np.einsum("ij,ij->i", M, M))
        E = rng.normal(size=(k, p))
        if k > 2 and trial % 4 == 0:
            E[-1] = E[0]  # a row the others fix: exactly dependent
        if k:
            E /= np.linalg.norm(E, axis=1, keepdims=True)
        t, e = rng.normal(size=len(M)), rng.normal(size=k)
        for working in (None, 1e-10):
            z, lam, N = eqp(M, t, m_scale, E, e, RANK_THRESHOLD, None, working)
            z_ref, lam_ref, N_ref = python_eqp(M, t, m_scale, E, e, RANK_THRESHOLD, None, working)
            np.testing.assert_allclose(z, z_ref, rtol=0, atol=1e-12 * max(1.0, np.abs(z_ref).max()))
            np.testing.assert_allclose(lam, lam_ref, rtol=0, atol=1e-10 * max(1.0, np.abs(lam_ref).max(initial=0.0)))
            assert (N is None) == (N_ref is None)
            if N is not None:  # the same subspace (the bases may differ by a rotation)
                np.testing.assert_allclose(N @ N.T, N_ref @ N_ref.T, atol=1e-12)


def assert_same_iterations(args: tuple) -> None:
    """The compiled :func:`_solve` and :func:`python_solve` on the same arguments: the same final working
    set and flags, the same point to round-off and the iteration count within one, or the same
    failure. (Their products go through different BLAS builds, numba's scipy's and numpy's own: a tie
    in the ratio test can then be broken the other way, one step more, the same answer; seen on 1
    call in 6960.)"""

    def run(solve):
        try:
            with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
                return solve(*args)
        except ActiveSetFailure as error:
            return str(error)

    got, expected = run(_solve), run(python_solve)
    if isinstance(expected, str) or isinstance(got, str):
        assert got == expected
        return
    np.testing.assert_array_equal(got.side, expected.side)
    assert (got.guess_accepted, got.verified) == (expected.guess_accepted, expected.verified)
    assert abs(got.iterations - expected.iterations) <= 1, (got.iterations, expected.iterations)
    np.testing.assert_allclose(got.z, expected.z, rtol=0, atol=1e-13 * max(1.0, np.abs(expected.z).max(initial=0.0)))


@pytest.mark.parametrize("seed", range(30))
def test_the_compiled_iterations_are_the_python_ones_on_random_levels(seed):
    """Random levels from z = 0: weighted, uniform, rank-deficient and projection objectives, equality
    rows, rows copied from others (degenerate vertices), infinite sides, random guesses (some held at
    an infinite side), the working-set threshold of the degenerate retry and iteration caps low
    enough to be met."""
    rng = np.random.default_rng(seed)
    for trial in range(20):
        p, m, rows = int(rng.integers(2, 25)), int(rng.integers(0, 30)), int(rng.integers(0, 35))
        projection = trial % 6 == 0
        M = np.eye(p) if projection else rng.normal(size=(m, p)) * 10.0 ** rng.uniform(-1, 1, size=(m, 1))
        m_scale = np.ones(len(M)) if projection or trial % 3 == 0 else np.linalg.norm(M, axis=1)
        t = 3.0 * rng.normal(size=len(M))
        G = rng.normal(size=(rows, p))
        if rows > 3 and trial % 4 == 0:
            G[1] = G[0]  # a copied row: the ratio test and the working set meet a dependent row
        G /= np.linalg.norm(G, axis=1, keepdims=True)
        lower, upper = -rng.uniform(0.0, 1.0, rows), rng.uniform(0.0, 1.0, rows)
        lower[rng.random(rows) < 0.2] = -np.inf
        upper[rng.random(rows) < 0.2] = np.inf
        pinned = rng.random(rows) < 0.1
        lower[pinned] = upper[pinned] = 0.0  # equality rows (z = 0 stays feasible)
        guess = None if trial % 5 == 0 else rng.integers(-1, 2, rows)
        cap = (None, None, 1, 3)[trial % 4]
        working = RANK_THRESHOLD if trial % 3 else 1e-4 * RANK_THRESHOLD
        assert_same_iterations((M, t, m_scale, G, lower, upper, np.zeros(p), guess, RANK_THRESHOLD, 1e-10, cap,
                                objective_kind(M, m_scale), bool(trial % 2), working))


@pytest.mark.parametrize("seed", range(15))
def test_the_compiled_iterations_are_the_python_ones_on_every_stage_of_random_stacks(seed, monkeypatch):
    """Every stage the hierarchical QP solves on random stacks (DAQP's and quadprog's cold guesses,
    the minimum-norm stage, the degenerate retries), compiled against Python."""
    compared = []

    def comparing(*args):
        assert_same_iterations(args)
        compared.append(args)
        return _solve(*args)

    monkeypatch.setattr(active_set, "_solve", comparing)
    for stack in range(10 * seed, 10 * seed + 10):
        n, levels, lower, upper = random_stack(np.random.default_rng(stack))
        HierarchicalQP(n).solve(levels, lower, upper)
    assert len(compared) >= 10


@compiled_only
def test_the_compiled_iterations_take_any_array_layout_without_another_compilation():
    """Read-only, Fortran-ordered, strided and integer inputs and a list as guess give the same bits
    without a second compilation."""
    from sotdrake.hqp.kernels import active_set as jit_active_set

    M, t, G, lower, upper = strictly_convex_level(np.random.default_rng(5))
    m_scale = np.ones(len(M))
    plain = solve_least_squares_qp(M, t, m_scale, G, lower, upper, np.zeros(M.shape[1]), guess=np.zeros(len(G), int))
    signatures = len(jit_active_set.solve.signatures)
    frozen = [a.copy() for a in (M, t, G)]
    for a in frozen:
        a.flags.writeable = False
    wide = np.zeros((len(G), 2 * G.shape[1]))
    wide[:, ::2] = G
    for arguments in (
        (frozen[0], frozen[1], m_scale, frozen[2], lower, upper, np.zeros(M.shape[1]), np.zeros(len(G), np.int32)),
        (np.asfortranarray(M), t, m_scale.astype(np.float32), wide[:, ::2], lower, upper, np.zeros(M.shape[1], int),
         [0] * len(G)),
    ):
        again = solve_least_squares_qp(*arguments[:7], guess=arguments[7])
        np.testing.assert_array_equal(again.z, plain.z)
        np.testing.assert_array_equal(again.side, plain.side)
    assert len(jit_active_set.solve.signatures) == signatures == 1


def test_where_the_compiled_iterations_give_way_the_python_ones_answer(monkeypatch):
    """A compiled solve that gives way (LAPACK refusing a factorisation) is answered by
    :func:`python_solve`, on the same arguments."""
    from sotdrake.hqp.kernels import active_set as jit_active_set

    M, t, G, lower, upper = strictly_convex_level(np.random.default_rng(8))
    arguments = (M, t, np.ones(len(M)), G, lower, upper, np.zeros(M.shape[1]))
    expected = solve_least_squares_qp(*arguments)
    monkeypatch.setattr(jit_active_set, "solve", lambda *args: (jit_active_set.GAVE_WAY, None, None, 0, False, False))
    called = []
    monkeypatch.setattr(active_set, "python_solve", lambda *args: called.append(args) or expected)
    assert solve_least_squares_qp(*arguments) is expected
    assert len(called) == 1 and called[0][0] is M and called[0][3] is G
