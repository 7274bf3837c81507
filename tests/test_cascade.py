"""The cascade against an independent lexicographic reference on random stacks."""

import numpy as np
import pytest

from sotdrake.exceptions import InvalidInput, SolverError
from sotdrake.hqp.cascade import _stacked, cascade_factorization, svd_cascade
from sotdrake.hqp.kernels.cascade import cascade, prefix
from sotdrake.solvers import solve_cascade


def random_stack(rng, nv):
    levels = []
    for _ in range(rng.integers(1, 6)):
        m = int(rng.integers(1, 8))
        rank = int(rng.integers(1, min(m, nv) + 1))
        J = rng.normal(size=(m, rank)) @ rng.normal(size=(rank, nv))  # rank-deficient rows
        if rng.random() < 0.3 and levels:  # a level in conflict with a higher one
            J[0] = levels[0][0][0]
        levels.append((J, rng.normal(size=m)))
    return levels


def lexicographic_reference(levels, nv):
    """Each level: min ‖J_i v - r_i‖ s.t. every higher level keeps its optimal value (KKT,
    least-squares); last, the minimum-norm v. Shares no code with the cascade."""
    A_fix, b_fix = np.zeros((0, nv)), np.zeros(0)
    v = np.zeros(nv)
    for J, r in [*levels, (np.eye(nv), np.zeros(nv))]:
        m = len(A_fix)
        K = np.block([[J.T @ J, A_fix.T], [A_fix, np.zeros((m, m))]])
        sol = np.linalg.lstsq(K, np.concatenate([J.T @ r, b_fix]), rcond=1e-10)[0]
        v = sol[:nv]
        A_fix, b_fix = np.vstack([A_fix, J]), np.concatenate([b_fix, J @ v])
    return v


@pytest.mark.parametrize("seed", range(200))
def test_cascade_equals_lexicographic_optimum(seed):
    rng = np.random.default_rng(seed)
    nv = int(rng.integers(3, 15))
    levels = random_stack(rng, nv)
    result = solve_cascade(levels, nv, svd_threshold=1e-8)
    reference = lexicographic_reference(levels, nv)
    np.testing.assert_allclose(result.velocity, reference, atol=1e-7)
    for i in range(len(levels)):  # strictness: adding lower levels never changes level i
        alone = solve_cascade(levels[: i + 1], nv, svd_threshold=1e-8)
        assert result.residuals[i] == pytest.approx(alone.residuals[i], abs=1e-8)


@pytest.mark.parametrize("seed", range(20))
def test_damping_keeps_priorities_and_bounds_velocity(seed):
    rng = np.random.default_rng(seed)
    nv = 8
    levels = random_stack(rng, nv)
    damped = solve_cascade(levels, nv, damping=1e-2)
    plain = solve_cascade(levels, nv)
    assert np.linalg.norm(damped.velocity) <= np.linalg.norm(plain.velocity) + 1e-12
    for i in range(len(levels)):
        alone = solve_cascade(levels[: i + 1], nv, damping=1e-2)
        assert damped.residuals[i] == pytest.approx(alone.residuals[i], abs=1e-9)


def test_control_selection_leaves_unselected_velocities_at_zero(rng):
    nv = 6
    levels = [(rng.normal(size=(2, nv)), rng.normal(size=2))]
    selection = np.array([True, False, True, True, False, True])
    result = solve_cascade(levels, nv, control_selection=selection)
    assert np.all(result.velocity[~selection] == 0)
    assert result.residuals[0] < 1e-10  # 4 free velocities still solve 2 rows


def test_singular_level_is_truncated_not_amplified():
    J = np.array([[1.0, 0.0], [0.0, 1e-6]])
    result = solve_cascade([(J, np.array([1.0, 1.0]))], 2, svd_threshold=1e-4)
    np.testing.assert_allclose(result.velocity, [1.0, 0.0])
    assert result.ranks[0] == 1


def compiled(levels, nv, selection=None, dampings=None, threshold=1e-4):
    """The compiled cascade's ``(v, ranks, levels solved by the QR prefix)`` (one reference column)."""
    J, references, sizes = _stacked(levels, None)
    mask = np.ones(nv) if selection is None else selection.astype(float)
    dampings = np.zeros(len(levels)) if dampings is None else np.asarray(dampings, dtype=float)
    v, ranks, solved = cascade(np.ascontiguousarray(J, dtype=float), sizes, references, mask, threshold, dampings)
    return v[:, 0], ranks, solved


def qr_prefix(levels, nv, threshold=1e-4):
    """The compiled prefix alone on the levels (``(solved, v, free)``)."""
    J, references, sizes = _stacked(levels, None)
    return prefix(np.ascontiguousarray(J, dtype=float), sizes, references, threshold, False)


