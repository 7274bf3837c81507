"""Both solvers keep a collision level's rows that can hold exact when one row cannot be met.

The collision task's level gets one more row that no motion can meet: the closest pair of a body
and the table asked to approach at a speed (or an acceleration) far beyond the joints' limits. In the least-squares sense
that row and the pair's own row share the violation, and the pair goes through; with the level
refined (:mod:`sotdrake.solvers.unmet_rows`) the impossible row is moved below the rest, and every
pair keeps its safety distance, checked by Drake's own query at every tick. The same run with the refinement
switched off lets pairs through: the check can fail.
"""

from __future__ import annotations

import numpy as np
import pytest

from sotdrake.collision import task as collision_task
from sotdrake.collision.reach import (
    build_collision_reach,
    build_dyn_collision_reach,
    run_collision_reach,
    run_dyn_collision_reach,
)
from sotdrake.collision.task import SAFETY_DISTANCE
from sotdrake.dynamics import dyn_solve
from sotdrake.solvers import solver_kine
from sotdrake.task import TaskLevel

TOLERANCE = 1e-4
TARGET = np.array([0.45, -0.3, 0.86])  # (the right hand onto the table top: pairs come within range)
IMPOSSIBLE = {"velocity": 50.0, "acceleration": 5e4}  # (m/s, m/s²: far beyond what any joint gives)
FAKE_KEY = 10**6


@pytest.fixture
def impossible_row(monkeypatch):
    """Append to every collision level with a body–table pair in range the row ``−J_c ≥ IMPOSSIBLE``
    of the closest such pair ``c`` (key FAKE_KEY)."""
    calc = collision_task.TaskCollision._calc_rows

    def with_impossible_row(self, context, output):
        calc(self, context, output)
        rows: TaskLevel = output.get_value()
        distances = self._distances.Eval(context)
        names = distances.names
        if self.controlled is not None:  # (the rows of the pairs the solver can move, as _calc_rows keeps them)
            movable = np.abs(distances.jacobian[:, self.controlled]).max(axis=1) > collision_task.MOVABLE_TOLERANCE
            names = [name for name, kept in zip(names, movable, strict=True) if kept]
        table = [i for i, name in enumerate(names) if "table" in name]
        if not table:
            return
        c = table[int(np.argmin(rows.error[table]))]
        kind = "velocity" if self._velocity is None else "acceleration"
        output.set_value(TaskLevel(np.vstack([rows.jacobian, -rows.jacobian[c]]), np.append(rows.lower, IMPOSSIBLE[kind]),
                                   np.append(rows.upper, np.inf), np.append(rows.error, 0.0), np.append(rows.row_keys, FAKE_KEY)))

    monkeypatch.setattr(collision_task.TaskCollision, "_calc_rows", with_impossible_row)


def without_refinement(monkeypatch):
    def unrefined(solve, tasks, result, first):
        return result

    monkeypatch.setattr(solver_kine, "keep_met_rows", unrefined)
    monkeypatch.setattr(dyn_solve, "keep_met_rows", unrefined)


def run(solver: str):
    if solver == "SolverKine":
        return run_collision_reach(build_collision_reach(), TARGET, duration=0.3, gain=10.0)
    from sotdrake import load_talos

    return run_dyn_collision_reach(build_dyn_collision_reach(load_talos("reduced")), TARGET, duration=0.3)


@pytest.mark.slow
@pytest.mark.parametrize("solver", ["SolverKine", "SolverDyn"])
def test_an_impossible_row_lets_no_pair_through(solver, impossible_row):
    report = run(solver)
    assert report.min_distance >= SAFETY_DISTANCE - TOLERANCE, report
    assert not report.nan and report.limit_excess <= 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("solver", ["SolverKine", "SolverDyn"])
def test_without_the_refinement_the_impossible_row_pulls_pairs_through(solver, impossible_row, monkeypatch):
    without_refinement(monkeypatch)
    assert run(solver).min_distance < SAFETY_DISTANCE - TOLERANCE
