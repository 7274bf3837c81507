"""The solvers' warm starts live in the Context: a cloned Context replays a run bit for bit, the
solver paths included (the tutorial under ``SolverKine``, the dynamic sway under ``SolverDyn``)."""

import numpy as np
import pytest
from conftest import load_diagram
from pydrake.systems.analysis import Simulator

from sotdrake.dynamics.solver_dyn import SolverDyn
from sotdrake.hqp.warm import WarmStart, WarmStarts
from sotdrake.solvers import SolverKine


def _solver(diagram, kind):
    (system,) = [system for system in diagram.GetSystems() if isinstance(system, kind)]
    return system


def _record(diagram, solver, simulator, ticks, dt, read):
    """Advance tick by tick from the simulator's time; each tick's solver outputs (``read``)."""
    records = []
    start = round(simulator.get_context().get_time() / dt)
    for k in range(start + 1, start + ticks + 1):
        simulator.AdvanceTo(k * dt)
        records.append(read(solver, solver.GetMyContextFromRoot(simulator.get_context())))
    return records


def _replays(diagram, solver, dt, read, before, after):
    """Run ``before`` ticks, clone the Context, run ``after`` more ticks on both (the original
    first, so that any state outside the Context has moved on): the records must be identical."""
    simulator = Simulator(diagram)
    simulator.Initialize()
    _record(diagram, solver, simulator, before, dt, read)
    clone = simulator.get_context().Clone()
    first = _record(diagram, solver, simulator, after, dt, read)
    replay = Simulator(diagram, clone)
    replay.Initialize()
    second = _record(diagram, solver, replay, after, dt, read)
    assert len(first) == len(second) == after
    for k, (a, b) in enumerate(zip(first, second, strict=True)):
        for name in a:
            assert np.array_equal(a[name], b[name]) if isinstance(a[name], np.ndarray) else a[name] == b[name], (
                f"tick {before + k + 1}: {name} differs after the clone")
    return first


def _kine(solver, context):
    diagnostics = solver.GetOutputPort("diagnostics").Eval(context)
    return {"control": solver.GetOutputPort("control").Eval(context).copy(),
            "level_solvers": list(diagnostics.level_solvers), "fallbacks": list(diagnostics.fallbacks),
            "iterations": diagnostics.max_iterations}


def _dyn(solver, context):
    diagnostics = solver.GetOutputPort("diagnostics").Eval(context)
    return {"torque": solver.GetOutputPort("torque").Eval(context).copy(),
            "level_solvers": list(diagnostics.level_solvers), "failure": diagnostics.failure,
            "eliminated": diagnostics.torques_eliminated}


@pytest.mark.slow
def test_a_cloned_context_replays_the_tutorial_under_solver_kine():
    appli = load_diagram("talos_appli").build_diagram(push_time=0.005, solver="hqp")
    solver = _solver(appli.diagram, SolverKine)
    records = _replays(appli.diagram, solver, 1e-3, _kine, before=20, after=40)
    assert any("active" in name for record in records for name in record["level_solvers"])
    assert np.all(np.isfinite(records[-1]["control"])) and np.any(records[-1]["control"] != 0.0)


@pytest.mark.slow
def test_a_cloned_context_replays_the_sway_under_solver_dyn():
    run = load_diagram("talos_dynamics").build_diagram("sway", device="dynsimu")
    solver = _solver(run.diagram, SolverDyn)
    records = _replays(run.diagram, solver, run.robot.dt, _dyn, before=20, after=40)
    assert all(record["failure"] == "" for record in records)
    assert np.all(np.isfinite(records[-1]["torque"]))


def test_warm_starts_are_copied_with_the_context():
    warm = WarmStart(3)
    warm.working_sets[(0, False, (1, 1), (1, 1))] = np.array([1, 0, -1])
    warm.failures, warm.skips = 2, 1
    starts = WarmStarts({("full", 3): warm})
    import copy

    copied = copy.deepcopy(starts)
    copied.of(("full", 3), 3).working_sets[(0, False, (1, 1), (1, 1))][0] = 0
    copied.of(("full", 3), 3).failures = 0
    assert warm.working_sets[(0, False, (1, 1), (1, 1))][0] == 1 and warm.failures == 2
    assert copied.of(("reduced", 2), 2).n == 2 and ("reduced", 2) not in starts
    warm.clear()
    assert warm.working_sets == {} and warm.failures == warm.skips == 0 and warm.bound_sides.tolist() == [0, 0, 0]