def full_rank_stack(rng, nv):
    """Levels whose stacked rows are independent: every level full rank below the ones above."""
    levels, total = [], 0
    while total < nv - 1 and (not levels or rng.random() < 0.8):
        m = int(rng.integers(1, min(7, nv - total) + 1))
        scale = 10.0 ** rng.uniform(-2, 2)
        levels.append((scale * rng.normal(size=(m, nv)), rng.normal(size=m)))
        total += m
    return levels


@pytest.mark.parametrize("seed", range(100))
def test_full_rank_fast_path_is_the_svd_cascade(seed):
    """The QR path returns the SVD cascade's v (to rounding), and is the one taken on such stacks."""
    rng = np.random.default_rng(seed)
    nv = int(rng.integers(2, 45))
    levels = full_rank_stack(rng, nv)
    selection = None
    if rng.random() < 0.5:
        selection = rng.random(nv) < 0.8
        selection[: sum(J.shape[0] for J, _ in levels)] = True  # enough free velocities
    fast, fast_ranks, solved = compiled(levels, nv, selection)
    assert solved == len(levels) and list(fast_ranks) == [J.shape[0] for J, _ in levels]
    v, ranks = svd_cascade(levels, nv, 1e-4, [0.0] * len(levels), selection)
    np.testing.assert_allclose(fast, v, rtol=0, atol=1e-10 * max(1.0, np.abs(v).max()))
    assert list(ranks) == [J.shape[0] for J, _ in levels]
    if selection is not None:
        assert np.all(fast[~selection] == 0)
    np.testing.assert_allclose(solve_cascade(levels, nv, control_selection=selection).velocity, fast, rtol=0, atol=0)


