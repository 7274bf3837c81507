"""Stages at a degenerate vertex where the active set cycled or ended outside the bounds (recorded
from SolverDyn's collision reach)."""

from pathlib import Path

import numpy as np
import pytest

from sotdrake.hqp.solve import HierarchicalQP, LevelRows
from sotdrake.hqp.warm import WarmStart
from tests.test_hqp import bounds_hold, round_off, same_norms

DATA = Path(__file__).parent / "data"
RECORDED = ["cycling_posture_stage.npz", "sliver_posture_stage.npz"]


def _recorded(name: str) -> tuple[list[LevelRows], np.ndarray, np.ndarray, np.ndarray, WarmStart]:
    """The stack (82 unknowns (q̈, w, τ): dynamics, contacts, CoM, collision rows, hand, damping,
    posture), its bounds and start, and the warm start the solve read (each stage's last working set)."""
    data = np.load(DATA / name)
    levels = [LevelRows(data[f"A{k}"], data[f"lower{k}"], data[f"upper{k}"]) for k in range(int(data["levels"]))]
    warm = WarmStart(len(data["x_lower"]))
    for i, (k, g0, g1, m0, m1) in enumerate(data["warm_keys"]):
        warm.working_sets[(int(k), False, (int(g0), int(g1)), (int(m0), int(m1)))] = data[f"warm{i}"].copy()
    warm.bound_sides = (data["warm_x"], data["warm_x_lower"], data["warm_x_upper"])
    return levels, data["x_lower"], data["x_upper"], data["start"], warm


@pytest.mark.parametrize("name", RECORDED)
def test_a_degenerate_posture_stage_is_solved_within_the_bounds_and_strictly(name):
    """On the posture level (6 directions left free, 34 bound and held rows) six rows meet at a
    vertex where one is implied by the other five only to within τ: dropped for its multiplier, it
    cannot block the next step, which moves it 2e-8 past its bound; it is added back at once and the
    active set's working sets cycle (warm and cold: no convergence in 450 iterations). In the second
    stack, two held rows pin a direction to within 8e-10 (the feasible set is a sliver): every
    path from the dual guess ended 5e-7 outside a bound. With the warm start of the recorded tick,
    solved: bounds to 1e-9, every level's slack that of the stack truncated after it (strict priority)."""
    levels, x_lower, x_upper, start, warm = _recorded(name)
    n = len(x_lower)
    result = HierarchicalQP(n).solve(levels, x_lower, x_upper, start=start, warm=warm)
    assert np.all(np.isfinite(result.x)) and bounds_hold(result.x, x_lower, x_upper)
    for k in range(len(levels)):
        alone = HierarchicalQP(n, regularize=False).solve(levels[: k + 1], x_lower, x_upper, start=start)
        floor = np.maximum(round_off(levels, result.x), round_off(levels, alone.x))[: k + 1]
        assert same_norms(result.slack_norms[: k + 1], alone.slack_norms, floor=floor), (k, result.slack_norms,
                                                                                        alone.slack_norms)


@pytest.mark.parametrize("name", RECORDED)
def test_a_degenerate_posture_stage_is_solved_cold_to_the_same_slacks(name):
    """The same stack cold (a fresh warm start): the same slacks, bounds to 1e-9."""
    levels, x_lower, x_upper, start, warm = _recorded(name)
    n = len(x_lower)
    warm_result = HierarchicalQP(n).solve(levels, x_lower, x_upper, start=start, warm=warm)
    cold = HierarchicalQP(n).solve(levels, x_lower, x_upper, start=start)
    assert bounds_hold(cold.x, x_lower, x_upper)
    assert same_norms(cold.slack_norms, warm_result.slack_norms, floor=round_off(levels, cold.x))
