"""The solvers' warm starts live in the Context: a cloned Context replays a run bit for bit, the
solver paths included (the tutorial under ``SolverKine``, the dynamic sway under ``SolverDyn``)."""

import copy
import math

import numpy as np
import pytest
from pydrake.systems.analysis import InitializeParams, Simulator

from sotdrake.dynamics.solver_dyn import SolverDyn
from sotdrake.hqp.warm import WarmStart, WarmStarts
from sotdrake.scenarios import talos_appli, talos_dynamics
from sotdrake.solvers import SolverKine


def _solver(diagram, kind):
    (system,) = [system for system in diagram.GetSystems() if isinstance(system, kind)]
    return system


def _warm_state(solver, root_context):
    """The solver's warm starts, as its Context holds them (one abstract state)."""
    context = solver.GetMyContextFromRoot(root_context)
    values = [context.get_abstract_state(i).get_value() for i in range(context.num_abstract_states())]
    (warm,) = [value for value in values if isinstance(value, (WarmStart, WarmStarts))]
    return warm


def _same_warm_state(a, b) -> bool:
    if isinstance(a, WarmStarts):
        return a.keys() == b.keys() and all(_same_warm_state(a[key], b[key]) for key in a)
    sides_a, sides_b = (a.bound_sides, b.bound_sides)
    same_sides = (all(np.array_equal(x, y) for x, y in zip(sides_a, sides_b, strict=True))
                  if isinstance(sides_a, tuple) and isinstance(sides_b, tuple) else
                  not isinstance(sides_a, tuple) and not isinstance(sides_b, tuple) and np.array_equal(sides_a, sides_b))
    counters = ("failures", "skips", "row_failures", "row_skips")
    return (same_sides and all(getattr(a, c) == getattr(b, c) for c in counters)
            and a.working_sets.keys() == b.working_sets.keys()
            and all(np.array_equal(np.asarray(a.working_sets[k]), np.asarray(b.working_sets[k])) for k in a.working_sets))


def _record(solver, simulator, ticks, dt, read):
    """Advance tick by tick from the simulator's time; each tick's solver outputs (``read``)."""
    records = []
    start = math.floor(simulator.get_context().get_time() / dt + 1e-9)
    for k in range(start + 1, start + ticks + 1):
        simulator.AdvanceTo(k * dt)
        records.append(read(solver, solver.GetMyContextFromRoot(simulator.get_context())))
    return records


def _replays(diagram, solver, dt, read, before, after):
    """Run ``before`` ticks and half a tick (a Simulator keeps the events due at its current time
    outside the Context: half a tick on, none is pending), clone the Context, run ``after`` more
    ticks on both (the original first, so that any state outside the Context has moved on): the
    records must be identical."""
    simulator = Simulator(diagram)
    simulator.Initialize()
    _record(solver, simulator, before, dt, read)
    simulator.AdvanceTo((before + 0.5) * dt)
    clone = simulator.get_context().Clone()
    kept = copy.deepcopy(_warm_state(solver, clone))
    assert _warm_state(solver, clone) is not _warm_state(solver, simulator.get_context())
    first = _record(solver, simulator, after, dt, read)
    assert _same_warm_state(_warm_state(solver, clone), kept)  # the original's run left the clone's alone
    replay = Simulator(diagram, clone)
    replay.Initialize(InitializeParams(suppress_initialization_events=True))
    second = _record(solver, replay, after, dt, read)
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
    appli = talos_appli.build_diagram(push_time=0.005, solver="hqp")
    solver = _solver(appli.diagram, SolverKine)
    records = _replays(appli.diagram, solver, 1e-3, _kine, before=20, after=40)
    assert any("active" in name for record in records for name in record["level_solvers"])
    assert np.all(np.isfinite(records[-1]["control"])) and np.any(records[-1]["control"] != 0.0)


@pytest.mark.slow
def test_a_cloned_context_replays_the_sway_under_solver_dyn():
    run = talos_dynamics.build_diagram("sway", device="dynsimu")
    solver = _solver(run.diagram, SolverDyn)
    records = _replays(run.diagram, solver, run.robot.dt, _dyn, before=20, after=40)
    assert all(record["failure"] == "" for record in records)
    assert np.all(np.isfinite(records[-1]["torque"]))


def test_a_context_cloned_at_a_tick_replays_the_run_and_its_kinematics():
    """Drake copies a cache entry as up to date with its context: a cloned plant context held in
    one (the kinematics') must be at the original's configuration, not at the default one."""
    from sotdrake.scenarios import kinesimple

    run = kinesimple.build_diagram()
    device, dynamic = run.robot.device, run.robot.dynamic
    simulator = Simulator(run.diagram)
    simulator.Initialize()
    simulator.AdvanceTo(0.1)
    clone = simulator.get_context().Clone()
    assert np.array_equal(dynamic.GetOutputPort("Jcom").Eval(dynamic.GetMyContextFromRoot(clone)),
                          dynamic.GetOutputPort("Jcom").Eval(dynamic.GetMyContextFromRoot(simulator.get_context())))
    replay = Simulator(run.diagram, clone)
    replay.Initialize()
    simulator.AdvanceTo(0.2)
    replay.AdvanceTo(0.2)
    state = device.GetOutputPort("state")
    assert np.array_equal(state.Eval(device.GetMyContextFromRoot(clone)),
                          state.Eval(device.GetMyContextFromRoot(simulator.get_context())))


def test_warm_starts_are_copied_with_the_context():
    warm = WarmStart(3)
    warm.working_sets[(0, False, (1, 1), (1, 1))] = np.array([1, 0, -1])
    warm.failures, warm.skips = 2, 1
    starts = WarmStarts({("full", 3): warm})
    copied = copy.deepcopy(starts)
    copied.of(("full", 3), 3).working_sets[(0, False, (1, 1), (1, 1))][0] = 0
    copied.of(("full", 3), 3).failures = 0
    assert warm.working_sets[(0, False, (1, 1), (1, 1))][0] == 1 and warm.failures == 2
    assert copied.of(("reduced", 2), 2).n == 2 and ("reduced", 2) not in starts
    warm.clear()
    assert warm.working_sets == {} and warm.failures == warm.skips == 0 and warm.bound_sides.tolist() == [0, 0, 0]