@pytest.mark.parametrize("seed", range(60))
def test_qr_prefix_stops_at_the_first_rank_loss(seed):
    """Full-rank levels, then levels that lose rank or repeat a higher level's row (and, half of
    the time, a posture level of nv rows): the QR path solves the leading full-rank levels only,
    the SVD cascade goes on from there and truncates; the result is the plain SVD cascade's."""
    rng = np.random.default_rng(seed)
    nv = int(rng.integers(8, 40))
    levels = full_rank_stack(rng, nv // 2) if rng.random() < 0.7 else []
    levels = [(np.hstack([J, rng.normal(size=(J.shape[0], nv - J.shape[1]))]), r) for J, r in levels]
    levels += random_stack(rng, nv)
    if rng.random() < 0.5:
        levels.append((np.eye(nv), rng.normal(size=nv)))
    selection = rng.random(nv) < 0.9 if rng.random() < 0.3 else None
    v, ranks = svd_cascade(levels, nv, 1e-4, [0.0] * len(levels), selection)
    solved = compiled(levels, nv, selection)[2]
    deficient = [i for i, (rank, (J, _)) in enumerate(zip(ranks, levels, strict=True)) if rank < J.shape[0]]
    if deficient:
        assert solved <= deficient[0]
    result = solve_cascade(levels, nv, control_selection=selection)
    if selection is not None:
        assert np.all(result.velocity[~selection] == 0.0)  # exactly: an unselected joint never moves
    np.testing.assert_allclose(result.velocity, v, rtol=0, atol=1e-9 * max(1.0, np.abs(v).max()))
    assert list(result.ranks) == list(ranks)


@pytest.mark.parametrize("seed", range(40))
def test_the_compiled_cascade_is_the_plain_one(seed):
    """The compiled cascade (the QR prefix when no level is damped, the SVD levels below it), damped
    per level, with or without a control selection, gives the plain cascade's velocity and ranks."""
    rng = np.random.default_rng(seed)
    nv = int(rng.integers(6, 40))
    levels = random_stack(rng, nv) + ([(np.eye(nv), rng.normal(size=nv))] if rng.random() < 0.5 else [])
    dampings = [float(d) for d in rng.choice([0.0, 1e-3, 0.1], size=len(levels))]
    selection = rng.random(nv) < 0.8 if rng.random() < 0.5 else None
    v, ranks = svd_cascade(levels, nv, 1e-4, dampings, selection)
    factorization = cascade_factorization(levels, nv, 1e-4, dampings, selection)
    np.testing.assert_allclose(factorization.velocity, v, rtol=0, atol=1e-9 * max(1.0, np.abs(v).max()))
    assert list(factorization.ranks) == list(ranks) and factorization.extra_velocity is None
    # Other references solved in the same pass: the plain cascade's velocity for them.
    extra = [rng.normal(size=J.shape[0]) for J, _ in levels]
    v_extra, _ = svd_cascade([(J, e) for (J, _), e in zip(levels, extra, strict=True)], nv, 1e-4, dampings, selection)
    again = cascade_factorization(levels, nv, 1e-4, dampings, selection, extra)
    np.testing.assert_allclose(again.velocity, v, rtol=0, atol=1e-9 * max(1.0, np.abs(v).max()))
    np.testing.assert_allclose(again.extra_velocity, v_extra, rtol=0, atol=1e-9 * max(1.0, np.abs(v_extra).max()))


@pytest.mark.parametrize("seed", range(40))
def test_the_extra_references_velocity_is_the_cascade_of_those_references(seed):
    """A factorization given extra references (the full-rank prefix, the SVD levels below it, or
    both) keeps their velocity: the cascade's, solved again for them."""
    rng = np.random.default_rng(seed)
    nv = int(rng.integers(6, 40))
    levels = random_stack(rng, nv) + ([(np.eye(nv), rng.normal(size=nv))] if rng.random() < 0.5 else [])
    selection = rng.random(nv) < 0.8 if rng.random() < 0.5 else None
    extra = [rng.normal(size=J.shape[0]) for J, _ in levels]
    factorization = cascade_factorization(levels, nv, 1e-4, 0.0, selection, extra)
    expected = solve_cascade([(J, e) for (J, _), e in zip(levels, extra, strict=True)], nv, control_selection=selection).velocity
    plain = solve_cascade(levels, nv, control_selection=selection).velocity
    np.testing.assert_allclose(factorization.extra_velocity, expected, rtol=0, atol=1e-9 * max(1.0, np.abs(expected).max()))
    np.testing.assert_allclose(factorization.velocity, plain, rtol=0, atol=1e-9 * max(1.0, np.abs(plain).max()))
    if selection is not None:
        assert np.all(factorization.extra_velocity[~selection] == 0.0)
    assert cascade_factorization(levels, nv, 1e-4, 0.0, selection).extra_velocity is None


def test_the_compiled_cascade_on_an_empty_stack_and_a_non_finite_level():
    nv = 6
    empty = cascade_factorization([], nv, 1e-4, 0.0, None, [])
    assert np.array_equal(empty.velocity, np.zeros(nv)) and len(empty.ranks) == 0
    assert np.array_equal(empty.extra_velocity, np.zeros(nv))
    levels = [(np.eye(2, nv), np.ones(2)), (np.full((1, nv), np.nan), np.zeros(1))]
    for damping in (0.0, 1e-3):  # below the QR prefix, and in the SVD levels from the top
        with pytest.raises(SolverError, match="finite"):
            cascade_factorization(levels, nv, 1e-4, damping)


@pytest.mark.parametrize("ratio", [0.5, 0.999, 1.001, 1.5, 2.0, 3.0, 10.0])
def test_near_the_threshold_the_rank_decision_is_the_svd_one(ratio):
    """A second level whose smallest singular value (in the first level's null space) is ``ratio``
    times the threshold: kept above it, truncated at or below it, whichever path solves it."""
    rng = np.random.default_rng(7)
    nv, threshold = 8, 1e-3
    J1 = rng.normal(size=(2, nv))
    Q = np.linalg.qr(rng.normal(size=(nv, nv)))[0]
    J1 = np.array([Q[:, 0], Q[:, 1]]) * 3.0
    J2 = np.array([Q[:, 2] + Q[:, 0], ratio * threshold * Q[:, 3] + 0.5 * Q[:, 1]])  # σ = (√2·…, ratio·thr)
    levels = [(J1, rng.normal(size=2)), (J2, rng.normal(size=2))]
    result = solve_cascade(levels, nv, svd_threshold=threshold)
    v, ranks = svd_cascade(levels, nv, threshold, [0.0, 0.0], None)
    assert list(result.ranks) == list(ranks) == [2, 2 if ratio > 1 else 1]
    np.testing.assert_allclose(result.velocity, v, rtol=1e-9, atol=1e-9)


def test_qr_prefix_on_nan_and_empty_levels():
    nv = 4
    J = np.ones((1, nv))
    assert qr_prefix([(np.full((1, nv), np.nan), np.zeros(1))], nv)[0] == 0
    v, ranks, solved = compiled([(np.zeros((0, nv)), np.zeros(0))], nv)
    assert solved == 0 and np.array_equal(v, np.zeros(nv)) and list(ranks) == [0]
    with_empty = [(np.zeros((0, nv)), np.zeros(0)), (J, np.ones(1))]
    v, ranks, solved = compiled(with_empty, nv)
    np.testing.assert_allclose(v, np.full(nv, 0.25))
    assert solved == 2 and list(ranks) == [0, 1]
    # a NaN below a full-rank level: the level above is solved, the NaN is left to the SVD cascade
    solved, v, free = qr_prefix([(J, np.ones(1)), (np.full((1, nv), np.nan), np.zeros(1))], nv)
    assert solved == 1 and np.isfinite(v).all() and np.isfinite(free).all()


@pytest.mark.parametrize("seed", range(120))
def test_the_factorization_solves_other_references(seed):
    """A factorisation given other references (``extra``) gives the cascade's v for them, and its own
    v unchanged: the QR path, the SVD levels after it, rank-deficient and conflicting levels,
    damping and control selection."""
    rng = np.random.default_rng(seed)
    nv = int(rng.integers(4, 40))
    levels = full_rank_stack(rng, nv // 2) if rng.random() < 0.7 else []
    levels = [(np.hstack([J, rng.normal(size=(J.shape[0], nv - J.shape[1]))]), r) for J, r in levels]
    if rng.random() < 0.7:
        levels += random_stack(rng, nv)
    if not levels:
        levels = random_stack(rng, nv)
    selection = rng.random(nv) < 0.9 if rng.random() < 0.3 else None
    damping = 1e-3 if rng.random() < 0.2 else 0.0
    others = [rng.normal(size=J.shape[0]) for J, _ in levels]
    kept = cascade_factorization(levels, nv, 1e-4, damping, selection, extra=others)
    own = solve_cascade(levels, nv, 1e-4, damping, selection).velocity
    expected = solve_cascade([(J, r) for (J, _), r in zip(levels, others, strict=True)], nv, 1e-4, damping, selection)
    np.testing.assert_allclose(kept.extra_velocity, expected.velocity, rtol=0, atol=1e-9 * max(1.0, np.abs(expected.velocity).max()))
    np.testing.assert_allclose(kept.velocity, own, rtol=0, atol=1e-9 * max(1.0, np.abs(own).max()))


@pytest.mark.parametrize("ratio", [0.5, 0.999, 1.001, 1.5, 3.0, 10.0])
@pytest.mark.parametrize("masked", [False, True])
def test_an_overdetermined_last_level_near_the_threshold_is_the_svd_one(ratio, masked):
    """A posture-like last level (more rows than what the level above leaves free) whose smallest
    singular value there is ``ratio`` times the threshold, with or without masked velocities: the
    cascade keeps it above the threshold and truncates it at or below, as the plain SVD cascade,
    with its velocity (whether one QR or the SVD solves the level)."""
    rng = np.random.default_rng(11)
    nv, threshold = 10, 1e-3
    Q = np.linalg.qr(rng.normal(size=(nv, nv)))[0]
    selection = np.ones(nv, dtype=bool)
    if masked:  # two velocities masked: the basis of the level above's null space made to contain them
        selection[[3, 7]] = False
        Q = np.linalg.qr(np.hstack([np.eye(nv)[:, [3, 7]], rng.normal(size=(nv, nv - 2))]))[0]
    top = 3
    J1 = 3.0 * Q[:, 2:2 + top].T  # (its rows are orthogonal to the masked velocities)
    free = Q[:, 2 + top:]  # what is left free and selected: nv - 2 - top directions
    scales = np.linspace(1.0, 2.0, free.shape[1])
    scales[-1] = ratio * threshold
    J2 = rng.normal(size=(nv + 4, free.shape[1])) @ np.diag(scales)
    J2 = np.linalg.qr(J2)[0] @ np.diag(scales) @ free.T + rng.normal(size=(nv + 4, 1)) @ J1[:1] / 3.0
    levels = [(J1, rng.normal(size=top)), (J2, rng.normal(size=nv + 4))]
    mask = selection if masked else None
    result = solve_cascade(levels, nv, svd_threshold=threshold, control_selection=mask)
    v, ranks = svd_cascade(levels, nv, threshold, [0.0, 0.0], mask)
    kept = free.shape[1] if ratio > 1 else free.shape[1] - 1
    assert list(result.ranks) == list(ranks) == [top, kept]
    np.testing.assert_allclose(result.velocity, v, rtol=1e-8, atol=1e-8)
    if masked:
        assert np.all(result.velocity[~selection] == 0.0)


def test_a_stack_that_does_not_fit_is_refused_naming_what():
    """Wrong sizes give an InvalidInput naming the argument, before any compiled code reads them."""
    nv, J, r = 4, np.eye(2, 4), np.ones(2)
    cases = {
        "damping": lambda: solve_cascade([(J, r)], nv, damping=[0.0, 0.1]),
        "control_selection": lambda: solve_cascade([(J, r)], nv, control_selection=np.ones(3, dtype=bool)),
        "columns": lambda: solve_cascade([(np.eye(2, 3), r)], nv),
        "level 1": lambda: solve_cascade([(J, r), (J, np.ones(3))], nv),
        "extra": lambda: cascade_factorization([(J, r)], nv, extra=[]),
        "level 0": lambda: cascade_factorization([(J, r)], nv, extra=[np.ones(3)]),
    }
    for name, call in cases.items():
        with pytest.raises(InvalidInput, match=name):
            call()
