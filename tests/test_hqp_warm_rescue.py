"""A warm-started solve on which every path of a stage failed is still solved: every level at the
cold solve's optimum, bounds held. The two problems are ``SolverDyn``'s, captured with their warm starts
on randomized collision reaches (``bench/collision_runs.py --dynamic``), where every path of the
damping level failed from the warm start (the active set cycling, or ending outside the bounds with
Clarabel and OSQP) while the same problem solved cold is solved."""

from __future__ import annotations

import gzip
import pickle
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from sotdrake.exceptions import SolverError
from sotdrake.hqp import HierarchicalQP, LevelRows, WarmStart
from sotdrake.hqp.rescue import cold_again

PROBLEMS = Path(__file__).parent / "data" / "dynamic_warm_failures.pkl.gz"


def problems() -> list[dict]:
    with gzip.open(PROBLEMS, "rb") as stream:
        return pickle.load(stream)


@pytest.mark.parametrize("index", [0, 1])
def test_a_warm_start_that_no_path_finishes_gives_the_cold_answer(index):
    p = problems()[index]
    n = len(p["x_lower"])
    levels = [LevelRows(A, lower, upper) for A, lower, upper in p["levels"]]
    warm = WarmStart(n, working_sets=dict(p["working_sets"]))
    result = HierarchicalQP(n).solve(levels, p["x_lower"], p["x_upper"], start=p["start"], warm=warm)
    cold = HierarchicalQP(n).solve(levels, p["x_lower"], p["x_upper"], start=p["start"])
    scale = 1.0 + np.abs(cold.x).max()
    np.testing.assert_allclose(result.slack_norms, cold.slack_norms, rtol=1e-9, atol=1e-9)  # every level at its optimum
    assert np.all(result.x >= p["x_lower"] - 1e-9 * scale) and np.all(result.x <= p["x_upper"] + 1e-9 * scale)
    # The minimum-norm stage: the same point, or (after a retry whose rank decisions are finer than
    # τ on this degenerate stack) a point of the same optimal set at most 1 % longer.
    assert np.linalg.norm(result.x) <= 1.01 * np.linalg.norm(cold.x)
    assert warm.working_sets  # what the cold solve left, for the next call


def test_a_cold_solve_that_fails_is_not_tried_again():
    calls = []
    error = SolverError("every path failed")
    owner = SimpleNamespace(warm=WarmStart(3))

    def solve():
        calls.append(1)
        raise AssertionError("not called")

    with pytest.raises(SolverError, match="every path failed"):
        cold_again(owner, error, solve)
    assert calls == []
    owner.warm.working_sets[(0, False, (1, 1), (1, 1))] = np.array([1])
    answer = SimpleNamespace(fallbacks=["level 1: cold"])
    assert cold_again(owner, error, lambda: answer) is answer
    assert owner.warm.working_sets == {} and answer.fallbacks[0].startswith("the warm start was dropped")
